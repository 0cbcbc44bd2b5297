"""Image files through OpenImageIO: read any HDR/LDR image as linear float32 RGB, write atomically.

Reading (:func:`read_image`) returns the pixels exactly as stored (no repair of NaN or negative values; that is
:mod:`lightprobe.envmap`'s job), as an (H, W, 3) float32 array, row 0 at the top:

* Radiance ``.hdr`` (run-length or flat), OpenEXR (half or float; the R, G, B channels by name), ``.pfm``
  (opened with an empty ``ImageSpec`` so OpenImageIO does not flip its bottom-up rows), and any 8/16-bit image such
  as ``.png`` or ``.jpg``, whose sRGB encoding is decoded to linear.
* One-channel images are repeated into grey RGB; alpha and other channels are dropped.
* Headers claiming more than :data:`MAX_PIXELS` pixels (override with ``LIGHTPROBE_MAX_PIXELS``) are refused before
  any pixel memory is allocated.

Writing (:func:`write_image`) picks the format by extension: ``.exr`` (float32, or half with ``half=True``),
``.hdr``, ``.pfm``, and ``.png``/``.jpg`` (tone-mapped with :func:`lightprobe.tonemap.tonemap`). Every write goes to a
temporary file in the target folder first and is renamed over the target only when complete.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .errors import InputError
from .tonemap import srgb_decode, to_uint8, tonemap

MAX_PIXELS = int(os.environ.get("LIGHTPROBE_MAX_PIXELS", 16384 * 8192))
HDR_WRITE_FORMATS = (".exr", ".hdr", ".pfm")
LDR_WRITE_FORMATS = (".png", ".jpg", ".jpeg")
WRITE_FORMATS = HDR_WRITE_FORMATS + LDR_WRITE_FORMATS


def _error_text(source=None) -> str:
    """The first line of OpenImageIO's pending error message (global, or of ``source``), or ''.

    The binding decodes messages as UTF-8, and a hostile file can put other bytes into them: that must not
    turn a clean refusal into a crash."""
    try:
        text = (source.geterror() if source is not None else oiio.geterror()) or ""
    except UnicodeDecodeError:
        return "the image library reported an error it could not spell (the file is probably corrupt)"
    lines = text.strip().splitlines()
    return lines[0] if lines else ""


def _open(path: Path):
    if not path.exists():
        raise InputError(f"cannot read {path}: no such file")
    if path.is_dir():
        raise InputError(f"cannot read {path}: it is a folder, not an image")
    # An empty ImageSpec as configuration makes the PFM reader keep the file's row order meaning (see module doc).
    config = oiio.ImageSpec() if path.suffix.lower() == ".pfm" else None
    inp = oiio.ImageInput.open(str(path), config) if config is not None else oiio.ImageInput.open(str(path))
    if inp is None:
        raise InputError(f"cannot read {path}: {_error_text() or 'not an image format OpenImageIO knows'}")
    return inp


def _check_spec(path: Path, spec) -> None:
    w, h, c, depth = spec.width, spec.height, spec.nchannels, max(spec.depth, 1)
    if w < 1 or h < 1 or c < 1:
        raise InputError(f"cannot read {path}: the header gives an empty image ({w}×{h}, {c} channels)")
    if w * h * depth > MAX_PIXELS or c > 64:
        raise InputError(
            f"refusing {path}: the header claims {w}×{h}×{depth} pixels with {c} channels, over the limit of "
            f"{MAX_PIXELS} pixels (set LIGHTPROBE_MAX_PIXELS to raise it)"
        )
    if depth > 1:
        raise InputError(f"cannot read {path}: volume images (depth {depth}) are not environment maps")


def _rgb_channels(spec) -> list[int]:
    names = [spec.channelnames[i] if i < len(spec.channelnames) else "" for i in range(spec.nchannels)]
    upper = [n.split(".")[-1].upper() for n in names]
    if all(k in upper for k in "RGB"):
        return [upper.index(k) for k in "RGB"]
    if spec.nchannels >= 3:
        return [0, 1, 2]
    return [0, 0, 0]  # grey (with or without alpha): repeat the first channel


def _is_display_encoded(spec) -> bool:
    """Integer pixels (PNG, JPEG, 8/16-bit TIFF …) hold sRGB-encoded values unless the file says linear."""
    if spec.format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE):
        return False
    colorspace = str(spec.get_string_attribute("oiio:ColorSpace", "")).lower()
    return not ("linear" in colorspace or colorspace.startswith("lin_"))


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as linear float32 RGB of shape (H, W, 3), row 0 at the top. See the module docstring."""
    path = Path(path)
    inp = _open(path)
    try:
        spec = inp.spec()
        _check_spec(path, spec)
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        trouble = _error_text(inp) or _error_text()
        if pixels is None or trouble:  # some readers report damage yet hand back (partly zero) pixels: refuse them
            raise InputError(f"cannot read {path}: {trouble or 'the pixel data is unreadable'}")
    finally:
        inp.close()
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    rgb = np.ascontiguousarray(pixels[..., _rgb_channels(spec)])
    return srgb_decode(rgb) if _is_display_encoded(spec) else rgb


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path`` (same extension); rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: folder {folder} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=folder)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files; give the result the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


HALF_MAX = 65504.0


def write_image(
    path: str | os.PathLike,
    rgb: np.ndarray,
    *,
    half: bool = False,
    exposure: float = 0.0,
    curve: str = "srgb",
    encoded: bool = False,
) -> Path:
    """Write linear RGB (H, W, 3) to ``path``; the extension picks the format (see the module docstring).

    HDR formats store the values as given (``exposure``/``curve`` apply only to ``.png``/``.jpg``; ``encoded``
    says the values are display-encoded already, to be written to 8 bits as they are). Returns the path.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in WRITE_FORMATS:
        raise InputError(f"cannot write {path}: unknown image format {ext or '(none)'}; use one of {WRITE_FORMATS}")
    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_image expects an (H, W, 3) array, got {rgb.shape}")
    h, w = rgb.shape[:2]
    if half and ext == ".exr" and np.nanmax(np.abs(rgb), initial=0.0) > HALF_MAX:
        raise InputError(
            f"cannot write {path} as half floats: values up to {np.nanmax(rgb):.6g} exceed the half range "
            f"({HALF_MAX:g}) and would become infinite; write float32 instead"
        )
    if ext in LDR_WRITE_FORMATS:
        display = np.clip(np.nan_to_num(rgb), 0, 1) if encoded else tonemap(rgb, exposure, curve)
        pixels, pixel_type = to_uint8(display), "uint8"
    else:
        pixels, pixel_type = np.ascontiguousarray(rgb), ("half" if half and ext == ".exr" else "float")
    spec = oiio.ImageSpec(w, h, 3, pixel_type)
    if ext == ".exr":
        spec.attribute("compression", "zip")
    if ext in LDR_WRITE_FORMATS:
        spec.attribute("oiio:ColorSpace", "sRGB")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise InputError(f"cannot write {path}: {_error_text(out) or _error_text() or 'OpenImageIO refused it'}")
        ok = out.write_image(pixels)
        err = _error_text(out)
        out.close()
        if not ok:
            raise InputError(f"cannot write {path}: {err or 'write failed'}")
    return path
