"""Resampling between layouts and sizes: footprint-aware, energy-conserving (∫L dω kept), and box reduction."""

from __future__ import annotations

import math

import numpy as np

from ..errors import LayoutError, UsageError
from ..layouts import CUBE, Cross, Layout
from ..limits import check_memory, check_pixels
from ..progress import track
from .map import EnvMap, owned

_CHUNK_SAMPLES = 1 << 18  # direction lookups per chunk of a resampling pass (bounds memory to ~100 MB)
MAX_FOOTPRINT_RATIO = 16  # source pixels per target pixel above which the source is box-reduced first


def _valid_ratio(source: EnvMap, target: Layout, grid: tuple[int, ...]) -> float:
    """Valid source pixels per valid target pixel."""
    return float(source.valid_mask().sum()) / max(int(target.valid_mask(grid).sum()), 1)


def auto_samples(ratio: float) -> int:
    """Supersampling rate k (k×k lookups per target pixel) for ``ratio`` source pixels per target pixel.

    k = ⌈2√ratio⌉, at least 2: lookups are spaced at most half a source pixel apart, where the cubic B-spline's
    sinc⁴ spectrum makes the sum of lookups integrate even a one-pixel sun to about 0.1 %."""
    return max(2, int(np.ceil(2 * np.sqrt(ratio))))


def box_reduce(env: EnvMap) -> EnvMap:
    """Halve the resolution: each new pixel is the solid-angle-weighted mean of a 2×2 block (∫L dω unchanged).

    Needs even dimensions; a cross is reduced as cube faces and returned as a cube."""
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


def _reducible(env: EnvMap) -> bool:
    h, w = env.grid[-2:]
    if isinstance(env.layout, Cross):
        h = w = h // env.layout.aspect[1]
    return h % 2 == 0 and w % 2 == 0 and min(h, w) >= 8


def resample(
    source: EnvMap,
    target: Layout,
    size: int | None = None,
    *,
    rotation: np.ndarray | None = None,
    samples: int | None = None,
) -> EnvMap:
    """Resample ``source`` into layout ``target`` of ``size`` (default: about the same number of valid pixels).

    Each target pixel is the solid-angle-weighted mean (weights ``dω/(du dv)`` of the target layout) of k×k
    stratified lookups spread over its footprint, each a cubic B-spline interpolation of the source. Lookups are
    at most half a source pixel apart, so ∫L dω is conserved (to ~0.1 % even for a sun of one pixel) and a uniform
    map stays exactly uniform; sources with over 16 pixels per target pixel are first box-reduced (exactly
    energy-preserving). ``rotation`` R turns the environment: the target at direction d shows the source at Rᵀd.
    """
    size = size or target.default_size(int(source.valid_mask().sum()))
    pixels = check_size(target, size)
    check_memory(resample_memory(math.prod(source.grid), pixels, target), f"resampling to {target.name} size {size}")
    grid = target.grid_shape(size)
    if isinstance(source.layout, Cross):  # exact rearrangement; the cube has a seamless padding
        source = EnvMap(source.layout.to_cube(source.data), CUBE)
    while samples is None and _valid_ratio(source, target, grid) > MAX_FOOTPRINT_RATIO and _reducible(source):
        source = box_reduce(source)
    k = samples or auto_samples(_valid_ratio(source, target, grid))
    lookup = source.layout.sampler(source.data, "bspline")
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
        d = np.where(weight[..., None] > 0, target.uv_to_dir(f, u, v), _ANY_DIRECTION)
        if rotation is not None:
            d = d @ rotation  # row vectors: d @ R = (Rᵀ d)ᵀ
        values = lookup(d)
        wsum = weight.sum(axis=(1, 2))
        out[sl] = np.einsum("pij,pijc->pc", weight, values) / np.where(wsum > 0, wsum, 1.0)[:, None]
        # a disc's rim pixel can have all its subsamples off the disc: it shows its centre's (rim) direction
        missed = np.nonzero((wsum == 0) & valid[sl])[0]
        if missed.size:
            f0, u0, v0 = flat_face[sl][missed], (flat_col[sl][missed] + 0.5) / w, (flat_row[sl][missed] + 0.5) / h
            d0 = np.nan_to_num(target.uv_to_dir(f0, u0, v0), nan=0.0)
            out[start + missed] = lookup(d0 if rotation is None else d0 @ rotation)
    out[~valid] = 0.0
    return EnvMap(owned(out.reshape(grid + (3,))), target)


_ANY_DIRECTION = np.array([0.0, 0.0, -1.0])  # stands in for subsamples off the valid region (their weight is 0)


# Peak bytes of :func:`resample` (measured on 2048×1024 and 4096×2048 sources, tests/test_limits.py). Per source
# pixel: the padded copy the B-spline lookup reads, box reductions, the source's geometry tables (~80 B measured).
# Per target pixel: the float32 output, the flat index arrays and validity mask (~30 B); a disc layout's exact
# solid angles take 4×4 Gauss–Legendre points per pixel of the whole grid (~390 B measured).
RESAMPLE_BYTES_PER_SOURCE_PIXEL = 96
RESAMPLE_BYTES_PER_TARGET_PIXEL = {"angular": 440, "sphere": 440}
RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT = 64


def check_size(layout: Layout, size: int) -> int:
    """Refuse sizes whose pixel count would be absurd before allocating anything; returns the pixel count (exact:
    Python integers, so no size can overflow)."""
    if not isinstance(size, (int, np.integer)) or size < 1:
        raise UsageError(f"size must be a positive whole number, got {size!r}")
    n = math.prod(int(v) for v in layout.grid_shape(int(size)))
    check_pixels(n, f"size {size} for {layout.name}")
    return n


def resample_memory(source_pixels: int, target_pixels: int, target: Layout) -> int:
    """Estimated peak memory (bytes) of :func:`resample` from ``source_pixels`` to ``target_pixels`` of ``target``
    (beyond the source map itself)."""
    per_target = RESAMPLE_BYTES_PER_TARGET_PIXEL.get(target.name, RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT)
    return source_pixels * RESAMPLE_BYTES_PER_SOURCE_PIXEL + target_pixels * per_target
