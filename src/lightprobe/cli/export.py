"""``lightprobe export``: SH irradiance in an engine's frame, sign convention and scaling, or the whole environment
in an engine's own container (Babylon ``.env``, glTF ``EXT_lights_image_based``)."""

from __future__ import annotations

from pathlib import Path

from .common import Number, add_option, add_probe, load, refuse, write_text

CONTAINERS = ("babylon-env",)
GLB_MAGIC = b"glTF"  # the first bytes of every binary glTF


def register(sub) -> None:
    from ..util.names import EXPORT_TARGETS as TARGETS, FRAMES, GLTF_SCALINGS, WINDOWS

    p = sub.add_parser("export", help="lighting for engines (three.js, Filament, Unity, glTF, Babylon, GLSL)",
                       description="Nine SH coefficients converted to an engine's frame, sign convention and "
                                   "scaling (see the README's table); with 'gltf' from a map, or 'babylon-env', the "
                                   "whole environment: GGX-prefiltered specular mips beside the SH.")
    add_probe(p)
    p.add_argument("--sh", type=Path, help="start from coefficients in lightprobe's SH JSON (from 'sh --json' or "
                                           "'design --json') instead of projecting a map")
    p.add_argument("--lights", type=Path, help="export the area lights of a 'lightprobe lights' JSON (with its "
                                               "ambient SH) as the engine's directional lights, instead of SH alone")
    p.add_argument("--to", "-t", required=True, choices=TARGETS + CONTAINERS)
    p.add_argument("--output", "-o", type=Path, required=True,
                   help="gltf from a map: .glb (binary) or .gltf (images embedded); babylon-env: .env")
    p.add_argument("--frame", choices=list(FRAMES), help="override the target's own frame")
    p.add_argument("--gltf-scaling", choices=GLTF_SCALINGS, default="irradiance",
                   help="glTF irradianceCoefficients: irradiance E_lm as Babylon.js's loader reads them (default), or "
                        "pi*L_lm (files of lightprobe 0.1)")
    add_option(p, "--specular-size", type=Number(int, 1, 512), default=256,
               help="face size of the specular cube in gltf/babylon-env files, a power of two (default 256)")
    p.add_argument("--window", choices=WINDOWS, default="none", help="de-ringing window")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..util.files import check_output

    inputs = [p for p in (args.file, args.sh, args.lights) if p is not None]
    if args.lights is not None:
        export_lights_file(args, inputs)
        return
    container = args.to in CONTAINERS or (args.to == "gltf" and args.sh is None)
    check_output(args.output, inputs, text=not container, signature=container_signature(args) if container else None)
    if args.sh is not None:
        if args.file is not None:
            refuse("give a map or --sh, not both")
        if args.to in CONTAINERS:
            refuse(f"--to {args.to} holds the environment itself: give the map, not --sh")
        sh = read_sh(args.sh)
        env = None
    else:
        env, sh = map_and_sh(args)
    sh = sh.windowed(args.window)
    if container:
        write_container(args, env, sh, inputs)
        return
    from ..exports.sh import export

    text = export(sh, args.to, args.frame, args.gltf_scaling, csharp=args.output.suffix.lower() == ".cs")
    write_text(args.output, text, inputs)
    print(f"wrote {args.output} ({args.to})")


def export_lights_file(args, inputs) -> None:
    from ..util.files import check_output, read_bounded
    from ..exports.lights import export_lights
    from ..lights.lightsfile import MAX_BYTES, read_lights_json
    from ..util.names import LIGHT_EXPORT_TARGETS

    if args.file is not None or args.sh is not None:
        refuse("--lights carries its own ambient: give no map and no --sh")
    if args.to not in LIGHT_EXPORT_TARGETS:
        refuse(f"--lights exports to {', '.join(LIGHT_EXPORT_TARGETS)}, not {args.to}")
    if args.frame is not None or args.window != "none":
        refuse("--lights exports in each engine's own frame, without a window")
    gltf = args.to == "gltf"
    if gltf and args.output.suffix.lower() not in (".glb", ".gltf"):
        refuse(f"--to gltf writes a .glb or .gltf file, not {args.output.name}")
    check_output(args.output, inputs, text=not gltf, signature=container_signature(args) if gltf else None)
    lights = read_lights_json(read_bounded(args.lights, MAX_BYTES, "lights file"), str(args.lights))
    if gltf:
        from ..exports.containers import glb, gltf_embedded
        from ..util.files import write_bytes
        from ..exports.lights import gltf_lights

        document, images = gltf_lights(lights)
        if args.output.suffix.lower() == ".glb":
            write_bytes(args.output, glb(document, images), inputs, signature=GLB_MAGIC)
        else:
            write_text(args.output, gltf_embedded(document, images), inputs)
    else:
        write_text(args.output, export_lights(lights, args.to), inputs)
    print(f"wrote {args.output} ({len(lights.radii)} lights + ambient for {args.to})")


def container_signature(args) -> bytes | None:
    """The first bytes of the binary container ``args`` asks for (Babylon's .env, a .glb), or None for text (.gltf):
    an existing output is overwritten only when it starts with them."""
    if args.to == "babylon-env":
        from ..exports.containers import ENV_MAGIC

        return ENV_MAGIC
    return GLB_MAGIC if args.output.suffix.lower() == ".glb" else None


def read_sh(path: Path):
    from ..sh.shfile import MAX_BYTES, read_sh_json
    from ..util.files import read_bounded

    sh = read_sh_json(read_bounded(path, MAX_BYTES, "SH file"), str(path))
    if sh.quantity != "radiance" or sh.l_max < 2:
        refuse(f"{path}: exports need radiance coefficients up to band 2")
    return sh


def map_and_sh(args):
    from ..sh.basis import project

    extra = 0
    if args.to in CONTAINERS or args.to == "gltf":
        from ..exports.containers import check_specular_size
        from ..glossy.prefilter import prefilter_memory

        extra = prefilter_memory(check_specular_size(args.specular_size))
    env = load(args.file, args.layout, working_bytes_per_pixel=64, extra_bytes=extra)
    return env, project(env, 2)


def write_container(args, env, sh, inputs) -> None:
    from ..exports.containers import babylon_env, glb, gltf_embedded, gltf_ibl
    from ..util.files import write_bytes
    from ..maps.frames import BABYLON, frame

    f = frame(args.frame) if args.frame else BABYLON
    if args.to == "babylon-env":
        write_bytes(args.output, babylon_env(env, sh, args.specular_size, f), inputs,
                    signature=container_signature(args))
    else:
        document, images = gltf_ibl(env, sh, args.specular_size, args.gltf_scaling, f)
        if args.output.suffix.lower() == ".glb":
            write_bytes(args.output, glb(document, images), inputs, signature=GLB_MAGIC)
        else:
            write_text(args.output, gltf_embedded(document, images), inputs)
    print(f"wrote {args.output} ({args.to}, {args.specular_size}² specular cube, frame {f.name})")
