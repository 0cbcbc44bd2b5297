"""Area lights + ambient (Arbree, Walter & Bala 2005) against Mitsuba 3, the point-light baselines and SH; light
counts beside the paper's Table 1; hybrid irradiance against brute force; speed as ratios in one run.

    python benchmarks/bench_lights.py [--part quality|table1|hybrid|speed|all] [--size 128] [--reference-spp 1024]

quality: the bunny and the dragon on the ground under each probe (turned so its brightest light is behind the
camera's left, as ``lightprobe render`` does), rendered by ``sh`` (SH9), ``lights`` (16 shadow rays per light),
``lights --ao`` (16 occlusion rays), ``mediancut`` and ``varmin`` with as many point lights as ``lights`` found
(``--baseline-count pow2``: the next power of two, the papers' own cuts), all at 2×2 samples per pixel, against
Mitsuba 3's
direct lighting with shadows: relative MSE and HDR-FLIP.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from common import SHARED, best_of, require  # sets the environment first

import numpy as np

from lightprobe.lights.baselines import median_cut, variance_minimisation
from lightprobe.maps import read_envmap
from lightprobe.lights.hybrid import DEFAULT_AMBIENT_ORDER, hybrid_error_report, hybrid_irradiance
from lightprobe.sh.irradiance import brute_irradiance, error_report, reference_normals
from lightprobe.maps.layouts import LATLONG
from lightprobe.lights.decompose import decompose
from lightprobe.render.compare import compare
from lightprobe.render.methods import method
from lightprobe.render.raycast import Tracer
from lightprobe.render.reference import reference_render
from lightprobe.render.renderer import render
from lightprobe.render.scene import mesh_scene

PROBES = {
    "grace": "debevec/angular/grace_probe.hdr",
    "galileo": "debevec/angular/galileo_probe.hdr",
    "kitchen": "debevec/angular/kitchen_probe.hdr",
    "stpeters": "debevec/cross/stpeters_cross.hdr",
    "rooitou": "polyhaven_1k/rooitou_park_1k.hdr",
    "immenstadter": "polyhaven_1k/immenstadter_horn_1k.hdr",
}
MESHES = {"bunny": "meshes/stanford/bun_zipper_res2.ply", "dragon": "meshes/stanford/dragon_vrip_res3.ply"}
TABLE1 = {"galileo": ("debevec/angular/galileo_probe.hdr", 8), "grace": ("debevec/angular/grace_probe.hdr", 10),
          "kitchen": ("debevec/angular/kitchen_probe.hdr", 4), "stpeters": ("debevec/cross/stpeters_cross.hdr", 17)}
HYBRID_PROBES = {"grace": "debevec/angular/grace_probe.hdr", "rnl": "debevec/angular/rnl_probe.hdr",
                 "galileo": "debevec/angular/galileo_probe.hdr", "kitchen": "debevec/angular/kitchen_probe.hdr",
                 "campus": "debevec/angular/campus_probe.hdr", "building": "debevec/angular/building_probe.hdr",
                 "rooitou": "polyhaven_1k/rooitou_park_1k.hdr", "immenstadter": "polyhaven_1k/immenstadter_horn_1k.hdr"}


def quality(size: int, spp: int, baseline_count: str = "same") -> None:
    print(f"\n## against Mitsuba 3 ({size}×{size}, reference {spp} spp, direct light with shadows)")
    print(f"{'scene':22s} {'lights':>6s} " + " ".join(f"{m:>16s}" for m in ("sh", "lights", "lights --ao",
                                                                               "mediancut", "varmin")))
    print(f"{'':22s} {'':6s} " + " ".join(f"{'relMSE  FLIP':>16s}" for _ in range(5)))
    wins = {"lights < sh": 0, "lights < mediancut": 0, "ao < lights": 0, "ao < mediancut": 0, "ao < varmin": 0}
    cases = 0
    for probe, path in PROBES.items():
        env = read_envmap(SHARED / path)
        for mesh, mesh_path in MESHES.items():
            scene = mesh_scene(SHARED / mesh_path, env, size, size)
            tracer = Tracer(scene)
            lights = method("lights", light_samples=16)
            found = len(lights.decomposition(scene).lights)
            count = max(found, 1) if baseline_count == "same" else 1 << max(0, math.ceil(math.log2(max(found, 1))))
            truth = reference_render(scene, spp=spp).image
            methods = {"sh": method("sh"), "lights": lights,
                       "ao": method("lights", light_samples=16, ao=True, ao_samples=16),
                       "mediancut": method("mediancut", count=count), "varmin": method("varmin", count=count)}
            m = {name: compare(render(scene, meth, 2, tracer).image, truth) for name, meth in methods.items()}
            r = {name: v.relative_mse for name, v in m.items()}
            wins["lights < sh"] += r["lights"] < r["sh"]
            wins["lights < mediancut"] += r["lights"] < r["mediancut"]
            wins["ao < lights"] += r["ao"] < r["lights"]
            wins["ao < mediancut"] += r["ao"] < r["mediancut"]
            wins["ao < varmin"] += r["ao"] < r["varmin"]
            cases += 1
            print(f"{probe + ' / ' + mesh:22s} {f'{found}/{count}':>6s} "
                  + " ".join(f"{v.relative_mse:8.4f} {v.flip:7.3f}" for v in m.values()), flush=True)
    print("  (lights: found / point lights given to the baselines)")
    print("  " + ", ".join(f"{k}: {v}/{cases}" for k, v in wins.items()))


def table1(previews: Path | None) -> None:
    from lightprobe.maps.images import write_image
    from lightprobe.lights.decompose import LightParams, preview
    from lightprobe.maps.tonemap import luminance

    print("\n## Table 1: lights found (paper's defaults), and with the stopping rule at 1 %")
    print(f"{'probe':10s} {'found':>6s} {'paper':>6s} {'in lights':>10s} {'next light':>11s} {'stop 1 %':>9s} "
          f"{'seconds':>8s}")
    for probe, (path, paper) in TABLE1.items():
        env = read_envmap(SHARED / path)
        t0 = time.perf_counter()
        dec = decompose(env)
        seconds = time.perf_counter() - t0
        share = float(luminance(dec.light_power) / luminance(dec.total))
        rejected = f"{100 * dec.rejected_share:.2f} %" if dec.rejected_share is not None else "—"
        looser = len(decompose(env, LightParams(stop_fraction=0.01)).lights)
        print(f"{probe:10s} {len(dec.lights):6d} {paper:6d} {100 * share:9.0f}% {rejected:>11s} {looser:9d} "
              f"{seconds:8.2f}")
        if previews is not None:
            previews.mkdir(parents=True, exist_ok=True)
            write_image(previews / f"table1_{probe}.png", preview(env, dec.lights), encoded=True)
    print("  (next light: the first light the 2 % rule turned away, as a share of the power of those kept before it)")


def hybrid() -> None:
    print(f"\n## hybrid irradiance vs brute force, per-normal relative error (1500 normals; ambient order "
          f"{DEFAULT_AMBIENT_ORDER})")
    print(f"{'probe':13s} {'lights':>6s} {'SH9 mean':>9s} {'SH9 max':>8s} {'SH12 mean':>9s} {'SH12 max':>9s} "
          f"{'hybrid mean':>11s} {'hybrid max':>10s}")
    normals = reference_normals(1500)
    for probe, path in HYBRID_PROBES.items():
        env = read_envmap(SHARED / path)
        reference = brute_irradiance(env, normals)
        dec = decompose(env)
        h = hybrid_error_report(env, normals, reference, hybrid_irradiance(env, dec))
        s2 = error_report(env, 2, normals=normals, reference=reference)
        s12 = error_report(env, DEFAULT_AMBIENT_ORDER, normals=normals, reference=reference)
        print(f"{probe:13s} {len(dec.lights):6d} {100 * s2.relative_mean:8.2f}% {100 * s2.relative_max:7.1f}% "
              f"{100 * s12.relative_mean:8.2f}% {100 * s12.relative_max:8.2f}% {100 * h.relative_mean:10.2f}% "
              f"{100 * h.relative_max:9.2f}%")


def speed() -> None:
    print("\n## speed (best of 3, one run)")
    grace = read_envmap(SHARED / "debevec/angular/grace_probe.hdr")
    decompose(grace)  # warm-up: kernels compiled
    one_pass = best_of(lambda: float(np.sum(grace.data)), 3)
    t_dec = best_of(lambda: decompose(grace), 3)
    t_mc = best_of(lambda: median_cut(grace, 16), 3)
    t_vm = best_of(lambda: variance_minimisation(grace, 16), 3)
    print(f"Grace 1000² angular: decomposition {t_dec:.2f} s (target ≤ 10 s, aim ≤ 2 s; the paper 0.5–1.5 h); "
          f"median cut 16 {t_mc:.2f} s ({t_dec / t_mc:.1f}× faster than the decomposition); variance "
          f"minimisation 16 {t_vm:.2f} s; one numpy pass over the map {1000 * one_pass:.1f} ms")
    scene = mesh_scene(SHARED / "meshes/stanford/bun_zipper_res2.ply", grace, 256, 256)
    tracer = Tracer(scene)
    sh, lights = method("sh"), method("lights", light_samples=16)
    ao = method("lights", light_samples=16, ao=True, ao_samples=16)
    for m in (sh, lights, ao):
        render(scene, m, 1, tracer)  # warm-ups, decomposition cached
    t_sh = best_of(lambda: render(scene, sh, 1, tracer), 3)
    t_lights = best_of(lambda: render(scene, lights, 1, tracer), 3)
    t_ao = best_of(lambda: render(scene, ao, 1, tracer), 3)
    n = len(lights.decomposition(scene).lights)
    print(f"bunny 256², 1 spp, {n} lights × 16 shadow rays: sh {t_sh:.3f} s, lights {t_lights:.3f} s = "
          f"{t_lights / t_sh:.1f}× sh (target ≤ 5×); lights --ao (16 rays) {t_ao:.3f} s = {t_ao / t_sh:.1f}× sh")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("quality", "table1", "hybrid", "speed", "all"), default="all")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--previews", type=Path, help="write Table 1's preview pictures (PNG) into this folder")
    parser.add_argument("--baseline-count", choices=("same", "pow2"), default="same",
                        help="quality: point lights for mediancut/varmin — as many as the area lights found, or "
                             "the next power of two")
    args = parser.parse_args()
    paths = [SHARED / p for p in (*PROBES.values(), *MESHES.values(), *HYBRID_PROBES.values())]
    if not require(*paths):
        return 2
    if args.part in ("table1", "all"):
        table1(args.previews)
    if args.part in ("speed", "all"):
        speed()
    if args.part in ("hybrid", "all"):
        hybrid()
    if args.part in ("quality", "all"):
        quality(args.size, args.reference_spp, args.baseline_count)
    return 0


if __name__ == "__main__":
    sys.exit(main())
