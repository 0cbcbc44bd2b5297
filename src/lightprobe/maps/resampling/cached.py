"""A conversion's weights computed once and applied to many maps (:class:`Resampler`), and its energy measure.

A :class:`Resampler` stores what :func:`lightprobe.maps.resampling.resampler.resample` sums for every target pixel —
the merged footprint taps of :mod:`lightprobe.maps.resampling.taps` in CSR arrays, or a lat-long's row and column
matrices (:mod:`lightprobe.maps.resampling.separable`) — with the conversion's flux correction and polar-row balance,
so converting a batch of maps of one geometry is one gather per pixel. Read as a sun in every source pixel, the same
weights give each pixel's energy gain through the conversion (:meth:`Resampler.energy_gains`), exactly and at once.
"""

from __future__ import annotations

import copy
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ...util import limits
from ...util.errors import LayoutError
from ...util.limits import check_memory
from ...util.progress import track
from ...util.jit import read_only
from ..envmap import EnvMap, owned, pixel_directions, pixel_solid_angles
from ..layouts import CUBE, LATLONG, Cross, Layout
from . import balance, flux, fused, polar, polar_balance, separable
from .budget import check_size
from .resampler import (_odd_halving_overlaps, _reduced_grid, _valid_pixels, adaptive_rate, box_reduce, resample,
                        supersampling)
from .taps import DISCS, _face_layout, _raw_pixel_delivery, _Taps, _unreduced


class Resampler:
    """One conversion's footprint weights, computed once, applied to many maps of the same geometry (a batch).

    ``Resampler(layout, grid, target, size)`` computes, for every target pixel, the source taps and weights that
    :func:`resample` would sum for it (its k×k subsamples' B-spline taps, merged); calling it on a map of that
    layout and grid is then one gather per pixel — the same values as :func:`resample` to float32 rounding
    (``tests/test_resample.py``), several times faster. The weights take ~8 bytes per tap, ~25 taps per target
    pixel at k = 3, more where each pixel takes its own rate (:func:`adaptive_rate`) (:attr:`nbytes`; refused
    over the memory budget); :meth:`energy_gains` reads them as a sun in every source pixel. Conversions that
    box-reduce the source first (over 16 source pixels per target pixel) are not cached: calling such a Resampler
    resamples directly.

    Parameters
    ----------
    layout : str or Layout
        The source maps' layout, by name or instance.
    grid : tuple of int
        The source maps' grid ((H, W), or (6, N, N) for ``cube``).
    target : str or Layout
        The target layout, by name or instance.
    size : int or None, default None
        The target's size, as :func:`resample` takes it; None (or 0): the default for the source's valid pixels.
    rotation : numpy.ndarray or None, default None
        3×3 rotation matrix R in the world frame (light from d comes from R·d), or None.
    samples : int or None, default None
        Supersampling rate k, or None for automatic, as :func:`resample` takes it.

    Raises
    ------
    LayoutError
        When a layout name is unknown or ``grid`` does not fit ``layout``.
    UsageError
        When ``size`` is negative or not a whole number.
    BudgetError
        When the target is over the pixel limit or the weights would exceed the memory budget.
    """

    def __init__(self, layout: str | Layout, grid: tuple[int, ...], target: str | Layout, size: int | None = None, *,
                 rotation: np.ndarray | None = None, samples: int | None = None):
        from ..layouts import layout as layout_named

        self.layout, self.grid, self.target = layout_named(layout), tuple(grid), layout_named(target)
        # C order, as resample() makes it: a transposed matrix would compile every kernel again for its layout
        self.rotation = None if rotation is None else np.ascontiguousarray(rotation, dtype=np.float64)
        self.samples = samples
        self._separable = None  # a lat-long on the source's rows: separable.Separable's matrices, not taps
        target = self.target
        self.layout.check_grid(self.grid)
        source_layout = CUBE if isinstance(self.layout, Cross) else self.layout
        source_grid = CUBE.grid_shape(self.layout.size_of(self.grid)) if isinstance(self.layout, Cross) else grid
        pixels = _valid_pixels(source_layout, source_grid)
        self.size = size or target.default_size(pixels)
        check_size(target, self.size)
        out_grid = target.grid_shape(self.size)
        self.offsets, self._flux, self._cells = None, None, None
        reduced_first = (samples is None
                         and _reduced_grid(source_layout, tuple(source_grid), target, out_grid)[1] != tuple(source_grid))
        if reduced_first or fused.CODES.get(source_layout.name) is None \
                or fused.CODES.get(_face_layout(target).name) is None:
            return  # not cached: __call__ resamples directly
        k, steps = supersampling(source_layout, tuple(source_grid), target, out_grid, rotation, samples)
        k_max = adaptive_rate(source_layout, _face_layout(target), k) if samples is None else k
        self._build(source_layout, source_grid, out_grid, k, k_max, steps)

    @property
    def nbytes(self) -> int:
        """Bytes of the cached weights (taps, or a lat-long's row and column matrices); 0 when nothing is cached."""
        if self._separable is not None:
            return self._separable.nbytes
        return 0 if self.offsets is None else self.offsets.nbytes + self.idx.nbytes + self.wts.nbytes

    def _splice(self, apart: np.ndarray, taps: _Taps, counts: np.ndarray) -> None:
        """Put the merged taps of the pixels :func:`lightprobe.maps.resampling.fused.footprint_taps` listed apart
        (sampled round a disc source's rim direction, :func:`lightprobe.maps.resampling.fused.source_rim_taps`) into the
        CSR arrays."""
        merged = np.zeros(taps.source_pixels)
        touched = np.empty(taps.source_pixels, np.int32)
        listed = []
        for p in apart:
            n = fused.source_rim_taps(*taps.kernel_args, int(p) // taps.width, int(p) % taps.width, merged, touched)
            index = touched[:n].copy()
            listed.append((index, merged[index].astype(np.float32)))
            merged[index] = 0.0
        old_offsets = self.offsets
        counts[apart] = [len(index) for index, _ in listed]
        self.offsets = np.zeros(len(counts) + 1, np.int64)
        np.cumsum(counts, out=self.offsets[1:])
        idx = np.empty(self.offsets[-1], np.int32)
        wts = np.empty(self.offsets[-1], np.float32)
        moved = np.arange(len(self.idx)) + np.repeat(self.offsets[:-1] - old_offsets[:-1], np.diff(old_offsets))
        idx[moved], wts[moved] = self.idx, self.wts
        for p, (index, weights) in zip(apart, listed):
            idx[self.offsets[p]:self.offsets[p + 1]], wts[self.offsets[p]:self.offsets[p + 1]] = index, weights
        self.idx, self.wts = idx, wts

    def _build(self, source_layout: Layout, source_grid, out_grid, k: int, k_max: int, steps: polar.Steps) -> None:
        filled = _face_layout(self.target)
        corrected = flux._corrected(source_layout, source_grid, filled, self.samples)
        if separable.applies(source_layout, filled, self.rotation) and not corrected:  # as resample does it
            self._separable = separable.Separable(tuple(source_grid), tuple(out_grid[-2:]), k, self.rotation)
            return
        taps = _Taps(source_layout, tuple(source_grid), self.target, self.size, k, k_max, steps, self.rotation)
        merging = 12 * taps.source_pixels if source_layout.name in DISCS else 0  # _splice's scratch
        check_memory(taps.lines * taps.width * (25 * 8 + 8) + taps.scratch_bytes + merging,
                     f"footprint weights of {self.layout.name} → {self.target.name} size {self.size}", kernels=True)
        self._levels = taps.found_levels

        def listed(first: int):
            counts, idx, wts = taps.band(first)
            keep = np.arange(idx.shape[1])[None, :] < counts[:, None]
            return counts, idx[keep], wts[keep]

        with ThreadPoolExecutor(limits.threads()) as pool:
            parts = list(track(pool.map(listed, taps.firsts), f"footprint weights for {self.target.name}",
                               total=len(taps.firsts)))
        counts = np.concatenate([c for c, _, _ in parts])
        apart = np.flatnonzero(counts < 0)  # pixels round a disc source's rim direction: listed apart, merged
        counts[apart] = 0
        self.offsets = np.zeros(len(counts) + 1, np.int64)
        np.cumsum(counts, out=self.offsets[1:])
        self.idx = np.concatenate([i for _, i, _ in parts])
        self.wts = np.concatenate([q for _, _, q in parts])
        if apart.size:
            self._splice(apart, taps, counts)
        self._filled_grid, self._lines = taps.grid, (taps.lines, taps.width)
        if self._levels is not None and not corrected and self.rotation is not None:  # balanced as resample's
            omega_t = pixel_solid_angles(filled, taps.grid).reshape(-1)
            per_cell = _tap_totals(self, omega_t, taps.source_pixels + taps.reduced_size)[taps.source_pixels:]
            parts = []
            for _, rows, _ in polar_balance.caps(self._levels, source_grid[-1]):
                parts += polar_balance.balance_of(per_cell, 0, self._levels, source_grid[-1], rows)
            self._cells = polar_balance.joined(parts)
        self._flux = flux._flux_stencil(source_layout, tuple(source_grid), self.target, taps.grid, self.rotation,
                                   self.samples, (k, k_max), lambda omega_t: _taps_delivery(self, source_layout,
                                                                                tuple(source_grid), omega_t))

    def without_flux_correction(self) -> Resampler:
        """This conversion as it would be without its flux correction (:mod:`lightprobe.maps.resampling.flux`).

        It shows what the correction removes, for pictures and tests. Shares the weights.

        Returns
        -------
        Resampler
            A shallow copy that skips the flux correction.
        """
        plain = copy.copy(self)
        plain._flux = None
        return plain

    def without_cell_balance(self) -> Resampler:
        """This conversion as it would be without the balance of a lat-long source's coarsest polar rows.

        The balance is :mod:`lightprobe.maps.resampling.polar_balance`'s; this shows what it removes, for pictures
        and tests. Shares the weights.

        Returns
        -------
        Resampler
            A shallow copy that skips the balance of the polar rows.
        """
        plain = copy.copy(self)
        plain._cells = None
        return plain

    def energy_gains(self, rim_margin: float | None = None) -> np.ndarray:
        """For every source pixel, the relative error of ∫L dω that a sun wholly in that pixel takes.

        It is, through this conversion, (Σ_t Ω_t W_ts) / Ω_s − 1, float64 of the source's grid (a cross's as cube faces;
        NaN where a pixel covers no sphere, and with ``rim_margin`` (degrees) where it lies that near either layout's
        disc rim direction — one direction spread over a ring of pixels). Exact for every pixel at once — the conversion
        is linear, so a sun's energy out is its column of the weights weighted by the target's solid angles — where
        sampling suns finds only the pixels it tries. A source box-reduced first is measured on its reduction: the box
        keeps each pixel's energy (its Ω-weighted mean), so a pixel's gain is its block's.

        Parameters
        ----------
        rim_margin : float or None, default None
            Angle in degrees: pixels whose direction lies within it of the source's or the target's rim direction
            are NaN; None keeps them.

        Returns
        -------
        numpy.ndarray
            float64 relative gains (0: energy kept; 0.01: 1 % too bright), shape of the source's grid ((6, N, N)
            for a cross source); NaN off the sphere and within ``rim_margin``.
        """
        layout = CUBE if isinstance(self.layout, Cross) else self.layout
        grid = CUBE.grid_shape(self.layout.size_of(self.grid)) if isinstance(self.layout, Cross) else self.grid
        if self._separable is None and self.offsets is None:
            gains = _expanded_gains(layout, grid, self.target, self.size, self.rotation)
        else:
            omega_s = pixel_solid_angles(layout, grid)
            filled = _face_layout(self.target)
            omega_t = pixel_solid_angles(filled, filled.grid_shape(self.size))
            if self._separable is not None:
                delivered = _separable_delivery(self._separable, omega_t)
            else:
                delivered = _raw_pixel_delivery(_taps_delivery(self, layout, grid, omega_t.reshape(-1)), layout,
                                                grid, self._flux)
            with np.errstate(invalid="ignore", divide="ignore"):
                gains = np.where(omega_s > 0, delivered.reshape(grid) / omega_s - 1.0, np.nan)
        if rim_margin is not None:
            d = pixel_directions(layout, grid)
            for rim in (layout.rim_direction(), self.target.rim_direction()):
                if rim is not None:
                    gains[d @ rim > math.cos(math.radians(rim_margin))] = np.nan
        return gains

    def __call__(self, env: EnvMap) -> EnvMap:
        """Convert ``env`` with the cached weights: the same values as :func:`resample` to float32 rounding.

        Parameters
        ----------
        env : EnvMap
            A map of this Resampler's source layout and grid.

        Returns
        -------
        EnvMap
            The converted map in the target layout and size.

        Raises
        ------
        LayoutError
            When ``env`` has another layout or grid.
        """
        if env.layout != self.layout or env.grid != self.grid:
            raise LayoutError(f"this Resampler converts {self.layout.name} maps of grid {self.grid}, "
                              f"not {env.layout.name} {env.grid}")
        if self._separable is not None:
            rows = self._separable.target_grid[0]
            return EnvMap(owned(self._separable.band(np.asarray(env.data), 0, rows)), self.target)
        if self.offsets is None:
            return resample(env, self.target, self.size, rotation=self.rotation, samples=self.samples)
        data = self.layout.to_cube(env.data) if isinstance(self.layout, Cross) else env.data
        if self._flux is not None:  # as resample: the flux correction (read-only, as resample's), then the balance
            data = owned(self._flux.apply(data))
        if balance.prefilter_for(self.layout) is not None:  # the taps read a cube's balanced texels, as resample
            data = balance.balanced_faces(np.asarray(data, dtype=np.float32))
        reduced = (polar.no_reduction()[1] if self._levels is None
                   else polar.reduced_rows(np.asarray(data), self._levels)[1])
        if self._cells is not None:
            self._cells.apply(reduced)
        src = read_only(np.asarray(data).reshape(-1, 3))
        lines, w = self._lines
        out = np.empty((lines * w, 3), np.float32)
        pixels = lines * w
        threads = min(limits.threads(), max(1, pixels // 4096))
        step = -(-pixels // (4 * threads))
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda s: fused.apply_taps(src, reduced, self.offsets, self.idx, self.wts, out[s:s + step], s),
                          range(0, pixels, step)))
        out = out.reshape(self._filled_grid + (3,))
        if isinstance(self.target, Cross):
            out = self.target.from_cube(out)
        return EnvMap(owned(out), self.target)


# ---- energy of a one-pixel sun, every pixel at once (Resampler.energy_gains) ----------------------------------------

def _tap_totals(resampler: Resampler, omega_t: np.ndarray, n: int) -> np.ndarray:
    """Σ_t Ω_t W_ti per tap index i (float64, at least ``n``: source pixels, then reduced polar rows), from the
    cached taps."""
    per_tap = resampler.wts.astype(np.float64) * np.repeat(omega_t, np.diff(resampler.offsets))
    return np.bincount(resampler.idx, per_tap, minlength=n)


def _taps_delivery(resampler: Resampler, layout: Layout, grid: tuple[int, ...], omega_t: np.ndarray) -> np.ndarray:
    """Σ_t Ω_t W_ts per source pixel s (flat), from the cached taps."""
    return _unreduced(_tap_totals(resampler, omega_t, math.prod(grid)), grid, resampler._levels, resampler._cells)


def _separable_delivery(matrices: separable.Separable, omega_t: np.ndarray) -> np.ndarray:
    """Σ_t Ω_t W_ts for a separable lat-long → lat-long: rows and columns apart (a target row's pixels share Ω)."""
    row_omega = omega_t[:, 0]
    out = np.zeros((matrices.rows.shape[1], matrices.columns.shape[1]))
    for rows, columns in ((matrices.rows, matrices.columns), (matrices.rows_half, matrices.columns_half)):
        out += np.outer(rows.T @ row_omega, np.asarray(columns.sum(axis=0)).ravel())
    return out


def _through_odd_halving(grid: tuple[int, ...], target: Layout, size: int, rotation) -> np.ndarray:
    """energy_gains of a lat-long of odd height, which :func:`~lightprobe.maps.resampling.resampler._odd_box_reduce`
    puts onto ⌊H/2⌋ rows first: old pixel s shares its energy out among the new pixels t it overlaps, each carrying its
    share on with its own gain g_t, so s's gain is Σ_t overlap_ts (1 + g_t) / Ω_s − 1 (the overlaps separable: rows and
    columns apart)."""
    half = LATLONG.grid_shape(grid[-2] // 2)
    gains = Resampler(LATLONG, half, target, size, rotation=rotation).energy_gains()
    rows, columns = _odd_halving_overlaps(tuple(grid))
    delivered = (columns.T @ (rows.T @ (1.0 + gains)).T).T
    return delivered / pixel_solid_angles(LATLONG, tuple(grid)) - 1.0


def _expanded_gains(layout: Layout, grid: tuple[int, ...], target: Layout, size: int, rotation) -> np.ndarray:
    """energy_gains of a source the conversion box-reduces first: its reduction's, each block's for its pixels.
    The Resampler of the halved grid halves it again only where :func:`resample` would
    (:func:`lightprobe.maps.resampling.resampler._reducible`): this measure once halved lat-longs under 48 rows, which
    no conversion does, and reported their pole rows +25 %. A lat-long of odd height is carried through its halving
    instead (:func:`_through_odd_halving`)."""
    if layout.name == "latlong" and grid[-2] % 2:
        return _through_odd_halving(grid, target, size, rotation)
    reduced = box_reduce(EnvMap(np.zeros(grid + (3,), np.float32), layout))
    gains = Resampler(layout, reduced.grid, target, size, rotation=rotation).energy_gains()
    gains = np.repeat(np.repeat(gains, 2, axis=-2), 2, axis=-1)
    return np.where(pixel_solid_angles(layout, grid) > 0, gains, np.nan)
