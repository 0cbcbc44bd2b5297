"""Glossy radiance maps (Cabral, Olano & Nemec 1999): RS-IBR synthesis against the map computed directly, the
white-furnace curves of the BRDFs, and speed as ratios in one run.

    python benchmarks/bench_glossy.py [--part synthesis|furnace|speed|quality|all] [--size 128] [--tests 100]

synthesis: for ``--tests`` random views, the map synthesised from the 12 / 42 / 162 source maps (GGX α 0.05, 0.1,
0.2, 0.4, no Fresnel; both warps) against the map computed directly for that view, relative RMSE over the texels
whose centres lie on the disc, mean and worst over the views, and for the mirror warp over the inner disc (r < 0.9:
normals within 64° of the view) — the rim ring, where the lobe is cut by the surface's horizon differently in each
view, holds almost all of the error. Probe: Grace.
furnace: directional albedo of GGX (F = 1) against n·v — what single scattering loses — and of the other BRDFs.
quality: against Mitsuba 3's roughconductor (GGX, same α; gold and no Fresnel) on a sphere and on the bunny (no
ground) under Grace, St. Peter's and Rooitou Park, five camera elevations from 5° (grazing) to 85°: relative MSE and
HDR-FLIP of ``direct``, ``rsibr`` (12 and 42 views), ``rsibr --per-pixel-view`` and ``splitsum``.
speed: precomputing 12 maps of 256² for GGX α = 0.2 from a 1024×512 probe (target ≤ 30 s) beside one brute-force
map (every texel of the 128² working cube); synthesising a 256² map (target ≤ 20 ms).
"""

from __future__ import annotations

import argparse
import sys
import time

from common import SHARED, best_of, require  # sets the environment first

import numpy as np

from lightprobe.glossy.brdf import parse_brdf
from lightprobe.glossy.brdf_sums import directional_albedo
from lightprobe.maps import read_envmap
from lightprobe.glossy.radiance import geodesic_views, prepare, radiance_map, reflected_radiance, sphere_normals, view_frame
from lightprobe.glossy.radiancefile import RadianceSet, radiance_set
from lightprobe.glossy import rsibr
from lightprobe.glossy.rsibr import synthesize

GRACE = "debevec/angular/grace_probe.hdr"
SUNNY = "polyhaven_1k/rooitou_park_1k.hdr"


def _disc(size: int, radius: float = 1.0) -> np.ndarray:
    """The texels of a sphere map whose centres lie within ``radius`` of its centre (1: the whole disc)."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)
    return x * x + y * y < radius * radius


INNER = 0.9  # the disc within this radius: normals within 64° of the view (n·v ≥ 0.44), the rim ring left out


def _relative_rmse(got: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean((got - truth) ** 2) / np.mean(truth ** 2)))


def synthesis(size: int, tests: int, alphas: list[float]) -> None:
    print(f"\n## RS-IBR synthesis vs the direct map ({size}², {tests} random views, Grace; relative RMSE over the disc "
          f"mean / max over the views; the paper's warps, and the mirror warp with the smooth part summed exactly; "
          f"the paper's mirror warp also over the inner disc r < {INNER}: n·v ≥ {np.sqrt(1 - INNER ** 2):.2f})")
    columns = ("normal", "mirror", "mirror+smooth")
    print(f"{'views':>5s} {'α':>5s} " + " ".join(f"{w:>19s}" for w in columns) + f" {'mirror r<0.9':>15s}")
    rsibr.SMOOTH_MIN_LOBE = 0.0  # the smooth part forced on at every α, to show why the default leaves it off below 10°
    lighting = prepare(read_envmap(SHARED / GRACE))
    rng = np.random.default_rng(1)
    targets = rng.normal(size=(tests, 3))
    targets /= np.linalg.norm(targets, axis=1, keepdims=True)
    disc, inner = _disc(size), _disc(size, INNER)
    for alpha in alphas:
        brdf = parse_brdf(f"ggx:alpha={alpha}")
        truth = [radiance_map(lighting, brdf, v, size).data for v in targets]
        for count in (12, 42, 162):
            rset = radiance_set(lighting, brdf, *geodesic_views(count), size)
            cells = []
            for warp, smooth in (("normal", False), ("mirror", False), ("mirror", True)):
                maps = [synthesize(rset, v, warp, smooth=smooth).data for v in targets]
                errors = [_relative_rmse(m[disc], t[disc]) for m, t in zip(maps, truth)]
                cells.append(f"{100 * np.mean(errors):9.2f} / {100 * np.max(errors):5.2f}%")
                if warp == "mirror" and not smooth:
                    inner_errors = [_relative_rmse(m[inner], t[inner]) for m, t in zip(maps, truth)]
            cells.append(f"{100 * np.mean(inner_errors):6.2f} / {100 * np.max(inner_errors):5.2f}%")
            print(f"{count:5d} {alpha:5.2f} " + " ".join(cells), flush=True)


def furnace() -> None:
    print("\n## white furnace: directional albedo against n·v (65 536 importance samples)")
    cos_view = np.array([1.0, 0.8, 0.6, 0.4, 0.2, 0.1, 0.05])
    print(f"{'BRDF':32s} " + " ".join(f"{c:>6.2f}" for c in cos_view))
    for spec in ("lambert", "ggx:alpha=0.05", "ggx:alpha=0.1", "ggx:alpha=0.2", "ggx:alpha=0.4", "ggx:alpha=0.7",
                 "ggx:alpha=1", "ggx:alpha=0.2,conductor=gold", "phong:n=50", "blinn:n=50",
                 "coat:alpha=0.1,albedo=1"):
        albedo = directional_albedo(parse_brdf(spec), cos_view, 65536)[:, 0]
        print(f"{spec:32s} " + " ".join(f"{a:6.3f}" for a in albedo))
    print("  (GGX with F = 1: what is missing from 1 is what single scattering loses; gold: its red channel)")


def speed() -> None:
    print("\n## speed (one run)")
    env = read_envmap(SHARED / SUNNY)
    brdf = parse_brdf("ggx:alpha=0.2")
    t0 = time.perf_counter()
    lighting = prepare(env)
    views, triangles = geodesic_views(12)
    radiance_map(lighting, brdf, views[0], 16)  # kernels compiled
    t_prepare = time.perf_counter() - t0
    t0 = time.perf_counter()
    maps = tuple(radiance_map(lighting, brdf, v, 256) for v in views)
    t_maps = time.perf_counter() - t0
    normals = sphere_normals(256).reshape(-1, 3)[_disc(256).reshape(-1)] @ view_frame(views[0]).T
    t0 = time.perf_counter()
    reflected_radiance(lighting, brdf, normals[::16], views[0], level=0)
    t_brute = (time.perf_counter() - t0) * 16
    print(f"12 maps 256² of GGX α = 0.2 from {env.data.shape[1]}×{env.data.shape[0]}: {t_maps:.1f} s (target ≤ 30 s; "
          f"working cube {t_prepare:.1f} s); one map by brute force over every texel of the 128² working cube "
          f"{t_brute:.1f} s (estimated from 1/16 of its texels) = {12 * t_brute / t_maps:.0f}× the 12 maps' time "
          f"for 12")
    rset = RadianceSet(brdf, views, np.array([view_frame(v) for v in views]), maps, triangles, {}, lighting.smooth)
    target = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    synthesize(rset, target)  # the sources' smooth tables, once per set
    t_syn = best_of(lambda: synthesize(rset, target), 5)
    t_paper = best_of(lambda: synthesize(rset, target, smooth=False), 5)
    one_pass = best_of(lambda: float(np.sum(maps[0].data)), 5)
    print(f"synthesising a 256² map: {1000 * t_syn:.1f} ms with the smooth part summed exactly, {1000 * t_paper:.1f} "
          f"ms warping the whole maps as the paper does (target ≤ 20 ms; one numpy pass over a map "
          f"{1000 * one_pass:.2f} ms)")


QUALITY_PROBES = {"grace": GRACE, "stpeters": "debevec/cross/stpeters_cross.hdr", "rooitou": SUNNY}
BUNNY = "meshes/stanford/bun_zipper_res2.ply"


def quality(size: int, spp: int) -> None:

    from lightprobe.maps import box_reduce
    from lightprobe.render.compare import compare
    from lightprobe.render.methods import method
    from lightprobe.render.raycast import Tracer
    from lightprobe.render.reference import reference_render
    from lightprobe.render.renderer import render
    from lightprobe.render.scene import Camera, Scene, fitted, load_mesh, sphere

    names = ("direct", "rsibr 12", "rsibr 42", "per-pixel 12", "per-pixel 42", "splitsum")
    print(f"\n## against Mitsuba 3 roughconductor ({size}², reference {spp} spp; relative MSE / HDR-FLIP)")
    print(f"{'probe / mesh / material / elevation':44s} " + " ".join(f"{n:>15s}" for n in names))
    wins = {n: 0 for n in names}
    cases = 0
    for probe, path in QUALITY_PROBES.items():
        env = box_reduce(read_envmap(SHARED / path))
        for spec in ("ggx:alpha=0.2,conductor=gold", "ggx:alpha=0.1"):
            from lightprobe.render.scene import Material

            material = Material(brdf=parse_brdf(spec))
            methods = {"direct": method("direct", map_size=128),  # baked once per probe and material
                       "rsibr 12": method("rsibr", views=12, map_size=128),
                       "rsibr 42": method("rsibr", views=42, map_size=128),
                       "per-pixel 12": method("rsibr", views=12, map_size=128, per_pixel_view=True),
                       "per-pixel 42": method("rsibr", views=42, map_size=128, per_pixel_view=True),
                       "splitsum": method("splitsum", cube_size=128)}
            methods["per-pixel 12"].radiance_set = methods["rsibr 12"].radiance_set
            methods["per-pixel 42"].radiance_set = methods["rsibr 42"].radiance_set
            for mesh_name in ("sphere", "bunny"):
                mesh = (sphere(0.5, (0, 0.5, 0), material, subdivisions=5) if mesh_name == "sphere"
                        else fitted(load_mesh(SHARED / BUNNY, material), 1.0, on_ground=True))
                for elevation in (5, 25, 45, 65, 85):
                    e = np.radians(elevation)
                    eye = (0.0, 0.5 + 2.4 * np.sin(e), 2.4 * np.cos(e))
                    scene = Scene((mesh,), Camera(eye=eye, target=(0, 0.5, 0), fov=30, width=size, height=size),
                                  env, False)
                    tracer = Tracer(scene)
                    truth = reference_render(scene, spp=spp).image
                    scores = {n: compare(render(scene, m, 2, tracer).image, truth) for n, m in methods.items()}
                    best = min(scores, key=lambda n: scores[n].relative_mse)
                    wins[best] += 1
                    cases += 1
                    print(f"{f'{probe} / {mesh_name} / {spec} / {elevation}°':44s} "
                          + " ".join(f"{v.relative_mse:7.4f} {v.flip:6.3f}" for v in scores.values()), flush=True)
    print("  lowest relative MSE: " + ", ".join(f"{n} {w}/{cases}" for n, w in wins.items()))

def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("synthesis", "furnace", "speed", "quality", "all"), default="all")
    parser.add_argument("--reference-spp", type=int, default=512)
    parser.add_argument("--alphas", default="0.05,0.1,0.2,0.4", help="synthesis: the GGX α values (comma-separated)")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--tests", type=int, default=100)
    args = parser.parse_args()
    if not require(SHARED / GRACE, SHARED / SUNNY):
        return 2
    if args.part in ("furnace", "all"):
        furnace()
    if args.part in ("speed", "all"):
        speed()
    if args.part in ("synthesis", "all"):
        synthesis(args.size, args.tests, [float(a) for a in args.alphas.split(",")])
    if args.part in ("quality", "all"):
        quality(min(args.size, 96), args.reference_spp)
    return 0

if __name__ == "__main__":
    sys.exit(main())
