"""The BRDF lookup tables of :mod:`lightprobe.glossy.dfg` as each engine samples them, and their files.

What each engine reads (from its own shaders and loaders):

* **Filament** — one table, (u, v) = (n·v, roughness): red DFG1 = B, green DFG2 = A + B (height-correlated Smith),
  blue the Charlie sheen albedo with Neubelt's visibility (``cmgen --ibl-dfg-multiscatter --ibl-dfg-cloth``;
  the engine bakes its own 128 × 128 copy in, so this is for custom renderers on Filament's shading model).
* **Babylon.js** — ``scene.environmentBRDFTexture``, (u, v) = (n·v, roughness), the same three channels
  (``BRDF_V_HEIGHT_CORRELATED``: E = (F90 − F0)·x + F0·y; its own is a 256 × 256 RGBD PNG).
* **glTF** (the Khronos sample viewer's ``lutFiles``) — ``lut_ggx`` red A, green B (height-correlated);
  ``lut_charlie`` blue the sheen albedo with Neubelt's visibility; ``lut_sheen_E`` red the sheen albedo with
  Estevez & Kulla's visibility (KHR_materials_sheen's albedo scaling); all (u, v) = (n·v, roughness).
* **three.js** — its DFG table, (u, v) = (roughness, n·v): red A, green B (height-correlated), 16 × 16 as its
  ``DFGLUTData``; rows here are n·v (the transpose of the other engines').

Every array returned here is in file order: row 0 is the first row an engine uploads (texture coordinate v ≈ 0),
the top row of the image file, since these engines load LUT images without flipping them.

Files: ``.exr`` (float32, or half) through :func:`lightprobe.maps.images.write_image`, and 16-bit ``.png``.
Pillow writes no 16-bit RGB PNG, and OpenImageIO's PNG writer always adds a gAMA chunk (and sRGB/cHRM), which a
browser may honour by re-encoding the image on upload (WebGL's default colour-space conversion) — a lookup table
must reach the shader as stored — so the PNG is encoded here: IHDR, one IDAT (zlib), IEND, nothing else.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from ..glossy.dfg import DEFAULT_SAMPLES, multiscatter_lut, sheen_lut, split_sum_lut
from ..maps.images import write_image
from ..util.errors import InputError, UsageError
from ..util.files import write_bytes

# The size of each engine's own table, used when none is given.
ENGINE_SIZES = {"filament": 128, "babylon": 256, "gltf": 256, "three": 16}
LUT_FORMATS = (".exr", ".png")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def engine_luts(engine: str, size: int | None = None, samples: int = DEFAULT_SAMPLES) -> dict[str, np.ndarray]:
    """The lookup tables ``engine`` samples, by the file name (without extension) its loader expects.

    Parameters
    ----------
    engine : {"filament", "babylon", "gltf", "three"}
        The engine (see the module's list).
    size : int, optional
        N, texels along each axis; the engine's own size (:data:`ENGINE_SIZES`) when None.
    samples : int, default :data:`lightprobe.glossy.dfg.DEFAULT_SAMPLES`
        Hammersley points per texel.

    Returns
    -------
    dict of str to numpy.ndarray
        Name → (N, N, 3) float64 RGB in file order (row 0 first uploaded, the top of an image file); channels the
        engine does not read are 0. Filament and Babylon: ``{"dfg": …}`` / ``{"environment_brdf": …}``; glTF:
        ``lut_ggx``, ``lut_charlie``, ``lut_sheen_E``; three.js: ``{"dfg": …}`` with rows n·v.

    Raises
    ------
    lightprobe.util.errors.UsageError
        An unknown engine, or ``size`` or ``samples`` out of range.
    """
    if engine not in ENGINE_SIZES:
        raise UsageError(f"no DFG table for engine {engine!r}; known: {', '.join(ENGINE_SIZES)}")
    size = ENGINE_SIZES[engine] if size is None else size
    if engine in ("filament", "babylon"):
        name = "dfg" if engine == "filament" else "environment_brdf"
        return {name: multiscatter_lut(size, sheen=True, samples=samples)}
    ab = split_sum_lut(size, samples=samples)
    if engine == "three":
        return {"dfg": _rgb(ab).transpose(1, 0, 2).copy()}
    zero = np.zeros((size, size))
    return {"lut_ggx": _rgb(ab),
            "lut_charlie": np.stack([zero, zero, sheen_lut(size, "neubelt", samples)], axis=-1),
            "lut_sheen_E": _rgb(sheen_lut(size, "charlie", samples)[..., None])}


def _rgb(table: np.ndarray) -> np.ndarray:
    """(H, W, C ≤ 3) → (H, W, 3), the missing channels 0."""
    out = np.zeros(table.shape[:2] + (3,))
    out[..., :table.shape[2]] = table
    return out


def png16_bytes(rgb: np.ndarray) -> bytes:
    """A 16-bit RGB PNG of values in [0, 1] (clipped; v ↦ round(65535 v)), row 0 at the top, with no colour chunk.

    Parameters
    ----------
    rgb : numpy.ndarray
        (H, W, 3) finite values.

    Returns
    -------
    bytes
        The whole file: signature, IHDR (bit depth 16, colour type 2), one IDAT (every row filter 0), IEND.

    Raises
    ------
    lightprobe.util.errors.UsageError
        When ``rgb`` is not (H, W, 3) with at least one pixel, or holds a NaN or infinity.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.size == 0 or not np.isfinite(rgb).all():
        raise UsageError("a PNG table must be a finite (H, W, 3) array")
    height, width = rgb.shape[:2]
    words = np.round(np.clip(rgb, 0.0, 1.0) * 65535.0).astype(">u2").reshape(height, width * 3)
    rows = np.concatenate([np.zeros((height, 1), dtype=np.uint8), words.view(np.uint8)], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 16, 2, 0, 0, 0)
    return (PNG_SIGNATURE + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows.tobytes(), 9))
            + chunk(b"IEND", b""))


def write_lut(path: str | os.PathLike, table: np.ndarray, *, half: bool = False, inputs=()) -> Path:
    """Write a lookup table, row 0 at the top of the image, atomically (:mod:`lightprobe.util.files`).

    Parameters
    ----------
    path : str or os.PathLike
        ``.exr`` (float32, or half with ``half``) or ``.png`` (16 bits per channel, values clipped to [0, 1]).
    table : numpy.ndarray
        (H, W) or (H, W, C) with C ≤ 3, in file order (as :func:`engine_luts` gives); a one-channel table is
        written grey (R = G = B), two channels as red and green with blue 0.
    half : bool, default False
        Store an ``.exr`` as half floats.
    inputs : iterable of path, default ()
        Files this output must not overwrite.

    Returns
    -------
    pathlib.Path
        ``path``, written and checked.

    Raises
    ------
    lightprobe.util.errors.InputError
        An extension other than ``.exr`` or ``.png``, or a failed write (``path`` is then untouched).
    lightprobe.util.errors.UsageError
        A table of another shape, or holding a NaN or infinity.
    """
    path = Path(path)
    if path.suffix.lower() not in LUT_FORMATS:
        raise InputError(f"cannot write {path}: a lookup table is written as {' or '.join(LUT_FORMATS)}")
    table = np.asarray(table, dtype=np.float64)
    if table.ndim == 2:
        table = np.repeat(table[..., None], 3, axis=-1)
    if table.ndim != 3 or not 1 <= table.shape[2] <= 3 or table.size == 0 or not np.isfinite(table).all():
        raise UsageError(f"a lookup table must be finite (H, W) or (H, W, C ≤ 3), got shape {table.shape}")
    if table.shape[2] == 1:
        table = np.repeat(table, 3, axis=-1)
    rgb = _rgb(table)
    if path.suffix.lower() == ".png":
        return write_bytes(path, png16_bytes(rgb), inputs)
    return write_image(path, rgb.astype(np.float32), half=half, inputs=inputs)
