"""SH projection, irradiance maps and CLI start-up, as ratios measured in one run.

    python benchmarks/bench_sh.py [--repeat N]

* SH projection of a 2048×1024 float32 lat-long map (the Poly Haven probe upsampled), orders 2 and 8, against one
  numpy pass over the same pixels (an elementwise multiply into a preallocated array: the fastest pass numpy makes;
  a numpy reduction such as ``pixels.sum(axis=(0, 1))`` is slower still) and against ducc0's ``analysis_2d`` (F1
  grid = the lat-long's rows, 2 threads) on the same pixels. The results are cross-checked on a band-limited map
  (where both must be exact) through band powers Σ_m L_lm², which neither basis convention nor frame changes.
* A 64×32 irradiance map from the 1000×1000 Grace angular probe: SH9 (projection + evaluation) against brute force.
* ``lightprobe sh`` in a fresh process, with the compiled-kernel cache warm and cold.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED, best_of, require  # sets the environment first

import numpy as np

from lightprobe.maps import read_envmap
from lightprobe.sh.irradiance import irradiance_map
from lightprobe.maps.layouts import LATLONG
from lightprobe.sh.basis import project




def band_powers(coeffs: np.ndarray, l_max: int) -> np.ndarray:
    return np.array([(coeffs[l * l:(l + 1) ** 2] ** 2).sum(axis=0) for l in range(l_max + 1)])


def ducc_projection(pixels: np.ndarray, l_max: int):
    """ducc0 analysis_2d per channel on the lat-long grid (F1 rings, φ0 so the first column's centre matches)."""
    import ducc0

    h, w, _ = pixels.shape
    maps = [np.ascontiguousarray(pixels[..., c])[None] for c in range(3)]
    phi0 = np.pi / w  # ducc's φ is measured in its own polar frame; only the band powers are compared

    def run():
        return [ducc0.sht.experimental.analysis_2d(map=m, spin=0, lmax=l_max, geometry="F1", nthreads=2,
                                                   phi0=phi0) for m in maps]
    return run


def ducc_band_powers(alms, l_max: int) -> np.ndarray:
    out = np.zeros((l_max + 1, 3))
    for c, alm in enumerate(alms):
        a = alm[0]
        idx = 0
        for m in range(l_max + 1):  # healpy order: all l for m = 0, then m = 1, …
            for l in range(m, l_max + 1):
                out[l, c] += abs(a[idx]) ** 2 * (1 if m == 0 else 2)
                idx += 1
    return out


def cross_check(l_max: int) -> float:
    """Largest band-power difference between lightprobe and ducc0 on a band-limited 1024×512 map, relative."""
    from lightprobe.maps import EnvMap
    from lightprobe.sh.basis import SHCoeffs, n_coeffs

    truth = np.random.default_rng(l_max).normal(size=(n_coeffs(l_max), 3))
    truth[0] += 3 * np.abs(truth).sum(axis=0)
    grid = LATLONG.grid_shape(512)
    pixels = SHCoeffs(truth).evaluate(LATLONG.directions(grid)).astype(np.float32)
    ours = band_powers(project(EnvMap(pixels, LATLONG), l_max).coeffs, l_max)
    theirs = ducc_band_powers(ducc_projection(pixels, l_max)(), l_max)
    return float(np.abs(ours - theirs).max() / ours[0].max())


def cli_seconds(env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(Path(sys.executable).with_name("lightprobe")), "sh"], env=env, check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    probe, grace = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr", SHARED / "debevec" / "angular" / "grace_probe.hdr"
    if not require(probe, grace):
        return 2
    big = read_envmap(probe).to(LATLONG, 1024)
    pixels = np.ascontiguousarray(big.data)
    out = np.empty_like(pixels)
    rows = []
    for l_max in (2, 8):
        project(big, l_max, compiled=True)  # compile / warm up
        t_pass = best_of(lambda: np.multiply(pixels, 1.0, out=out), args.repeat)
        t_ours = best_of(lambda: project(big, l_max, compiled=True), args.repeat)
        try:
            run_ducc = ducc_projection(pixels, l_max)
            run_ducc()  # warm up
        except ImportError:  # a peer, installed in .venv-peers (benchmarks/peers/setup.sh), not a dependency
            rows.append((f"SH projection, l_max {l_max}, 2048×1024", t_ours, t_pass, float("nan"), float("nan")))
            continue
        t_ducc = best_of(run_ducc, args.repeat)
        rows.append((f"SH projection, l_max {l_max}, 2048×1024", t_ours, t_pass, t_ducc, cross_check(l_max)))
    print(f"{'operation':36s} {'lightprobe':>11s} {'÷ numpy pass':>13s} {'÷ ducc0':>9s} {'agreement':>10s}")
    for name, t, t_pass, t_ducc, agree in rows:
        print(f"{name:36s} {1000 * t:9.2f}ms {t / t_pass:12.2f}× {t / t_ducc:8.2f}× {agree:10.1e}")

    env = read_envmap(grace)
    irradiance_map(env, "latlong", 4, "sh")  # warm up
    t_sh = best_of(lambda: irradiance_map(env, "latlong", 32, "sh"), 3)
    t_brute = best_of(lambda: irradiance_map(env, "latlong", 32, "brute"), 1)
    print(f"\nirradiance map 64×32 from the 1000² Grace probe: SH9 {1000 * t_sh:.1f} ms, brute force "
          f"{t_brute:.2f} s → SH is {t_brute / t_sh:.0f}× faster")

    warm = cli_seconds({**os.environ})
    with tempfile.TemporaryDirectory() as cold_cache:
        cold = cli_seconds({**os.environ, "NUMBA_CACHE_DIR": cold_cache})
    warm_again = cli_seconds({**os.environ})
    print(f"`lightprobe sh` in a fresh process: {min(warm, warm_again):.2f} s with the kernel cache, "
          f"{cold:.2f} s compiling from scratch")
    print(f"(best of {args.repeat}; {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
