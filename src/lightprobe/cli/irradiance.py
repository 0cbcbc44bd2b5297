"""``lightprobe irradiance``: an irradiance map by SH or by brute force."""

from __future__ import annotations

from pathlib import Path

from .common import ImageSize, Number, add_option, add_probe, layout_names, load, refuse

MAX_ORDER = 32
OUTPUT_BYTES_PER_PIXEL = 400  # normals (float64), the SH basis at every normal (order ≤ 32 adds the band count)
INPUT_WORKING_BYTES_PER_PIXEL = 64  # brute force: the map's weighted light samples


def register(sub) -> None:
    from ..util.names import WINDOWS

    p = sub.add_parser("irradiance", help="irradiance map (SH or brute force)",
                       description="Irradiance E (not divided by pi) for every texel direction taken as a surface "
                                   "normal, by SH (fast), by brute-force integration of the whole map (exact), "
                                   "or by the hybrid (area lights exact + SH of the ambient).")
    add_probe(p, layout_flag="--in-layout")
    p.add_argument("--output", "-o", type=Path, required=True, help="output image (.exr, .hdr, .pfm, .png)")
    p.add_argument("--layout", dest="out_layout", choices=layout_names(), default="latlong", help="output layout")
    add_option(p, "--size", type=ImageSize(65536, single=True), default="64x32",
               help="N (the layout's size) or WxH of the output")
    add_option(p, "--order", type=Number(int, 0, MAX_ORDER), default=None,
               help="SH order l_max: of the map for --method sh (default 2), of the ambient for --method hybrid "
                    "(default 12)")
    p.add_argument("--method", choices=("sh", "brute", "hybrid"), default="sh",
                   help="sh: the map's SH; brute: every pixel summed (exact); hybrid: the map's area lights "
                        "(Arbree et al. 2005) summed exactly plus SH of the ambient")
    p.add_argument("--window", choices=WINDOWS, default="none", help="de-ringing window for --method sh")
    p.set_defaults(run=run)


def layout_size(size: tuple[int, int | None], layout) -> int:
    """The layout's size from 'N' or from 'WxH' (which must be the image shape of that layout)."""
    w, h = size
    if h is None:
        return w
    n = h // layout.aspect[1] if layout.faces == 1 else h
    expected = (6 * n, n) if layout.faces == 6 else tuple(layout.grid_shape(max(n, 1))[::-1])
    if n < 1 or (w, h) != expected:
        refuse(f"--size {w}x{h} does not fit the {layout.name} layout (an image {expected[0]}x{expected[1]} would)")
    return n


def run(args) -> None:
    from ..maps import check_size
    from ..util.files import check_output
    from ..sh.irradiance import irradiance_map
    from ..maps.layouts import layout as layout_named

    check_output(args.output, [args.file])
    lay = layout_named(args.out_layout)
    size = layout_size(args.size, lay)
    pixels = check_size(lay, size)
    env = load(args.file, args.layout, working_bytes_per_pixel=INPUT_WORKING_BYTES_PER_PIXEL,
               extra_bytes=pixels * OUTPUT_BYTES_PER_PIXEL)
    if args.method == "hybrid":
        from ..lights.hybrid import DEFAULT_AMBIENT_ORDER, hybrid_irradiance_map

        out = hybrid_irradiance_map(env, lay, size, DEFAULT_AMBIENT_ORDER if args.order is None else args.order)
    else:
        out = irradiance_map(env, lay, size, args.method, 2 if args.order is None else args.order, args.window)
    out.to_envmap_image().save(args.output, inputs=[args.file])
    print(f"wrote {args.output} (irradiance, {args.method}, {lay.name} size {size})")
