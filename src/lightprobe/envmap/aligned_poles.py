"""A lat-long target's polar rows from a lat-long source on the same rows, integrated exactly in θ.

The resampler averages k×k lookups over a target pixel with weights dω/(du dv) ∝ sin θ. For a lat-long target
whose rows are the source's (unturned, or turned about the vertical) that midpoint rule in θ is poor in the rows
at a pole: dω vanishes there and the source's pole rows, read through the cubic B-spline folded across the pole,
vary within a single target row. A sun wholly in the source's first row came out +1.5–1.9 % (k = 4; the error
falls only as 1/k²).

These rows are separable, so they are computed apart: a target pixel is Σ_r W_tr · X_r(col) — W_tr = the mean of
source row r's y weight (the kernel's own rational B-spline weights, :func:`lightprobe.envmap.fused._pole_rows4`,
with a tap past the pole being row −1 − r half a turn round) over the target row's θ span against sin θ, by
Gauss–Legendre on each piece between the spline's knots (exact to float rounding for the polynomial pieces, ~1e-12
for the rational ones); X_r(col) = the mean of the k lookups of row r across the pixel's columns (the same
subsamples and cubic B-spline in azimuth as the kernel's). Σ_r W_tr = 1, so a uniform map stays exactly uniform,
and every source row gives its (1 + ε) solid angle in total, as elsewhere (:mod:`lightprobe.envmap.pole_rows`).
"""

from __future__ import annotations

import math

import numpy as np

from ..layouts import LATLONG, Layout
from . import fused, pole_rows
from .pole_rows import bspline

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(8)
EXTRA_ROWS = 3  # source rows past the rational weights' reach whose target rows are also integrated exactly


def applies(source: Layout, target: Layout, rotation: np.ndarray | None) -> bool:
    """Whether the target's rows are the source's: lat-long into lat-long, unturned or turned about +Y alone."""
    return (source.name == "latlong" and target.name == "latlong"
            and (rotation is None or abs(float(np.asarray(rotation)[1, 1])) > 1 - 1e-12))


def polar_target_rows(source_height: int, target_height: int) -> list[int]:
    """The target rows computed here: those reaching within the rational weights' reach (or two rows) of a pole,
    plus :data:`EXTRA_ROWS` source rows, at each end."""
    reach = max(pole_rows.reach(source_height), 2) + EXTRA_ROWS
    n = min(math.ceil(reach * target_height / source_height), target_height // 2)
    return list(range(n)) + list(range(target_height - n, target_height))


def row_weights(source_height: int, target_height: int, row: int) -> dict[tuple[int, bool], float]:
    """W for one target row: {(source row, half a turn round): mean y weight over the row's θ span, against
    sin θ}, with the kernel's own tap weights."""
    scale = source_height / target_height
    lo, hi = row * scale - 0.5, (row + 1) * scale - 0.5  # the row's span in source row coordinates (centre r at r)
    knots = np.concatenate([[lo], np.arange(math.floor(lo) + 1, math.ceil(hi)), [hi]])
    weights: dict[tuple[int, bool], float] = {}
    total = 0.0
    for a, b in zip(knots[:-1], knots[1:]):
        if b <= a:
            continue
        for y, wq in zip((a + b) / 2 + (b - a) / 2 * _NODES, (b - a) / 2 * _WEIGHTS):
            fy = math.floor(y)
            taps = fused._pole_rows4.py_func(fy - 1, source_height, *fused._bspline4.py_func(y - fy))
            dw = wq * math.sin(math.pi * (y + 0.5) / source_height)
            total += dw
            for dy, t in enumerate(taps):
                key = fused._reflected_row.py_func(fy - 1 + dy, source_height)
                weights[key] = weights.get(key, 0.0) + t * dw
    return {key: value / total for key, value in weights.items()}


def _column_means(row: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(W_t, 3) float64: the mean over the last axis of x (W_t, k) source column coordinates (column c's centre at
    c) of a source row's (W_s, 3) periodic cubic B-spline interpolation."""
    w = row.shape[0]
    fx = np.floor(x)
    t = x - fx
    out = np.zeros((x.shape[0], 3))
    for d in range(4):
        cols = (fx.astype(np.int64) - 1 + d) % w
        out += np.einsum("tk,tkc->tc", bspline(t + 1 - d), row[cols].astype(np.float64))
    return out / x.shape[1]


def polar_rows(data: np.ndarray, target_grid: tuple[int, int], k: int,
               rotation: np.ndarray | None) -> dict[int, np.ndarray]:
    """{target row: its (W_t, 3) float32 values} for the rows of :func:`polar_target_rows`, from a lat-long source
    ``data`` (H, W, 3) on the same rows (:func:`applies`); the k subsamples across each pixel's columns as the
    kernel places them, turned as the kernel turns them (d @ R)."""
    h_s, w_s = data.shape[:2]
    h_t, w_t = target_grid
    u = (np.arange(w_t)[:, None] + (np.arange(k)[None, :] + 0.5) / k) / w_t
    d = LATLONG.uv_to_dir(np.zeros(u.shape, np.int64), u, np.full(u.shape, 0.5))  # the equator: azimuth alone
    if rotation is not None:
        d = d @ np.asarray(rotation, np.float64)
    _, x, _ = LATLONG.pixel_coords(d, (h_s, w_s))
    weights = {row: row_weights(h_s, h_t, row) for row in polar_target_rows(h_s, h_t)}
    keys = {key for w in weights.values() for key in w}
    means = {(r, half): _column_means(data[r], x + (w_s / 2 if half else 0.0)) for r, half in keys}
    out = {}
    for row, w in weights.items():
        value = np.zeros((w_t, 3))
        for key, weight in sorted(w.items()):
            value += weight * means[key]
        out[row] = value.astype(np.float32)
    return out
