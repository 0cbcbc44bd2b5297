"""``lightprobe export``: nine SH coefficients in an engine's frame, sign convention and scaling."""

from __future__ import annotations

from pathlib import Path

from .common import add_probe, load, refuse, write_text


def register(sub) -> None:
    from ..export import GLTF_SCALINGS, TARGETS
    from ..frames import FRAMES
    from ..sh import WINDOWS

    p = sub.add_parser("export", help="SH irradiance for engines (three.js, Filament, Unity, glTF, Babylon, GLSL)",
                       description="Nine SH coefficients converted to an engine's frame, sign convention and "
                                   "scaling (see the README's table).")
    add_probe(p)
    p.add_argument("--sh", type=Path, help="start from coefficients in lightprobe's SH JSON (from 'sh --json' or "
                                           "'design --json') instead of projecting a map")
    p.add_argument("--to", "-t", required=True, choices=TARGETS)
    p.add_argument("--output", "-o", type=Path, required=True)
    p.add_argument("--frame", choices=list(FRAMES), help="override the target's own frame")
    p.add_argument("--gltf-scaling", choices=GLTF_SCALINGS, default="irradiance",
                   help="glTF irradianceCoefficients: irradiance E_lm as Babylon.js's loader reads them (default), or "
                        "pi*L_lm (files of lightprobe 0.1)")
    p.add_argument("--window", choices=WINDOWS, default="none", help="de-ringing window")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..export import export
    from ..files import check_output
    from ..sh import project

    inputs = [p for p in (args.file, args.sh) if p is not None]
    check_output(args.output, inputs, text=True)
    if args.sh is not None:
        if args.file is not None:
            refuse("give a map or --sh, not both")
        from ..io import check_regular_file
        from ..shfile import read_sh_json

        check_regular_file(args.sh, "SH file")
        sh = read_sh_json(args.sh.read_bytes()[: 8 << 20], str(args.sh))
        if sh.quantity != "radiance" or sh.l_max < 2:
            refuse(f"{args.sh}: exports need radiance coefficients up to band 2")
    else:
        sh = project(load(args.file, args.layout, working_bytes_per_pixel=64), 2)
    text = export(sh.windowed(args.window), args.to, args.frame, args.gltf_scaling,
                  csharp=args.output.suffix.lower() == ".cs")
    write_text(args.output, text, inputs)
    print(f"wrote {args.output} ({args.to})")
