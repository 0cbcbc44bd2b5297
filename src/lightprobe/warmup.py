"""Compile lightprobe's numba kernels once, on tiny inputs, so that later commands load them from numba's cache.

``setup.sh`` runs ``python -m lightprobe.warmup`` after installing: without it the first ``lightprobe demo`` on a
machine spends about two minutes compiling (2 cores), and every first command pays for its own kernels.
numba caches a kernel per source file and argument types, in ``NUMBA_CACHE_DIR`` (the user's cache folder, see
:mod:`lightprobe`); the calls here pass the types the commands pass — float32 maps, float64 directions and
normals, the scenes' arrays — so a kernel met later with other types still compiles then, as it would have.

What runs: every layout conversion between any two layouts, direct, and through cached weights from a lat-long; SH projection of the orders
the commands use; brute-force and hybrid irradiance; the area-light decomposition and its baselines; a tiny
scene rendered by every method (shadow rays, ambient occlusion, glossy gold and plastic); radiance maps, RS-IBR
synthesis and the split sum's prefiltered cube; a turned map's conversions; the DFG tables the bakes write.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def _probe():
    """A 32×16 lat-long sky with a small bright sun: enough for lights to be found and every path to run."""
    from .maps import EnvMap
    from .maps.layouts import LATLONG

    data = np.full((16, 32, 3), 0.5, np.float32)
    data[4, 10] = 400.0
    return EnvMap(data, LATLONG)


def _maps(env) -> None:
    from .maps import Resampler
    from .sh.irradiance import brute_irradiance, irradiance_map
    from .maps.layouts import LAYOUTS, LATLONG
    from .sh.basis import project

    for source in LAYOUTS:  # probes come in every layout, and go to every other
        mapped = env.to(source, 8)
        project(mapped, 2, compiled=True)
        for target in LAYOUTS:
            mapped.to(target, 8)
    Resampler(LATLONG, env.grid, "cube", 8)(env)
    turned = env.rotated((40.0, -25.0, 10.0))  # a rotation is its own specialisation of the conversion kernels
    for target in ("latlong", "cube", "angular"):
        turned.to(target, 8)
    for l_max in (2, 6, 8, 12, 16):
        project(env, l_max)
        project(env, l_max, compiled=True)
    brute_irradiance(env, np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]))
    irradiance_map(env, "latlong", 8)
    irradiance_map(env, "latlong", 8, method="brute")


def _lights(env) -> None:
    from .lights.baselines import median_cut, variance_minimisation
    from .lights.hybrid import hybrid_irradiance
    from .lights.decompose import decompose

    dec = decompose(env)
    hybrid_irradiance(env, dec).evaluate(np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]))
    median_cut(env, 4)
    variance_minimisation(env, 4)


def _renders(env) -> None:
    from .glossy.brdf import parse_brdf
    from .render.methods import method
    from .render.raycast import Tracer
    from .render.renderer import render
    from .render.scene import Camera, Material, Scene, ground_plane, sphere

    gold = Material(brdf=parse_brdf("ggx:alpha=0.3,conductor=gold"))
    plastic = Material(brdf=parse_brdf("plastic:alpha=0.2,albedo=0.6/0.08/0.05"))
    camera = Camera(eye=(0.0, 1.0, 3.0), target=(0.0, 0.4, 0.0), fov=40, width=12, height=12)
    diffuse = Scene((sphere(0.4, (0, 0.4, 0), subdivisions=2), ground_plane(4.0, 0.0)), camera, env, False)
    tracer = Tracer(diffuse)
    for name, options in (("sh", {}), ("brute", {}), ("hybrid", {}), ("lights", {"light_samples": 4}),
                          ("lights", {"light_samples": 4, "ao": True, "ao_samples": 4}), ("mediancut", {"count": 4})):
        render(diffuse, method(name, **options), 1, tracer)
    for material in (gold, plastic):
        glossy = Scene((sphere(0.4, (0, 0.4, 0), material, subdivisions=2), ground_plane(4.0, 0.0)), camera, env,
                       False)
        tracer = Tracer(glossy)
        for name, options in (("brute", {}), ("direct", {"map_size": 8}), ("rsibr", {"views": 12, "map_size": 8}),
                              ("rsibr", {"views": 12, "map_size": 8, "per_pixel_view": True}),
                              ("splitsum", {"cube_size": 8})):
            if name != "splitsum" or material is gold:  # the split sum is GGX's alone
                render(glossy, method(name, **options), 1, tracer)


def _radiance(env) -> None:
    from .glossy.brdf import parse_brdf
    from .glossy.radiance import geodesic_views, prepare, radiance_map
    from .glossy.radiancefile import radiance_set
    from .glossy.rsibr import synthesize

    lighting = prepare(env)
    for spec in ("ggx:alpha=0.3,conductor=gold", "lambert"):
        brdf = parse_brdf(spec)
        rset = radiance_set(lighting, brdf, *geodesic_views(12), 8)
        view = np.array([0.35, 0.45, 0.82]) / np.linalg.norm([0.35, 0.45, 0.82])
        synthesize(rset, view)
        synthesize(rset, view, smooth=False)
        radiance_map(lighting, brdf, view, 8)


def _bake(env) -> None:
    from .glossy.dfg import multiscatter_lut, sheen_lut, split_sum_lut

    multiscatter_lut(4, sheen=True, samples=16)
    split_sum_lut(4, samples=16)
    split_sum_lut(4, visibility="separable", samples=16)
    for visibility in ("neubelt", "charlie"):
        sheen_lut(4, visibility, samples=16)


def compile_kernels(report=None) -> float:
    """Run every compiled kernel the commands use once (compiling it, or loading it from numba's cache); returns
    the seconds it took. ``report(step)``, if given, is told each step's name before it runs."""
    t0 = time.perf_counter()
    env = _probe()
    for name, step in (("maps", _maps), ("lights", _lights), ("renders", _renders), ("radiance", _radiance),
                       ("bake", _bake)):
        if report:
            report(name)
        step(env)
    return time.perf_counter() - t0


def prune_stale_caches(days: float = 14.0) -> list[str]:
    """Remove the numba cache folders of other source states (:mod:`lightprobe` keys the folder by its sources)
    untouched for ``days``: each edit or reinstall leaves one behind. Recent ones stay — another checkout on the
    machine may be using its own right now. Returns the folders removed."""
    import os
    import shutil

    current = os.environ.get("NUMBA_CACHE_DIR", "")
    parent = os.path.dirname(current)
    if os.path.basename(parent) != "numba" or not os.path.isdir(parent):
        return []  # a NUMBA_CACHE_DIR of the user's own: not ours to tidy
    removed = []
    for entry in os.scandir(parent):
        stale = time.time() - entry.stat().st_mtime > days * 86400
        if entry.is_dir() and entry.path != current and len(entry.name) == 8 and stale:
            shutil.rmtree(entry.path, ignore_errors=True)
            removed.append(entry.path)
    return removed


def main() -> int:
    prune_stale_caches()
    seconds = compile_kernels(lambda step: print(f"lightprobe: compiling kernels ({step})", file=sys.stderr,
                                                 flush=True))
    print(f"lightprobe: kernels compiled (or loaded from numba's cache) in {seconds:.1f} s", file=sys.stderr)
    mark_warm()
    return 0


WARM = ".lightprobe-warm"  # in numba's cache folder: every kernel compiled into it (setup.sh compiles only without it)


def mark_warm() -> None:
    """Mark this source state's numba cache folder as complete (``setup.sh`` then skips the warm-up)."""
    import os

    folder = os.environ.get("NUMBA_CACHE_DIR")
    if folder and os.path.isdir(folder):
        with open(os.path.join(folder, WARM), "w", encoding="utf-8") as marker:
            marker.write("every kernel of `python -m lightprobe.warmup` is in this folder\n")


if __name__ == "__main__":
    sys.exit(main())
