"""``lightprobe convert``: between layouts (and sizes, and turned), energy-conserving."""

from __future__ import annotations

from pathlib import Path

from .common import Number, Triple, add_option, layout_names, load, refuse

LDR_WRITE_BYTES_PER_PIXEL = 40  # .png/.jpg: the flat output image, its tone-mapped and 8-bit copies, the encoding
HDR_WRITE_BYTES = 32 << 20  # .exr/.hdr/.pfm are written in strips as they are computed: one strip, and the read-back


def register(sub) -> None:
    from ..util.names import CURVES

    p = sub.add_parser("convert", help="convert between layouts (and rotate)",
                       description="Convert between layouts with footprint-aware resampling (∫L dω conserved), "
                                   "optionally turning the environment.")
    p.add_argument("src", type=Path, help="input environment map")
    p.add_argument("dst", type=Path, help="output: .exr, .hdr, .pfm, or .png/.jpg (tone-mapped)")
    p.add_argument("--to", "-t", required=True, choices=layout_names(), help="target layout (cube: a 6N×N strip)")
    add_option(p, "--size", type=Number(int, 1, 65536),
               help="height (latlong, angular, sphere) or face edge (cube, cross, hcross); default keeps the "
                    "angular resolution")
    add_option(p, "--rotate", metavar="Y,P,R", type=Triple(-36000, 36000),
               help="turn the environment by yaw,pitch,roll degrees (R = Ry·Rx·Rz, +Y up)")
    p.add_argument("--layout", "-l", choices=layout_names(), help="layout of the input (default: from aspect ratio)")
    p.add_argument("--half", action="store_true", help="write half floats (EXR only)")
    add_option(p, "--exposure", type=Number(float, -64, 64), default=0.0, help="exposure in stops for .png/.jpg")
    p.add_argument("--curve", choices=CURVES, default="srgb", help="tone curve for .png/.jpg output")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..maps import check_size, resample, resample_memory, resample_strips
    from ..util.files import check_output
    from ..maps.frames import as_rotation
    from ..maps.images import HDR_WRITE_FORMATS, WRITE_FORMATS, image_header, write_image_strips
    from ..maps.layouts import layout as layout_named

    if args.dst.suffix.lower() not in WRITE_FORMATS:
        refuse(f"cannot write {args.dst}: unknown image format; use one of {', '.join(WRITE_FORMATS)}")
    check_output(args.dst, [args.src])
    target = layout_named(args.to)
    rotation = as_rotation(args.rotate) if args.rotate is not None else None
    header = image_header(args.src)
    out_pixels = check_size(target, args.size or target.default_size(header.pixels))
    streamed = args.dst.suffix.lower() in HDR_WRITE_FORMATS
    writing = HDR_WRITE_BYTES if streamed else out_pixels * LDR_WRITE_BYTES_PER_PIXEL
    source = layout_named(args.layout) if args.layout else _detected(header)
    _link_kernels(source, header.pixels, target, args.size or target.default_size(header.pixels), rotation, streamed)
    env = load(args.src, args.layout, extra_bytes=resample_memory(header.pixels, out_pixels, target, source) + writing,
               kernels=True,
               what=f"converting {args.src} ({header.width}×{header.height}) to {args.to} ({out_pixels} pixels)")
    size = args.size or target.default_size(env.valid_pixels)
    if streamed:  # each strip is written as it is computed
        shape, strips = resample_strips(env, target, size, rotation=rotation)
        write_image_strips(args.dst, shape, strips, half=args.half, inputs=[args.src])
    else:
        out = resample(env, target, size, rotation=rotation)
        out.save(args.dst, exposure=args.exposure, curve=args.curve, inputs=[args.src])
    print(f"wrote {args.dst} ({args.to}, size {size})")


def _detected(header):
    """The source's layout as its aspect ratio says, for the memory estimate (None where it cannot tell: the read
    that follows says why)."""
    from ..util.errors import LayoutError
    from ..maps.layouts import detect_layout

    try:
        return detect_layout(header.width, header.height)
    except LayoutError:
        return None


def _link_kernels(source, source_pixels: int, target, size: int, rotation, streamed: bool) -> None:
    """Link the conversion's compiled kernels on a small map that takes its route before the map itself is read
    (:func:`lightprobe.maps.link_kernels`), then let LLVM's pages go (:func:`lightprobe.util.jit.release_compiler_pages`):
    they would otherwise stay resident beside the map through the conversion — 4k lat-long → cube: 321 → 257 MiB at
    the peak, 3.35 → 2.68× the map. A path the small map does not take links its kernel later, reading back only the
    pages it needs."""
    from ..maps import link_kernels
    from ..util.jit import release_compiler_pages

    if source is None:  # the read that follows says why
        return
    link_kernels(source, source_pixels, target, size, rotation=rotation, streamed=streamed)
    release_compiler_pages()
