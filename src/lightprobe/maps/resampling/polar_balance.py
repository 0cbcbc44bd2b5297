"""A lat-long source's coarsest polar rows, balanced: every reduced cell of such a row delivers its row's mean.

Rows by a pole are read from their box reductions in azimuth (:mod:`lightprobe.maps.resampling.polar`), down to 4 cells
(8 where a row is reduced by overlaps), through a periodic B-spline over the cells. A cell's basis then spans a
quarter to a half of the circle, and a sun in that cell reaches the target through all of it: what it delivers is
that basis summed over the target's subsamples round the pole, and a turned target's subsamples are not spread
evenly in azimuth there (a cube's pixel grid seen from the pole, its rates stepping). The cells of one row came
out unequal while the rows' means held: lat-long 2048×1024 → a cube of 300 turned (30°, 40°, 50°), row 0 of 4 cells
+0.74 / −0.65 % against a mean of +0.045 %; 2098×1049 → a turned cube of 20, a row of 8 cells +0.22 %.

The balance is the flux correction's difference form (:mod:`lightprobe.maps.resampling.flux`) on a ring of cells: each
balanced cell's value is blended with its neighbours', v'_c = v_c + r_c (v_{c+1} − v_c) + l_c (v_{c−1} − v_c),
r, l ≥ 0, so part of what cell c delivers moves to the neighbour it reads. On a ring the flows that bring every
cell to the row's mean delivery are fixed up to one constant, chosen to make the largest flow least; a uniform row
stays uniform and a positive one positive. What is left is each row's mean, which the rational pole rows hold
(:mod:`lightprobe.maps.resampling.pole_rows`).

The deliveries are measured where they arise: on the target pixels whose footprints can reach the balanced rows
(:func:`near_pole`, blocks of target pixels by their corners' angle to the source's pole; the compiled adjoint
skips the rest), so the balance costs a small part of the conversion. A flux-corrected conversion needs none (its
correction makes each source pixel exact), nor one that reads the source's rows as they are
(:mod:`lightprobe.maps.resampling.separable`), nor an unturned one: its target is symmetric about the source's poles there
(2048×1024 → cubes of 50–591, 1049 rows → cube 80, → lat-long 300: weights under 0.03 %, no pixel's gain moved in
the fourth decimal of a percent), and measuring would load the adjoint's compiled code for nothing (5–15 MB at the
peak of a 4k map's convert, over the 3× the map tests/test_limits.py holds). A conversion's balance is measured
when the conversion is first made and kept for the last pairs of grids (:func:`_cell_balance`).
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ...util import limits
from ..layouts import LATLONG, Layout
from . import fused, polar
from .taps import _Taps

MAX_CELLS = 64  # rows reduced to at most this many cells are balanced (with more, each cell's basis is narrow: the
#                 rows of 16–64 cells of 2048×1024 → a turned cube of 300 were within 0.012 % of their means)
MAX_WEIGHT = 0.5  # a row whose balance would blend more than this is left as it is (the most measured: 0.7 %,
#                   2048×1024 → a turned cube of 300)
BLOCKS = 128  # blocks a side of a face at most, each tested by its corners (:func:`near_pole`): its grids of corner
#               directions stay ~1 MB (at 8 pixels a block a 3268-pixel disc's took 20 MB beside a 4k map)
SPLINE_ROWS = 2  # source rows a B-spline lookup reaches past its own row


@dataclass(frozen=True)
class CellBalance:
    """Blend weights of the balanced cells, by flat index into a lat-long's reduced polar rows (as
    :func:`lightprobe.maps.resampling.polar.reduced_rows` lays them out): cell ``cells[i]`` reads ``after[i]`` (the next
    cell of its ring) with weight ``right[i]`` and ``before[i]`` with ``left[i]`` (float32)."""

    cells: np.ndarray
    after: np.ndarray
    before: np.ndarray
    right: np.ndarray
    left: np.ndarray

    def apply(self, reduced: np.ndarray) -> np.ndarray:
        """Balance the reduced rows (float32 (cells, 3)) in place, and return them; rows not balanced are left as
        they are. Only the balanced cells are gathered: a 4k map's reduced rows are ~12 MB."""
        v = reduced[self.cells]
        step = self.right[:, None] * (reduced[self.after] - v) + self.left[:, None] * (reduced[self.before] - v)
        reduced[self.cells] = v + step
        return reduced

    def delivered(self, per_cell: np.ndarray) -> np.ndarray:
        """What each reduced cell delivers once balanced, from what it delivered read as it is (float64): the
        transpose of :meth:`apply`."""
        out = np.array(per_cell, dtype=np.float64, copy=True)
        d = out[self.cells].copy()
        right, left = self.right.astype(np.float64), self.left.astype(np.float64)
        out[self.cells] -= d * (right + left)
        np.add.at(out, self.after, d * right)
        np.add.at(out, self.before, d * left)
        return out


def balanced_rows(found: np.ndarray, width: int) -> np.ndarray:
    """Source rows (int64, in order) whose reduced cells are balanced, from :func:`lightprobe.maps.resampling.polar.
    polar_levels` ``found``: reduced to at most :data:`MAX_CELLS` cells, and not read as their whole row's mean."""
    deepest = polar.max_level(width)
    rows = np.flatnonzero((found > 0) & (found <= deepest))
    return rows[polar.reduced_width(width, found[rows]) <= MAX_CELLS]


def caps(found: np.ndarray, width: int) -> list[tuple[int, np.ndarray, float]]:
    """Per pole with balanced rows (north, then south): (its sign along +Y, those rows, the angle from that pole
    within which a lookup's B-spline taps can reach one of them)."""
    height = found.size
    rows = balanced_rows(found, width)
    out = []
    for sign, mine in ((1, rows[rows < height / 2]), (-1, rows[rows >= height / 2])):
        if mine.size:
            from_pole = np.minimum(mine + 1, height - mine).max()  # rows from the pole, the farthest one's included
            out.append((sign, mine, (int(from_pole) + SPLINE_ROWS) * math.pi / height))
    return out


def cell_span(found: np.ndarray, width: int, rows: np.ndarray) -> tuple[int, int]:
    """(first, end) of the reduced cells of ``rows`` in the reduced rows' layout."""
    levels = polar.kernel_levels(found, width)
    row_offsets, _, _ = polar.row_layout(levels, width)
    first, last = int(rows.min()), int(rows.max())
    return int(row_offsets[first]), int(row_offsets[last]) + int(polar.reduced_width(width, int(levels[last])))


def balance_of(per_cell: np.ndarray, first_cell: int, found: np.ndarray, width: int,
               rows: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """The balance of ``rows`` (balanced rows of one cap) of a lat-long ``width`` columns wide, from what each of
    their reduced cells delivers (float64, the cells from ``first_cell`` of the reduced rows' layout on): a list of
    (cells, after, before, right, left) per row balanced, for :func:`joined`."""
    levels = polar.kernel_levels(found, width)
    row_offsets, _, _ = polar.row_layout(levels, width)
    parts = []
    for r in rows:
        n = polar.reduced_width(width, int(levels[r]))
        first = int(row_offsets[r])
        d = np.asarray(per_cell[first - first_cell:first - first_cell + n], dtype=np.float64)
        if not (d > 0).all():
            continue  # a cell no target pixel reads: nothing to balance against
        flow = np.cumsum(d - d.mean())  # flow[c]: delivery passed from cell c to c + 1, up to one constant
        flow -= (flow.max() + flow.min()) / 2  # the constant that makes the largest flow least
        cells = np.arange(n)
        after = (cells + 1) % n
        right = np.maximum(flow, 0.0) / d
        left = np.empty(n)
        left[after] = np.maximum(-flow, 0.0) / d[after]  # a negative flow: cell c + 1 passes to c, reading it
        if (right + left).max() > MAX_WEIGHT:
            continue
        parts.append((first + cells, first + after, first + (cells - 1) % n, right, left))
    return parts


def joined(parts: list[tuple[np.ndarray, ...]]) -> CellBalance | None:
    """One :class:`CellBalance` of the rows :func:`balance_of` balanced (None where it balanced none)."""
    if not parts:
        return None
    cells, after, before, right, left = (np.concatenate(column) for column in zip(*parts))
    return CellBalance(cells.astype(np.int64), after.astype(np.int64), before.astype(np.int64),
                       right.astype(np.float32), left.astype(np.float32))


def near_pole(target: Layout, grid: tuple[int, ...], rotation: np.ndarray | None, sign: int,
              angle: float) -> np.ndarray:
    """The target's pixels that may look at a source direction within ``angle`` of the source's pole ``sign``·Y
    (the target at d showing the source at d·R): sorted int64 indices, flat over the (faces, H, W) grid. Tested a
    block of pixels at a time (8 a side, more where a face is over :data:`BLOCKS` blocks wide) by its corners: a
    block is kept where a corner lies within ``angle`` plus the block's diagonal (any point of the block is that
    near its corners), or where a corner has no direction (off a disc). Nothing the size of the target is made."""
    faces = target.faces
    h, w = grid[-2:]
    block = max(8, -(-max(h, w) // BLOCKS))
    rows = np.unique(np.minimum(np.arange(0, h + block, block), h))
    cols = np.unique(np.minimum(np.arange(0, w + block, block), w))
    face = np.broadcast_to(np.arange(faces)[:, None, None], (faces, rows.size, cols.size))
    u = np.broadcast_to(cols[None, None, :] / w, face.shape)
    v = np.broadcast_to(rows[None, :, None] / h, face.shape)
    pole = sign * (np.eye(3)[1] if rotation is None else np.asarray(rotation, np.float64)[:, 1])
    with np.errstate(invalid="ignore"):
        d = target.uv_to_dir(face, u, v)
        from_pole = np.arccos(np.clip(d @ pole, -1.0, 1.0))

    def between(a, b):
        with np.errstate(invalid="ignore"):
            return np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))

    diagonal = np.fmax(between(d[:, :-1, :-1], d[:, 1:, 1:]), between(d[:, 1:, :-1], d[:, :-1, 1:]))
    corners = np.stack([from_pole[:, :-1, :-1], from_pole[:, 1:, :-1], from_pole[:, :-1, 1:], from_pole[:, 1:, 1:]])
    off_disc = np.isnan(corners).any(axis=0) | np.isnan(diagonal)
    near = off_disc | (np.where(np.isnan(corners), np.inf, corners).min(axis=0) <= angle + diagonal)
    f, br, bc = np.nonzero(near)
    step = np.arange(block)
    r = rows[br][:, None, None] + step[None, :, None]
    c = cols[bc][:, None, None] + step[None, None, :]
    inside = (r < rows[br + 1][:, None, None]) & (c < cols[bc + 1][:, None, None])
    flat = (f[:, None, None] * h + r) * w + c
    return np.sort(flat[inside])


# ---- a conversion's balance, measured by the compiled adjoint and kept -------------------------------------------
_CELL_CACHE: dict = {}
_CELL_CACHE_PAIRS = 16  # balances a process keeps (a few kB each)
_CELL_LOCK = threading.Lock()


def _cell_balance(source_grid: tuple[int, int], found: np.ndarray, filled: Layout, grid: tuple[int, ...], k: int,
                  k_max: int, steps: polar.Steps, rotation) -> CellBalance | None:
    """The balance of a lat-long source's coarsest polar rows in this conversion, or None where it has none; kept
    for the last pairs of grids. Measured by the compiled adjoint, a pole at a time, on the target pixels by that pole
    alone and into its balanced rows' cells alone."""
    pole_caps = caps(found, source_grid[-1])
    if not pole_caps:
        return None
    key = (source_grid, filled, tuple(grid), k, k_max, found.tobytes(),
           None if rotation is None else np.asarray(rotation, np.float64).tobytes())
    with _CELL_LOCK:
        if key in _CELL_CACHE:
            return _CELL_CACHE[key]
    taps = _Taps(LATLONG, source_grid, filled, filled.size_of(grid), k, k_max, steps, rotation)
    parts = []
    for sign, rows, angle in pole_caps:
        first, end = cell_span(found, source_grid[-1], rows)
        kept = near_pole(filled, grid, rotation, sign, angle)
        per_cell = _kept_delivery(taps, filled, grid, kept, taps.source_pixels + first, end - first)
        parts += balance_of(per_cell, first, found, source_grid[-1], rows)
    cells = joined(parts)
    with _CELL_LOCK:
        while len(_CELL_CACHE) >= _CELL_CACHE_PAIRS:
            _CELL_CACHE.pop(next(iter(_CELL_CACHE)))
        _CELL_CACHE[key] = cells
    return cells


def _kept_delivery(taps: _Taps, filled: Layout, grid: tuple[int, ...], kept: np.ndarray, base: int,
                   size: int) -> np.ndarray:
    """Σ_t Ω_t W_ti over the target pixels ``kept`` (sorted, flat over the target's lines) for the ``size`` tap
    indices from ``base`` on (float64): the compiled adjoint on each run of lines that holds a kept pixel, the
    others weighing 0 there (the kernel skips them)."""
    omega_kept = filled.solid_angles_of(tuple(grid), kept)
    lines = np.unique(kept // taps.width)
    runs = np.split(lines, np.flatnonzero(np.diff(lines) > 1) + 1)
    runs = [part for run in runs for part in np.array_split(run, -(-len(run) // 32))]  # ≤ 32 lines of weights
    threads = max(1, min(limits.threads(), len(runs)))

    def thread_total(t: int) -> np.ndarray:
        total = np.zeros(size)
        for run in runs[t::threads]:
            first, last = int(run[0]), int(run[-1]) + 1
            lo, hi = np.searchsorted(kept, [first * taps.width, last * taps.width])
            omega_t = np.zeros((last - first) * taps.width)
            omega_t[kept[lo:hi] - first * taps.width] = omega_kept[lo:hi]
            fused.footprint_delivery(*taps.kernel_args, first, last, omega_t, taps.max_taps, total, base)
        return total

    with ThreadPoolExecutor(threads) as pool:
        return np.sum(list(pool.map(thread_total, range(threads))), axis=0)
