"""A lat-long source's polar rows, reduced in azimuth to what the target samples: no aliasing near the poles.

Near a lat-long pole one row's pixels are narrow (each spans 2π sin θ / W), and a target pixel there covers many of
them — at the pole, all. Its k×k lookups then land several columns apart, and a source feature one column wide (a
sun) is hit or missed by chance: ∫L dω was off by 0.3–0.7 % at 20° from the pole and by up to 88 % at the pole row.

The cure is the source's, not the target's: every row whose lookups land more than :data:`MAX_SPACING` columns
apart is read from its box reduction in azimuth — 2^ℓ neighbouring columns averaged, W / 2^ℓ pixels left (past a
width's last whole halving, W / 2^ℓ rounded, each the mean of the columns it overlaps) — with ℓ the least that
brings the lookups within :data:`MAX_SPACING` reduced columns. All pixels of a row have the same
solid angle, so the reduction keeps the row's ∫L dω exactly and a uniform row uniform; the kernel interpolates each
row on its own grid (:func:`lightprobe.maps.resampling.fused._lookup_latlong`). Only rows within the polar caps
(|cos θ| ≥ :data:`CAP_COS`) are reduced: elsewhere a row is wider than any sane target's pixel, and a mirror ball's
rim — whose pixels are long arcs anywhere — must not blur the equator.

How far apart the lookups land is measured, not modelled: on a sample of target pixels, the azimuth step to the next
pixel right and below, in source columns, over k; each source row takes the largest among the samples whose
footprint reaches it.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from dataclasses import dataclass

from ...util.jit import njit, read_only
from ..layouts import Layout
from . import pole_rows

MAX_SPACING = 0.5  # source pixels between a pixel's neighbouring lookups, at most (keeps a one-pixel sun to ~0.1 %)
MAX_SAMPLES = 16  # k×k lookups per target pixel, at most
CAP_COS = 0.7  # rows with |cos θ| at least this (within ~46° of a pole) may be reduced
MIN_CELLS = 4  # reduced columns a row keeps at its deepest halving (fewer: read as its mean): the B-spline's
#               taps. At 8 a turned lat-long target's pole rows kept a sun better (2048×1024 → 194: two rows 0.22 %
#               off at 4), but a sun 2–4° from the pole was read as its row's mean and moved over a target pixel;
#               the cells of so coarse a row are now balanced (polar_balance: 0.09 % there)
MIN_OVERLAP_CELLS = 8  # the same for a level reduced by overlaps: at 4, a turned cube of 20 from a lat-long of
#                       1049 rows (read as 131, W = 2 × 131) lost 0.69 % of a sun in its source's pole rows, 2012×1006
#                       → a turned lat-long of 194 0.31 %; at 8, 0.22 % and 0.19 % (0.20 and 0.19 read as means),
#                       and 0.13 % and 0.09 % since the cells are balanced (polar_balance)
SAMPLES = 16_000  # target pixels sampled (every stride-th) to measure the lookup spacing


def no_reduction(rows: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(levels, reduced, row_offsets, caps) for a source of ``rows`` rows read as it is (the kernel reads a
    latlong's level for every row it looks up: ``rows`` must be its height). The caps still cover the rows with
    rational weights (:mod:`lightprobe.maps.resampling.pole_rows`), which only the per-row path applies."""
    caps = np.full(2, pole_rows.reach(rows), np.int64)
    return np.zeros(rows, np.int64), np.zeros((1, 3), np.float32), np.zeros(rows, np.int64), caps


def reduced_width(width: int, level):
    """Columns of a row of ``width`` reduced to ``level`` ℓ (an int, or an array of them): W / 2^ℓ, rounded to the
    nearest whole number where it is not one (W = 2 × odd for a lat-long of odd height). Such a row's reduced
    columns each cover W / W_ℓ source columns — not a whole number — and are the exact means of the columns they
    overlap (:func:`lightprobe.maps.resampling.overlaps.column_means`)."""
    return (width + ((1 << level) >> 1)) >> level


def max_level(width: int) -> int:
    """The deepest reduction a row of ``width`` columns allows: at least :data:`MIN_CELLS` columns left
    (:data:`MIN_OVERLAP_CELLS` by overlaps); a row whose lookups want more is read as its mean. Halvings while they
    leave whole pairs, then reductions by overlaps. Asking whole pairs at every level had left a width of 2^a × odd
    a halvings: the rows by the poles that wanted more were read as their means, flat in azimuth — a smooth field 1
    ± 0.1 there came out up to 0.10 off within 12° of the pole (1612×806 → cube 128), 0.058 (3000×1500 → cube 512) —
    and an odd height none at all before a row's last width could be odd (+2920 % for a sun, 746×373 → cube 352)."""
    level = 0
    while reduced_width(width, level + 1) >= (MIN_CELLS if halves_exactly(width, level + 1) else MIN_OVERLAP_CELLS):
        level += 1
    return level


def halves_exactly(width: int, level: int) -> bool:
    """Whether a row of ``width`` reduces to ``level`` by whole pairs (each reduced column 2^ℓ source columns)."""
    return width % (1 << level) == 0


@dataclass(frozen=True)
class Steps:
    """How far apart, in source pixels, neighbouring target pixels land: for a sample of target pixels, the source
    polar angle θ of each (latlong sources; else NaN) and the larger of its steps right and down, in source
    columns (x) and rows (y). Lookups land these steps / k apart."""

    theta: np.ndarray
    x: np.ndarray
    y: np.ndarray
    row: np.ndarray  # the pixel centre's source row coordinate (row r's centre at r)
    # The target's rows are the source's (a lat-long, unturned, turned about the vertical or upside down): its
    # lookups keep their column spacing at any row. Any other target is locally flat, and nearer the pole than a
    # pixel's centre the same arc between its lookups spans more columns.
    rows_aligned: bool = False


def no_steps() -> Steps:
    """Steps of no pixel: nothing measured (:func:`samples_needed` then keeps its floor)."""
    empty = np.zeros(0)
    return Steps(empty, empty, empty, empty)


def measure_steps(source: Layout, source_grid: tuple[int, ...], target: Layout, grid: tuple[int, ...],
                  rotation: np.ndarray | None) -> Steps:
    """:class:`Steps` on a sample of the target's pixels (every stride-th, and every one near a latlong source's
    poles, where the steps change fastest). Steps that cross between cube faces are left out. Geometry alone, so
    kept for the last few geometries (read-only arrays): a batch of maps of one size measures once (~9 ms of a
    150 ms conversion of 2048×1024 into 6×512²)."""
    turn = None if rotation is None else np.asarray(rotation, np.float64).tobytes()
    return _measured_steps(source, tuple(source_grid), target, tuple(grid), turn)


@functools.lru_cache(maxsize=16)
def _measured_steps(source: Layout, source_grid: tuple[int, ...], target: Layout, grid: tuple[int, ...],
                    turn: bytes | None) -> Steps:
    rotation = None if turn is None else np.frombuffer(turn, np.float64).reshape(3, 3)
    face, u, v, du, dv = _sampled_pixels(target, grid, rotation if source.name == "latlong" else None,
                                         source.name == "latlong")
    empty = np.zeros(0)
    if face.size == 0:
        return Steps(empty, empty, empty, empty)
    right = np.where(u + du < 1.0, u + du, u - du)  # the neighbour inside the grid (not past a pole or edge)
    below = np.where(v + dv < 1.0, v + dv, v - dv)
    coords = [source.pixel_coords(_source_direction(target, face, uu, vv, rotation), source_grid)
              for uu, vv in ((u, v), (right, v), (u, below))]
    (f0, x0, y0), w = coords[0], source_grid[-1]
    xs, ys = [], []
    for f1, x1, y1 in coords[1:]:
        dx = np.abs(x1 - x0)
        if source.name == "latlong":
            dx = np.minimum(dx, w - dx)  # across the seam
        same = np.asarray(f1) == np.asarray(f0)
        xs.append(np.where(same, dx, 0.0))
        ys.append(np.where(same, np.abs(y1 - y0), 0.0))
    step_x, step_y = np.maximum(*xs), np.maximum(*ys)
    theta = ((np.asarray(y0) + 0.5) / source_grid[-2] * math.pi if source.name == "latlong"
             else np.full(step_x.shape, np.nan))
    aligned = target.name == "latlong" and (rotation is None or abs(rotation[1, 1]) > 1 - 1e-12)
    steps = Steps(theta, step_x, step_y, np.asarray(y0, np.float64), aligned)
    for values in (steps.theta, steps.x, steps.y, steps.row):
        values.setflags(write=False)  # shared by every caller of this geometry
    return steps


def samples_needed(steps: Steps, at_least: int) -> int:
    """The supersampling rate k: at least ``at_least``, and enough that lookups of all but the widest 0.5 % of
    the sampled pixels (a mirror ball's rim) land within :data:`MAX_SPACING` source pixels in y, and in x outside
    a latlong's polar caps (inside them, the rows are reduced instead: :func:`polar_levels`)."""
    if steps.x.size == 0:
        return at_least
    polar = np.abs(np.cos(steps.theta)) >= CAP_COS  # False for non-latlong sources (NaN)
    widest = np.maximum(steps.y, np.where(polar, 0.0, steps.x))
    need = math.ceil(float(np.percentile(widest, 99.5)) / MAX_SPACING - 1e-9)
    return max(at_least, min(need, MAX_SAMPLES))


def polar_levels(steps: Steps, source_grid: tuple[int, int], k: int) -> np.ndarray:
    """Per source row (H,) int64, its reduction level ℓ (0: read as it is): in the polar caps, the least ℓ that
    brings the widest lookup spacing in azimuth among the sampled pixels reaching the row within
    :data:`MAX_SPACING` reduced columns; :func:`max_level` + 1 where even the deepest reduction leaves the lookups
    further apart — the rows next to a pole under a coarse target — which are then read as their whole row's mean
    (:func:`reduced_rows`): a few wedges of azimuth meeting at the pole, each hit or missed by the target's
    subsamples, took a pole-row sun ±2–7 % off in 32–80 pixel angular, mirror-ball and small cube targets."""
    h, w = source_grid
    spacing = np.zeros(h)
    if steps.x.size:  # each sampled pixel's spacing goes to every row its lookups' B-spline taps reach
        reach = steps.y / 2 + 2.0
        first = np.floor(steps.row - reach).astype(np.int64) + 1
        count = np.ceil(steps.row + reach).astype(np.int64) - first
        centre = np.sin(steps.theta)
        for offset in range(int(count.max())):
            rows = first + offset
            hit = (offset < count) & (rows >= 0) & (rows < h)  # rows past a pole are the pole's own: reached
            spread = 1.0
            if not steps.rows_aligned:  # nearer the pole than the centre, one arc spans more columns (∝ 1/sin θ)
                spread = np.maximum(centre / np.sin((np.clip(rows, 0, h - 1) + 0.5) / h * math.pi), 1.0)
            np.maximum.at(spacing, rows[hit], (steps.x / k * spread)[hit])
    need = np.ceil(np.log2(np.maximum(spacing, 1e-300) / MAX_SPACING) - 1e-9)
    levels = np.clip(need, 0, max_level(w) + 1).astype(np.int64)
    cos = np.cos((np.arange(h) + 0.5) / h * math.pi)
    levels[np.abs(cos) < CAP_COS] = 0
    return _rising_to_the_poles(levels)


def _rising_to_the_poles(levels: np.ndarray) -> np.ndarray:
    """``levels`` raised so that none falls towards a pole: each row at least the level of every row between it and
    the equator. A row's pixels narrow towards the pole, so a row nearer it never needs less; but the spacing is
    measured on a sample of target pixels, and a row their footprints happened not to reach came out lower than
    its neighbours — unreduced (ℓ = 0) among rows of ℓ = 3 for a 4096×2048 map into a cube of 512, whose sun in
    such a row came out +54 % (``Resampler.energy_gains``), a single ℓ = 2 row among ℓ = 3 ones into a mirror
    ball of 2048, ±0.34 %. The spline across rows read at different levels is what the kernel handles anyway
    (the level steps at the cap's edge)."""
    h = levels.size
    rising = levels.copy()
    rising[:h // 2] = np.maximum.accumulate(levels[:h // 2][::-1])[::-1]  # north: row 0 is the pole
    rising[h // 2:] = np.maximum.accumulate(levels[h // 2:])
    return rising


def kernel_levels(levels: np.ndarray, width: int) -> np.ndarray:
    """:func:`polar_levels` as the kernel reads them: a whole-row level (max_level + 1) is stored at max_level."""
    return np.minimum(levels, max_level(width))


def row_layout(levels: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Where each reduced row sits: (row_offsets (H,), caps (2,), total reduced pixels); ``caps`` is how many rows
    at the north and south ends the reduced rows — or the rows with rational weights near the poles
    (:mod:`lightprobe.maps.resampling.pole_rows`) — reach: plain footprint tiles stay clear of them."""
    h = levels.size
    levels = kernel_levels(levels, width)
    widths = np.where(levels > 0, reduced_width(width, levels), 0)
    row_offsets = np.zeros(h, np.int64)
    np.cumsum(widths[:-1], out=row_offsets[1:])
    nonzero = np.nonzero(levels)[0]
    north, south = nonzero[nonzero < h / 2], nonzero[nonzero >= h / 2]
    caps = np.array([north[-1] + 1 if north.size else 0, h - south[0] if south.size else 0], np.int64)
    caps = np.maximum(caps, pole_rows.reach(h))
    return row_offsets, caps, int(widths.sum())


def reduced_rows(data: np.ndarray, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(levels, reduced, row_offsets, caps) for the kernel: row r of a latlong image (H, W, 3) with level ℓ > 0
    becomes W / 2^ℓ means of 2^ℓ columns at ``reduced[row_offsets[r]:]`` (:func:`row_layout`), by ℓ halvings
    (each the mean of a pair in float32: ``(a + b) · ½``, the same bits as numpy's ``(x[0::2] + x[1::2]) * ½``) —
    or, where W / 2^ℓ is not whole, :func:`reduced_width` means of the columns each overlaps (:func:`_overlap_rows`).
    A whole-row level (:func:`polar_levels`) fills its row at max_level with the mean of those values (in float64:
    a uniform row stays exactly uniform); the returned levels are the kernel's."""
    h, w = data.shape[:2]
    whole = np.nonzero(levels > max_level(w))[0]
    levels = kernel_levels(levels.astype(np.int64), w)
    if not levels.any():  # nothing to reduce, or a row too narrow for any (under 2 × MIN_CELLS columns)
        return no_reduction(h)
    row_offsets, caps, total = row_layout(levels, w)
    reduced = np.empty((total, 3), np.float32)
    rows = np.nonzero(levels)[0]
    exact = np.array([halves_exactly(w, level) for level in levels[rows]], bool)
    _halve_rows(read_only(np.asarray(data, np.float32)), rows[exact], levels, row_offsets, reduced)
    _overlap_rows(data, rows[~exact], levels, row_offsets, reduced)
    width = reduced_width(w, max_level(w))
    for r in whole:  # a few rows at each pole
        row = reduced[row_offsets[r]:row_offsets[r] + width]
        row[:] = row.mean(axis=0, dtype=np.float64).astype(np.float32)
    return levels, reduced, row_offsets, caps


def _overlap_rows(data: np.ndarray, rows: np.ndarray, levels: np.ndarray, row_offsets: np.ndarray,
                  reduced: np.ndarray) -> None:
    """Rows of ``rows`` whose level does not halve them exactly, reduced by exact overlaps into
    reduced[row_offsets[r]:] (float64 sums, stored float32): a sparse product per level and band of
    :data:`_OVERLAP_BAND` rows (a float64 copy of a whole cap of a 4k map would be ~100 MB)."""
    from .overlaps import column_means

    w = data.shape[1]
    for level in np.unique(levels[rows]):
        cells = reduced_width(w, int(level))
        means = column_means(w, cells)
        mine = rows[levels[rows] == level]
        for start in range(0, len(mine), _OVERLAP_BAND):
            band = mine[start:start + _OVERLAP_BAND]
            part = means @ np.asarray(data[band], np.float64).transpose(1, 0, 2).reshape(w, -1)
            part = part.reshape(cells, len(band), 3).astype(np.float32)
            for i, r in enumerate(band):
                reduced[row_offsets[r]:row_offsets[r] + cells] = part[:, i]


_OVERLAP_BAND = 64


@njit(cache=True, nogil=True, error_model="numpy")
def _halve_rows(data, rows, levels, row_offsets, reduced):  # pragma: no cover - compiled
    """Each row r of ``rows`` halved levels[r] times (pair means, float32) into reduced[row_offsets[r]:]; a
    pass over those rows with one row of scratch (numpy's slices took 8 ms for a 2048-wide map's caps, this 2)."""
    w = data.shape[1]
    half = np.float32(0.5)
    line = np.empty((w // 2, 3), np.float32)
    for r in rows:
        n = w // 2
        for c in range(n):
            for ch in range(3):
                line[c, ch] = (data[r, 2 * c, ch] + data[r, 2 * c + 1, ch]) * half
        for _ in range(1, levels[r]):
            n //= 2
            for c in range(n):  # in place: entry c is written after entries 2c and 2c + 1 (≥ c) are read
                for ch in range(3):
                    line[c, ch] = (line[2 * c, ch] + line[2 * c + 1, ch]) * half
        start = row_offsets[r]
        for c in range(n):
            for ch in range(3):
                reduced[start + c, ch] = line[c, ch]


def _stride(target: Layout, grid: tuple[int, ...]) -> int:
    return max(1, int(round(math.sqrt(math.prod(grid) / SAMPLES))))


def _sampled_pixels(target: Layout, grid: tuple[int, ...], rotation: np.ndarray | None, poles: bool):
    """Target pixel centres inside the layout — every stride-th, and (``poles``) every one near the source's
    poles — as (face, u, v), with one pixel's step (du, dv)."""
    stride = _stride(target, grid)
    h, w = grid[-2:]
    faces = grid[0] if len(grid) == 3 else 1
    f, r, c = np.meshgrid(np.arange(faces), np.arange(stride // 2, h, stride), np.arange(stride // 2, w, stride),
                          indexing="ij")
    f, r, c = f.ravel(), r.ravel(), c.ravel()
    if stride > 1 and poles:
        near = [_pixels_near_pole(target, grid, pole, rotation, 2 * stride) for pole in (1.0, -1.0)]
        f, r, c = (np.concatenate([a] + [n[i] for n in near]) for i, a in enumerate((f, r, c)))
    u, v = (c + 0.5) / w, (r + 0.5) / h
    inside = target.uv_density(f, u, v) > 0
    return f[inside], u[inside], v[inside], 1.0 / w, 1.0 / h


def _pixels_near_pole(target: Layout, grid: tuple[int, ...], pole: float, rotation: np.ndarray | None,
                      radius: int):
    """(face, row, column) of the target pixels within about ``radius`` pixels of the source pole (0, ±1, 0)."""
    pitch = math.sqrt(4 * math.pi / math.prod(grid))  # a typical pixel's angle: points about a pixel apart
    a = np.linspace(-2 * radius * pitch, 2 * radius * pitch, 4 * radius + 1)
    x, z = np.meshgrid(a, a)
    d = np.stack([x, np.full_like(x, pole), z], axis=-1).reshape(-1, 3)  # the tangent plane at the pole
    if rotation is not None:
        d = d @ rotation.T  # the target direction showing source direction s is R s
    face, px, py = target.pixel_coords(d / np.sqrt((d * d).sum(axis=-1))[:, None], grid)
    h, w = grid[-2:]
    rows = np.clip(np.floor(py + 0.5), 0, h - 1).astype(np.int64)
    cols = np.clip(np.floor(px + 0.5), 0, w - 1).astype(np.int64)
    face = np.zeros_like(rows) if len(grid) == 2 else np.asarray(face, np.int64)
    flat = np.unique((face * h + rows) * w + cols)
    return flat // (h * w), flat // w % h, flat % w


def _source_direction(target: Layout, face, u, v, rotation) -> np.ndarray:
    d = target.uv_to_dir(face, u, v)
    d = d / np.sqrt((d * d).sum(axis=-1))[:, None]
    return d if rotation is None else d @ rotation  # row vectors: d @ R = (Rᵀ d)ᵀ, the kernel's turn
