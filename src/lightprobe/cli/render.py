"""``lightprobe render``: a scene or a mesh under a probe, by SH, brute force, or the Mitsuba 3 reference."""

from __future__ import annotations

from pathlib import Path

from .common import ImageSize, Number, add_option, probe_path, refuse

MAX_ORDER = 32
SPP_RANGES = {"sh": (1, 16), "brute": (1, 16), "reference": (1, 65536)}
DEFAULT_SPP = {"sh": 2, "brute": 2, "reference": 256}


def register(sub) -> None:
    from ..names import RENDER_METHODS as METHODS, WINDOWS

    p = sub.add_parser("render", help="render a scene or a mesh under a probe (sh, brute, or the Mitsuba reference)",
                       description="Render a scene file (.yaml/.json) or a mesh file (.obj, .ply, .glb, ...; placed on "
                                   "a ground plane) under a probe. Output: .exr (linear radiance) or .png (tone-mapped).")
    p.add_argument("scene", nargs="?", type=Path,
                   help="scene (.yaml, .yml, .json) or mesh file; omitted: the built-in sphere-and-torus scene")
    p.add_argument("--probe", type=Path, help="environment map (default: the scene's, else the shipped probe)")
    p.add_argument("--method", "-m", choices=[*METHODS, "reference"], default="sh")
    p.add_argument("--output", "-o", type=Path, required=True)
    add_option(p, "--size", type=ImageSize(16384), help="image WxH (default: the scene's camera, 256x256 for meshes)")
    add_option(p, "--spp", type=Number(int, 1, 65536),
               help="sh/brute: spp×spp samples per pixel (1..16, default 2); reference: samples per pixel "
                    "(default 256)")
    add_option(p, "--order", type=Number(int, 0, MAX_ORDER), default=2, help="SH order l_max")
    p.add_argument("--window", choices=WINDOWS, default="none", help="SH de-ringing window")
    p.add_argument("--per-vertex", action="store_true", help="SH evaluated at vertices and interpolated")
    p.add_argument("--gi", action="store_true", help="reference: full global illumination (default: direct only)")
    add_option(p, "--exposure", type=Number(float, -64, 64), default=0.0, help="exposure in stops for .png output")
    p.set_defaults(run=run)


def scene_for(args):
    from dataclasses import replace

    from ..envmap import read_envmap
    from ..render.scene import builtin_scene, mesh_scene
    from ..render.scenefile import load_scene

    env = read_envmap(args.probe) if args.probe else None
    path = args.scene
    if path is None:
        scene = builtin_scene(env or read_envmap(probe_path(None)))
    elif path.suffix.lower() in (".yaml", ".yml", ".json"):
        scene = load_scene(path, env)
    else:
        scene = mesh_scene(path, env or read_envmap(probe_path(None)))
    if args.size:
        w, h = args.size
        scene = replace(scene, camera=replace(scene.camera, width=w, height=h))
    return scene


def run(args) -> None:
    from ..files import check_output
    from ..io import WRITE_FORMATS, write_image
    from ..render.methods import method
    from ..render.renderer import render

    if args.output.suffix.lower() not in WRITE_FORMATS:
        refuse(f"cannot write {args.output}: use one of {', '.join(WRITE_FORMATS)}")
    inputs = [p for p in (args.scene, args.probe) if p is not None]
    check_output(args.output, inputs)
    spp = DEFAULT_SPP[args.method] if args.spp is None else args.spp
    lo, hi = SPP_RANGES[args.method]
    if not lo <= spp <= hi:
        refuse(f"--spp for {args.method} must be within {lo}..{hi}, got {spp}")
    if args.size is not None and args.method != "reference":  # refuse before reading anything when the size says so
        from ..limits import check_memory
        from ..render.renderer import render_memory

        check_memory(render_memory(*args.size, spp, 0), f"rendering {args.size[0]}x{args.size[1]} at {spp}x{spp} "
                                                        "samples per pixel", kernels=True)
    scene = scene_for(args)  # both renderers check their memory estimate against the budget before they start
    if args.method == "reference":
        from ..render.reference import reference_render

        result = reference_render(scene, spp, args.gi)
    else:
        options = {"order": args.order, "per_vertex": args.per_vertex, "window": args.window} \
            if args.method == "sh" else {}
        result = render(scene, method(args.method, **options), spp)
    write_image(args.output, result.image, exposure=args.exposure, curve="aces", inputs=inputs)
    total = sum(result.seconds.values())
    print(f"wrote {args.output} ({result.method}; {scene.camera.width}x{scene.camera.height}, {total:.2f} s)")
