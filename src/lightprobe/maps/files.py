"""Environment maps in image files: the flat image of each layout (cube maps as a 6N × N strip) and reading."""

from __future__ import annotations

import os

import numpy as np

from ..util.errors import LayoutError
from .images import read_image
from .layouts import Layout, detect_layout, layout as layout_named
from .envmap import EnvMap, owned
from .pixels import repair


def file_shape(env: EnvMap) -> tuple[int, int]:
    """(height, width) of the image file that holds ``env``.

    Parameters
    ----------
    env : EnvMap
        The map, in any layout; only its layout and grid are read (no pixel).

    Returns
    -------
    tuple[int, int]
        (height, width) in pixels: a cube's (N, 6N) strip of its faces side by side, for the flat layouts their
        grid (H, W).
    """
    if env.layout.faces == 6:
        return env.grid[1], 6 * env.grid[2]
    return env.grid[0], env.grid[1]


def to_image(env: EnvMap) -> np.ndarray:
    """The flat (H, W, 3) image of a map: cube faces side by side (+X, −X, +Y, −Y, +Z, −Z), others as they are.

    Parameters
    ----------
    env : EnvMap
        The map whose pixels are laid out as its file holds them.

    Returns
    -------
    numpy.ndarray
        float32 linear RGB radiance of shape :func:`file_shape` ``+ (3,)``, row 0 at the top: for a cube a new
        (N, 6N, 3) array, for the flat layouts ``env.data`` itself (read-only).
    """
    if env.layout.faces == 6:
        n = env.grid[1]
        return env.data.transpose(1, 0, 2, 3).reshape(n, 6 * n, 3)
    return env.data


def from_image(image: np.ndarray, layout: str | Layout | None = None) -> EnvMap:
    """An :class:`EnvMap` from a flat (H, W, 3) image; the layout is detected from the aspect ratio if not given.

    The image is copied unless it is read-only (see :class:`EnvMap`).

    Parameters
    ----------
    image : numpy.ndarray
        Linear RGB radiance of shape (H, W, 3), row 0 at the top; a cube as its 6N × N strip of faces side by side
        (+X, −X, +Y, −Y, +Z, −Z).
    layout : str or Layout or None, default None
        The layout (a name such as ``"latlong"``, or a :class:`~lightprobe.maps.layouts.Layout`); None: detected
        from the aspect ratio by :func:`~lightprobe.maps.layouts.detect_layout` (2:1 latlong, 1:1 angular, 3:4
        cross, 4:3 hcross, 6:1 cube; a mirror ball must be named).

    Returns
    -------
    EnvMap
        The map in that layout (a cube's faces as its (6, N, N) grid).

    Raises
    ------
    LayoutError
        When the layout name is unknown, the aspect ratio names no layout, or the image does not fit the layout.
    """
    h, w = image.shape[:2]
    lay = detect_layout(w, h) if layout is None else layout_named(layout)
    if lay.faces == 6:
        if w != 6 * h:
            raise LayoutError(f"a {w}×{h} image does not fit the cube layout (a 6:1 strip of faces)")
        return EnvMap(image.reshape(h, 6, h, 3).transpose(1, 0, 2, 3), lay)
    lay.check_grid((h, w))
    return EnvMap(image, lay)


def read_envmap(path: str | os.PathLike, layout: str | Layout | None = None, *, fix: bool = True,
                working_bytes_per_pixel: int = 0) -> EnvMap:
    """Read an environment map file. ``layout`` None: detected from the aspect ratio.

    With ``fix`` (the default) NaN, infinite and negative values are replaced by 0 with a
    :class:`LightprobeWarning` saying how many pixels; with ``fix=False`` they are kept (as ``info`` needs).
    ``working_bytes_per_pixel``: memory the caller needs per pixel beyond reading, checked with the read's own
    estimate against the memory budget before any pixel is decoded.

    Parameters
    ----------
    path : str or os.PathLike
        The image file (any format :func:`~lightprobe.maps.images.read_image` reads: ``.hdr``, ``.exr``, ``.pfm``,
        8/16-bit images decoded from sRGB to linear); a cube as its 6N × N strip.
    layout : str or Layout or None, default None
        The layout of the file's image (name or :class:`~lightprobe.maps.layouts.Layout`); None: detected from the
        aspect ratio (see :func:`from_image`).
    fix : bool, default True
        Replace NaN, infinite and negative values by 0 (with one warning); False keeps the pixels as stored.
    working_bytes_per_pixel : int, default 0
        Bytes per pixel the caller needs beyond the read, counted in the memory check before decoding.

    Returns
    -------
    EnvMap
        The map (linear RGB radiance, world frame), holding the decoded pixels without a further copy.

    Raises
    ------
    InputError
        When the file cannot be read (missing, not a regular file, not an image, truncated or corrupt).
    LayoutError
        When the image does not fit the stated or detected layout; the message names the file.
    BudgetError
        When the image is over the pixel limit or reading it would exceed the memory budget.
    """
    image = read_image(path, working_bytes_per_pixel)
    if fix:
        image = repair(image, str(path))
    try:
        return from_image(owned(image), layout)  # a fresh array of ours: the map takes it without a copy
    except LayoutError as e:
        raise LayoutError(f"{path}: {e}") from None


def read_envmap_within_budget(path: str | os.PathLike, layout: str | Layout | None = None, *, fix: bool = True,
                              working_bytes_per_pixel: int = 0, extra_bytes: int = 0, what: str = "",
                              kernels: bool = False) -> EnvMap:
    """:func:`read_envmap` after checking, from the file's header alone, that the work fits the memory budget.

    Reading the file plus ``working_bytes_per_pixel`` per pixel plus ``extra_bytes`` must fit the memory budget
    (with numba's own memory when the work runs compiled ``kernels``): what every command and every batch worker
    reads a probe with.

    Parameters
    ----------
    path : str or os.PathLike
        The image file, as for :func:`read_envmap`.
    layout : str or Layout or None, default None
        The layout of the file's image; None: detected from the aspect ratio.
    fix : bool, default True
        Replace NaN, infinite and negative values by 0 (with one warning), as for :func:`read_envmap`.
    working_bytes_per_pixel : int, default 0
        Bytes per pixel of the image the work needs beyond reading it.
    extra_bytes : int, default 0
        Bytes the work needs whatever the image's size.
    what : str, default ""
        How a refusal names the work; empty: the path and the image's width × height.
    kernels : bool, default False
        The work runs compiled (numba) kernels: their memory counts too.

    Returns
    -------
    EnvMap
        The map, as :func:`read_envmap` returns it.

    Raises
    ------
    BudgetError
        When the estimate is over the memory budget (before any pixel is decoded).
    InputError
        When the file cannot be read.
    LayoutError
        When the image does not fit the stated or detected layout.
    """
    from .images import image_header
    from ..util.limits import check_memory

    header = image_header(path)
    check_memory(header.read_bytes() + header.pixels * working_bytes_per_pixel + extra_bytes,
                 what or f"{path} ({header.width}×{header.height} pixels)", kernels=kernels)
    return read_envmap(path, layout, fix=fix)

