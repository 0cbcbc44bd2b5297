"""Resampling between layouts and sizes: footprint-aware, energy-conserving (∫L dω kept), and box reduction.

This module plans a conversion and runs it: :func:`resample` and :func:`resample_strips`, the box reduction of a
source with too many pixels a target pixel, the supersampling rate. Its mechanisms are modules of their own beside
it: the compiled kernel (``fused``), its taps and their adjoint (``taps``), the flux correction (``flux``), the polar
rows' reduction and balance (``polar``, ``polar_balance``), the size and memory checks (``budget``), the numpy
reference (``reference``); a conversion's weights kept for many maps are a ``cached.Resampler``.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ...util.errors import LayoutError
from ..layouts import CUBE, Cross, Layout
from ...util import limits
from ...util.limits import check_memory
from ...util.progress import track
from ...util.jit import read_only
from . import balance, cube_symmetry, flux, fused, polar, polar_balance, pole_rows, separable
from ..envmap import EnvMap, owned
from .budget import check_size, resample_memory
from .overlaps import interval_overlaps
from .reference import reference_resample
from .taps import DISCS, _axes, _face_layout, _target_valid, _Taps, delivered

MAX_FOOTPRINT_RATIO = 16  # source pixels per target pixel above which the source is box-reduced first


def _valid_pixels(lay: Layout, grid: tuple[int, ...]) -> int:
    """Pixels of ``grid`` that cover the sphere (no mask is made for layouts whose pixels all do)."""
    return math.prod(grid) if lay.valid_fraction == 1.0 else int(np.count_nonzero(lay.shared_valid_mask(grid)))


def auto_samples(ratio: float) -> int:
    """Supersampling rate k (k×k lookups per target pixel) for ``ratio`` source pixels per target pixel.

    k = ⌈2√ratio⌉, at least 2: lookups are spaced at most half a source pixel apart, where the cubic B-spline's
    sinc⁴ spectrum makes the sum of lookups integrate even a one-pixel sun to about 0.1 %.

    Parameters
    ----------
    ratio : float
        Valid source pixels per valid target pixel (a footprint's area in source pixels).

    Returns
    -------
    int
        k, lookups per side of a target pixel.
    """
    return max(2, int(np.ceil(2 * np.sqrt(ratio))))


def box_reduce(env: EnvMap) -> EnvMap:
    """Halve the resolution: each new pixel is the solid-angle-weighted mean of a 2×2 block (∫L dω unchanged).

    Needs even dimensions; a cross is reduced as cube faces and returned as a cube.

    Parameters
    ----------
    env : EnvMap
        The map (linear RGB radiance); its grid's last two axes must be even (a cross's tiles: its face edge).

    Returns
    -------
    EnvMap
        The map at half the height and width, in the same layout (``cube`` for a cross), float32.

    Raises
    ------
    LayoutError
        When a side is odd.
    """
    if isinstance(env.layout, Cross):
        env = EnvMap(env.layout.to_cube(env.data), CUBE)
    h, w = env.grid[-2:]
    if h % 2 or w % 2:
        raise LayoutError(f"cannot halve a {w}×{h} map")
    omega = env.solid_angles()[..., None]
    lead = env.grid[:-2]

    def blocks(a):
        return a.reshape(lead + (h // 2, 2, w // 2, 2, a.shape[-1])).sum(axis=(-4, -2))

    weight = blocks(omega)
    mean = blocks(omega * env.data) / np.where(weight > 0, weight, 1.0)
    return EnvMap(owned(mean.astype(np.float32)), env.layout)


# A mirror ball squeezes its back hemisphere into its outer rings: θ from its rim direction, a ring is 2 / sin(θ/2)
# times wider in angle than in the image — 10° a pixel at 20° from the rim for a ball of 128 pixels, 20° at 64. When
# the flux correction left the pixels within 20° of the rim alone, a ball halved to 64 for a 16-pixel target left suns
# in pixels just outside the 25° rim margin 19–24 % off: their 64-pixel blocks straddled it. A smaller ball is not
# halved; a tiny target reads its 128 pixels with more subsamples instead. (Since the ball's ring is corrected too, a
# ball halved to 64 keeps every sun as well: tests/test_resample.py.)
SPHERE_MIN_SIDE = 128


def _reducible(layout: Layout, grid: tuple[int, ...]) -> bool:
    """Whether a box reduction may halve a source of this layout and grid: even sides, at least 8 pixels, a lat-long
    keeps the rational pole rows (:data:`lightprobe.maps.resampling.pole_rows.MIN_HEIGHT`: a sun in a pole row of a
    source halved under 48 rows gained 22 % of its energy; a tiny target reads the 48 rows with more subsamples
    instead), and a mirror ball keeps :data:`SPHERE_MIN_SIDE` pixels."""
    h, w = grid[-2:]
    if isinstance(layout, Cross):
        h = w = h // layout.aspect[1]
    if layout.name == "latlong":  # an odd height too, by exact overlaps (_halved)
        return not h // 2 < pole_rows.MIN_HEIGHT <= h and h >= 8
    if layout.name == "sphere" and h // 2 < SPHERE_MIN_SIDE:
        return False
    return h % 2 == 0 and w % 2 == 0 and min(h, w) >= 8


def _reduced_grid(layout: Layout, grid: tuple[int, ...], target: Layout,
                  target_grid: tuple[int, ...]) -> tuple[Layout, tuple[int, ...]]:
    """The (layout, grid) a source of ``layout`` and ``grid`` is read at into ``target_grid`` with its rate left
    automatic: a cross as cube faces, halved (:func:`box_reduce`) while it has over :data:`MAX_FOOTPRINT_RATIO`
    valid pixels per valid target pixel and :func:`_reducible` allows."""
    if isinstance(layout, Cross):
        layout, grid = CUBE, CUBE.grid_shape(layout.size_of(grid))
    target_pixels = max(_valid_pixels(target, target_grid), 1)
    while _valid_pixels(layout, grid) / target_pixels > MAX_FOOTPRINT_RATIO and _reducible(layout, grid):
        half = grid[-2] // 2
        grid = grid[:-2] + ((half, 2 * half) if layout.name == "latlong" else (half, grid[-1] // 2))
    return layout, grid


def _halved(env: EnvMap) -> EnvMap:
    """One halving of a source that a conversion reduces first: :func:`box_reduce`, or for a lat-long of odd height
    (whose rows cannot pair) :func:`_odd_box_reduce`. Unhalved, such a map was read whole by targets of any size:
    lookups columns apart in a cube of 23 from 2094×1047 (0.36 %), a mirror ball of 31 from 894×447 (70 %, past what
    its flux correction mends), a turned lat-long of 156 from 1882×941 (1.7 %)."""
    if env.layout.name == "latlong" and env.grid[-2] % 2:
        return _odd_box_reduce(env)
    return box_reduce(env)


def _odd_box_reduce(env: EnvMap) -> EnvMap:
    """A lat-long of odd height H onto ⌊H/2⌋ rows: each new pixel the solid-angle-weighted mean of the parts of the
    old pixels it overlaps (rows by their span of cos θ, columns by their span of azimuth: the overlaps are
    separable). Every old pixel's ∫L dω is shared out whole among the new pixels it overlaps, so a sun anywhere keeps
    its energy exactly, and a uniform map stays uniform. (The separable lat-long resampling kept it within 0.097 %,
    which the conversion that follows adds to.)"""
    rows, columns = _odd_halving_overlaps(env.grid)
    (h, h_old), (w, w_old) = rows.shape, columns.shape
    area = np.asarray(rows.sum(axis=1)).ravel()[:, None] * np.asarray(columns.sum(axis=1)).ravel()[None, :]
    by_rows = (rows @ env.data.reshape(h_old, w_old * 3)).reshape(h, w_old, 3)  # float64, half the rows
    by_columns = columns @ by_rows.transpose(1, 0, 2).reshape(w_old, h * 3)
    out = by_columns.reshape(w, h, 3).transpose(1, 0, 2) / area[..., None]
    return EnvMap(owned(out.astype(np.float32)), env.layout)


def _odd_halving_overlaps(grid: tuple[int, int]):
    """(rows, columns) sparse: rows[i, r] = ∫ sin θ dθ over new row i ∩ old row r, columns[j, c] = the azimuth new
    column j and old column c share, for a lat-long of ``grid`` onto ⌊H/2⌋ rows."""
    h, w = grid
    half = h // 2
    return (interval_overlaps(-np.cos(np.pi * np.arange(h + 1) / h),  # −cos θ: increasing down the rows
                      -np.cos(np.pi * np.arange(half + 1) / half)),
            interval_overlaps(np.arange(w + 1) * (2 * np.pi / w), np.arange(2 * half + 1) * (np.pi / half)))


def resample(
    source: EnvMap,
    target: Layout,
    size: int | None = None,
    *,
    rotation: np.ndarray | None = None,
    samples: int | None = None,
) -> EnvMap:
    """Resample ``source`` into layout ``target`` of ``size`` (default: about the same number of valid pixels).

    Each target pixel is the solid-angle-weighted mean (weights ``dω/(du dv)`` of the target layout) of k×k stratified
    lookups spread over its footprint, each a cubic B-spline interpolation of the source. Lookups are at most half a
    source pixel apart (k is measured on a sample of the target's pixels: :func:`supersampling`), so ∫L dω is conserved
    (to ~0.1 % even for a sun of one pixel) and a uniform map stays exactly uniform; sources with over 16 pixels per
    target pixel are first box-reduced (exactly energy-preserving), and a latlong source's polar rows are read from
    their reductions in azimuth where the lookups would skip columns (:mod:`lightprobe.maps.resampling.polar`), with
    rational spline weights in the rows next to the poles so each row keeps its solid angle
    (:mod:`lightprobe.maps.resampling.pole_rows`). ``rotation`` R turns the environment: the target at direction d shows
    the source at Rᵀd. The work is one compiled pass (:mod:`lightprobe.maps.resampling.fused`) whose memory is the
    output; an unturned lat-long into a cube reads each footprint for its images under the cube's symmetries
    (:mod:`lightprobe.maps.resampling.cube_symmetry`).

    With ``samples`` given, k is that rate for every pixel, and the box reduction and the flux correction
    (:mod:`lightprobe.maps.resampling.flux`) are left out: the kernel as it is, for comparisons.

    Parameters
    ----------
    source : EnvMap
        The map to convert (linear RGB radiance, world frame), in any layout.
    target : Layout
        The target layout, an instance (:func:`lightprobe.maps.layouts.layout` looks one up by name).
    size : int or None, default None
        The target's size: image height for latlong, angular and sphere, face edge for cube, cross and hcross.
        None (or 0): :meth:`~lightprobe.maps.layouts.Layout.default_size` of the source's valid pixel count.
    rotation : numpy.ndarray or None, default None
        3×3 rotation matrix R in the world frame (+Y up, front −Z): light that came from d comes from R·d; None:
        not turned. Taken as given (:func:`lightprobe.maps.frames.as_rotation` checks one).
    samples : int or None, default None
        Supersampling rate k (k×k lookups per target pixel); None: automatic (:func:`supersampling`, and per
        pixel up to :func:`adaptive_rate`).

    Returns
    -------
    EnvMap
        The converted map in ``target`` (float32 radiance, the target's grid for ``size``).

    Raises
    ------
    UsageError
        When ``size`` is negative or not a whole number.
    BudgetError
        When the target is over the pixel limit or the conversion would exceed the memory budget.
    """
    rotation = _contiguous(rotation)
    plan = _plan(source, target, size, rotation, samples)
    if plan is None:
        source, grid, k, _ = _prepared(source, target, size, samples, rotation)
        return reference_resample(source, target, grid, k, rotation)  # a layout the kernel does not know
    return plan.finish(plan.fill_all(f"resampling to {target.name}"))


def resample_strips(source: EnvMap, target: Layout, size: int | None = None, *, rotation: np.ndarray | None = None,
                    samples: int | None = None, strip_pixels: int = 1 << 18):
    """:func:`resample` for writing a file as it is computed: the image's shape and an iterator of its strips.

    ``(shape, strips)`` — the (H, W) of the target's image file (a cube's 6N × N strip) and an iterator of
    ``(top, rows)``, float32 (n, W, 3) blocks of image rows of about ``strip_pixels`` pixels, top to bottom (what
    :func:`lightprobe.maps.images.write_image_strips` takes). The same values as :func:`resample`; memory is one
    strip, not the map. A cross is computed strip by strip from the rows of its faces where no tile is a transposed
    face (:meth:`~lightprobe.maps.layouts.Cross.rows_are_face_rows`); a cross with a transposed tile and layouts
    the kernel does not know come as one strip.

    Parameters
    ----------
    source : EnvMap
        The map to convert, in any layout.
    target : Layout
        The target layout, an instance.
    size : int or None, default None
        The target's size, as :func:`resample` takes it.
    rotation : numpy.ndarray or None, default None
        3×3 rotation matrix R in the world frame (light from d comes from R·d), or None.
    samples : int or None, default None
        Supersampling rate k, or None for automatic, as :func:`resample` takes it.
    strip_pixels : int, default 262144
        About how many pixels of the image each strip holds (at least one image row).

    Returns
    -------
    shape : tuple of int
        (H, W) of the target's image file.
    strips : iterator of tuple
        ``(top, rows)``: ``top`` the first image row of the strip, ``rows`` float32 (n, W, 3) radiance. The
        strips are computed as they are taken (with a progress bar), except where all comes as one strip: then
        before this returns.

    Raises
    ------
    UsageError
        When ``size`` is negative or not a whole number: checked when called, before any strip.
    BudgetError
        When the target is over the pixel limit or the conversion would exceed the memory budget, also before any
        strip.
    """
    rotation = _contiguous(rotation)
    plan = _plan(source, target, size, rotation, samples)
    if plan is None or (isinstance(target, Cross) and not target.rows_are_face_rows()):
        from ..files import to_image

        image = to_image(resample(source, target, size, rotation=rotation, samples=samples))
        return image.shape[:2], iter([(0, image)])
    if isinstance(target, Cross):
        return _cross_strips(plan, target, strip_pixels)
    faces, h, w = plan.lines_shape[0] // plan.height, plan.height, plan.lines_shape[1]
    rows = max(1, strip_pixels // (faces * w))

    def strips():
        for top in track(range(0, h, rows), f"resampling to {target.name}", total=-(-h // rows)):
            n = min(rows, h - top)
            block = np.empty((faces, n, w, 3), dtype=np.float32)
            if plan.cube_rows is not None:
                plan.fill_rows(block, top, 0, n)
            else:
                for face in range(faces):
                    plan.fill(block[face], face * h + top)
            yield top, block.transpose(1, 0, 2, 3).reshape(n, faces * w, 3)  # a cube file's rows: faces side by side

    return (h, faces * w), strips()


def link_kernels(source: Layout, source_pixels: int, target: Layout, size: int, *,
                 rotation: np.ndarray | None = None, streamed: bool = True) -> None:
    """Run the compiled kernels of a conversion once, on a small zero map that takes the same route.

    The conversion is a map of ``source_pixels`` in layout ``source`` into ``target`` of ``size``; its kernels are
    linked (loaded or compiled) before the map itself is read (``lightprobe convert``; see
    :func:`lightprobe.util.jit.release_compiler_pages`). The route that matters is whether the flux is corrected
    (:func:`lightprobe.maps.resampling.flux._corrected`): a lat-long of 64 rows into a disc is and a 4k one is not, and
    linked on 64 rows that correction's kernels (~5 MiB resident) stayed beside a 4k map that never ran them. Where the
    map is not corrected, the small one is run without (box reductions are numpy's: no kernel to link).

    Parameters
    ----------
    source : Layout
        The layout of the map that will be converted.
    source_pixels : int
        Its pixel count (the whole image grid), from which the route is judged.
    target : Layout
        The target layout.
    size : int
        The target's size.
    rotation : numpy.ndarray or None, default None
        The 3×3 rotation the conversion will apply, or None.
    streamed : bool, default True
        Link the kernels of :func:`resample_strips` (True) or of :func:`resample` (False), as the conversion will run.
    """
    grid = source.grid_shape(source.default_size(round(source_pixels * source.valid_fraction)))
    reduced_layout, reduced = _reduced_grid(source, grid, target, target.grid_shape(size))
    corrected = flux._corrected(reduced_layout, reduced, target, None)
    rows = 64
    small = EnvMap(np.zeros(source.grid_shape(rows) + (3,), np.float32), source)
    small_size = rows // 2  # 4–10 source pixels a target pixel: read as it is, not box-reduced
    flux._LINKING.uncorrected = not corrected  # a small lat-long into a disc is corrected where a 4k one is not
    flux._LINKING.small = True  # a small map's memory is not checked: the map's own conversion is, after this
    try:
        if streamed:
            for _ in resample_strips(small, target, small_size, rotation=rotation)[1]:
                pass
        else:
            resample(small, target, small_size, rotation=rotation)
    finally:
        flux._LINKING.uncorrected = flux._LINKING.small = False


def _cross_strips(plan: _Plan, target: Cross, strip_pixels: int):
    """resample_strips into a cross whose tiles are its faces flipped (no transposed tile): each strip's rows are
    rows of the faces in its band of tiles, computed as the strip needs them — no whole cube, no whole cross (a
    4k map's cross was 1.5 GB at the peak, 200 MB of it the cross image). Side faces that need the same rows in a
    strip (a cross's middle band) take them through the cube's symmetries when the plan has them, as a cube's
    strips do: the general kernel face by face made a 2k lat-long's cross 3.1× its cube's strips."""
    n = plan.height
    shape = target.grid_shape(n)
    rows = max(1, strip_pixels // shape[1])

    def strips():
        for top in track(range(0, shape[0], rows), f"resampling to {target.name}", total=-(-shape[0] // rows)):
            block = np.zeros((min(rows, shape[0] - top), shape[1], 3), dtype=np.float32)
            tiles = _strip_tiles(target, n, top, len(block))
            faces = _side_rows(plan, tiles, n)
            for face, (lo, hi), (first, last), tile_col, flip_rows, flip_cols in tiles:
                lines = faces.get(face)
                if lines is None:
                    lines = np.empty((hi - lo, n, 3), dtype=np.float32)
                    plan.fill(lines, face * n + lo)
                block[first - top:last - top, tile_col * n:(tile_col + 1) * n] = \
                    lines[::-1 if flip_rows else 1, ::-1 if flip_cols else 1]
            yield top, block

    return shape, strips()


def _strip_tiles(target: Cross, n: int, top: int, height: int) -> list[tuple]:
    """The tiles a cross strip of ``height`` image rows from ``top`` cuts: per face (face, its rows (lo, hi), the
    image rows (first, last), tile column, flip rows, flip columns)."""
    tiles = []
    for face, (tile_row, tile_col, (_, flip_rows, flip_cols)) in enumerate(target.tile_turns()):
        first, last = max(top, tile_row * n), min(top + height, (tile_row + 1) * n)
        if first < last:
            a, b = first - tile_row * n, last - tile_row * n
            tiles.append((face, (n - b, n - a) if flip_rows else (a, b), (first, last), tile_col, flip_rows,
                          flip_cols))
    return tiles


_SIDE_FACES = frozenset(int(face) for face in cube_symmetry.SIDE_FACES[:, 0])  # whose rows it computes together


def _side_rows(plan: _Plan, tiles: list[tuple], n: int) -> dict[int, np.ndarray]:
    """Rows of the side faces that two or more of ``tiles`` need alike, through the cube's symmetries (one pass
    for all four; the others are left to the general kernel): face → its rows."""
    if plan.cube_rows is None:
        return {}
    wanted: dict[tuple[int, int], list[int]] = {}
    for face, rows, *_ in tiles:
        if face in _SIDE_FACES:
            wanted.setdefault(rows, []).append(face)
    out = {}
    for (lo, hi), faces in wanted.items():
        if len(faces) > 1:
            sides = np.empty((6, hi - lo, n, 3), dtype=np.float32)
            plan.fill_rows(sides, lo, 0, hi - lo, poles=False)
            out.update({face: sides[face] for face in faces})
    return out


def _contiguous(rotation: np.ndarray | None) -> np.ndarray | None:
    """The rotation as a C-ordered float64 array: the kernels are compiled per array layout, and a transposed matrix
    (``R.T``, a frame's ``to_frame``) is Fortran-ordered, which would compile every resampling kernel a second time
    (minutes) for the same arithmetic."""
    return None if rotation is None else np.ascontiguousarray(rotation, dtype=np.float64)


def _prepared(source: EnvMap, target: Layout, size: int | None, samples: int | None, rotation=None):
    """Checks, then (source, target grid, k, steps): a cross source as cube faces, box-reduced while it has over
    :data:`MAX_FOOTPRINT_RATIO` pixels per target pixel, the supersampling rate (:func:`supersampling`) and the
    measured steps it was chosen from."""
    size = size or target.default_size(source.valid_pixels)
    pixels = check_size(target, size)
    if not getattr(flux._LINKING, "small", False):
        check_memory(resample_memory(math.prod(source.grid), pixels, target, source.layout),
                     f"resampling to {target.name} size {size}", kernels=True)
    grid = target.grid_shape(size)
    if isinstance(source.layout, Cross):  # exact rearrangement; the cube has a seamless padding
        source = EnvMap(source.layout.to_cube(source.data), CUBE)
    if samples is None:
        reduced = _reduced_grid(source.layout, source.grid, target, grid)[1]
        while source.grid != reduced:
            source = _halved(source)
    k, steps = supersampling(source.layout, source.grid, target, grid, rotation, samples)
    return source, grid, k, steps


def supersampling(source: Layout, source_grid: tuple[int, ...], target: Layout, grid: tuple[int, ...], rotation,
                  samples: int | None) -> tuple[int, polar.Steps]:
    """(k, steps): the supersampling rate of a conversion and the steps measured to choose it.

    k is ``samples`` if given, else the rate :func:`auto_samples` gives for the valid-pixel ratio — from a lat-long
    into a lat-long or cube, raised where the target's pixels land further apart in the source than the ratio says
    (a turned grid): :func:`lightprobe.maps.resampling.polar.samples_needed` on the measured steps.

    Parameters
    ----------
    source : Layout
        The source's layout, as the conversion reads it (a cross as ``cube``).
    source_grid : tuple of int
        The source's grid, after any box reduction.
    target : Layout
        The target layout (a cross is measured as its cube faces).
    grid : tuple of int
        The target's grid.
    rotation : numpy.ndarray or None
        The conversion's 3×3 rotation in the world frame, or None.
    samples : int or None
        A rate given by hand, or None for automatic.

    Returns
    -------
    k : int
        Lookups per side of a target pixel.
    steps : lightprobe.maps.resampling.polar.Steps
        How far apart, in source pixels, neighbouring target pixels land, measured for a lat-long source only
        (nothing measured for the others).
    """
    filled = _face_layout(target)
    filled_grid = filled.grid_shape(target.size_of(grid))
    ratio = _valid_pixels(source, source_grid) / max(_valid_pixels(target, grid), 1)
    if source.name != "latlong":  # the steps serve only a lat-long source (its k and its polar rows): not measured
        return samples or auto_samples(ratio), polar.no_steps()
    steps = polar.measure_steps(source, source_grid, filled, filled_grid, rotation)
    if samples:
        return samples, steps
    if filled.valid_fraction < 1.0:
        # Measured only from a lat-long into a lat-long or cube (a turned lat-long's equator lands further apart than
        # the ratio says). A disc's rim, as source or target, is one direction spread over a ring — the steps there
        # grow without bound and the measured rate would be the cap — and a cube's corner texels are a fifth of its
        # centre's: from a cube the rate would double for its corners alone. The ratio gives those their base rate;
        # each pixel raises its own where its footprint is long (adaptive_rate).
        return auto_samples(ratio), steps
    return polar.samples_needed(steps, auto_samples(ratio)), steps


# A mirror ball's pixels 25–40° from its rim direction span 10–30 rows of a lat-long source radially (the ball
# squeezes its back hemisphere into the outer rings): at 16 subsamples a side their lookups were 0.7–2 rows apart and a
# one-pixel sun there came out 0.3–0.7 % off (lat-long 256 → mirror ball 128 0.24 %, 2048 → 1024 0.40 %); they may
# take 32 (0.08–0.19 %; the ring is thin: 1.1–1.3× the conversion's time, lat-long 2048 → 256–1024). Other sources
# into a mirror ball are flux-corrected (:mod:`lightprobe.maps.resampling.flux`) and keep 16, as the correction's adjoint lists
# every pixel's taps.
LATLONG_SPHERE_MAX_SAMPLES = 32


def adaptive_rate(source: Layout, target: Layout, k: int) -> int:
    """The most subsamples a side (k_max) a pixel may take, when the rate is automatic.

    Where either layout is a disc, whose rim spreads one direction over a ring, or the source is a cube, whose corner
    texels are a fifth of its centre's, or the target is a lat-long, whose rows next to a pole are rings, each pixel
    takes its own rate between k and :data:`lightprobe.maps.resampling.polar.MAX_SAMPLES`
    (:data:`LATLONG_SPHERE_MAX_SAMPLES` from a lat-long into a mirror ball)
    (:func:`lightprobe.maps.resampling.fused._rates`). Elsewhere k (a lat-long into a cube: its polar rows are shortened
    by their reductions). A mirror ball source may take 2k: kept at :data:`SPHERE_MIN_SIDE` pixels for a tiny target,
    its base rate is high and its outer rings need more again — 128 → angular 16 at 16 a side left its pixels 25–35°
    from the rim up to 74 % off before the flux correction, more than its capped weights can mend (23 % after); at 32,
    exact (weights ≤ 21 %). Halved to 64 it had k = 8 and 16 as well.

    Parameters
    ----------
    source : Layout
        The source's layout as the conversion reads it.
    target : Layout
        The layout the kernel fills (cube faces for a cross).
    k : int
        The conversion's base rate (:func:`supersampling`).

    Returns
    -------
    int
        k_max, at least ``k``: lookups per side a pixel may take.
    """
    if source.name == "latlong" and target.name == "sphere":
        return max(k, LATLONG_SPHERE_MAX_SAMPLES)
    if source.name == "sphere":
        return max(2 * k, polar.MAX_SAMPLES)
    if source.name in DISCS or target.name in DISCS or source.name == "cube" or target.name == "latlong":
        return max(k, polar.MAX_SAMPLES)
    return k


@dataclass(frozen=True)
class _Plan:
    """Everything :func:`lightprobe.maps.resampling.fused.resample_into` needs, prepared once for a map's lines."""

    target: Layout
    filled: Layout  # what the kernel fills (cube faces for a cross)
    grid: tuple[int, ...]  # the filled layout's grid
    height: int  # rows per face
    args: tuple  # the kernel's arguments before ``out, first``
    cube_rows: tuple | None = None  # lat-long → cube by symmetry: cube_symmetry.cube_rows_into's before ``out, …``
    separable: tuple | None = None  # lat-long → lat-long on the same rows: (separable.Separable, source data)

    @property
    def lines_shape(self) -> tuple[int, int, int]:
        faces = self.grid[0] if len(self.grid) == 3 else 1
        return faces * self.height, self.grid[-1], 3

    def fill(self, out: np.ndarray, first: int) -> None:
        """Compute lines ``first`` … ``first + len(out) − 1`` (face-major rows) into ``out``, in bands on
        :func:`lightprobe.util.limits.threads` threads (the kernel releases the GIL)."""
        if self.separable is not None:  # a lat-long target: one face, lines are rows
            matrices, data = self.separable
            out[:] = matrices.band(data, first, first + len(out))
            return
        threads = min(limits.threads(), max(1, len(out) // 8))
        if threads == 1:
            fused.resample_into(*self.args, out, first)
            return
        band = max(1, -(-len(out) // (4 * threads)))  # 4 bands a thread: the slow bands (poles) even out
        starts = range(0, len(out), band)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda s: fused.resample_into(*self.args, out[s:s + band], first + s), starts))

    def fill_rows(self, faces: np.ndarray, top: int, first: int, last: int, poles: bool = True) -> None:
        """Compute rows ``first`` … ``last − 1`` of ``faces`` (6, R, n, 3) — image rows ``top + first`` … of the
        cube's side faces, and of +Y and −Y if ``poles`` — through the cube's symmetries
        (:mod:`lightprobe.maps.resampling.cube_symmetry`)."""
        self._bands(lambda a, b: cube_symmetry.cube_rows_into(*self.cube_rows, poles, faces, top, a, b), first, last)

    def fill_polar_faces(self, faces: np.ndarray) -> None:
        """Compute the +Y and −Y faces of ``faces`` (6, n, n, 3) whole, through their eight symmetries."""
        self._bands(lambda a, b: cube_symmetry.polar_faces_into(*self.cube_rows, faces, a, b), 0,
                    (self.height + 1) // 2, per_thread=16)  # a triangle: its first rows are the longest

    @staticmethod
    def _bands(kernel, first: int, last: int, per_thread: int = 4) -> None:
        """kernel(a, b) over bands of [first, last) on :func:`lightprobe.util.limits.threads` threads (it releases the
        GIL), several bands a thread: the slow bands (near the poles) even out."""
        rows = last - first
        threads = min(limits.threads(), max(1, rows // 2))
        if threads == 1:
            kernel(first, last)
            return
        band = max(1, -(-rows // (per_thread * threads)))
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda a: kernel(a, min(a + band, last)), range(first, last, band)))

    def fill_all(self, what: str) -> np.ndarray:
        """The whole map's lines (face-major rows), in steps a progress bar follows."""
        out = np.empty(self.lines_shape, dtype=np.float32)
        if self.cube_rows is not None:
            # The whole map is here: +Y and −Y through all eight of their symmetries (a strip has only its rows)
            faces, h = out.reshape(6, self.height, -1, 3), self.height
            for part in track(range(2), what, total=2):  # each part is one pool of threads: no waits between steps
                if part == 0:
                    self.fill_polar_faces(faces)
                else:
                    self.fill_rows(faces, 0, 0, h, poles=False)
            return out
        step = max(64, -(-len(out) // 16))
        for first in track(range(0, len(out), step), what, total=-(-len(out) // step)):
            self.fill(out[first:first + step], first)
        return out

    def finish(self, lines: np.ndarray) -> EnvMap:
        out = lines.reshape(self.grid + (3,))
        if isinstance(self.target, Cross):
            out = self.target.from_cube(out)
        return EnvMap(owned(out), self.target)


def _plan(source: EnvMap, target: Layout, size: int | None, rotation, samples: int | None,
          reduce_poles: bool = True, symmetric: bool = True) -> _Plan | None:
    """The compiled pass for this resampling, or None when the kernel does not know one of the layouts; an
    unturned lat-long into a cube goes through the cube's symmetries unless ``symmetric`` is False."""
    if fused.CODES.get(source.layout.name) is None and not isinstance(source.layout, Cross):
        return None
    if fused.CODES.get(_face_layout(target).name) is None:
        return None
    source, grid, k, steps = _prepared(source, target, size, samples, rotation)
    filled = _face_layout(target)
    grid = filled.grid_shape(target.size_of(grid))
    faces = grid if filled.faces > 1 else (1,) + grid
    src_kind = fused.CODES[source.layout.name]
    turn = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    reduction = polar.no_reduction(source.grid[-2])
    k_max = _k_max(source, filled, k, samples)
    data = source.data
    corrected = flux._flux_stencil(source.layout, source.grid, target, grid, rotation, samples, (k, k_max),
                                   lambda omega_t: delivered(_Taps(source.layout, source.grid, filled,
                                                                   filled.size_of(grid), k, k_max, steps, rotation),
                                                             source.grid, omega_t))
    if corrected is not None:  # read-only, as a map's pixels are: the kernel is compiled for one array type
        data = owned(corrected.apply(data))
    rows_alone = reduce_poles and separable.applies(source.layout, filled, rotation) and corrected is None
    if src_kind == fused.LATLONG:  # read in place: columns wrap and rows reflect across the poles in the kernel
        img, valid = np.ascontiguousarray(data)[None], np.ones((1, 1, 1), dtype=np.float32)
        if reduce_poles:
            found = polar.polar_levels(steps, source.grid, k)
            reduction = polar.reduced_rows(img[0], found)
            cells = None if corrected is not None or rows_alone or rotation is None else polar_balance._cell_balance(
                source.grid, found, filled, grid, k, k_max, steps, rotation)
            if cells is not None:
                cells.apply(reduction[1])  # in place: the reduced rows are this conversion's own
    else:
        img, valid = source.layout.padded(data, prefilter=balance.prefilter_for(source.layout))
        if source.all_valid:  # a cube's padding is valid everywhere: no table of ones for the kernel to read
            valid = np.ones((1, 1, 1), dtype=np.float32)
    all_valid = filled.valid_fraction == 1.0  # latlong, cube: no per-pixel mask
    tgt_valid = _target_valid(filled, grid, faces)
    img = read_only(img)  # as a map's pixels are: the kernels compile for one array type (util.jit.read_only)
    args = (src_kind, img, valid, *reduction, _axes(source.layout), source.grid[-2], source.grid[-1],
            fused.CODES[filled.name], _axes(filled), faces[1], tgt_valid, all_valid, k, k_max, turn)
    by_symmetry = (symmetric and src_kind == fused.LATLONG and filled.name == "cube"
                   and cube_symmetry.applies(source.grid[-1], rotation))
    cube_rows = (img, *reduction, faces[1], k, cube_symmetry._kinds()) if by_symmetry else None
    by_rows = (separable.Separable(source.grid, grid[-2:], k, rotation), source.data) if rows_alone else None
    return _Plan(target, filled, grid, faces[1], args, cube_rows, by_rows)


def _k_max(source: EnvMap, filled: Layout, k: int, samples: int | None) -> int:
    return adaptive_rate(source.layout, filled, k) if samples is None else k


def _fused_resample(source: EnvMap, target: Layout, grid: tuple[int, ...], k: int,
                    rotation: np.ndarray | None, reduce_poles: bool = False, symmetric: bool = True) -> EnvMap:
    """The compiled pass at a given supersampling rate k (for tests comparing it with :func:`reference_resample`,
    which reads every row as it is: by default so does this; ``symmetric`` False takes the general kernel where the
    cube's symmetries would serve)."""
    plan = _plan(source, target, target.size_of(grid), rotation, k, reduce_poles, symmetric)
    return plan.finish(plan.fill_all("resampling"))
