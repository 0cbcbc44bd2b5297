"""Reading and layout conversion, as ratios against baselines measured in the same run.

    python benchmarks/bench_layouts.py [--repeat N]

Baselines: OpenImageIO's own read of the same file (ImageInput.read_image as float: decoding only, no checks),
one numpy pass over the same pixels (an elementwise multiply into a preallocated array), and a plain nearest-pixel
numpy resampler (directions of the target's pixel centres → source pixel → fancy index; no footprint, no
filtering) doing the same conversion, generic over layouts (float64 directions: slower than the float32 per-face
one of bench_peers.py, which is the baseline the performance figures quote).
"""

from __future__ import annotations

import argparse
import os
import sys

from common import SHARED, best_of, require  # sets the environment first

import tempfile
from pathlib import Path

import numpy as np

from lightprobe.maps import EnvMap, read_envmap, resample
from lightprobe.maps.images import read_image, write_image
from lightprobe.maps.layouts import CUBE, LATLONG




def oiio_read(path: Path):
    import OpenImageIO as oiio

    def run():
        inp = oiio.ImageInput.open(str(path))
        pixels = inp.read_image(0, 0, 0, 3, "float")
        inp.close()
        return pixels
    return run


def numpy_pass(pixels: np.ndarray):
    out = np.empty_like(pixels)
    return lambda: np.multiply(pixels, 1.0, out=out)


def nearest_resampler(source: EnvMap, target, size: int):
    """The plain way: one point lookup per target pixel, no footprint."""
    def run():
        grid = target.grid_shape(size)
        d = target.directions(grid)
        face, x, y = source.layout.pixel_coords(d, source.grid)
        h, w = source.grid[-2:]
        col = np.clip(np.rint(x).astype(np.int64), 0, w - 1)
        row = np.clip(np.rint(y).astype(np.int64), 0, h - 1)
        return source.data[face, row, col] if source.layout.faces > 1 else source.data[row, col]
    return run


def streamed_rows(big: EnvMap, repeat: int) -> list[tuple]:
    """lat-long → cube, cross and horizontal cross at 512, streamed in strips (resample_strips, what `lightprobe
    convert` writes): each against the cube's strips and against its own whole-map resample."""
    from lightprobe.maps import resample_strips
    from lightprobe.maps.layouts import layout

    def strips(target):
        def run():
            for _ in resample_strips(big, target, 512)[1]:
                pass
        return run

    rows, t_cube = [], None
    for name in ("cube", "cross", "hcross"):
        target = layout(name)
        strips(target)()  # compile first
        t = best_of(strips(target), repeat)
        t_cube = t_cube or t
        rows.append((f"latlong 2048×1024 → {name} 512, strips", t, t_cube,
                     best_of(lambda: resample(big, target, 512), repeat)))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    probe = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr"
    if not require(probe):
        return 2

    rows, reads = [], []
    pixels = read_image(probe)
    t_read = best_of(lambda: read_image(probe), args.repeat)
    t_pass = best_of(numpy_pass(pixels), args.repeat)
    rows.append(("read 1024×512 .hdr", t_read, t_pass, None))

    big = read_envmap(probe).to(LATLONG, 1024)  # 2048×1024 latlong, the benchmark's input
    with tempfile.TemporaryDirectory() as folder:
        for ext in (".hdr", ".exr"):
            path = write_image(Path(folder) / f"big{ext}", big.data)
            read_envmap(path)  # compile the pixel check before timing
            t_read = best_of(lambda: read_envmap(path), args.repeat)
            t_oiio = best_of(oiio_read(path), args.repeat)
            reads.append((f"read_envmap 2048×1024 {ext}", t_read, t_oiio))
    resample(big, CUBE, 16)  # compile the kernels before timing
    t_pass = best_of(numpy_pass(big.data), args.repeat)
    t_to = best_of(lambda: resample(big, CUBE, 512), args.repeat)
    t_near = best_of(nearest_resampler(big, CUBE, 512), args.repeat)
    rows.append(("latlong 2048×1024 → cube 512²", t_to, t_pass, t_near))
    cube = resample(big, CUBE, 512)
    t_back = best_of(lambda: resample(cube, LATLONG, 1024), args.repeat)
    t_near = best_of(nearest_resampler(cube, LATLONG, 1024), args.repeat)
    t_pass = best_of(numpy_pass(cube.data), args.repeat)
    rows.append(("cube 512² → latlong 2048×1024", t_back, t_pass, t_near))
    drift = np.abs(resample(cube, LATLONG, 1024).integral() / big.integral() - 1).max()
    streamed = streamed_rows(big, args.repeat)

    print(f"{'reading':34s} {'lightprobe':>11s} {'÷ OpenImageIO':>14s}")
    for name, t, t_oiio in reads:
        print(f"{name:34s} {1000 * t:9.1f}ms {t / t_oiio:13.2f}×")
    print(f"\n{'operation':34s} {'lightprobe':>11s} {'÷ numpy pass':>13s} {'÷ nearest resampler':>20s}")
    for name, t, t_pass, t_near in rows:
        near = f"{t / t_near:19.1f}×" if t_near else f"{'—':>20s}"
        print(f"{name:34s} {1000 * t:9.1f}ms {t / t_pass:12.1f}× {near}")
    print(f"\n{'streamed, as convert writes a file':40s} {'lightprobe':>11s} {'÷ cube strips':>14s} {'÷ whole map':>12s}")
    for name, t, t_cube, t_whole in streamed:
        print(f"{name:40s} {1000 * t:9.1f}ms {t / t_cube:13.2f}× {t / t_whole:11.2f}×")
    print(f"∫L dω drift after latlong → cube → latlong: {100 * drift:.3f} % (sun: 68 % of the energy in 200 px)")
    print(f"(best of {args.repeat}; {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
