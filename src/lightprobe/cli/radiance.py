"""``lightprobe radiance``: radiance environment maps for a BRDF at geodesic views, or one exact map for one view
(Cabral, Olano & Nemec 1999; docs/spec.md §4)."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from .common import Number, add_option, add_probe, load, refuse

WORKING_BYTES_PER_PIXEL = 64  # the working cube's resampling of each input pixel
# Synthesis, per texel of each of the set's maps: the maps stacked for the kernel and their residuals (24 bytes),
# and the new map's own arrays (~250 bytes a texel of one map, under 24 a texel of each of a set's 12 or more maps)
SYNTHESIS_BYTES_PER_TEXEL = 48


def _direction(text: str):
    import numpy as np

    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.isfinite(v).all() or np.linalg.norm(v) < 1e-9:
        raise argparse.ArgumentTypeError(f"wants a direction X,Y,Z (not all 0), got {text[:40]!r}")
    return v / np.linalg.norm(v)


def register(sub) -> None:
    p = sub.add_parser("radiance", help="radiance environment maps of a BRDF (Cabral, Olano & Nemec 1999)",
                       description="Compute sphere-layout radiance maps L_r(n; v) of an isotropic BRDF: one per "
                                   "view of an icosahedron (12) or its geodesic subdivisions (42, 162) into a "
                                   "folder with manifest.json (format lightprobe.radiance, version 1), or with "
                                   "--view one exact map for one view (OUT.exr and OUT.json); or, with "
                                   "--synthesize, the map of a new view blended from a folder of maps "
                                   "(reflection-space IBR).")
    add_probe(p, help_text="HDR environment map (omitted: the shipped probe); with --synthesize, the folder of "
                           "radiance maps")
    p.add_argument("--brdf",
                   help="name:key=value,… — lambert, phong:n=50, blinn:n=50, ggx:alpha=0.2,f0=0.04, "
                        "ggx:alpha=0.2,conductor=gold (or eta=r/g/b,k=r/g/b, or ior=1.5), coat:alpha=0.1,ior=1.5,"
                        "albedo=r/g/b")
    add_option(p, "--views", type=Number(int, 1, 1000), default=12, help="number of views: 12, 42 or 162")
    p.add_argument("--view", type=_direction, help="one view direction X,Y,Z (world frame, toward the eye): "
                                                   "write one exact map to OUTPUT (.exr) and OUTPUT's .json")
    p.add_argument("--synthesize", type=_direction, metavar="X,Y,Z",
                   help="a new view direction: blend its map from the folder FILE's three maps around it, write "
                        "OUTPUT (.exr) and OUTPUT's .json")
    p.add_argument("--warp", choices=("normal", "mirror"),
                   help="with --synthesize: the warp (default: the BRDF's central direction, in the manifest)")
    p.add_argument("--paper-synthesis", action="store_true",
                   help="with --synthesize: warp the whole maps as Cabral et al. do (default: the set's smooth part "
                        "summed exactly for the new view, where the folder holds smooth.exr)")
    add_option(p, "--size", type=Number(int, 2, 2048), default=256, help="texels across each map")
    p.add_argument("--output", "-o", type=Path, required=True, help="the folder (or, with --view, the .exr)")
    p.set_defaults(run=run)


def run(args) -> None:
    if args.synthesize is not None:
        _synthesize(args)
        return
    if args.brdf is None:
        refuse("--brdf is needed (e.g. --brdf ggx:alpha=0.2), unless --synthesize reads a folder of maps")
    _bake(args)


def _synthesize(args) -> None:
    import json

    from ..util.files import atomic_outputs, check_output, write_text
    from ..glossy.radiance import view_frame
    from ..glossy.radiancefile import RadianceSet, manifest, read_radiance_set
    from ..glossy.rsibr import blend_weights, sums_smooth_part, synthesize

    if args.file is None or not args.file.is_dir():
        refuse("--synthesize reads a folder of radiance maps (lightprobe radiance … -o FOLDER): give it as FILE")
    if args.brdf is not None or args.view is not None:
        refuse("--synthesize takes the BRDF and the views from the folder's manifest: no --brdf or --view")
    if args.output.suffix.lower() != ".exr":
        refuse("with --synthesize, --output is the map's .exr file")
    folder = Path(os.path.realpath(args.file))
    if folder in Path(os.path.realpath(args.output.parent)).joinpath(args.output.name).parents:
        refuse(f"refusing to write {args.output}: it is inside the set {args.file} that --synthesize reads (its "
               "maps and manifest.json stay as they are): choose an output outside the folder")
    check_output(args.output)
    check_output(args.output.with_suffix(".json"), text=True)
    rset = read_radiance_set(args.file, SYNTHESIS_BYTES_PER_TEXEL, kernels=True)
    if rset.triangles is None:
        refuse(f"{args.file} holds one view: synthesis needs a set (--views 12, 42 or 162)")
    t0 = time.perf_counter()
    smooth = not args.paper_synthesis and sums_smooth_part(rset)
    out = synthesize(rset, args.synthesize, args.warp, smooth=smooth)
    seconds = time.perf_counter() - t0
    sources, weights = blend_weights(rset.views, rset.triangles, args.synthesize)
    method = {"how": "reflection-space IBR", "warp": args.warp or rset.brdf.central,
              "smooth_part": "summed exactly" if smooth else "warped with the rest (the paper's synthesis)",
              "sources": [int(i) for i in sources], "weights": [float(w) for w in weights], "set": str(args.file)}
    one = RadianceSet(rset.brdf, args.synthesize[None, :], view_frame(args.synthesize)[None], (out,), None, method)
    with atomic_outputs([args.output, args.output.with_suffix(".json")]):
        out.save(args.output)
        write_text(args.output.with_suffix(".json"),
                   json.dumps(manifest(one, [args.output.name], {"synthesis": seconds}), indent=1,
                              allow_nan=False) + "\n")
    print(f"synthesised {rset.size}² map for view {', '.join(f'{x:.4f}' for x in args.synthesize)} from views "
          f"{', '.join(str(int(i)) for i in sources)} (weights {', '.join(f'{w:.3f}' for w in weights)}): "
          f"{args.output}")


def _bake(args) -> None:
    from ..glossy.brdf import parse_brdf
    from ..util.files import check_output
    from ..glossy.radiance import check_views, geodesic_views, prepare, radiance_set_bytes
    from ..glossy.radiancefile import manifest, radiance_set, write_radiance_set

    brdf = parse_brdf(args.brdf)
    inputs = [args.file] if args.file else []
    if args.view is None:
        check_views(args.views)
        if args.output.suffix:
            refuse(f"--output {args.output} looks like a file: the maps go into a folder (or give --view)")
    else:
        if args.output.suffix.lower() != ".exr":
            refuse("with --view, --output is the map's .exr file")
        check_output(args.output, inputs)
        check_output(args.output.with_suffix(".json"), inputs, text=True)
    count = 1 if args.view is not None else args.views
    env = load(args.file, args.layout, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL, kernels=True,
               extra_bytes=radiance_set_bytes(count, args.size),
               what=f"{count} radiance map{'s' if count > 1 else ''} of {args.size}² from "
                    f"{args.file or 'the shipped probe'}")
    t0 = time.perf_counter()
    lighting = prepare(env)
    timings = {"prepare": time.perf_counter() - t0}
    if args.view is not None:
        views, triangles = args.view[None, :], None
    else:
        views, triangles = geodesic_views(args.views)
    t0 = time.perf_counter()
    level = lighting.level_for(brdf, args.size * args.size)
    face = lighting.levels[level].grid[-1]
    method = {"how": "exact sums over a box-filtered level of the working cube, the brightest texels as point "
                     "sources", "working_size": lighting.levels[0].grid[-1], "source_level": level,
              "source_face_size": face, "peaks": int(len(lighting.peak_directions))}
    rset = radiance_set(lighting, brdf, views, triangles, args.size, method, progress="radiance maps")
    maps = rset.maps
    timings["maps"] = time.perf_counter() - t0
    source = str(args.file) if args.file else "(shipped probe)"
    if args.view is None:
        write_radiance_set(args.output, rset, timings, source)
        print(f"{len(maps)} radiance maps {args.size}² of {brdf.spec()} in {args.output} "
              f"({timings['maps']:.1f} s; source level {face}² faces)")
        return
    import json

    from ..util.files import atomic_outputs, write_text

    doc = manifest(rset, [args.output.name], timings, source)
    with atomic_outputs([args.output, args.output.with_suffix(".json")]):
        maps[0].save(args.output, inputs=inputs)
        write_text(args.output.with_suffix(".json"), json.dumps(doc, indent=1, allow_nan=False) + "\n", inputs)
    print(f"radiance map {args.size}² of {brdf.spec()} for view {', '.join(f'{x:.4f}' for x in args.view)}: "
          f"{args.output} (frame in {args.output.with_suffix('.json').name})")
