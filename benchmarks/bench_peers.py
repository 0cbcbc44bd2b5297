"""lightprobe against its peers, in one run: conversion (with its energy error), reading, SH projection, start-up.

    bash benchmarks/peers/setup.sh                 # once: .venv-peers with lightprobe and the peers, pinned
    .venv-peers/bin/python benchmarks/bench_peers.py [--rounds N]

Every row is a ratio measured in this run: the contenders of a row run in alternating rounds (A, B, A, B, …), each
round's ratio is taken, and the table gives the best and the median ratio, so a noisy 2-core machine moves both
sides of a ratio alike. lightprobe's conversion is measured twice: direct (one compiled pass) and with its footprint
weights cached (``Resampler``: built once per geometry, then one gather per map, as a batch runs). Peers: py360convert (bilinear), skylibs (its default interpolation), a plain numpy
nearest-pixel resampler (float32, per face: one lookup per target pixel), OpenImageIO's own read, imageio,
ducc0's ``analysis_2d`` and pyshtools' ``SHExpandDH`` (per channel), and ``python -c "import numpy"``.
A peer that does not import is reported as such, not skipped silently.

Energy error: |∫L dω of the output / ∫L dω of the input − 1| (worst channel), each output integrated with the exact
solid angles of its own pixels, on two maps: Rooitou Park (a real sun) and a one-pixel sun holding 10× the sky's
power on a cube corner, where resamplers that ignore the footprint miss or double it.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED, require  # sets the environment first

import numpy as np

from lightprobe.maps import EnvMap, Resampler, auto_samples, read_envmap, resample
from lightprobe.maps.images import write_image
from lightprobe.maps.cube_layouts import _cube_texel_solid_angles
from lightprobe.maps.layouts import CUBE, CUBE_FACE_ORDER, CUBE_FACES, LATLONG
from lightprobe.sh.basis import project


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def rounds(ours, theirs, n: int) -> tuple[float, float, float]:
    """Alternate the two ``n`` times; (our best time, best ratio, median ratio)."""
    ours(), theirs()  # warm both (caches, compiled kernels, page cache)
    pairs = [(timed(ours), timed(theirs)) for _ in range(n)]
    ratios = [a / b for a, b in pairs]
    return min(a for a, _ in pairs), min(ratios), statistics.median(ratios)


def peer(name: str):
    """Import a peer, or None with a line saying why."""
    try:
        return __import__(name)
    except Exception as e:  # noqa: BLE001 - any failure to import is reported, never hidden
        print(f"  ({name} does not import here: {type(e).__name__}: {e})")
        return None


# ---- conversion -----------------------------------------------------------------------------------------------------
def nearest_cube(src: np.ndarray, n: int) -> np.ndarray:
    """The plain way, written as well as numpy allows: per face, float32 directions of the texel centres → the
    source pixel they fall in (atan2 twice) → one fancy-index gather. No footprint, no filtering."""
    h, w = src.shape[:2]
    s = ((np.arange(n, dtype=np.float32) + 0.5) / n) * 2 - 1
    out = np.empty((6, n, n, 3), np.float32)
    for f, key in enumerate(CUBE_FACE_ORDER):
        a = CUBE_FACES[key].astype(np.float32)
        x = a[0, 0] * s[None, :] + a[0, 1] * s[:, None] + a[0, 2]
        y = a[1, 0] * s[None, :] + a[1, 1] * s[:, None] + a[1, 2]
        z = a[2, 0] * s[None, :] + a[2, 1] * s[:, None] + a[2, 2]
        col = (np.arctan2(x, -z) * (w / (2 * np.pi)) + w / 2).astype(np.int64) % w
        row = np.minimum((np.arctan2(np.hypot(x, z), y) * (h / np.pi)).astype(np.int64), h - 1)
        out[f] = src[row, col]
    return out


def cube_integral(faces: np.ndarray) -> np.ndarray:
    """∫L dω of six N×N faces (any orientation: every face has the same texel solid angles)."""
    omega = _cube_texel_solid_angles(faces.shape[1])
    return np.einsum("ij,fijc->c", omega, faces.astype(np.float64))


def energy_error(integral: np.ndarray, truth: np.ndarray) -> float:
    return float(np.abs(integral / truth - 1).max())


def sub_pixel_sun(h: int) -> EnvMap:
    """A dim uniform sky and a sun in one source pixel (smaller than a target texel) at the cube corner direction
    (1, 1, 1)/√3, where three faces meet: the sun holds 10× the sky's power, so an error in the sun shows."""
    data = np.full((h, 2 * h, 3), 0.05, np.float32)
    _, x, y = LATLONG.pixel_coords(np.array([1.0, 1.0, 1.0]) / math.sqrt(3), (h, 2 * h))
    row, col = int(round(float(y))), int(round(float(x)))
    data[row, col] += 10 * 0.05 * 4 * math.pi / LATLONG.row_solid_angles((h, 2 * h))[row]
    return EnvMap(data, LATLONG)


def conversion_rows(big: EnvMap, n_rounds: int) -> list[tuple]:
    src, n = np.ascontiguousarray(big.data), 512
    sun = sub_pixel_sun(big.grid[0])
    t0 = time.perf_counter()
    cached = Resampler(LATLONG, big.grid, CUBE, n)  # the footprint weights, once for every map of this grid
    build = time.perf_counter() - t0
    print(f"  (lightprobe's cached weights: built once in {1000 * build:.0f} ms, {cached.nbytes / 2**20:.0f} MiB)")
    contenders = {"lightprobe": lambda e: resample(e, CUBE, n).data,
                  "numpy nearest": lambda e: nearest_cube(np.ascontiguousarray(e.data), n),
                  "lp cached": lambda e: cached(e).data}
    p360 = peer("py360convert")
    if p360:
        contenders["py360convert"] = lambda e: np.stack(p360.e2c(np.ascontiguousarray(e.data), face_w=n,
                                                                 mode="bilinear", cube_format="list"))
    sky = peer("envmap")
    if sky:
        def skylibs(e):
            return sky.EnvironmentMap(np.array(e.data), "latlong").convertTo("cube", 4 * n)
        contenders["skylibs"] = skylibs

    rows = []
    ours = contenders["lightprobe"]
    nearest = contenders["numpy nearest"]
    for name, run in contenders.items():
        if name == "lp cached":  # its own row: the cached path against the nearest resampler
            t, best, median = rounds(lambda: run(big), lambda: nearest(big), n_rounds)
        elif name == "lightprobe":
            t, best, median = min(timed(lambda: ours(big)) for _ in range(n_rounds)), 1.0, 1.0
        else:
            t, best, median = rounds(lambda: ours(big), lambda: run(big), n_rounds)
        errors = []
        for env in (big, sun):
            out = run(env)
            if name == "skylibs":
                integral = np.einsum("ij,ijc->c", np.nan_to_num(out.solidAngles()), np.nan_to_num(out.data))
            else:
                integral = cube_integral(out)
            errors.append(energy_error(integral, env.integral()))
        rows.append((name, t, best, median, *errors))
    return rows


# ---- reading ------------------------------------------------------------------------------------------------------
def reading_rows(big: EnvMap, folder: Path, n_rounds: int) -> list[tuple]:
    import OpenImageIO as oiio

    iio = peer("imageio")
    rows = []
    for ext in (".hdr", ".exr"):
        path = write_image(folder / f"big{ext}", big.data)

        def oiio_read():
            inp = oiio.ImageInput.open(str(path))
            pixels = inp.read_image(0, 0, 0, 3, "float")
            inp.close()
            return pixels

        ours = lambda: read_envmap(path)  # noqa: E731
        t, best, median = rounds(ours, oiio_read, n_rounds)
        rows.append((f"read 2048×1024 {ext}", "OpenImageIO read_image", t, best, median))
        if iio:
            try:
                shape = np.shape(iio.v3.imread(path))
                if shape[:2] != big.grid:  # no HDR plugin here (FreeImage is a download): another plugin took it
                    raise ValueError(f"read as an image of shape {shape}")
                t, best, median = rounds(ours, lambda: iio.v3.imread(path), n_rounds)
                rows.append((f"read 2048×1024 {ext}", "imageio v3.imread", t, best, median))
            except Exception as e:  # noqa: BLE001
                rows.append((f"read 2048×1024 {ext}", f"imageio: cannot ({type(e).__name__})", t, math.nan, math.nan))
    return rows


# ---- SH -------------------------------------------------------------------------------------------------------------
def sh_rows(big: EnvMap, n_rounds: int) -> list[tuple]:
    pixels = np.ascontiguousarray(big.data)
    out = np.empty_like(pixels)
    one_pass = lambda: np.multiply(pixels, 1.0, out=out)  # noqa: E731 - the fastest pass numpy makes
    ducc0, shtools = peer("ducc0"), peer("pyshtools")
    channels = [np.ascontiguousarray(pixels[..., c]) for c in range(3)]
    rows = []
    for l_max in (2, 4, 8, 16):
        ours = lambda: project(big, l_max, compiled=True)  # noqa: E731 - the kernels, as in a long-running process
        t, best, median = rounds(ours, one_pass, n_rounds)
        rows.append((f"SH order {l_max}", "one numpy pass", t, best, median))
        if ducc0:
            def run_ducc():
                return [ducc0.sht.experimental.analysis_2d(map=m[None], spin=0, lmax=l_max, geometry="F1",
                                                           nthreads=2) for m in channels]
            t, best, median = rounds(ours, run_ducc, n_rounds)
            rows.append((f"SH order {l_max}", "ducc0 analysis_2d (2 threads)", t, best, median))
        if shtools:
            def run_shtools():  # DH sampling 2 (N × 2N): the grid closest to a lat-long map
                return [shtools.expand.SHExpandDH(m.astype(np.float64), sampling=2, lmax_calc=l_max)
                        for m in channels]
            t, best, median = rounds(ours, run_shtools, n_rounds)
            rows.append((f"SH order {l_max}", "pyshtools SHExpandDH", t, best, median))
    return rows


# ---- start-up -------------------------------------------------------------------------------------------------------
def startup_rows(probe: Path, n_rounds: int) -> list[tuple]:
    exe = str(Path(sys.executable).with_name("lightprobe"))
    numpy_import = [sys.executable, "-c", "import numpy"]
    # "warm": bytecode caches written (a shell with PYTHONDONTWRITEBYTECODE would recompile every module each run)
    warm_env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    rows = []
    for argv in (["--help"], ["info", str(probe)], ["sh", str(probe)]):
        t, best, median = rounds(lambda: subprocess.run([exe, *argv], capture_output=True, check=True, env=warm_env),
                                 lambda: subprocess.run(numpy_import, capture_output=True, check=True, env=warm_env),
                                 n_rounds)
        rows.append((f"lightprobe {argv[0]}", 'python -c "import numpy"', t, best, median))
    with tempfile.TemporaryDirectory() as cold:  # the first compile: an empty kernel cache
        env = {**os.environ, "NUMBA_CACHE_DIR": cold}
        t = timed(lambda: subprocess.run([exe, "convert", str(probe), f"{cold}/c.exr", "--to", "cube"], env=env,
                                         capture_output=True, check=True))
        warm = min(timed(lambda: subprocess.run([exe, "convert", str(probe), f"{cold}/c.exr", "--to", "cube"],
                                                env=env, capture_output=True, check=True)) for _ in range(2))
    rows.append(("lightprobe convert, first compile", "the same, cache warm", t, t / warm, t / warm))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    probe = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr"
    if not require(probe):
        return 2
    big = read_envmap(probe).to(LATLONG, 1024)  # 2048×1024
    print(f"lightprobe against its peers ({os.cpu_count()} cores, {args.rounds} alternating rounds; "
          "ratio = lightprobe ÷ the other, best / median)\n")

    print("latlong 2048×1024 → cube 6×512²")
    print(f"  {'converter':26s} {'time':>9s} {'lightprobe ÷ it':>24s} {'energy error: Rooitou':>22s} "
          f"{'sub-pixel sun':>14s}")
    for name, t, best, median, e_sun, e_sub in conversion_rows(big, args.rounds):
        ratio = "—" if name == "lightprobe" else f"{best:.2f} / {median:.2f}×"
        if name == "lp cached":
            name, ratio = "lightprobe, cached weights", f"÷ nearest: {best:.2f} / {median:.2f}×"
        print(f"  {name:26s} {1000 * t:7.0f}ms {ratio:>24s} {100 * e_sun:21.3f}% {100 * e_sub:13.3f}%")

    per_pixel = []
    for n in (256, 512, 1024):  # k is fixed by the 2048×1024 source's pixels per target pixel, so cost ∝ output
        k = auto_samples(big.valid_pixels / (6 * n * n))
        t = min(timed(lambda: resample(big, CUBE, n)) for _ in range(args.rounds))
        per_pixel.append(f"{n}²: {1e9 * t / (6 * n * n * k * k):.0f} ns (k = {k})")
    print("  time per output pixel and subsample: " + ", ".join(per_pixel))

    with tempfile.TemporaryDirectory() as folder:
        groups = [("reading", reading_rows(big, Path(folder), args.rounds)),
                  ("SH projection of the 2048×1024 map (lightprobe's compiled path)", sh_rows(big, args.rounds)),
                  ("start-up (fresh processes, warm cache, 2048×1024 .exr)",
                   startup_rows(write_image(Path(folder) / "p.exr", big.data), args.rounds))]
        for title, rows in groups:
            print(f"\n{title}")
            print(f"  {'work':34s} {'against':32s} {'lightprobe':>10s} {'ratio best / median':>20s}")
            for work, against, t, best, median in rows:
                print(f"  {work:34s} {against:32s} {1000 * t:8.1f}ms {best:9.2f} / {median:.2f}×")
    return 0


if __name__ == "__main__":
    sys.exit(main())
