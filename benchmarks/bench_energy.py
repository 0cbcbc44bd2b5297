"""Energy of a one-pixel sun through every conversion: the accuracy bar (∫L dω within 0.2 %) measured on
directions nobody chose, beside the ones the tests pin down.

    python benchmarks/bench_energy.py [--suns 40] [--seed 11] [--part all|balance|flux|rows]

For each source layout (a 128-row lat-long, 64² cube faces, 128² angular and mirror-ball maps) and each target
layout at sizes 16, 32 and 64 (unturned), two tables:
- sampled suns: a sky of 0.05 with one pixel holding 10× the sky's power is converted at ``--suns`` random
  directions plus eight within 3° of the poles; the worst and the median relative error of the map's ∫L dω and
  how many exceed 0.2 %;
- every pixel: the gain of a sun in each source pixel, relative to the sun's own ∫L dω, for all pixels at once —
  exact, from the conversion's weights (:meth:`lightprobe.maps.Resampler.energy_gains`). Random suns miss the
  few pixels where a conversion goes wrong (a cube's edges, the rim side of a disc); this table does not.
Then the every-pixel measure at full size (cube 256–512, discs 1024, targets 256–1024), lat-longs into discs as a
map too large for the flux correction has them (``--part rows``), what each pixel's own subsample rate costs against
one rate for the whole map, what a cube source's texel balance costs (:mod:`lightprobe.maps.resampling.balance`: its weights
once per size, then one pass over the faces), and what the flux correction costs (:mod:`lightprobe.maps.resampling.flux`: the
conversion's adjoint and the flows once per pair of grids and process, then one pass over the source).
Suns within 25° of a disc's rim direction (where one direction is a ring of pixels) are left out, in the source and
in the target.
"""

from __future__ import annotations

import argparse
import importlib
import math

from common import require  # noqa: F401  (sets the environment first)

import numpy as np

from lightprobe.maps import EnvMap, Resampler, resample
from lightprobe.maps.layouts import layout

SOURCES = {"latlong": 128, "cube": 64, "angular": 128, "sphere": 128}
TARGETS = ("latlong", "cube", "angular", "sphere")
SIZES = (16, 32, 64)
RIM_MARGIN = 25.0  # degrees from a disc's rim direction left out
RIM_COS = math.cos(math.radians(RIM_MARGIN))


def near_rim(lay, d: np.ndarray) -> bool:
    rim = lay.rim_direction()
    return rim is not None and float(d @ rim) > RIM_COS


def sun_map(lay, size: int, d: np.ndarray) -> EnvMap:
    grid = lay.grid_shape(size)
    data = np.full(grid + (3,), 0.05, np.float32)
    face, x, y = lay.pixel_coords(d[None], grid)
    row = int(np.clip(np.rint(y[0]), 0, grid[-2] - 1))
    col = int(np.clip(np.rint(x[0]), 0, grid[-1] - 1))
    index = (int(face[0]), row, col) if len(grid) == 3 else (row, col)
    one = np.zeros_like(data)
    one[index] = 1.0
    data[index] += 10 * 0.05 * 4 * np.pi / EnvMap(one, lay).integral()[0]
    return EnvMap(data, lay)


def directions(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    random = rng.normal(size=(count, 3))
    polar = np.radians(rng.uniform(0.0, 3.0, 8))
    azimuth = rng.uniform(0.0, 2 * np.pi, 8)
    sign = np.where(np.arange(8) % 2 == 0, 1.0, -1.0)
    poles = np.stack([np.sin(polar) * np.sin(azimuth), sign * np.cos(polar), np.sin(polar) * np.cos(azimuth)], -1)
    d = np.concatenate([random, poles])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--suns", type=int, default=40)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--part", choices=("all", "balance", "flux", "rows"), default="all",
                        help="'balance' or 'flux': only that correction's cost table; 'rows': only lat-longs into "
                             "discs without it")
    args = parser.parse_args()
    if args.part != "all":
        {"balance": balance_cost, "flux": flux_cost, "rows": rows_alone}[args.part]()
        return
    suns = directions(args.suns, args.seed)
    print(f"one-pixel sun (10× the sky's power), {len(suns)} directions ({args.suns} random, 8 at the poles)")
    print(f"  {'source':16s} {'target':8s} {'size':>4s} {'suns':>5s} {'worst':>8s} {'median':>8s}  over 0.2 %")
    for name, size in SOURCES.items():
        src_layout = layout(name)
        for target in TARGETS:
            tgt_layout = layout(target)
            for out_size in SIZES:
                errors = []
                for d in suns:
                    if near_rim(src_layout, d) or near_rim(tgt_layout, d):
                        continue
                    src = sun_map(src_layout, size, d)
                    out = resample(src, tgt_layout, out_size)
                    errors.append(abs(out.integral()[0] / src.integral()[0] - 1) * 100)
                errors = np.array(errors)
                print(f"  {name + ' ' + str(size):16s} {target:8s} {out_size:4d} {errors.size:5d} "
                      f"{errors.max():7.3f}% {np.median(errors):7.3f}%  {(errors > 0.2).sum():3d}")
    every_pixel()
    full_size()
    rows_alone()
    rate_cost()
    balance_cost()
    flux_cost()


def kept_percent(resampler: Resampler) -> np.ndarray:
    """|energy gain| in % of a sun in each source pixel, those within RIM_MARGIN of a rim direction left out."""
    gains = resampler.energy_gains(rim_margin=RIM_MARGIN)
    return np.abs(gains[np.isfinite(gains)]) * 100


def every_pixel() -> None:
    print("\nevery source pixel as the sun (exact, from the conversion's weights; gain relative to the sun's own ∫L dω)")
    print(f"  {'source':16s} {'target':8s} {'size':>4s} {'pixels':>6s} {'worst':>8s} {'99.9th':>8s} {'median':>8s}"
          "  over 0.2 %")
    for name, size in SOURCES.items():
        src_layout = layout(name)
        grid = src_layout.grid_shape(size)
        for target in TARGETS:
            for out_size in SIZES:
                gains = kept_percent(Resampler(src_layout, grid, layout(target), out_size))
                print(f"  {name + ' ' + str(size):16s} {target:8s} {out_size:4d} {gains.size:6d} {gains.max():7.3f}% "
                      f"{np.percentile(gains, 99.9):7.3f}% {np.median(gains):7.3f}%  {(gains > 0.2).mean() * 100:5.1f} %")


FULL_SIZE = [("cube", 256, "latlong", 512), ("cube", 512, "latlong", 1024), ("cube", 256, "cube", 256),
             ("cube", 256, "angular", 512), ("angular", 1024, "latlong", 512), ("angular", 1024, "cube", 256),
             ("sphere", 1024, "cube", 256), ("sphere", 1024, "angular", 512), ("latlong", 1024, "angular", 512),
             ("latlong", 1024, "angular", 1024), ("latlong", 1024, "sphere", 512)]


def full_size() -> None:
    """The every-pixel measure at the sizes maps are converted at, and a turned cube into a cube."""
    from lightprobe.maps.frames import rotation_from_ypr

    print("\nevery source pixel as the sun, at full size (a turned cube: yaw 30°, pitch 20°, roll 10°)")
    print(f"  {'conversion':34s} {'worst':>8s} {'99.9th':>8s}  over 0.2 %")
    cases = [(*case, None) for case in FULL_SIZE] + [("cube", 256, "cube", 256, rotation_from_ypr(30, 20, 10))]
    for name, size, target, out_size, turn in cases:
        src_layout = layout(name)
        gains = kept_percent(Resampler(src_layout, src_layout.grid_shape(size), layout(target), out_size,
                                       rotation=turn))
        label = f"{name} {size} → {target} {out_size}" + (" turned" if turn is not None else "")
        print(f"  {label:34s} {gains.max():7.3f}% {np.percentile(gains, 99.9):7.3f}%  {(gains > 0.2).mean() * 100:7.3f} %")


ROWS_ALONE = [("latlong", 512, "sphere", 233), ("latlong", 1100, "sphere", 500), ("latlong", 256, "angular", 408),
              ("latlong", 1024, "angular", 1634), ("latlong", 2048, "sphere", 1024), ("latlong", 2048, "sphere", 3268)]


def rows_alone() -> None:
    """Lat-long sources into discs without the flux correction and with no margin by the rim direction: what a
    lat-long larger than 2048×1024 keeps (it is not flux-corrected), at the ratios of source to target a 4k map has
    into its default-sized discs. Seconds each, so the demo leaves them here."""
    print("\nlat-long into discs, no flux correction, no margin by the rim direction (as a lat-long over 2048×1024)")
    print(f"  {'conversion':34s} {'worst':>8s} {'99.9th':>8s}  over 0.2 %")
    src_layout = layout("latlong")
    for _, size, target, out_size in ROWS_ALONE:
        resampler = Resampler(src_layout, src_layout.grid_shape(size), layout(target), out_size)
        gains = resampler.without_flux_correction().energy_gains()
        gains = np.abs(gains[np.isfinite(gains)]) * 100
        label, over = f"latlong {2 * size}×{size} → {target} {out_size}", (gains > 0.2).mean() * 100
        print(f"  {label:34s} {gains.max():7.3f}% {np.percentile(gains, 99.9):7.3f}%  {over:7.3f} %")


RATE_COST = [("angular", 1000, "latlong", 1024), ("sphere", 1000, "latlong", 1024), ("angular", 1000, "cube", 512),
             ("cube", 512, "latlong", 1024), ("cube", 512, "angular", 1024), ("latlong", 1024, "sphere", 1024)]


def rate_cost(rounds: int = 3) -> None:
    """Time of each pixel's own rate (graded cells, the vertex ramp) against one rate for the map (``samples`` =
    the automatic base rate k), best of ``rounds`` alternating runs, on random maps; the flux correction off in
    both (a rate given by hand has none: flux_cost times it)."""
    import time

    from lightprobe.maps.resampling.resampler import supersampling

    flux_module = importlib.import_module("lightprobe.maps.resampling.flux")
    with_flux, flux_module._flux_stencil = flux_module._flux_stencil, lambda *args, **kwargs: None

    print("\nper-pixel rates against one rate k for the whole map (best of 3, alternating)")
    print(f"  {'conversion':34s} {'k':>3s} {'one rate':>9s} {'per pixel':>9s}  ratio")
    rng = np.random.default_rng(1)
    for name, size, target, out_size in RATE_COST:
        src_layout, tgt_layout = layout(name), layout(target)
        env = EnvMap(rng.random(src_layout.grid_shape(size) + (3,)).astype(np.float32), src_layout)
        k = supersampling(src_layout, env.grid, tgt_layout, tgt_layout.grid_shape(out_size), None, None)[0]
        best = {"one": math.inf, "own": math.inf}
        for _ in range(rounds):
            for mode in best:
                t0 = time.perf_counter()
                resample(env, tgt_layout, out_size, samples=k if mode == "one" else None)
                best[mode] = min(best[mode], time.perf_counter() - t0)
        print(f"  {name} {size} → {target} {out_size}".ljust(36) + f"{k:3d} {best['one']:8.3f}s {best['own']:8.3f}s "
              f"{best['own'] / best['one']:5.2f}×")
    flux_module._flux_stencil = with_flux


BALANCE_COST = [("cube", 256, "latlong", 512), ("cube", 512, "latlong", 1024), ("cube", 1024, "latlong", 2048),
                ("cube", 512, "angular", 1024)]


def balance_cost(rounds: int = 3) -> None:
    """A cube source's conversion with its texel balance against the same conversion with the prefilter switched
    off (best of ``rounds`` alternating runs; the balance's weights are made once per size and kept: their time is
    its own column)."""
    import time

    from lightprobe.maps.resampling import balance

    print("\na cube source's texel balance: conversion time with it against without (best of 3, alternating)")
    print(f"  {'conversion':34s} {'weights':>8s} {'pass':>7s} {'without':>8s} {'with':>8s}  ratio")
    rng = np.random.default_rng(2)
    with_balance = balance.prefilter_for
    flux_module = importlib.import_module("lightprobe.maps.resampling.flux")
    with_flux, flux_module._flux_stencil = flux_module._flux_stencil, lambda *args, **kwargs: None
    for name, size, target, out_size in BALANCE_COST:
        src_layout, tgt_layout = layout(name), layout(target)
        env = EnvMap(rng.random(src_layout.grid_shape(size) + (3,)).astype(np.float32), src_layout)
        balance.balance_of.cache_clear()
        t0 = time.perf_counter()
        weights = balance.balance_of(size)
        made = time.perf_counter() - t0
        t0 = time.perf_counter()
        weights.apply(env.data)
        one_pass = time.perf_counter() - t0
        best = {"without": math.inf, "with": math.inf}
        try:
            for _ in range(rounds):
                for mode in best:
                    balance.prefilter_for = with_balance if mode == "with" else (lambda _layout: None)
                    t0 = time.perf_counter()
                    resample(env, tgt_layout, out_size)
                    best[mode] = min(best[mode], time.perf_counter() - t0)
        finally:
            balance.prefilter_for = with_balance
        print(f"  {name} {size} → {target} {out_size}".ljust(36) + f"{made:7.3f}s {one_pass:6.3f}s "
              f"{best['without']:7.3f}s {best['with']:7.3f}s {best['with'] / best['without']:5.2f}×")
    flux_module._flux_stencil = with_flux


FLUX_COST = [("cube", 256, "latlong", 512), ("cube", 512, "latlong", 1024), ("cube", 1024, "latlong", 2048),
             ("cube", 512, "cube", 512), ("cube", 512, "angular", 1024), ("angular", 1000, "latlong", 1000),
             ("sphere", 1024, "cube", 256), ("latlong", 256, "sphere", 64)]


def flux_cost(rounds: int = 3) -> None:
    """A conversion with its flux correction made (the adjoint pass and the flows: once per pair of grids and
    process), with it kept, and without it (best of ``rounds`` alternating runs each), and the largest weight."""
    import time

    flux_module = importlib.import_module("lightprobe.maps.resampling.flux")
    print("\nthe flux correction: conversion time when it is made, when it is kept, and without it (best of 3)")
    print(f"  {'conversion':34s} {'without':>8s} {'made':>8s} {'kept':>8s}  made/without kept/without  weight")
    rng = np.random.default_rng(3)
    with_flux = flux_module._flux_stencil
    for name, size, target, out_size in FLUX_COST:
        src_layout, tgt_layout = layout(name), layout(target)
        env = EnvMap(rng.random(src_layout.grid_shape(size) + (3,)).astype(np.float32), src_layout)
        best = {"without": math.inf, "made": math.inf, "kept": math.inf}
        try:
            for _ in range(rounds):
                for mode in best:
                    flux_module._flux_stencil = with_flux if mode != "without" else (lambda *a, **k: None)
                    if mode == "made":
                        flux_module._FLUX_CACHE.clear()
                    t0 = time.perf_counter()
                    resample(env, tgt_layout, out_size)
                    best[mode] = min(best[mode], time.perf_counter() - t0)
        finally:
            flux_module._flux_stencil = with_flux
        weight = max(stencil.largest_weight for stencil in flux_module._FLUX_CACHE.values())
        flux_module._FLUX_CACHE.clear()
        print(f"  {name} {size} → {target} {out_size}".ljust(36) + f"{best['without']:7.3f}s {best['made']:7.3f}s "
              f"{best['kept']:7.3f}s  {best['made'] / best['without']:11.2f}× {best['kept'] / best['without']:10.2f}×"
              f"  {100 * weight:5.2f} %")


if __name__ == "__main__":
    main()
