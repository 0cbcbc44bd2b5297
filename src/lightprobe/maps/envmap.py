"""The :class:`EnvMap` type: an HDR environment map (linear RGB radiance) in one layout, world frame.

Conventions: ``data`` is float32 of shape ``grid + (3,)`` (see :mod:`lightprobe.maps.layouts`); the numbers are
**radiance** (linear RGB, any consistent unit) arriving at the probe from each direction; directions are in the world
frame (+Y up, front −Z). ``∫L dω`` is the per-channel integral of radiance over the sphere (units × sr).

An ``EnvMap`` is immutable: its ``data`` is read-only, and an array handed in by a caller is copied unless it is
read-only all the way down (so changing the caller's array can never change the map).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..util.errors import LayoutError
from .frames import as_rotation
from .layouts import Layout, layout as layout_named
from .tonemap import luminance


def frozen_array(a: np.ndarray) -> np.ndarray:
    """``a`` as float32 that nobody can write: ``a`` itself when it and every array it views are read-only, else a
    read-only copy."""
    a = np.asarray(a)
    owner, shared = a, False
    while isinstance(owner, np.ndarray):
        shared |= owner.flags.writeable
        owner = owner.base
    if a.dtype != np.float32 or shared:
        a = np.array(a, dtype=np.float32)
        a.setflags(write=False)
    return a


def owned(a: np.ndarray) -> np.ndarray:
    """Mark a fresh array that no one else holds (and every array it views) read-only, so that :class:`EnvMap`
    takes it without a copy. Only for arrays the calling code has just made."""
    owner = a
    while isinstance(owner, np.ndarray):
        owner.setflags(write=False)
        owner = owner.base
    return a


@dataclass(frozen=True, eq=False, repr=False)
class EnvMap:
    """Radiance from every direction, stored in ``layout``; ``data`` has shape ``layout grid + (3,)``, read-only."""

    data: np.ndarray
    layout: Layout

    def __post_init__(self) -> None:
        data = np.asarray(self.data)
        if data.ndim < 3 or data.shape[-1] != 3:
            raise LayoutError(f"an environment map needs RGB pixels (…, 3), got shape {data.shape}")
        self.layout.check_grid(data.shape[:-1])
        object.__setattr__(self, "data", frozen_array(data))

    def __repr__(self) -> str:
        return f"EnvMap({self.layout.name}, grid {'×'.join(map(str, self.grid))}, size {self.size})"

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
        return pixel_directions(self.layout, self.grid)

    def solid_angles(self) -> np.ndarray:
        """Exact solid angle of every pixel (sr), shape ``grid``; sums to 4π (read-only, shared)."""
        return pixel_solid_angles(self.layout, self.grid)

    @property
    def all_valid(self) -> bool:
        """True when every pixel covers part of the sphere (latlong, cube): no mask is needed."""
        return self.layout.valid_fraction == 1.0

    def valid_mask(self) -> np.ndarray:
        """True for the pixels that cover part of the sphere (read-only; all true for latlong and cube)."""
        if self.all_valid:
            return np.broadcast_to(np.True_, self.grid)  # no per-pixel table for a mask that is all true
        return pixel_solid_angles(self.layout, self.grid) > 0

    @property
    def valid_pixels(self) -> int:
        return math.prod(self.grid) if self.all_valid else int(self.valid_mask().sum())

    # ---- quantities --------------------------------------------------------------------------------------------
    def integral(self) -> np.ndarray:
        """∫L dω per channel (radiance × sr), with the exact per-pixel solid angles, summed in float64.

        A latlong map's pixels of one row share their solid angle: row sums times row solid angles, with no
        per-pixel table. Other layouts go in chunks of rows, so no float64 copy of the map is made."""
        if self.layout.name == "latlong":
            return self.layout.row_solid_angles(self.grid) @ _row_sums(self.data)
        omega = self.solid_angles().reshape(-1)
        px = self.data.reshape(-1, 3)
        total = np.zeros(3)
        for start in range(0, len(omega), 1 << 20):
            chunk = slice(start, start + (1 << 20))
            total += omega[chunk] @ px[chunk].astype(np.float64)
        return total

    def lookup(self, d: np.ndarray) -> np.ndarray:
        """Radiance arriving from world directions ``d`` (..., 3), bilinear, seam- and pole-correct."""
        return self.layout.sample(self.data, np.asarray(d, dtype=np.float64))

    def stats(self) -> dict:
        """Size, layout and statistics over valid pixels. ``mean`` is the solid-angle mean ∫L dω / 4π; values that
        cannot be computed (a map of NaN pixels) are None."""
        from .files import file_shape
        from .pixels import bad_pixel_counts

        px = self.data.reshape(-1, 3) if self.all_valid else self.data[self.valid_mask()]
        low, high = _channel_min_max(px)  # NaN propagates into both
        clean = bool((low >= 0).all() and (high < np.inf).all())
        counts = {"nan": 0, "inf": 0, "negative": 0} if clean else bad_pixel_counts(px)
        if counts["nan"] + counts["inf"]:  # the rare bad map: set its non-finite pixels aside (a copy)
            px = px[np.isfinite(px).all(axis=1)]
            low, high = _channel_min_max(px)
        integral = self.integral().tolist() if counts["nan"] + counts["inf"] == 0 else None
        image_h, image_w = file_shape(self)
        return {
            "width": image_w,
            "height": image_h,
            "layout": self.layout.name,
            "size": self.size,
            "valid_pixels": self.valid_pixels,
            "min": low.tolist() if len(px) else None,
            "max": high.tolist() if len(px) else None,
            "mean": None if integral is None else [v / (4 * math.pi) for v in integral],
            "integral": integral,
            "luminance_integral": None if integral is None else float(luminance(np.array(integral))),
            **{f"{k}_pixels": v for k, v in counts.items()},
        }

    # ---- transforms --------------------------------------------------------------------------------------------
    def to(self, layout: str | Layout, size: int | None = None, samples: int | None = None) -> EnvMap:
        """This map in another layout (footprint-aware resampling, see :func:`lightprobe.maps.resampling`)."""
        from .resampling.resampler import resample

        return resample(self, layout_named(layout), size, samples=samples)

    def rotated(self, rotation, samples: int | None = None) -> EnvMap:
        """The environment turned by ``rotation`` (3×3 matrix or (yaw, pitch, roll) degrees, see
        :func:`lightprobe.maps.frames.rotation_from_ypr`): light that came from d now comes from R·d. Same layout."""
        from .resampling.resampler import resample

        return resample(self, self.layout, self.size, rotation=as_rotation(rotation), samples=samples)

    def save(self, path: str | os.PathLike, **kwargs) -> Path:
        """Write to an image file (cube maps as a 6N × N strip); keyword arguments go to :func:`write_image`."""
        from .images import write_image
        from .files import to_image

        return write_image(path, to_image(self), **kwargs)


_BLOCK = 1 << 20  # values a block of the reductions below handles at once (8 MB as float64)


def _row_sums(data: np.ndarray) -> np.ndarray:
    """Σ over each row of an (H, W, 3) float32 array, in float64: blocks of rows cast and summed by a matrix product
    (numpy's ``sum(axis=1, dtype=float64)`` is ~8× slower: a strided, casting reduction)."""
    h, w, _ = data.shape
    out, ones = np.empty((h, 3)), np.ones(w)
    rows = max(1, _BLOCK // (3 * w))
    for top in range(0, h, rows):
        out[top:top + rows] = ones @ data[top:top + rows].astype(np.float64)
    return out


def _channel_min_max(px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel minimum and maximum of (N, 3) pixels: reduced over the long axis of a (blocks, 3·k) view first
    (``px.min(axis=0)`` reduces with a stride of 3 and is ~25× slower)."""
    if len(px) == 0:
        return np.zeros(3, np.float32), np.zeros(3, np.float32)
    k = 1 << 12
    whole = len(px) - len(px) % k
    view = px[:whole].reshape(-1, 3 * k)
    parts = [(view.min(axis=0).reshape(-1, 3), view.max(axis=0).reshape(-1, 3))] if whole else []
    if whole < len(px):
        parts.append((px[whole:], px[whole:]))
    low = np.concatenate([p[0] for p in parts]).min(axis=0)
    high = np.concatenate([p[1] for p in parts]).max(axis=0)
    return low, high


@lru_cache(maxsize=4)
def pixel_directions(lay: Layout, grid: tuple[int, ...]) -> np.ndarray:
    """Directions of a layout's pixel grid (float64, 24 B a pixel), computed once per grid like a renderer's lookup
    table, and only for work that needs them; read-only so that no caller can corrupt them for the next."""
    d = lay.directions(grid)
    d.setflags(write=False)
    return d


@lru_cache(maxsize=4)
def pixel_solid_angles(lay: Layout, grid: tuple[int, ...]) -> np.ndarray:
    """Solid angles of a layout's pixel grid (float64), cached and read-only like :func:`pixel_directions`."""
    omega = lay.solid_angles(grid)
    omega.setflags(write=False)
    return omega


def pixel_geometry(lay: Layout, grid: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(directions, solid angles) of a layout's pixel grid."""
    return pixel_directions(lay, grid), pixel_solid_angles(lay, grid)
