"""``lightprobe sh``: the radiance SH coefficients of a map (paper Figure 2 with ``--frame rh2001``)."""

from __future__ import annotations

import sys
from pathlib import Path

from .common import Number, add_option, add_probe, load, refuse, write_text

MAX_ORDER = 64
WORKING_BYTES_PER_PIXEL = 64  # per-pixel directions and solid angles for layouts other than lat-long


def register(sub) -> None:
    from ..util.names import FRAMES, WINDOWS

    p = sub.add_parser("sh", help="spherical-harmonic coefficients of the lighting (paper Figure 2)",
                       description="Radiance SH coefficients L_lm (real SH without Condon-Shortley phase, flat "
                                   "order l(l+1)+m) of a map, in a chosen frame. JSON is lightprobe's SH schema "
                                   "(format lightprobe.sh, version 2), the same as 'export --to json'.")
    add_probe(p)
    add_option(p, "--order", type=Number(int, 0, MAX_ORDER), default=2, help="l_max (2: nine coefficients)")
    p.add_argument("--frame", choices=list(FRAMES), default="world",
                   help="frame of the coefficients (rh2001: the paper's; world: +Y up, front -Z)")
    p.add_argument("--window", choices=WINDOWS, default="none", help="de-ringing window")
    p.add_argument("--format", choices=("json", "csv", "npy"), default="json")
    p.add_argument("--json", dest="format", action="store_const", const="json", help="same as --format json")
    p.add_argument("--output", "-o", type=Path, help="write to a file instead of stdout (needed for npy)")
    p.set_defaults(run=run)


def run(args) -> None:
    import numpy as np

    from ..sh.basis import degree_order, name, project
    from ..sh.shfile import sh_json

    inputs = [args.file] if args.file else []
    if args.format == "npy" and not args.output:
        refuse("--format npy needs --output FILE")
    if args.output:
        from ..util.files import check_output

        check_output(args.output, inputs, text=args.format != "npy")
    sh = project(load(args.file, args.layout, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL), args.order,
                 args.frame).windowed(args.window)
    if args.format == "npy":
        import io

        buffer = io.BytesIO()
        np.save(buffer, sh.coeffs)
        from ..util.files import write_bytes

        write_bytes(args.output, buffer.getvalue(), inputs)
        return
    if args.format == "csv":
        rows = ["name,l,m,R,G,B"] + [f"{name(i)},{degree_order(i)[0]},{degree_order(i)[1]},"
                                     + ",".join(f"{v:.9g}" for v in row) for i, row in enumerate(sh.coeffs)]
        text = "\n".join(rows) + "\n"
    else:
        text = sh_json(sh, sh.frame, str(args.file or "(shipped probe)"))
    if args.output:
        write_text(args.output, text, inputs)
    else:
        sys.stdout.write(text)
