"""``lightprobe compare``: relative MSE, MARE and HDR-FLIP of a rendering against a reference."""

from __future__ import annotations

from pathlib import Path

from .common import print_json

WORKING_BYTES_PER_PIXEL = 110  # per image: float64 copies, FLIP's buffers, the error maps (~120 B/px measured in all)


def register(sub) -> None:
    p = sub.add_parser("compare", help="error of a rendering against a reference (relMSE, MARE, HDR-FLIP)",
                       description="Relative MSE, mean absolute relative error and HDR-FLIP of TEST against REF "
                                   "(linear HDR images of one size), and an error heat map. NaN, infinite and "
                                   "negative pixels are replaced by 0 with a warning, as everywhere.")
    p.add_argument("test", type=Path)
    p.add_argument("reference", type=Path)
    p.add_argument("--heatmap", type=Path, help="write the relative-error heat map (PNG)")
    p.add_argument("--flipmap", type=Path, help="write the FLIP error map (PNG)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..maps import repair
    from ..util.files import atomic_outputs, check_output, distinct_outputs
    from ..maps.images import image_header, read_image, write_image
    from ..util.limits import check_memory
    from ..render.compare import compare, error_heatmap, hdr_flip
    from ..maps.tonemap import heatmap

    inputs = [args.test, args.reference]
    for out in distinct_outputs([args.heatmap, args.flipmap]):
        check_output(out, inputs)
    headers = [image_header(p) for p in inputs]
    check_memory(sum(h.read_bytes() + h.pixels * WORKING_BYTES_PER_PIXEL for h in headers),
                 f"comparing {args.test} with {args.reference}")
    test = repair(read_image(args.test), str(args.test))
    ref = repair(read_image(args.reference), str(args.reference))
    metrics = compare(test, ref)
    with atomic_outputs([args.heatmap, args.flipmap]):  # both or neither; one file named twice is refused
        if args.heatmap:
            write_image(args.heatmap, error_heatmap(test, ref), encoded=True, inputs=inputs)
        if args.flipmap:
            write_image(args.flipmap, heatmap(hdr_flip(test, ref)[1], 1.0), encoded=True, inputs=inputs)
    if args.json:
        print_json(metrics.as_dict())
    else:
        print(f"relative MSE {metrics.relative_mse:.4g}   MARE {metrics.mare:.4g}   HDR-FLIP {metrics.flip:.4g}   "
              f"({metrics.pixels} pixels)")
