"""Resampling between layouts and sizes: footprint-aware, energy-conserving (∫L dω kept), and box reduction."""

from __future__ import annotations

import copy
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ...util.errors import LayoutError, UsageError
from ..layouts import CUBE, LATLONG, Cross, Layout
from ...util import limits
from ...util.limits import check_memory, check_pixels
from ...util.progress import track
from . import balance, cube_symmetry, flux, fused, polar, polar_balance, pole_rows, separable
from ..envmap import EnvMap, owned, pixel_directions, pixel_solid_angles
from .overlaps import column_means, interval_overlaps

_CHUNK_SAMPLES = 1 << 18  # direction lookups per chunk of a resampling pass (bounds memory to ~100 MB)
MAX_FOOTPRINT_RATIO = 16  # source pixels per target pixel above which the source is box-reduced first


def _valid_pixels(lay: Layout, grid: tuple[int, ...]) -> int:
    """Pixels of ``grid`` that cover the sphere (no mask is made for layouts whose pixels all do)."""
    return math.prod(grid) if lay.valid_fraction == 1.0 else int(np.count_nonzero(lay.shared_valid_mask(grid)))


def _target_valid(filled: Layout, grid: tuple[int, ...], faces: tuple[int, int, int]) -> np.ndarray:
    """The kernels' table of valid target pixels, (faces, H, W) uint8, read-only (one array type for numba): a
    1×1×1 table where every pixel is valid, else the layout's shared mask viewed as bytes (no copy)."""
    if filled.valid_fraction == 1.0:
        table = np.ones((1, 1, 1), dtype=np.uint8)
        table.setflags(write=False)
        return table
    return filled.shared_valid_mask(grid).reshape(faces).view(np.uint8)


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


_LINKING = threading.local()  # while link_kernels runs its small map: .small, and .uncorrected where the map is not


def link_kernels(source: Layout, source_pixels: int, target: Layout, size: int, *,
                 rotation: np.ndarray | None = None, streamed: bool = True) -> None:
    """Run the compiled kernels of a conversion once, on a small zero map that takes the same route.

    The conversion is a map of ``source_pixels`` in layout ``source`` into ``target`` of ``size``; its kernels are
    linked (loaded or compiled) before the map itself is read (``lightprobe convert``; see
    :func:`lightprobe.util.jit.release_compiler_pages`). The route that matters is whether the flux is corrected
    (:func:`_corrected`): a lat-long of 64 rows into a disc is and a 4k one is not, and linked on 64 rows that
    correction's kernels (~5 MiB resident) stayed beside a 4k map that never ran them. Where the map is not corrected,
    the small one is run without (box reductions are numpy's: no kernel to link).

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
    corrected = _corrected(reduced_layout, reduced, target, None)
    rows = 64
    small = EnvMap(np.zeros(source.grid_shape(rows) + (3,), np.float32), source)
    small_size = rows // 2  # 4–10 source pixels a target pixel: read as it is, not box-reduced
    _LINKING.uncorrected = not corrected  # a small lat-long into a disc is corrected where a 4k one is not
    _LINKING.small = True  # a small map's memory is not checked: the map's own conversion is, after this
    try:
        if streamed:
            for _ in resample_strips(small, target, small_size, rotation=rotation)[1]:
                pass
        else:
            resample(small, target, small_size, rotation=rotation)
    finally:
        _LINKING.uncorrected = _LINKING.small = False


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


def _prepared(source: EnvMap, target: Layout, size: int | None, samples: int | None, rotation=None):
    """Checks, then (source, target grid, k, steps): a cross source as cube faces, box-reduced while it has over
    :data:`MAX_FOOTPRINT_RATIO` pixels per target pixel, the supersampling rate (:func:`supersampling`) and the
    measured steps it was chosen from."""
    size = size or target.default_size(source.valid_pixels)
    pixels = check_size(target, size)
    if not getattr(_LINKING, "small", False):
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


DISCS = ("angular", "sphere")  # layouts whose rim spreads one direction over a ring of pixels


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


def _face_layout(target: Layout) -> Layout:
    """The layout the kernel fills: a cross is filled as cube faces and rearranged (exactly: same texel centres)."""
    return CUBE if isinstance(target, Cross) else target


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
    corrected = _flux_stencil(source.layout, source.grid, target, grid, rotation, samples, (k, k_max),
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
            cells = None if corrected is not None or rows_alone or rotation is None else _cell_balance(
                source.grid, found, filled, grid, k, k_max, steps, rotation)
            if cells is not None:
                cells.apply(reduction[1])  # in place: the reduced rows are this conversion's own
    else:
        img, valid = source.layout.padded(data, prefilter=balance.prefilter_for(source.layout))
        if source.all_valid:  # a cube's padding is valid everywhere: no table of ones for the kernel to read
            valid = np.ones((1, 1, 1), dtype=np.float32)
    all_valid = filled.valid_fraction == 1.0  # latlong, cube: no per-pixel mask
    tgt_valid = _target_valid(filled, grid, faces)
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
        self.rotation, self.samples = rotation, samples
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
        corrected = _corrected(source_layout, source_grid, filled, self.samples)
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
        self._flux = _flux_stencil(source_layout, tuple(source_grid), self.target, taps.grid, self.rotation,
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
        src = np.ascontiguousarray(data).reshape(-1, 3)
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


class _Taps:
    """The footprint taps of a conversion, listed a band of target lines at a time by the compiled kernel
    (:func:`lightprobe.maps.resampling.fused.footprint_taps`): what a :class:`Resampler` stores, and what
    :func:`delivered` reads without storing. ``band(first)`` → (counts (n·W,), idx, wts (n·W, max_taps)) for lines
    first … first+n−1; tap indices are flat source pixels (as the kernel reads them: a cube's balanced texels), then
    reduced polar rows."""

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
    :class:`Resampler` holds them: :func:`_taps_delivery`). The same shares in the same order every time: the same
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


_CELL_CACHE: dict = {}
_CELL_CACHE_PAIRS = 16  # balances a process keeps (a few kB each)
_FLUX_CACHE: dict = {}
_FLUX_LOCK = threading.Lock()
_FLUX_CACHE_BYTES = 256 << 20  # the corrections a process keeps (a batch converts one pair of grids many times)


def _cell_balance(source_grid: tuple[int, int], found: np.ndarray, filled: Layout, grid: tuple[int, ...], k: int,
                  k_max: int, steps: polar.Steps, rotation) -> polar_balance.CellBalance | None:
    """The balance of a lat-long source's coarsest polar rows in this conversion
    (:mod:`lightprobe.maps.resampling.polar_balance`), or None where it has none; kept for the last pairs of grids.
    Measured by the compiled adjoint, a pole at a time, on the target pixels by that pole alone and into its balanced
    rows' cells alone."""
    caps = polar_balance.caps(found, source_grid[-1])
    if not caps:
        return None
    key = (source_grid, filled, tuple(grid), k, k_max, found.tobytes(),
           None if rotation is None else np.asarray(rotation, np.float64).tobytes())
    with _FLUX_LOCK:
        if key in _CELL_CACHE:
            return _CELL_CACHE[key]
    taps = _Taps(LATLONG, source_grid, filled, filled.size_of(grid), k, k_max, steps, rotation)
    parts = []
    for sign, rows, angle in caps:
        first, end = polar_balance.cell_span(found, source_grid[-1], rows)
        kept = polar_balance.near_pole(filled, grid, rotation, sign, angle)
        per_cell = _kept_delivery(taps, filled, grid, kept, taps.source_pixels + first, end - first)
        parts += polar_balance.balance_of(per_cell, first, found, source_grid[-1], rows)
    cells = polar_balance.joined(parts)
    with _FLUX_LOCK:
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


# Lat-long sources are flux-corrected into discs up to this many pixels (as the conversion reads them, after any box
# reduction): 2048×1024. A 16–32-pixel disc's outer rings span 20–40° each, and a one-pixel sun read by them came out
# 0.26–0.74 % off (no rate fixes a pixel that straddles the rim). Larger discs hold most of the 0.2 % by their rates
# (LATLONG_SPHERE_MAX_SAMPLES, fused.LATLONG_ANGULAR_SPACING) and, to the rim direction, by their rim pixels' rows
# round it (fused._rim_subsamples), but not all of it: where a ball's rim-row pixel meets a plain one (lat-long
# 2048×1024 → mirror ball 512, 0.22 % 10–25° from its rim direction; 1536×768 → 384, 0.25 %), where the rates step
# mid-ball (1024×512 → 817, the default size, 0.33 %), at an angular map's rim direction (2048×1024 → 1634, 0.34 %):
# corrected, each is exact. It costs 2.4× the conversion the first time (2048×1024 → mirror ball 512–1024, 1.1–1.5 s
# → 2.7–3.6 s; then the weights are cached) and ~130 B a source pixel while it is made (+270 MB at 2048×1024). A 4k
# lat-long's correction would hold more than convert may (tests/test_limits.py: 3× the map): there it is not made.
# Its rows alone hold the bar into a mirror ball since lookups are 0.35 source pixels apart there
# (fused.LATLONG_SPHERE_SPACING), a side may take more than k_max where the other needs fewer (fused._within_budget)
# and the ball's long ring pixels are read round its rim direction (fused._rim_polar): 4096×2048 → mirror ball 1024
# 0.16 % (was 0.41 %), → 3268, its default size, 0.12 % (0.30 %). Into an angular map, since the pixels by its rim
# direction take lookups closer there (fused.ANGULAR_RIM_SPACING): → angular 3268 0.15 % (0.26 %; 0.12 % at the rim
# direction).
LATLONG_FLUX_MAX_PIXELS = 1 << 21
# pbrt's equal-area octahedral map joins the discs here: its square folds along the axes through its centre (+Y) and
# its corners (−Y), where the direction's angle from the pole goes as |s| + |t|, kinked along whole pixel edges, so the
# midpoint rule's end terms there do not cancel: a one-pixel sun in a lat-long's first two rows came out 0.7–2.2 %
# low (lat-long 64 and 128 rows → octahedral-ea 32–96), every other row within 0.22 %. Godot's plain map, whose poles
# are the middles of two edges, keeps every row within 0.11 % by its rates alone and is not corrected.
LATLONG_FLUX_TARGETS = DISCS + ("octahedral-ea",)


def _flux_corrects(source_layout: Layout, source_pixels: int, target: Layout) -> bool:
    """Whether a conversion from ``source_layout`` (``source_pixels`` as read) into ``target`` is flux-corrected (with
    its rate left automatic): every source but a lat-long; a lat-long into a disc up to :data:`LATLONG_FLUX_MAX_PIXELS`,
    and into anything when it has fewer rows than the rational pole rows need
    (:data:`lightprobe.maps.resampling.pole_rows.MIN_HEIGHT`: its first rows keep the plain spline, a sun there
    +22–25 %). Into a lat-long or a cube a larger lat-long keeps a sun's energy by its own construction — the polar
    rows' reductions and rational weights, measured in tests/test_resample.py. Into pbrt's equal-area octahedral map
    it is corrected as into a disc (:data:`LATLONG_FLUX_TARGETS`)."""
    if source_layout.name != "latlong":
        return True
    if math.isqrt(source_pixels // 2) < pole_rows.MIN_HEIGHT:  # a lat-long of H rows has 2H² pixels
        return True
    return target.name in LATLONG_FLUX_TARGETS and source_pixels <= LATLONG_FLUX_MAX_PIXELS


def _corrected(source_layout: Layout, source_grid: tuple[int, ...], target: Layout, samples: int | None) -> bool:
    """Whether this conversion gets a flux correction: :func:`_flux_corrects`, with the rate left automatic (and
    not while :func:`link_kernels` runs a small map for a large one that is not corrected)."""
    if getattr(_LINKING, "uncorrected", False):
        return False
    return samples is None and _flux_corrects(source_layout, math.prod(source_grid), _face_layout(target))


def _flux_stencil(source_layout: Layout, source_grid: tuple[int, ...], target: Layout, filled_grid, rotation,
                  samples: int | None, rates: tuple[int, int], delivery_of) -> flux.Stencil | None:
    """The flux correction of this conversion (:mod:`lightprobe.maps.resampling.flux`), or None where none is made (see
    :func:`_flux_corrects`; nor where the rate is given by hand, ``samples``: the kernel compared as it is).
    ``rates`` (k, k_max) are the conversion's; ``delivery_of(omega_t)`` gives each source pixel's delivery, flat,
    as the kernel reads them. Kept for the last pairs of grids, up to :data:`_FLUX_CACHE_BYTES` of weights, keyed by
    the layouts themselves (a turned mirror ball is named "sphere" too)."""
    if not _corrected(source_layout, source_grid, target, samples):
        return None
    target = _face_layout(target)  # a cross target is filled as cube faces
    key = (source_layout, source_grid, target, tuple(filled_grid), rates,
           None if rotation is None else np.asarray(rotation, np.float64).tobytes())
    with _FLUX_LOCK:
        if key in _FLUX_CACHE:
            return _FLUX_CACHE[key]
    omega_t = pixel_solid_angles(target, tuple(filled_grid)).reshape(-1)
    per_pixel = _raw_pixel_delivery(delivery_of(omega_t), source_layout, source_grid)
    omega_s = pixel_solid_angles(source_layout, source_grid)
    face_shape = (-1,) + tuple(source_grid[-2:])
    stencil = flux.stencil_for(source_layout, per_pixel.reshape(face_shape), omega_s.reshape(face_shape))
    with _FLUX_LOCK:  # threads converting at once (a Dask worker's) share the cache
        while _FLUX_CACHE and sum(kept.nbytes for kept in _FLUX_CACHE.values()) + stencil.nbytes > _FLUX_CACHE_BYTES:
            _FLUX_CACHE.pop(next(iter(_FLUX_CACHE)))  # the oldest first
        _FLUX_CACHE[key] = stencil
    return stencil


TILE_TAPS = fused.TILE * fused.TILE
TAPS_SCRATCH_BYTES = 64 << 20  # a thread's buffer of unmerged taps while a Resampler lists them


def _axes(lay: Layout) -> np.ndarray:
    return np.asarray(getattr(lay, "camera_axes", np.eye(3)), dtype=np.float64)


def reference_resample(source: EnvMap, target: Layout, grid: tuple[int, ...], k: int,
                       rotation: np.ndarray | None) -> EnvMap:
    """The numpy formulation of :func:`resample`: the reference the compiled kernel is tested against.

    k×k lookups per target pixel, in chunks; a lat-long target's pole rows in the kernel's cells, a cube target's edge
    terms as the kernel's. It is also the path for layouts the kernel does not know. Its lookups are the layout's
    plain B-spline: near a lat-long source's poles it lacks the kernel's rational row weights (the tests compare the
    two on sources under :data:`lightprobe.maps.resampling.pole_rows.MIN_HEIGHT` rows, where the kernel has none
    either).

    Parameters
    ----------
    source : EnvMap
        The map to convert, as the conversion reads it (no box reduction is made here).
    target : Layout
        The target layout, an instance.
    grid : tuple of int
        The target's grid (``target.grid_shape(size)``).
    k : int
        Lookups per side of a target pixel.
    rotation : numpy.ndarray or None
        3×3 rotation matrix R in the world frame (the target at direction d shows the source at Rᵀd), or None.

    Returns
    -------
    EnvMap
        The converted map in ``target`` of ``grid`` (float32 radiance; 0 on pixels off the sphere).
    """
    if isinstance(target, Cross):  # filled as cube faces and rearranged, as the kernel does (edge terms are a face's)
        faces = reference_resample(source, CUBE, CUBE.grid_shape(target.size_of(grid)), k, rotation)
        return EnvMap(owned(target.from_cube(faces.data)), target)
    lookup = source.layout.sampler(source.data, "bspline", balance.prefilter_for(source.layout))
    sub = (np.arange(k) + 0.5) / k
    h, w = grid[-2:]
    index = [a.ravel() for a in np.indices(grid)]
    flat_face, flat_row, flat_col = index if target.faces > 1 else [np.zeros_like(index[0]), *index]
    valid = target.valid_mask(grid).ravel()
    out = np.zeros((flat_row.size, 3), dtype=np.float32)
    step = max(1, _CHUNK_SAMPLES // (k * k))
    chunks = range(0, flat_row.size, step)
    for start in track(chunks, f"resampling to {target.name}", total=len(chunks)):
        sl = slice(start, start + step)
        f, u, v = np.broadcast_arrays(
            flat_face[sl, None, None],
            (flat_col[sl, None, None] + sub[None, None, :]) / w,
            (flat_row[sl, None, None] + sub[None, :, None]) / h,
        )
        weight = target.uv_density(f, u, v)
        if target.name == "latlong":  # the kernel's cells in its pole rows (fused.POLE)
            v, weight = _pole_cells(flat_row[sl], sub, h, u, v, weight)
        d = np.where(weight[..., None] > 0, target.uv_to_dir(f, u, v), _ANY_DIRECTION)
        if rotation is not None:
            d = d @ rotation  # row vectors: d @ R = (Rᵀ d)ᵀ
        values = lookup(d)
        wsum = weight.sum(axis=(1, 2))
        total = np.einsum("pij,pijc->pc", weight, values)
        if target.name == "cube":  # the kernel's edge terms (fused._cube_edge_terms)
            _add_cube_edge_terms(lookup, flat_face[sl], flat_row[sl], flat_col[sl], h, w, rotation, total, wsum)
        out[sl] = total / np.where(wsum > 0, wsum, 1.0)[:, None]
        # a disc's rim pixel can have all its subsamples off the disc: it shows its centre's (rim) direction
        missed = np.nonzero((wsum == 0) & valid[sl])[0]
        if missed.size:
            f0, u0, v0 = flat_face[sl][missed], (flat_col[sl][missed] + 0.5) / w, (flat_row[sl][missed] + 0.5) / h
            d0 = np.nan_to_num(target.uv_to_dir(f0, u0, v0), nan=0.0)
            out[start + missed] = lookup(d0 if rotation is None else d0 @ rotation)
    out[~valid] = 0.0
    return EnvMap(owned(out.reshape(grid + (3,))), target)


def _add_cube_edge_terms(lookup, face: np.ndarray, row: np.ndarray, col: np.ndarray, h: int, w: int, rotation,
                         total: np.ndarray, wsum: np.ndarray) -> None:
    """Add to cube pixels' weighted sums ``total`` (p, 3) and weight sums ``wsum`` (p,), at k × k plain cells, the
    kernel's edge terms (:func:`lightprobe.maps.resampling.fused._cube_edge_terms`): for each side of a pixel on its
    face's side, lookups at the side's ends weighted ± t·(dω/(du dv))/48."""
    for side in range(4):
        across = float(side % 2)
        on = (col == (0 if side == 0 else w - 1)) if side < 2 else (row == (0 if side == 2 else h - 1))
        at = np.nonzero(on)[0]
        for end in (0, 1):
            if side < 2:
                u, v = np.full(at.size, across), (row[at] + end) / h
                t = 2 * v - 1
            else:
                u, v = (col[at] + end) / w, np.full(at.size, across)
                t = 2 * u - 1
            weight = (-1.0 if end else 1.0) * t * CUBE.uv_density(face[at], u, v) / 48.0
            d = CUBE.uv_to_dir(face[at], u, v)
            total[at] += weight[:, None] * lookup(d if rotation is None else d @ rotation)
            wsum[at] += weight


def _pole_cells(rows: np.ndarray, sub: np.ndarray, h: int, u: np.ndarray, v: np.ndarray,
                weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v, weight) of a lat-long target's (p, k, k) subsamples (v along axis 1) of pixels in ``rows`` of ``h``,
    with the pole rows' cells warped as the kernel's (:data:`lightprobe.maps.resampling.fused.POLE`): v at the warped
    positions, the density there times the cell's width."""
    k = sub.size
    v, weight = v.copy(), weight.copy()
    for pole_row in (0, h - 1):
        before = fused.POLE if pole_row == 0 else k
        after = fused.POLE if pole_row == h - 1 else k
        fv, sv = fused._graded.py_func(sub, k, before, after)
        at = rows == pole_row
        v[at] = (pole_row + fv[None, :, None]) / h
        weight[at] = LATLONG.uv_density(None, u[at], v[at]) * sv[None, :, None]
    return v, weight


_ANY_DIRECTION = np.array([0.0, 0.0, -1.0])  # stands in for subsamples off the valid region (their weight is 0)


# Peak bytes of :func:`resample` beyond the source (measured on 2048×1024 and 4096×2048 sources,
# tests/test_limits.py). Per source pixel: the padded copy a cube or disc source is read from (a latlong is read in
# place), box reductions. Per target pixel: the float32 output and, for discs, the validity mask.
RESAMPLE_BYTES_PER_SOURCE_PIXEL = 24
FLUX_BYTES_PER_SOURCE_PIXEL = 160
RESAMPLE_BYTES_PER_TARGET_PIXEL = {"angular": 20, "sphere": 20}
RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT = 16


def check_size(layout: Layout, size: int) -> int:
    """Refuse sizes whose pixel count would be absurd before allocating anything; returns the pixel count.

    The count is exact: Python integers, so no size can overflow.

    Parameters
    ----------
    layout : Layout
        The layout the size is for.
    size : int
        Its size (image height, or face edge for cube layouts); a positive whole number (a numpy integer too).

    Returns
    -------
    int
        The number of pixels of the layout's grid for ``size``.

    Raises
    ------
    UsageError
        When ``size`` is not a whole number or is under 1.
    BudgetError
        When the pixel count is over the pixel limit (``LIGHTPROBE_MAX_PIXELS``).
    """
    if not isinstance(size, (int, np.integer)) or size < 1:
        raise UsageError(f"size must be a positive whole number, got {size!r}")
    n = math.prod(int(v) for v in layout.grid_shape(int(size)))
    check_pixels(n, f"size {size} for {layout.name}")
    return n


def resample_memory(source_pixels: int, target_pixels: int, target: Layout, source: Layout | None = None) -> int:
    """Estimated peak memory (bytes) of :func:`resample` beyond the source map itself.

    From ``source_pixels`` to ``target_pixels`` of ``target``; a ``source`` whose conversions are flux-corrected
    (:func:`_flux_corrects`: all but a lat-long's, save small ones into discs), or not named, adds its correction's
    deliveries, flows and weights (:func:`_flux_stencil`: measured 75–120 B a source pixel, more where a face's side is
    just past a power of two).

    Parameters
    ----------
    source_pixels : int
        Pixels of the source map's grid.
    target_pixels : int
        Pixels of the target's grid.
    target : Layout
        The target layout (a disc target needs more a pixel: its validity mask).
    source : Layout or None, default None
        The source's layout; None counts the flux correction's memory, as the worst case.

    Returns
    -------
    int
        Bytes: per source pixel 24 (+ 160 with the flux correction), per target pixel 16 (20 for discs).
    """
    per_target = RESAMPLE_BYTES_PER_TARGET_PIXEL.get(target.name, RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT)
    per_source = RESAMPLE_BYTES_PER_SOURCE_PIXEL
    if source is None or _flux_corrects(source, source_pixels, _face_layout(target)):
        per_source += FLUX_BYTES_PER_SOURCE_PIXEL
    return source_pixels * per_source + target_pixels * per_target


# ---- energy of a one-pixel sun, every pixel at once (Resampler.energy_gains) ----------------------------------------

def _tap_totals(resampler: Resampler, omega_t: np.ndarray, n: int) -> np.ndarray:
    """Σ_t Ω_t W_ti per tap index i (float64, at least ``n``: source pixels, then reduced polar rows), from the
    cached taps."""
    per_tap = resampler.wts.astype(np.float64) * np.repeat(omega_t, np.diff(resampler.offsets))
    return np.bincount(resampler.idx, per_tap, minlength=n)


def _taps_delivery(resampler: Resampler, layout: Layout, grid: tuple[int, ...], omega_t: np.ndarray) -> np.ndarray:
    """Σ_t Ω_t W_ts per source pixel s (flat), from the cached taps."""
    return _unreduced(_tap_totals(resampler, omega_t, math.prod(grid)), grid, resampler._levels, resampler._cells)


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


def _separable_delivery(matrices: separable.Separable, omega_t: np.ndarray) -> np.ndarray:
    """Σ_t Ω_t W_ts for a separable lat-long → lat-long: rows and columns apart (a target row's pixels share Ω)."""
    row_omega = omega_t[:, 0]
    out = np.zeros((matrices.rows.shape[1], matrices.columns.shape[1]))
    for rows, columns in ((matrices.rows, matrices.columns), (matrices.rows_half, matrices.columns_half)):
        out += np.outer(rows.T @ row_omega, np.asarray(columns.sum(axis=0)).ravel())
    return out


def _through_odd_halving(grid: tuple[int, ...], target: Layout, size: int, rotation) -> np.ndarray:
    """energy_gains of a lat-long of odd height, which :func:`_odd_box_reduce` puts onto ⌊H/2⌋ rows first: old
    pixel s shares its energy out among the new pixels t it overlaps, each carrying its share on with its own gain
    g_t, so s's gain is Σ_t overlap_ts (1 + g_t) / Ω_s − 1 (the overlaps separable: rows and columns apart)."""
    half = LATLONG.grid_shape(grid[-2] // 2)
    gains = Resampler(LATLONG, half, target, size, rotation=rotation).energy_gains()
    rows, columns = _odd_halving_overlaps(tuple(grid))
    delivered = (columns.T @ (rows.T @ (1.0 + gains)).T).T
    return delivered / pixel_solid_angles(LATLONG, tuple(grid)) - 1.0


def _expanded_gains(layout: Layout, grid: tuple[int, ...], target: Layout, size: int, rotation) -> np.ndarray:
    """energy_gains of a source the conversion box-reduces first: its reduction's, each block's for its pixels.
    The Resampler of the halved grid halves it again only where :func:`resample` would (:func:`_reducible`): this
    measure once halved lat-longs under 48 rows, which no conversion does, and reported their pole rows +25 %.
    A lat-long of odd height is carried through its halving instead (:func:`_through_odd_halving`)."""
    if layout.name == "latlong" and grid[-2] % 2:
        return _through_odd_halving(grid, target, size, rotation)
    reduced = box_reduce(EnvMap(np.zeros(grid + (3,), np.float32), layout))
    gains = Resampler(layout, reduced.grid, target, size, rotation=rotation).energy_gains()
    gains = np.repeat(np.repeat(gains, 2, axis=-2), 2, axis=-1)
    return np.where(pixel_solid_angles(layout, grid) > 0, gains, np.nan)
