"""Rendering the Stanford bunny at 512×512: lightprobe's SH renderer against Mitsuba's reference and brute force.

    python benchmarks/bench_render.py [--size 512] [--reference-spp 256]

Same scene for all (bun_zipper.ply, 69k triangles, on a ground plane, shipped probe), timed in one run; the SH and
brute-force renders use 1 sample per pixel, Mitsuba ``--reference-spp`` (direct lighting), each after a warm-up so
compilation is not counted. Errors against the reference are printed beside the times.
"""

from __future__ import annotations

import argparse
import sys
import time

from common import SHARED, require  # sets the environment first

from lightprobe.data import default_probe_path
from lightprobe.maps import read_envmap
from lightprobe.render.compare import compare
from lightprobe.render.methods import method
from lightprobe.render.raycast import Tracer
from lightprobe.render.reference import reference_render
from lightprobe.render.renderer import render
from lightprobe.render.scene import mesh_scene


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--reference-spp", type=int, default=256)
    args = parser.parse_args()
    bunny = SHARED / "meshes" / "stanford" / "bun_zipper.ply"
    if not require(bunny):
        return 2
    env = read_envmap(default_probe_path())
    scene = mesh_scene(bunny, env, args.size, args.size)
    small = mesh_scene(bunny, env, 16, 16)
    render(small, method("sh"))  # warm-ups: kernels compiled, caches filled
    render(small, method("brute"))
    reference_render(small, spp=4)

    t0 = time.perf_counter()
    tracer = Tracer(scene)
    t_bvh = time.perf_counter() - t0
    runs = {}
    for name, run in (("sh", lambda: render(scene, method("sh"), 1, tracer)),
                      ("reference", lambda: reference_render(scene, spp=args.reference_spp)),
                      ("brute", lambda: render(scene, method("brute"), 1, tracer))):
        t0 = time.perf_counter()
        result = run()
        runs[name] = (time.perf_counter() - t0, result)
    t_sh = runs["sh"][0] + t_bvh
    ref = runs["reference"][1].image
    print(f"bunny {len(scene.meshes[0].faces)} triangles + ground, {args.size}×{args.size}, "
          f"{scene.environment.grid[1]}×{scene.environment.grid[0]} probe")
    print(f"{'method':10s} {'time':>10s} {'÷ sh':>8s} {'relMSE':>9s} {'HDR-FLIP':>9s}  what")
    for name, (seconds, result) in runs.items():
        if name == "sh":
            seconds = t_sh
        m = compare(result.image, ref) if name != "reference" else None
        err = f"{m.relative_mse:9.4f} {m.flip:9.3f}" if m else f"{'—':>9s} {'—':>9s}"
        print(f"{name:10s} {seconds:9.2f}s {seconds / t_sh:7.1f}× {err}  {result.method}")
    print(f"(sh includes building the ray-tracing structure, {t_bvh:.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
