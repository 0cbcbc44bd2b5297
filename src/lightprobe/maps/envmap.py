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
    """``a`` as float32 that nobody can write.

    ``a`` itself when it and every array it views are read-only, else a read-only copy.

    Parameters
    ----------
    a : numpy.ndarray
        Any array (or array-like); its values are taken as they are.

    Returns
    -------
    numpy.ndarray
        A read-only float32 array of the shape of ``a``: ``a`` itself when it is float32 and read-only all the way
        down, else a new read-only float32 copy.
    """
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
    """Mark a fresh array that no one else holds (and every array it views) read-only.

    :class:`EnvMap` then takes it without a copy. Only for arrays the calling code has just made.

    Parameters
    ----------
    a : numpy.ndarray
        An array the caller has just made and shares with no one; it and every array it views are set read-only
        in place.

    Returns
    -------
    numpy.ndarray
        ``a`` itself, now read-only.
    """
    owner = a
    while isinstance(owner, np.ndarray):
        owner.setflags(write=False)
        owner = owner.base
    return a


@dataclass(frozen=True, eq=False, repr=False)
class EnvMap:
    """Radiance from every direction, stored in ``layout``; ``data`` has shape ``layout grid + (3,)``, read-only.

    Parameters
    ----------
    data : numpy.ndarray
        Linear RGB radiance, shape ``grid + (3,)`` for a grid of ``layout`` (``(H, W)`` for the flat layouts,
        ``(6, N, N)`` for ``cube``), directions in the world frame (+Y up, front −Z). Kept as read-only float32:
        copied unless it is float32 and read-only all the way down (:func:`frozen_array`).
    layout : Layout
        The layout (:mod:`lightprobe.maps.layouts`) that maps the pixels to directions.

    Raises
    ------
    LayoutError
        When ``data`` is not RGB pixels (``(…, 3)`` with at least two grid axes) or its grid does not fit
        ``layout``.
    """

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
        """The pixel grid, ``data.shape[:-1]``: (H, W) for the flat layouts, (6, N, N) for ``cube``."""
        return self.data.shape[:-1]

    @property
    def size(self) -> int:
        """The layout's ``size`` of this map (height, or face edge for cube layouts)."""
        return self.layout.size_of(self.grid)

    def directions(self) -> np.ndarray:
        """World direction of every pixel centre, ``grid + (3,)`` (read-only; shared by maps of the same grid).

        Returns
        -------
        numpy.ndarray
            float64 unit vectors in the world frame (+Y up, front −Z), shape ``grid + (3,)``; zero for pixels
            that cover no part of the sphere. Cached per layout and grid (:func:`pixel_directions`).
        """
        return pixel_directions(self.layout, self.grid)

    def solid_angles(self) -> np.ndarray:
        """Exact solid angle of every pixel (sr), shape ``grid``; sums to 4π (read-only, shared).

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape ``grid``; 0 for pixels that cover no part of the sphere. Cached per layout
            and grid (:func:`pixel_solid_angles`).
        """
        return pixel_solid_angles(self.layout, self.grid)

    @property
    def all_valid(self) -> bool:
        """True when every pixel covers part of the sphere (latlong, cube): no mask is needed."""
        return self.layout.valid_fraction == 1.0

    def valid_mask(self) -> np.ndarray:
        """True for the pixels that cover part of the sphere (all true for latlong and cube).

        Returns
        -------
        numpy.ndarray
            bool, shape ``grid``: for latlong and cube a read-only broadcast of True (no per-pixel table), for the
            other layouts a new array, true where the pixel's solid angle is positive.
        """
        if self.all_valid:
            return np.broadcast_to(np.True_, self.grid)  # no per-pixel table for a mask that is all true
        return pixel_solid_angles(self.layout, self.grid) > 0

    @property
    def valid_pixels(self) -> int:
        """How many pixels cover part of the sphere: all of them for latlong and cube."""
        return math.prod(self.grid) if self.all_valid else int(self.valid_mask().sum())

    # ---- quantities --------------------------------------------------------------------------------------------
    def integral(self) -> np.ndarray:
        """∫L dω per channel (radiance × sr), with the exact per-pixel solid angles, summed in float64.

        A latlong map's pixels of one row share their solid angle: row sums times row solid angles, with no
        per-pixel table. Other layouts go in chunks of rows, so no float64 copy of the map is made.

        Returns
        -------
        numpy.ndarray
            float64 (3,): ∫L dω of R, G and B, in the radiance's unit × sr (NaN or ±inf if a pixel is).
        """
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
        """Radiance arriving from world directions ``d`` (..., 3), bilinear, seam- and pole-correct.

        Parameters
        ----------
        d : numpy.ndarray
            Unit direction vectors in the world frame (+Y up, front −Z), shape (..., 3).

        Returns
        -------
        numpy.ndarray
            float32 linear RGB radiance, shape (..., 3): the bilinear interpolation of the four nearest pixels,
            each weighted by its validity (a disc's rim pixel by its share of the sphere), renormalised.
        """
        return self.layout.sample(self.data, np.asarray(d, dtype=np.float64))

    def stats(self) -> dict:
        """Size, layout and statistics over valid pixels.

        ``mean`` is the solid-angle mean ∫L dω / 4π; values that cannot be computed (a map of NaN pixels) are None.

        Returns
        -------
        dict
            ``width``, ``height``: the image file's size in pixels (:func:`lightprobe.maps.files.file_shape`);
            ``layout``: its name; ``size``: :attr:`size`; ``valid_pixels``; ``min``, ``max``: per-channel [R, G, B]
            over the valid pixels whose channels are all finite (None when there are none); ``integral``: ∫L dω
            per channel (radiance × sr), ``mean``: ∫L dω / 4π per channel (radiance), ``luminance_integral``: the
            Rec. 709 luminance of the integral, these three None when any valid pixel has a NaN or infinite
            channel; ``nan_pixels``, ``inf_pixels``, ``negative_pixels``: counts of valid pixels with such a
            channel (:func:`lightprobe.maps.pixels.bad_pixel_counts`).
        """
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
        """This map in another layout (footprint-aware resampling, see :mod:`lightprobe.maps.resampling`).

        The conversion is :func:`lightprobe.maps.resampling.resampler.resample`: ∫L dω is kept, a uniform map stays
        uniform, and the directions stay in the world frame.

        Parameters
        ----------
        layout : str or Layout
            The target layout, by name (``latlong``, ``angular``, ``sphere``, ``cube``, ``cross``, ``hcross``) or
            as a :class:`~lightprobe.maps.layouts.Layout`.
        size : int or None, default None
            The target's size: image height for latlong, angular and sphere, face edge N for cube, cross and
            hcross. None (or 0): about as many valid pixels as this map.
        samples : int or None, default None
            Supersampling rate k (k×k lookups per target pixel); None: chosen automatically, with the box
            reduction of a much larger source, per-pixel rates and the flux correction, which a given k all skips.

        Returns
        -------
        EnvMap
            The new map in ``layout``.

        Raises
        ------
        LayoutError
            When ``layout`` names no layout.
        UsageError
            When ``size`` is negative or not a whole number.
        BudgetError
            When the target's pixels or the conversion's memory are over their limits.
        """
        from .resampling.resampler import resample

        return resample(self, layout_named(layout), size, samples=samples)

    def rotated(self, rotation, samples: int | None = None) -> EnvMap:
        """The environment turned by ``rotation``: light that came from d now comes from R·d. Same layout.

        ``rotation`` is a 3×3 matrix or (yaw, pitch, roll) degrees, see
        :func:`lightprobe.maps.frames.rotation_from_ypr`. The map is resampled at its own layout and size.

        Parameters
        ----------
        rotation : numpy.ndarray or tuple of float
            A 3×3 proper rotation matrix R in the world frame (+Y up, front −Z), or (yaw, pitch, roll) in degrees.
        samples : int or None, default None
            Supersampling rate k (k×k lookups per pixel); None: chosen automatically, as for :meth:`to`.

        Returns
        -------
        EnvMap
            The turned map, in this map's layout and size.

        Raises
        ------
        UsageError
            When ``rotation`` is not finite, a mirror, or neither a 3×3 matrix nor three angles.
        """
        from .resampling.resampler import resample

        return resample(self, self.layout, self.size, rotation=as_rotation(rotation), samples=samples)

    def save(self, path: str | os.PathLike, **kwargs) -> Path:
        """Write to an image file (cube maps as a 6N × N strip).

        Keyword arguments go to :func:`lightprobe.maps.images.write_image`.

        Parameters
        ----------
        path : str or os.PathLike
            The output file; its extension picks the format (``.exr``, ``.hdr``, ``.pfm``, or tone-mapped
            ``.png``/``.jpg``). Written atomically.
        **kwargs
            ``half``, ``exposure``, ``curve``, ``encoded``, ``inputs``: as
            :func:`lightprobe.maps.images.write_image` takes them.

        Returns
        -------
        pathlib.Path
            The path written.

        Raises
        ------
        InputError
            When the file cannot be written (unknown extension, a folder, an input of the command, a failed
            write or read-back).
        """
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
    """Directions of a layout's pixel grid (float64, 24 B a pixel), computed once per grid.

    Like a renderer's lookup table, and only for work that needs them; read-only so that no caller can corrupt them
    for the next. The last 4 grids are kept.

    Parameters
    ----------
    lay : Layout
        The layout.
    grid : tuple of int
        Its pixel grid ((H, W), or (6, N, N) for ``cube``); a tuple, as the cache's key.

    Returns
    -------
    numpy.ndarray
        Read-only float64 unit vectors in the world frame (+Y up, front −Z) of every pixel centre, shape
        ``grid + (3,)``; zero for pixels that cover no part of the sphere.
    """
    d = lay.directions(grid)
    d.setflags(write=False)
    return d


@lru_cache(maxsize=4)
def pixel_solid_angles(lay: Layout, grid: tuple[int, ...]) -> np.ndarray:
    """Solid angles of a layout's pixel grid (float64), cached and read-only like :func:`pixel_directions`.

    Parameters
    ----------
    lay : Layout
        The layout.
    grid : tuple of int
        Its pixel grid; a tuple, as the cache's key.

    Returns
    -------
    numpy.ndarray
        Read-only float64 exact solid angles in steradians, shape ``grid``, summing to 4π; 0 for pixels that cover
        no part of the sphere.
    """
    omega = lay.solid_angles(grid)
    omega.setflags(write=False)
    return omega


def pixel_geometry(lay: Layout, grid: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(directions, solid angles) of a layout's pixel grid.

    Parameters
    ----------
    lay : Layout
        The layout.
    grid : tuple of int
        Its pixel grid; a tuple.

    Returns
    -------
    directions : numpy.ndarray
        :func:`pixel_directions`: read-only float64 world-frame unit vectors, shape ``grid + (3,)``.
    solid_angles : numpy.ndarray
        :func:`pixel_solid_angles`: read-only float64 steradians, shape ``grid``.
    """
    return pixel_directions(lay, grid), pixel_solid_angles(lay, grid)
