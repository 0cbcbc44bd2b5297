"""A conversion's footprint taps as the compiled kernel lists them, and their adjoint: each source pixel's delivery.

The kernel (:mod:`lightprobe.maps.resampling.fused`) reads a conversion through the arguments made here: the layout it
fills (a cross as cube faces, :func:`_face_layout`), the table of valid target pixels and the layouts' axes. For each
target pixel it lists the merged taps — (source index, weight) pairs that sum its k×k lookups — a band of target lines
at a time (:class:`_Taps`): what a :class:`~lightprobe.maps.resampling.cached.Resampler` stores. Or it sums their
adjoint without storing them (:func:`delivered`): Σ_t Ω_t W_ts, the energy a sun wholly in source pixel s ends with,
which the flux correction (:mod:`lightprobe.maps.resampling.flux`) and the polar rows' balance
(:mod:`lightprobe.maps.resampling.polar_balance`) are measured from. Tap indices are flat source pixels as the kernel
reads them (a cube's balanced texels), then a lat-long's reduced polar rows; :func:`_unreduced` and
:func:`_raw_pixel_delivery` carry a delivery back to the map's own pixels.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

from ...util import limits
from ..layouts import CUBE, Cross, Layout
from . import balance, fused, polar
from .overlaps import column_means

if TYPE_CHECKING:
    from . import flux, polar_balance


DISCS = ("angular", "sphere")  # layouts whose rim spreads one direction over a ring of pixels


def _face_layout(target: Layout) -> Layout:
    """The layout the kernel fills: a cross is filled as cube faces and rearranged (exactly: same texel centres)."""
    return CUBE if isinstance(target, Cross) else target


def _target_valid(filled: Layout, grid: tuple[int, ...], faces: tuple[int, int, int]) -> np.ndarray:
    """The kernels' table of valid target pixels, (faces, H, W) uint8, read-only (one array type for numba): a
    1×1×1 table where every pixel is valid, else the layout's shared mask viewed as bytes (no copy)."""
    if filled.valid_fraction == 1.0:
        table = np.ones((1, 1, 1), dtype=np.uint8)
        table.setflags(write=False)
        return table
    return filled.shared_valid_mask(grid).reshape(faces).view(np.uint8)


def _axes(lay: Layout) -> np.ndarray:
    return np.asarray(getattr(lay, "camera_axes", np.eye(3)), dtype=np.float64)


TILE_TAPS = fused.TILE * fused.TILE
TAPS_SCRATCH_BYTES = 64 << 20  # a thread's buffer of unmerged taps while a Resampler lists them


class _Taps:
    """The footprint taps of a conversion, listed a band of target lines at a time by the compiled kernel
    (:func:`lightprobe.maps.resampling.fused.footprint_taps`): what a
    :class:`~lightprobe.maps.resampling.cached.Resampler` stores, and what :func:`delivered` reads without storing.
    ``band(first)`` → (counts (n·W,), idx, wts (n·W, max_taps)) for lines first … first+n−1; tap indices are flat source
    pixels (as the kernel reads them: a cube's balanced texels), then reduced polar rows."""

    def __init__(self, source_layout: Layout, source_grid: tuple[int, ...], target: Layout, size: int, k: int,
                 k_max: int, steps: polar.Steps, rotation):
        filled = _face_layout(target)
        self.grid = grid = filled.grid_shape(size)
        faces = grid if filled.faces > 1 else (1,) + grid
        self.lines, self.width = faces[0] * faces[1], faces[2]
        self.max_taps = max(TILE_TAPS, 16 * fused.slots(k_max))
        band = max(1, min(16, TAPS_SCRATCH_BYTES // (self.width * self.max_taps * 8)))  # lines a thread lists
        self.firsts = range(0, self.lines, band)
        self.band_lines = band
        self.scratch_bytes = limits.threads() * band * self.width * self.max_taps * 8
        src_kind = fused.CODES[source_layout.name]
        self.found_levels = None  # a latlong source's polar reduction levels, when it has any
        self.reduced_size = 0  # their reduced pixels (taps past the source's own)
        self.source_pixels = math.prod(source_grid)
        levels, _, row_offsets, caps = polar.no_reduction(source_grid[-2])
        if src_kind == fused.LATLONG:
            src_shape, valid = (1,) + tuple(source_grid) + (3,), np.ones((1, 1, 1), np.float32)
            index_map = np.zeros((1, 1, 1), np.int32)
            found = polar.polar_levels(steps, tuple(source_grid), k)
            if found.any():  # where the reduced rows go (their values come with each map)
                self.found_levels = found
                levels = polar.kernel_levels(found, source_grid[-1])
                row_offsets, caps, self.reduced_size = polar.row_layout(levels, source_grid[-1])
        else:
            flat = np.arange(math.prod(source_grid), dtype=np.int32).reshape(source_grid)[..., None]
            padded_index, valid = source_layout.padded(flat.astype(np.float64))  # padding is exact for integers
            index_map = np.rint(padded_index[..., 0]).astype(np.int32)
            src_shape = padded_index.shape
            if source_layout.valid_fraction == 1.0:
                valid = np.ones((1, 1, 1), np.float32)
        all_valid = filled.valid_fraction == 1.0
        tgt_valid = _target_valid(filled, grid, faces)
        turn = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        self.kernel_args = (src_kind, src_shape, valid, index_map, levels, row_offsets, caps, _axes(source_layout),
                            source_grid[-2], source_grid[-1], fused.CODES[filled.name], _axes(filled), faces[1],
                            self.width, tgt_valid, all_valid, k, k_max, turn)

    def band(self, first: int):
        n = min(self.band_lines, self.lines - first)
        idx = np.empty((n * self.width, self.max_taps), np.int32)
        wts = np.empty((n * self.width, self.max_taps), np.float32)
        counts = np.empty(n * self.width, np.int64)
        fused.footprint_taps(*self.kernel_args, first, idx, wts, counts)
        return counts, idx, wts


def delivered(taps: _Taps, source_grid: tuple[int, ...], omega_t: np.ndarray) -> np.ndarray:
    """Σ_t Ω_t W_ts for every source pixel s (flat float64, as the kernel reads them).

    It is the energy a sun wholly in each pixel ends with. The compiled adjoint of the taps
    (:func:`lightprobe.maps.resampling.fused.footprint_delivery`), a share of the target's lines on each of
    :func:`lightprobe.util.limits.threads` threads, each into its own total: nothing the size of the taps is held (a
    :class:`~lightprobe.maps.resampling.cached.Resampler` holds them:
    :func:`lightprobe.maps.resampling.cached._taps_delivery`). The same shares in the same order every time: the same
    sums.

    Parameters
    ----------
    taps : _Taps
        The conversion's footprint taps (listed by the kernel as they are needed, not stored).
    source_grid : tuple of int
        The source's grid, as the kernel reads it.
    omega_t : numpy.ndarray
        Solid angle (sr) of every target pixel, flat over the filled layout's lines (a cross as cube faces).

    Returns
    -------
    numpy.ndarray
        float64 (source pixels,): Σ_t Ω_t W_ts per source pixel, flat; taps on a lat-long's reduced polar rows
        handed on to the pixels they average.
    """
    n_total = math.prod(source_grid) + taps.reduced_size
    omega_t = np.ascontiguousarray(omega_t, dtype=np.float64)
    threads = min(limits.threads(), max(1, taps.lines // 8))
    step = -(-taps.lines // (4 * threads))  # 4 shares a thread, interleaved: the slow lines (poles, rims) even out
    firsts = list(range(0, taps.lines, step))

    def thread_total(t: int) -> np.ndarray:  # the same shares in the same order every time: the same sums
        total = np.zeros(n_total)
        for first in firsts[t::threads]:
            fused.footprint_delivery(*taps.kernel_args, first, min(first + step, taps.lines),
                                     omega_t[first * taps.width:], taps.max_taps, total, 0)
        return total

    with ThreadPoolExecutor(threads) as pool:
        totals = list(pool.map(thread_total, range(threads)))
    return _unreduced(np.sum(totals, axis=0), source_grid, taps.found_levels)


def _raw_pixel_delivery(per_texel: np.ndarray, layout: Layout, grid: tuple[int, ...],
                        stencil: flux.Stencil | None = None) -> np.ndarray:
    """Each pixel's delivery (the source's grid) from the delivery of the texels the kernel reads (flat): those are
    a cube's balanced texels (each raw texel's share through the balance's transpose), read from the flux-corrected
    pixels when there is a ``stencil`` (its transpose, applied last: the correction comes first)."""
    per_pixel = np.asarray(per_texel).reshape(grid)
    if balance.prefilter_for(layout) is not None:
        per_pixel = balance.delivered_to_texels(per_pixel)
    return per_pixel if stencil is None else stencil.delivered(per_pixel)


def _unreduced(total: np.ndarray, grid: tuple[int, ...], found: np.ndarray | None,
               cells: polar_balance.CellBalance | None = None) -> np.ndarray:
    """Per source pixel (flat) from per tap index: a tap on a lat-long's reduced polar row is handed on, through
    the rows' balance if there is one (``cells``), to the source pixels it averages (2^ℓ of them, the columns it
    overlaps by their shares, or the whole row)."""
    n_src = math.prod(grid)
    delivered = total[:n_src].copy()
    if found is None:
        return delivered
    h, w = grid
    levels = polar.kernel_levels(found, w)
    row_offsets, _, _ = polar.row_layout(levels, w)
    reduced = total[n_src:] if cells is None else cells.delivered(total[n_src:])
    rows = delivered.reshape(h, w)
    for r in np.nonzero(levels)[0]:
        n = polar.reduced_width(w, int(levels[r]))
        part = reduced[row_offsets[r]:row_offsets[r] + n]
        if found[r] > polar.max_level(w):  # read as the whole row's mean
            rows[r] += part.sum() / w
        elif polar.halves_exactly(w, int(levels[r])):
            rows[r] += np.repeat(part / (w // n), w // n)
        else:  # the overlaps' transpose: each column's share of every cell it meets
            rows[r] += column_means(w, n).T @ part
    return delivered
