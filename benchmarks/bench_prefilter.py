"""The GGX prefilter (lightprobe.glossy.prefilter): speed against the previous method in one run, peak memory, the
commands that use it, and accuracy per level against brute force over every source pixel.

    python benchmarks/bench_prefilter.py [--part speed|memory|commands|accuracy|all] [--repeat 3] [--texels 200]

speed: a full GGX chain (babylon_alphas) of 256² and of 512² from a 2048×1024 lat-long (Rooitou Park 1k resampled
up: a sunny probe), warm (kernels compiled, coefficient caches filled), best of ``--repeat``: the harmonic method
(``prefilter_cube``) beside the previous one (``_prefilter_sampled``: peaks + direct sums / filtered importance
sampling over a box pyramid), and their ratio. Targets: 256² ≤ 0.5 s, 512² ≤ 2 s and ≥ 20× the previous method.
memory: tracemalloc's peak during the 512² chain, as a multiple of the source map's float32 array (target ≤ 4×).
commands: wall time of ``lightprobe bake --for all`` of the 2048×1024 probe (target ≤ 5 s) and of ``lightprobe
export rooitou_park_1k.hdr --to babylon-env --specular-size 256``, each a fresh process, best of ``--repeat``.
accuracy: each level of a 256² chain against ``brute_force_prefiltered`` over every pixel of the probe, at
``--texels`` random texels per level: median and worst relative error of the luminance (targets < 1 % / < 5 %), on
the shipped probe (rooitou_park_512), a sunny and an interior Poly Haven probe, and the 2048×1024 map.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

from common import SHARED, best_of, require  # sets the environment first

import numpy as np

from lightprobe.glossy.prefilter import _prefilter_sampled, brute_force_prefiltered, prefilter_cube
from lightprobe.maps import EnvMap, read_envmap, resample, to_image
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import CUBE, LATLONG

SUNNY = SHARED / "polyhaven_1k/rooitou_park_1k.hdr"
INTERIOR = SHARED / "polyhaven_1k/st_fagans_interior_1k.hdr"
SHIPPED = Path(__file__).resolve().parents[1] / "src/lightprobe/data/rooitou_park_512.hdr"
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def _big() -> EnvMap:
    """The 2048×1024 lat-long the targets name: the sunny 1k probe resampled up (energy-conserving)."""
    return resample(read_envmap(SUNNY), LATLONG, 1024)


def speed(repeat: int) -> None:
    env = _big()
    print("\n## GGX chain from a 2048×1024 lat-long, warm, best of", repeat)
    print(f"{'chain':>6s} {'harmonics (s)':>14s} {'previous (s)':>13s} {'ratio':>7s} {'target':>18s}")
    for size, target in ((256, 0.5), (512, 2.0)):
        prefilter_cube(env, size)  # warm: compiled kernels, cached coefficients
        new = best_of(lambda: prefilter_cube(env, size), repeat)
        _prefilter_sampled(env, 16)
        old = best_of(lambda: _prefilter_sampled(env, size), 1)
        verdict = "met" if new <= target and (size < 512 or old / new >= 20) else "NOT met"
        print(f"{size:>5d}² {new:14.3f} {old:13.2f} {old / new:6.1f}× {f'≤ {target} s' + (', ≥ 20×' if size == 512 else ''):>13s} "
              f"{verdict}")


def memory() -> None:
    env = _big()
    prefilter_cube(env, 512)
    tracemalloc.start()
    prefilter_cube(env, 512)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ratio = peak / env.data.nbytes
    print(f"\n## peak memory of the 512² chain (tracemalloc): {peak / 2**20:.0f} MiB = {ratio:.2f}× the "
          f"{env.data.nbytes / 2**20:.0f} MiB source map (target ≤ 4×: {'met' if ratio <= 4 else 'NOT met'})")


def commands(repeat: int) -> None:
    print("\n## commands, fresh process each, wall, best of", repeat)
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe_2k.hdr"
        write_image(probe, to_image(_big()))
        runs = {"bake --for all (2048×1024)": ["bake", str(probe), "--for", "all", "-o", f"{tmp}/bake"],
                "export --to babylon-env --specular-size 256 (1k)":
                    ["export", str(SUNNY), "--to", "babylon-env", "--specular-size", "256", "-o", f"{tmp}/out.env"]}
        for name, argv in runs.items():
            cmd = [str(Path(sys.executable).with_name("lightprobe")), *argv]
            subprocess.run(cmd, check=True, capture_output=True)  # first use: numba's cache, the OS's file cache
            times = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                times.append(time.perf_counter() - t0)
            print(f"{name:>50s}: {min(times):6.2f} s (median {np.median(times):.2f} s)")


def accuracy(texels: int) -> None:
    print(f"\n## 256² chain vs brute force over every source pixel ({texels} random texels a level): median / worst "
          f"relative error of the luminance (targets < 1 % / < 5 %)")
    probes = {"shipped rooitou_park_512": lambda: read_envmap(SHIPPED), "rooitou_park_1k (sunny)":
              lambda: read_envmap(SUNNY), "st_fagans_interior_1k": lambda: read_envmap(INTERIOR),
              "2048×1024 (sunny, resampled)": _big}
    for name, load in probes.items():
        env = load()
        chain = prefilter_cube(env, 256)
        rng = np.random.default_rng(5)
        print(f"\n{name} ({env.grid[1]}×{env.grid[0]})")
        print(f"{'level':>5s} {'α':>8s} {'median':>9s} {'worst':>9s}")
        for i, alpha in enumerate(chain.alphas):
            if alpha == 0:
                continue
            d = CUBE.directions(CUBE.grid_shape(256 >> i)).reshape(-1, 3)
            pick = rng.choice(len(d), min(texels, len(d)), replace=False)
            got = chain.levels[i].reshape(-1, 3)[pick] @ LUMINANCE
            ref = brute_force_prefiltered(env, d[pick], alpha) @ LUMINANCE
            error = np.abs(got - ref) / ref
            print(f"{i:>5d} {alpha:8.4f} {np.median(error):9.4%} {error.max():9.4%}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--part", choices=("speed", "memory", "commands", "accuracy", "all"), default="all")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--texels", type=int, default=200)
    args = p.parse_args()
    if not require(SUNNY, INTERIOR):
        sys.exit(2)
    if args.part in ("speed", "all"):
        speed(args.repeat)
    if args.part in ("memory", "all"):
        memory()
    if args.part in ("commands", "all"):
        commands(args.repeat)
    if args.part in ("accuracy", "all"):
        accuracy(args.texels)


if __name__ == "__main__":
    main()
