"""The :class:`EnvMap` type: an HDR environment map (linear RGB radiance) in one layout, world frame.

Conventions: ``data`` is float32 of shape ``grid + (3,)`` (see :mod:`lightprobe.layouts`); the numbers are
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

from ..errors import LayoutError
from ..frames import as_rotation
from ..layouts import Layout, layout as layout_named
from ..tonemap import luminance


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
        """Size, layout and statistics over valid pixels. ``mean`` is the solid-angle mean ∫L dω / 4π; values that
        cannot be computed (a map of NaN pixels) are None."""
        from .files import file_shape
        from .pixels import bad_pixel_counts

        valid = self.valid_mask()
        px = self.data[valid]
        finite = px[np.isfinite(px).all(axis=1)]
        counts = bad_pixel_counts(px)
        integral = self.integral().tolist() if counts["nan"] + counts["inf"] == 0 else None
        image_h, image_w = file_shape(self)
        return {
            "width": image_w,
            "height": image_h,
            "layout": self.layout.name,
            "size": self.size,
            "valid_pixels": int(valid.sum()),
            "min": finite.min(axis=0).tolist() if len(finite) else None,
            "max": finite.max(axis=0).tolist() if len(finite) else None,
            "mean": None if integral is None else [v / (4 * math.pi) for v in integral],
            "integral": integral,
            "luminance_integral": None if integral is None else float(luminance(np.array(integral))),
            **{f"{k}_pixels": v for k, v in counts.items()},
        }

    # ---- transforms --------------------------------------------------------------------------------------------
    def to(self, layout: str | Layout, size: int | None = None, samples: int | None = None) -> EnvMap:
        """This map in another layout (footprint-aware resampling, see :func:`lightprobe.envmap.resample`)."""
        from .resample import resample

        return resample(self, layout_named(layout), size, samples=samples)

    def rotated(self, rotation, samples: int | None = None) -> EnvMap:
        """The environment turned by ``rotation`` (3×3 matrix or (yaw, pitch, roll) degrees, see
        :func:`lightprobe.frames.rotation_from_ypr`): light that came from d now comes from R·d. Same layout."""
        from .resample import resample

        return resample(self, self.layout, self.size, rotation=as_rotation(rotation), samples=samples)

    def save(self, path: str | os.PathLike, **kwargs) -> Path:
        """Write to an image file (cube maps as a 6N × N strip); keyword arguments go to :func:`write_image`."""
        from ..io import write_image
        from .files import to_image

        return write_image(path, to_image(self), **kwargs)


@lru_cache(maxsize=4)
def pixel_geometry(lay: Layout, grid: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(directions, solid angles) of a layout's pixel grid, computed once per grid like a renderer's lookup
    tables; read-only so that no caller can corrupt them for the next."""
    d, omega = lay.directions(grid), lay.solid_angles(grid)
    d.setflags(write=False)
    omega.setflags(write=False)
    return d, omega
