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
    """An :class:`EnvMap` from a flat (H, W, 3) image; the layout is detected from the aspect ratio if not given.
    The image is copied unless it is read-only (see :class:`EnvMap`)."""
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
    """:func:`read_envmap` after checking, from the file's header alone, that reading it plus
    ``working_bytes_per_pixel`` per pixel plus ``extra_bytes`` fits the memory budget (with numba's own memory when
    the work runs compiled ``kernels``): what every command and every batch worker reads a probe with."""
    from .images import image_header
    from ..util.limits import check_memory

    header = image_header(path)
    check_memory(header.read_bytes() + header.pixels * working_bytes_per_pixel + extra_bytes,
                 what or f"{path} ({header.width}×{header.height} pixels)", kernels=kernels)
    return read_envmap(path, layout, fix=fix)

