"""``lightprobe render``: a scene or a mesh under a probe, by SH, brute force, or the Mitsuba 3 reference."""

from __future__ import annotations

from pathlib import Path

from .common import ImageSize, Number, add_option, probe_path, refuse

MAX_ORDER = 32
SPP_RANGES = {"reference": (1, 65536)}  # the project's renderer: 1..16 per axis
DEFAULT_SPP = {"reference": 256}  # the project's renderer: 2 per axis


def register(sub) -> None:
    from ..util.names import RENDER_METHODS as METHODS, WINDOWS

    p = sub.add_parser("render", help="render a scene or a mesh under a probe (sh, brute, hybrid, lights, mediancut, varmin, "
                            "or the Mitsuba reference)",
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
    add_option(p, "--order", type=Number(int, 0, MAX_ORDER), default=None,
               help="SH order l_max: of the map for sh (default 2), of the ambient for lights and hybrid (12)")
    p.add_argument("--window", choices=WINDOWS, default="none", help="SH de-ringing window")
    p.add_argument("--per-vertex", action="store_true", help="SH evaluated at vertices and interpolated")
    p.add_argument("--gi", action="store_true", help="reference: full global illumination (default: direct only)")
    add_option(p, "--light-samples", type=Number(int, 1, 1024), default=16,
               help="lights: stratified shadow rays per light per shading point")
    p.add_argument("--ao", action="store_true",
                   help="lights: shadow the ambient too (brightness-weighted cosine occlusion rays)")
    add_option(p, "--ao-samples", type=Number(int, 1, 1024), default=16, help="lights --ao: rays per shading point")
    add_option(p, "--count", type=Number(int, 1, 4096), default=16,
               help="mediancut, varmin: number of point lights (any number; a power of two is the papers' own cut)")
    add_option(p, "--seed", type=Number(int, 0, 2 ** 63 - 1), default=0,
               help="lights: the random generator's seed (a render is the same bit for bit for the same seed)")
    add_option(p, "--views", type=Number(int, 1, 1000), default=12,
               help="rsibr: source views (12, 42 or 162)")
    add_option(p, "--map-size", type=Number(int, 8, 1024), default=128,
               help="direct, rsibr: texels across each radiance map")
    p.add_argument("--per-pixel-view", action="store_true",
                   help="rsibr: blend each pixel's own view (not one map per frame)")
    p.add_argument("--warp", choices=("normal", "mirror"), help="rsibr: the warp (default: the BRDF's central direction)")
    p.add_argument("--paper-synthesis", action="store_true",
                   help="rsibr: warp the whole maps as Cabral et al. do (default: the smooth part summed exactly)")
    add_option(p, "--exposure", type=Number(float, -64, 64), default=0.0, help="exposure in stops for .png output")
    p.set_defaults(run=run)


def scene_for(args):
    from dataclasses import replace

    from ..maps import read_envmap
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


def method_options(args) -> dict:
    """The options of the chosen method, from the command line (checked: a bad count is one line, exit 2)."""
    from ..lights.hybrid import DEFAULT_AMBIENT_ORDER

    if args.method in ("mediancut", "varmin"):
        from ..lights.baselines import check_count

        check_count(args.count)
        return {"count": args.count}
    if args.method == "sh":
        return {"order": 2 if args.order is None else args.order, "per_vertex": args.per_vertex,
                "window": args.window}
    order = DEFAULT_AMBIENT_ORDER if args.order is None else args.order
    if args.method == "lights":
        return {"light_samples": args.light_samples, "ao": args.ao, "ao_samples": args.ao_samples,
                "seed": args.seed, "order": order}
    if args.method == "direct":
        return {"map_size": args.map_size}
    if args.method == "rsibr":
        return {"views": args.views, "map_size": args.map_size, "per_pixel_view": args.per_pixel_view,
                "warp": args.warp, "smooth": not args.paper_synthesis}
    return {"order": order} if args.method == "hybrid" else {}


def run(args) -> None:
    from ..util.files import check_output
    from ..maps.images import WRITE_FORMATS, write_image
    from ..render.methods import method
    from ..render.renderer import render

    if args.output.suffix.lower() not in WRITE_FORMATS:
        refuse(f"cannot write {args.output}: use one of {', '.join(WRITE_FORMATS)}")
    inputs = [p for p in (args.scene, args.probe) if p is not None]
    check_output(args.output, inputs)
    spp = DEFAULT_SPP.get(args.method, 2) if args.spp is None else args.spp
    lo, hi = SPP_RANGES.get(args.method, (1, 16))
    if not lo <= spp <= hi:
        refuse(f"--spp for {args.method} must be within {lo}..{hi}, got {spp}")
    options = method_options(args) if args.method != "reference" else {}
    if args.size is not None and args.method != "reference":  # refuse before reading anything when the size says so
        from ..util.limits import check_memory
        from ..render.renderer import render_memory

        check_memory(render_memory(*args.size, spp, 0), f"rendering {args.size[0]}x{args.size[1]} at {spp}x{spp} "
                                                        "samples per pixel", kernels=True)
    scene = scene_for(args)  # both renderers check their memory estimate against the budget before they start
    if args.method == "reference":
        from ..render.reference import reference_render

        result = reference_render(scene, spp, args.gi)
    else:
        result = render(scene, method(args.method, **options), spp)
    write_image(args.output, result.image, exposure=args.exposure, curve="aces", inputs=inputs)
    total = sum(result.seconds.values())
    print(f"wrote {args.output} ({result.method}; {scene.camera.width}x{scene.camera.height}, {total:.2f} s)")
