"""The :class:`EnvMap` type: an HDR environment map (linear RGB radiance) in one layout, world frame.

Conventions: ``data`` is float32 of shape ``grid + (3,)`` (see :mod:`lightprobe.layouts`); the numbers are
**radiance** (linear RGB, any consistent unit) arriving at the probe from each direction; directions are in the world
frame (+Y up, front −Z). ``∫L dω`` is the per-channel integral of radiance over the sphere (units × sr).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from .errors import InputError, LayoutError, LightprobeWarning
from .frames import as_rotation
from .io import read_image, write_image
from .layouts import CUBE, Cross, Layout, detect_layout, layout as layout_named
from .progress import track
from .tonemap import luminance

_CHUNK_SAMPLES = 1 << 18  # direction lookups per chunk of a resampling pass (bounds memory to ~100 MB)


@dataclass(frozen=True, eq=False)
class EnvMap:
    """Radiance from every direction, stored in ``layout``; ``data`` has shape ``layout grid + (3,)``."""

    data: np.ndarray
    layout: Layout

    def __post_init__(self) -> None:
        data = np.asarray(self.data, dtype=np.float32)
        if data.ndim < 3 or data.shape[-1] != 3:
            raise LayoutError(f"an environment map needs RGB pixels (…, 3), got shape {data.shape}")
        self.layout.check_grid(data.shape[:-1])
        object.__setattr__(self, "data", data)

    # ---- geometry ----------------------------------------------------------------------------------------------
    @property
    def grid(self) -> tuple[int, ...]:
        return self.data.shape[:-1]

    @property
    def size(self) -> int:
        """The layout's ``size`` of this map (height, or face edge for cube layouts)."""
        return self.layout.size_of(self.grid)

    def directions(self) -> np.ndarray:
        """World direction of every pixel centre, ``grid + (3,)`` (read-only; shared by maps of the same grid)."""
        return pixel_geometry(self.layout, self.grid)[0]

    def solid_angles(self) -> np.ndarray:
        """Exact solid angle of every pixel (sr), shape ``grid``; sums to 4π (read-only, shared)."""
        return pixel_geometry(self.layout, self.grid)[1]

    def valid_mask(self) -> np.ndarray:
        return pixel_geometry(self.layout, self.grid)[1] > 0

    # ---- quantities --------------------------------------------------------------------------------------------
    def integral(self) -> np.ndarray:
        """∫L dω per channel (radiance × sr), with the exact per-pixel solid angles."""
        omega = self.solid_angles().astype(np.float64)
        return omega.reshape(-1) @ self.data.reshape(-1, 3).astype(np.float64)

    def lookup(self, d: np.ndarray) -> np.ndarray:
        """Radiance arriving from world directions ``d`` (..., 3), bilinear, seam- and pole-correct."""
        return self.layout.sample(self.data, np.asarray(d, dtype=np.float64))

    def stats(self) -> dict:
        """Size, layout and statistics over valid pixels. ``mean`` is the solid-angle mean ∫L dω / 4π."""
        valid = self.valid_mask()
        px = self.data[valid]
        finite = px[np.isfinite(px).all(axis=1)]
        counts = bad_pixel_counts(self.data[valid])
        integral = self.integral() if counts["nan"] + counts["inf"] == 0 else np.full(3, np.nan)
        image_h, image_w = file_shape(self)
        return {
            "width": image_w,
            "height": image_h,
            "layout": self.layout.name,
            "size": self.size,
            "valid_pixels": int(valid.sum()),
            "min": finite.min(axis=0).tolist() if len(finite) else [math.nan] * 3,
            "max": finite.max(axis=0).tolist() if len(finite) else [math.nan] * 3,
            "mean": (integral / (4 * np.pi)).tolist(),
            "integral": integral.tolist(),
            "luminance_integral": float(luminance(integral)),
            **{f"{k}_pixels": v for k, v in counts.items()},
        }

    # ---- transforms --------------------------------------------------------------------------------------------
    def to(self, layout: str | Layout, size: int | None = None, samples: int | None = None) -> EnvMap:
        """This map in another layout (footprint-aware resampling, see :func:`resample`)."""
        return resample(self, layout_named(layout), size, samples=samples)

    def rotated(self, rotation, samples: int | None = None) -> EnvMap:
        """The environment turned by ``rotation`` (3×3 matrix or (yaw, pitch, roll) degrees, see
        :func:`lightprobe.frames.rotation_from_ypr`): light that came from d now comes from R·d. Same layout."""
        return resample(self, self.layout, self.size, rotation=as_rotation(rotation), samples=samples)

    def save(self, path: str | os.PathLike, **kwargs) -> Path:
        """Write to an image file (cube maps as a 6N × N strip); keyword arguments go to :func:`write_image`."""
        return write_image(path, to_image(self), **kwargs)


@lru_cache(maxsize=4)
def pixel_geometry(lay: Layout, grid: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(directions, solid angles) of a layout's pixel grid, computed once per grid like a renderer's lookup
    tables; read-only so that no caller can corrupt them for the next."""
    d, omega = lay.directions(grid), lay.solid_angles(grid)
    d.setflags(write=False)
    omega.setflags(write=False)
    return d, omega


# ---- files ------------------------------------------------------------------------------------------------------
def file_shape(env: EnvMap) -> tuple[int, int]:
    """(height, width) of the image file that holds ``env``."""
    if env.layout.faces == 6:
        return env.grid[1], 6 * env.grid[2]
    return env.grid[0], env.grid[1]


def to_image(env: EnvMap) -> np.ndarray:
    """The flat (H, W, 3) image of a map: cube faces side by side (+X, −X, +Y, −Y, +Z, −Z), others as they are."""
    if env.layout.faces == 6:
        n = env.grid[1]
        return env.data.transpose(1, 0, 2, 3).reshape(n, 6 * n, 3)
    return env.data


def from_image(image: np.ndarray, layout: str | Layout | None = None) -> EnvMap:
    """An :class:`EnvMap` from a flat (H, W, 3) image; the layout is detected from the aspect ratio if not given."""
    h, w = image.shape[:2]
    lay = detect_layout(w, h) if layout is None else layout_named(layout)
    if lay.faces == 6:
        if w != 6 * h:
            raise LayoutError(f"a {w}×{h} image does not fit the cube layout (a 6:1 strip of faces)")
        return EnvMap(image.reshape(h, 6, h, 3).transpose(1, 0, 2, 3), lay)
    lay.check_grid((h, w))
    return EnvMap(image, lay)


def bad_pixel_counts(data: np.ndarray) -> dict[str, int]:
    """Number of pixels with any NaN, any ±inf, or any negative (finite) channel."""
    px = np.asarray(data).reshape(-1, 3)
    nan = np.isnan(px).any(axis=1)
    inf = np.isinf(px).any(axis=1)
    neg = (np.nan_to_num(px, nan=0.0, posinf=0.0, neginf=0.0) < 0).any(axis=1)
    return {"nan": int(nan.sum()), "inf": int(inf.sum()), "negative": int(neg.sum())}


def repair(data: np.ndarray, source: str = "image") -> np.ndarray:
    """Replace NaN, infinite and negative values by 0, warning once with how many pixels were touched."""
    counts = bad_pixel_counts(data)
    if not any(counts.values()):
        return data
    warnings.warn(
        f"{source}: replaced by 0 the bad values of {counts['nan']} NaN, {counts['inf']} infinite and "
        f"{counts['negative']} negative pixels",
        LightprobeWarning,
        stacklevel=3,
    )
    clean = np.nan_to_num(data, nan=0.0, posinf=0.0, neginf=0.0)
    return np.maximum(clean, 0.0).astype(np.float32)


def read_envmap(path: str | os.PathLike, layout: str | Layout | None = None, *, fix: bool = True) -> EnvMap:
    """Read an environment map file. ``layout`` None: detected from the aspect ratio.

    With ``fix`` (the default) NaN, infinite and negative values are replaced by 0 with a
    :class:`LightprobeWarning` saying how many pixels; with ``fix=False`` they are kept (as ``info`` needs).
    """
    image = read_image(path)
    if fix:
        image = repair(image, str(path))
    try:
        return from_image(image, layout)
    except LayoutError as e:
        raise LayoutError(f"{path}: {e}") from None


# ---- resampling ---------------------------------------------------------------------------------------------------
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
    return EnvMap(mean.astype(np.float32), env.layout)


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
    check_size(target, size)
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
    return EnvMap(out.reshape(grid + (3,)), target)


_ANY_DIRECTION = np.array([0.0, 0.0, -1.0])  # stands in for subsamples off the valid region (their weight is 0)


def check_size(layout: Layout, size: int) -> None:
    """Refuse sizes whose pixel count would be absurd before allocating anything."""
    from .io import MAX_PIXELS

    n = int(np.prod(layout.grid_shape(size)))
    if n > MAX_PIXELS:
        raise InputError(f"refusing size {size} for {layout.name}: {n} pixels is over the limit of {MAX_PIXELS}")
