"""``lightprobe design``: edit SH lighting and see it on spheres (paper §3.3, Figure 4)."""

from __future__ import annotations

from pathlib import Path

from .common import Number, add_option, add_probe, load, write_text


def register(sub) -> None:
    p = sub.add_parser("design", help="edit SH lighting and see it on spheres (paper Figure 4)",
                       description="Edit radiance SH coefficients (world frame) and render the nine basis "
                                   "functions and the original and edited lighting on white spheres, front and back.")
    add_probe(p)
    p.add_argument("--output", "-o", type=Path, required=True, help="PNG picture")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="Llm=V",
                   help="set a coefficient, e.g. L1-1=-0.4 or L20=0.1,0.2,0.3 (repeatable; finite values, "
                        "|V| ≤ 1e9)")
    p.add_argument("--scale-band", dest="scales", action="append", default=[], metavar="L=F",
                   help="multiply band L (0..2) by F (|F| ≤ 1e6), e.g. 2=0.5 (repeatable)")
    add_option(p, "--size", type=Number(int, 16, 1024), default=128, help="sphere size in pixels")
    p.add_argument("--json", type=Path, help="also write the edited coefficients (lightprobe SH JSON)")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..sh.design import design_figure, edit
    from ..util.files import atomic_outputs, check_output
    from ..maps.images import write_image
    from ..sh.basis import project
    from ..sh.shfile import sh_json

    inputs = [args.file] if args.file else []
    check_output(args.output, inputs)
    if args.json:
        check_output(args.json, inputs + [args.output], text=True)
    original = project(load(args.file, args.layout, working_bytes_per_pixel=64), 2)
    edited = edit(original, args.sets, args.scales)
    with atomic_outputs([args.output, args.json]):  # both or neither
        write_image(args.output, design_figure(original, edited, args.size), encoded=True, inputs=inputs)
        if args.json:
            write_text(args.json, sh_json(edited, source=str(args.file or "(shipped probe)")), inputs + [args.output])
    print(f"wrote {args.output}")
