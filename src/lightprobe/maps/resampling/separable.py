"""A lat-long into a lat-long on the same rows, as two sparse products: rows integrated exactly in θ.

The resampler averages k×k lookups over a target pixel with weights dω/(du dv) ∝ sin θ. For a lat-long target
whose rows are the source's (unturned, or turned about the vertical) that midpoint rule in θ is poor next to a
pole — dω vanishes there, and the source's pole rows, read through the cubic B-spline folded across the pole, vary
within one target row: a sun wholly in the source's first row came out +1.5–1.9 % (k = 4; the error falls as
1/k²). Computing only the polar rows apart does not do: where the exact rows meet the midpoint ones, a sun whose
spline straddles the seam between them lost or gained up to 0.6 % — the midpoints are exact for the spline only
as an unbroken grid.

So the whole conversion is done this way; it is separable. A target pixel is Σ_r W_tr · X_r(col):
- W_tr (:func:`row_matrix`): the mean of source row r's y weight over the target row's θ span, against sin θ — the
  kernel's own rational B-spline weights (:func:`lightprobe.maps.resampling.fused._pole_rows4`), a tap past a pole being
  row −1 − r read half a turn round — by 8-point Gauss–Legendre on each piece between the spline's knots (exact
  for the polynomial pieces; ~1e-12 for the rational ones next to the poles);
- X_r(col) (:func:`column_matrix`): the mean over the pixel's k column subsamples — placed and turned as the
  kernel places and turns them — of row r's periodic cubic B-spline, lookups half a source column apart at most.
Each source row then gives its (1 + ε) solid angle in total (:mod:`lightprobe.maps.resampling.pole_rows`), Σ_r W_tr = 1
and every row of the column matrix sums to 1, so a uniform map stays exactly uniform (float64 sums, one float32
rounding). Both matrices depend on the geometry alone: :class:`lightprobe.maps.Resampler` keeps them.
"""

from __future__ import annotations

import math

import numpy as np

from ..layouts import LATLONG, Layout
from . import fused
from .pole_rows import bspline

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(8)
STRIP_BYTES = 32 << 20  # float64 working memory of one band of target rows


def applies(source: Layout, target: Layout, rotation: np.ndarray | None) -> bool:
    """Whether the target's rows are the source's: lat-long into lat-long, unturned or turned about +Y alone."""
    return (source.name == "latlong" and target.name == "latlong"
            and (rotation is None or float(np.asarray(rotation)[1, 1]) > 1 - 1e-12))


def _row_weights(source_height: int, target_height: int, row: int) -> dict[tuple[int, bool], float]:
    """W for one target row: {(source row, half a turn round): its mean y weight over the row's θ span against
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


def row_matrix(source_height: int, target_height: int):
    """(W, W_half): (H_t, H_s) sparse matrices of the rows read as they are and of those read half a turn round."""
    from scipy import sparse

    parts = {False: ([], [], []), True: ([], [], [])}
    for t in range(target_height):
        for (r, half), value in _row_weights(source_height, target_height, t).items():
            rows, cols, values = parts[half]
            rows.append(t), cols.append(r), values.append(value)
    shape = (target_height, source_height)
    return tuple(sparse.csr_matrix((np.array(v), (np.array(r, np.int64), np.array(c, np.int64))), shape=shape)
                 for r, c, v in (parts[False], parts[True]))


def column_matrix(source_width: int, target_width: int, k: int, rotation: np.ndarray | None, half: bool = False):
    """(W_t, W_s) sparse: target column c's value = the mean over its k subsamples (the kernel's: u = (c + (j + ½)
    / k) / W_t, turned by d @ R) of a source row's periodic cubic B-spline (column c's centre at c); ``half`` reads
    the row half a turn round, as a tap past a pole is read."""
    from scipy import sparse

    u = (np.arange(target_width)[:, None] + (np.arange(k)[None, :] + 0.5) / k) / target_width
    d = LATLONG.uv_to_dir(np.zeros(u.shape, np.int64), u, np.full(u.shape, 0.5))  # the equator: azimuth alone
    if rotation is not None:
        d = d @ np.asarray(rotation, np.float64)
    _, x, _ = LATLONG.pixel_coords(d, (2, source_width))
    x = x + (source_width / 2 if half else 0.0)
    fx = np.floor(x)
    rows = np.repeat(np.arange(target_width), 4 * k)
    cols = np.concatenate([((fx.astype(np.int64) - 1 + tap) % source_width)[..., None] for tap in range(4)], -1)
    values = np.concatenate([bspline(x - fx + 1 - tap)[..., None] for tap in range(4)], -1) / k
    return sparse.csr_matrix((values.ravel(), (rows, cols.ravel())), shape=(target_width, source_width))


class Separable:
    """The matrices of one geometry (source grid → target grid, k, rotation) and the rows they make."""

    def __init__(self, source_grid: tuple[int, int], target_grid: tuple[int, int], k: int,
                 rotation: np.ndarray | None):
        (h_s, w_s), (h_t, w_t) = source_grid, target_grid
        self.target_grid = (h_t, w_t)
        self.rows, self.rows_half = row_matrix(h_s, h_t)
        self.columns = column_matrix(w_s, w_t, k, rotation)
        self.columns_half = column_matrix(w_s, w_t, k, rotation, half=True)

    @property
    def nbytes(self) -> int:
        return sum(m.data.nbytes + m.indices.nbytes + m.indptr.nbytes
                   for m in (self.rows, self.rows_half, self.columns, self.columns_half))

    def band(self, data: np.ndarray, first: int, last: int) -> np.ndarray:
        """Target rows ``first`` … ``last − 1`` (float32 (n, W_t, 3)) from the source ``data`` (H_s, W_s, 3)."""
        w_t = self.target_grid[1]
        out = np.empty((last - first, w_t, 3), np.float32)
        step = max(1, STRIP_BYTES // (8 * 3 * w_t * 8))  # float64 RGB rows: ~8 a target row (its own, its sources)
        for top in range(first, last, step):
            bottom = min(top + step, last)
            value = np.zeros((bottom - top, w_t * 3))
            for weights, columns in ((self.rows, self.columns), (self.rows_half, self.columns_half)):
                band = weights[top:bottom]
                used = np.unique(band.indices)
                if used.size == 0:
                    continue
                src = np.asarray(data[used], np.float64)  # (n, W_s, 3)
                x = (columns @ src.transpose(1, 0, 2).reshape(src.shape[1], -1))  # (W_t, n·3)
                x = x.reshape(w_t, used.size, 3).transpose(1, 0, 2).reshape(used.size, w_t * 3)
                value += band[:, used] @ x
            out[top - first:bottom - first] = value.reshape(bottom - top, w_t, 3)
        return out
