"""Image files: read any HDR/LDR image as linear float32 RGB through OpenImageIO; write atomically and checked.

Reading (:func:`read_image`) returns the pixels exactly as stored (no repair of NaN or negative values; that is
:mod:`lightprobe.maps`'s job), as an (H, W, 3) float32 array, row 0 at the top:

* Radiance ``.hdr`` (run-length or flat), OpenEXR (half or float; the R, G, B channels by name), ``.pfm``
  (opened with an empty ``ImageSpec`` so OpenImageIO does not flip its bottom-up rows), and any 8/16-bit image such
  as ``.png`` or ``.jpg``, whose sRGB encoding is decoded to linear.
* One-channel images are repeated into grey RGB; alpha and other channels are dropped.
* Only regular files are opened (a FIFO or a device would block or never end). The header is checked before any
  pixel memory is allocated: the pixel limit and the memory budget of :mod:`lightprobe.util.limits` (a PNG of a few
  hundred kB can claim 16384×8192 pixels), and a file too short to hold what its header claims.
* What the image libraries print on stderr (libpng's warnings, libjpeg's errors) is captured, never shown: a
  failure becomes one line, a success stays silent.

Writing (:func:`write_image`) picks the format by extension: ``.exr`` (float32, or half with ``half=True``),
``.hdr``, ``.pfm`` through OpenImageIO, and ``.png``/``.jpg`` (tone-mapped with :func:`lightprobe.maps.tonemap.tonemap`)
encoded in memory by Pillow — libjpeg, under OpenImageIO, ends the whole process when a write fails. Every write goes
through :func:`lightprobe.util.files.atomic_path`: a temporary file, read back (HDR) or size-checked (LDR) before it is
renamed over the target.
"""

from __future__ import annotations

import contextlib
import hashlib
import io as _bytes_io
import os
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from ..util.errors import InputError, UsageError
from ..util.files import atomic_path, write_bytes
from ..util.limits import check_memory, check_pixels
from .tonemap import srgb_decode, to_uint8, tonemap

HDR_WRITE_FORMATS = (".exr", ".hdr", ".pfm")
LDR_WRITE_FORMATS = (".png", ".jpg", ".jpeg")
WRITE_FORMATS = HDR_WRITE_FORMATS + LDR_WRITE_FORMATS
HALF_MAX = 65504.0
# The most raw (decoded, as the header's pixel type) bytes that one byte of a file can hold, for formats where that is
# known exactly: Radiance RLE packs at most 127 equal bytes of a component into 2 (≤ 1/16 byte per float RGB pixel
# of 12 bytes), PFM is raw, PNG is deflate (at most 1032:1). A file shorter than its header's raw size divided by
# this cannot hold the pixels it claims, and is refused before the pixels are allocated. (EXR's PIZ and JPEG can
# compress flat images further, so they get no such check; the memory budget still applies.)
MAX_COMPRESSION = {".hdr": 192, ".pic": 192, ".rgbe": 192, ".pfm": 1, ".png": 1032}
READ_BYTES_PER_PIXEL_BASE = 12  # the float32 RGB result (decoded in strips); plus 4 bytes per channel for the
READ_STRIP_BYTES = 16 << 20  # strip decode and display decoding; and OpenImageIO's buffers for one strip


@contextlib.contextmanager
def captured_stderr():
    """Capture what C libraries write to file descriptor 2 during the block; yields a list that receives the text.

    Without a file descriptor 2 nothing is captured and the list stays empty.

    Yields
    ------
    list of str
        Empty during the block; on leaving it, receives the captured text (its first 64 KiB, decoded as UTF-8 with
        replacement characters) as one string.
    """
    captured: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no stderr at all: nothing to capture
        yield captured
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.append(sink.read(1 << 16).decode("utf-8", "replace"))


def _first_line(*texts: str) -> str:
    for text in texts:
        for line in (text or "").strip().splitlines():
            if line.strip():
                return line.strip()[:300]
    return ""


def _error_text(source=None) -> str:
    """The first line of OpenImageIO's pending error message (global, or of ``source``), or ''.

    The binding decodes messages as UTF-8, and a hostile file can put other bytes into them: that must not
    turn a clean refusal into a crash."""
    try:
        text = (source.geterror() if source is not None else oiio.geterror()) or ""
    except UnicodeDecodeError:
        return "the image library reported an error it could not spell (the file is probably corrupt)"
    return _first_line(text)


def check_regular_file(path: Path, what: str = "") -> None:
    """Refuse a missing path, a folder, or anything that is not a regular file (FIFO, device, socket).

    Parameters
    ----------
    path : pathlib.Path
        The path to check (links are followed).
    what : str, default ""
        What the file is for, put before the path in the message (``"probe"`` gives "cannot read probe PATH: …").

    Raises
    ------
    InputError
        When the path does not exist, cannot be examined, is a folder, or is not a regular file.
    """
    label = f"{what} {path}" if what else str(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(f"cannot read {label}: no such file") from None
    except OSError as e:
        raise InputError(f"cannot read {label}: {e.strerror}") from None
    if stat.S_ISDIR(mode):
        raise InputError(f"cannot read {label}: it is a folder, not a file")
    if not stat.S_ISREG(mode):
        raise InputError(f"cannot read {label}: it is not a regular file (a FIFO, device or socket)")


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header says about its pixels (:func:`image_header`).

    Parameters
    ----------
    width : int
        Width in pixels.
    height : int
        Height in pixels.
    channels : int
        Channels per pixel, as stored (alpha and others included).
    bytes_per_channel : int
        Bytes of one channel value as stored (1 for 8-bit, 2 for 16-bit or half, 4 for float).
    """

    width: int
    height: int
    channels: int
    bytes_per_channel: int

    @property
    def pixels(self) -> int:
        """width × height."""
        return self.width * self.height

    def read_bytes(self) -> int:
        """Estimated peak memory of reading the pixels as float32 RGB (the decode buffer and the result).

        Returns
        -------
        int
            Bytes: per pixel 12 (the float32 RGB result) plus 4 per stored channel, plus 16 MiB for OpenImageIO's
            buffers of one strip.
        """
        return self.pixels * (READ_BYTES_PER_PIXEL_BASE + 4 * self.channels) + READ_STRIP_BYTES


def _open(path: Path):
    check_regular_file(path)
    # An empty ImageSpec as configuration makes the PFM reader keep the file's row order meaning (see module doc).
    config = oiio.ImageSpec() if path.suffix.lower() == ".pfm" else None
    with captured_stderr() as said:
        inp = oiio.ImageInput.open(str(path), config) if config is not None else oiio.ImageInput.open(str(path))
    if inp is None:
        reason = _error_text() or _first_line(*said) or "not an image format OpenImageIO knows"
        raise InputError(f"cannot read {path}: {reason}")
    return inp


def _header(path: Path, spec) -> ImageHeader:
    w, h, c, depth = spec.width, spec.height, spec.nchannels, max(spec.depth, 1)
    if w < 1 or h < 1 or c < 1:
        raise InputError(f"cannot read {path}: the header gives an empty image ({w}×{h}, {c} channels)")
    if c > 64:
        raise InputError(f"refusing {path}: the header claims {c} channels")
    check_pixels(w * h * depth, f"{path} ({w}×{h}×{depth} pixels claimed by its header)")
    if depth > 1:
        raise InputError(f"cannot read {path}: volume images (depth {depth}) are not environment maps")
    header = ImageHeader(w, h, c, max(spec.format.size(), 1))
    raw = header.pixels * c * header.bytes_per_channel
    size = path.stat().st_size
    ratio = MAX_COMPRESSION.get(path.suffix.lower())
    if ratio is not None and size * ratio < raw:
        raise InputError(f"cannot read {path}: the header claims {w}×{h} pixels, more than a file of {size} bytes "
                         "can hold (truncated or corrupt)")
    return header


def image_header(path: str | os.PathLike) -> ImageHeader:
    """Size and channels of an image file from its header alone (checked as :func:`read_image` checks it).

    Parameters
    ----------
    path : str or os.PathLike
        The image file; only a regular file is opened.

    Returns
    -------
    ImageHeader
        Width, height, channels and bytes per channel as the header gives them.

    Raises
    ------
    InputError
        When the file is missing, not a regular file, not an image OpenImageIO reads, or its header gives an empty
        image, over 64 channels, a volume, or (``.hdr``, ``.pfm``, ``.png``) more pixels than a file of its size can
        hold.
    BudgetError
        When the header claims more pixels than the pixel limit.
    """
    path = Path(path)
    inp = _open(path)
    try:
        return _header(path, inp.spec())
    finally:
        inp.close()


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


def read_image(path: str | os.PathLike, working_bytes_per_pixel: int = 0) -> np.ndarray:
    """Read an image file as linear float32 RGB of shape (H, W, 3), row 0 at the top. See the module docstring.

    ``working_bytes_per_pixel``: memory the caller will need per pixel of this image beyond the read itself; the
    sum is checked against the memory budget before any pixel is decoded.

    Parameters
    ----------
    path : str or os.PathLike
        The image file: ``.hdr``, OpenEXR, ``.pfm``, or any 8/16-bit image OpenImageIO reads (``.png``, ``.jpg``,
        …).
    working_bytes_per_pixel : int, default 0
        Bytes per pixel the caller needs beyond the read, added to the read's own estimate
        (:meth:`ImageHeader.read_bytes`) in the memory check.

    Returns
    -------
    numpy.ndarray
        float32 (H, W, 3) linear RGB, row 0 at the top, values as stored (NaN and negative values kept); integer
        images decoded from sRGB to linear unless the file says it is linear.

    Raises
    ------
    InputError
        When the file cannot be opened as an image, its header is refused (see :func:`image_header`), or its pixel
        data cannot be decoded.
    BudgetError
        When the image is over the pixel limit or reading it would exceed the memory budget.
    """
    path = Path(path)
    inp = _open(path)
    try:
        spec = inp.spec()
        header = _header(path, spec)
        check_memory(header.read_bytes() + header.pixels * working_bytes_per_pixel,
                     f"{path} ({header.width}×{header.height} pixels)")
        channels = _rgb_channels(spec)
        with captured_stderr() as said:
            rgb = _read_rgb(inp, spec, channels)
            trouble = _error_text(inp) or _error_text()
        if rgb is None or trouble:  # some readers report damage yet hand back (partly zero) pixels: refuse them
            raise InputError(f"cannot read {path}: {trouble or _first_line(*said) or 'the pixel data is unreadable'}")
    finally:
        inp.close()
    return srgb_decode(rgb) if _is_display_encoded(spec) else rgb


_STRIP_BYTES = 2 << 20  # decoded bytes per strip of scanlines: OpenImageIO's own buffer stays this small


def _read_rgb(inp, spec, channels: list[int]) -> np.ndarray | None:
    """The R, G, B channels as one (H, W, 3) float32 array, decoded in strips of rows straight into it, so the peak
    is the array plus one strip (a whole-image read holds a second copy of the image while it converts)."""
    rgb = np.empty((spec.height, spec.width, 3), dtype=np.float32)
    for top, strip in _rgb_strips(inp, spec, channels):
        if strip is None:
            return None
        rgb[top:top + len(strip)] = strip
    return rgb


def _rgb_strips(inp, spec, channels: list[int]):
    """(top row, (n, W, 3) float32) strips of an open image, top to bottom; (top, None) where decoding fails."""
    direct = channels == [0, 1, 2]  # R, G, B first and in order (nearly every file): read just those
    nch = 3 if direct else spec.nchannels
    rows = -(-max(1, _STRIP_BYTES // max(1, spec.width * nch * 4)) // 32) * 32  # whole 16- and 32-line EXR blocks
    for top in range(0, spec.height, rows):
        bottom = min(top + rows, spec.height)
        strip = inp.read_scanlines(0, 0, top, bottom, 0, 0, nch, "float")
        if strip is None or inp.has_error:
            yield top, None
            return
        strip = np.asarray(strip, dtype=np.float32).reshape(bottom - top, spec.width, nch)
        yield top, strip if direct else strip[..., channels]


def _check_rgb(rgb) -> np.ndarray:
    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] < 1 or rgb.shape[1] < 1:
        raise UsageError(f"write_image expects an (H, W, 3) array, got shape {rgb.shape}")
    return rgb


def _encode_ldr(path: Path, display: np.ndarray) -> bytes:
    """8-bit sRGB PNG or JPEG bytes, encoded in memory (so a failing disk cannot end the process)."""
    from PIL import Image

    buffer = _bytes_io.BytesIO()
    image = Image.fromarray(to_uint8(display), "RGB")
    if path.suffix.lower() == ".png":
        image.save(buffer, "PNG", compress_level=6)
    else:
        image.save(buffer, "JPEG", quality=95)
    return buffer.getvalue()


def _digest(strip: np.ndarray, digest) -> None:
    """Add a strip of float32 pixels to a running hash (NaNs made one bit pattern: writers may change them). The
    strip's own buffer is hashed; a copy is made only to rewrite NaNs (three strip-sized temporaries each strip were
    a tenth of a 4k convert's peak)."""
    strip = np.ascontiguousarray(strip, dtype=np.float32)
    if np.isnan(strip).any():
        strip = np.where(np.isnan(strip), np.float32(np.nan), strip)
    digest.update(memoryview(strip).cast("B"))


def _read_back(path: Path, shape: tuple[int, int], expected, exact: bool):
    """A verifier for :func:`atomic_path`: the temporary file must decode to ``shape`` and, when ``exact``, to
    pixels whose hash is ``expected.digest()`` (read in strips: nothing the size of the image is held)."""
    def verify(tmp: Path) -> None:
        back = hashlib.blake2b(digest_size=16)
        try:
            inp = _open(tmp)
            try:
                spec = inp.spec()
                if (spec.height, spec.width) != shape:
                    raise InputError("wrong size")
                for _, strip in _rgb_strips(inp, spec, _rgb_channels(spec)):
                    if strip is None:
                        raise InputError("undecodable pixels")
                    _digest(strip, back)
            finally:
                inp.close()
        except InputError as e:
            raise InputError(f"cannot write {path}: the written file does not read back "
                             f"({str(e).split(': ', 1)[-1]})") from None
        if exact and back.digest() != expected.digest():
            raise InputError(f"cannot write {path}: the written file does not read back as written")
    return verify


def _array_strips(rgb: np.ndarray, rows: int):
    for top in range(0, rgb.shape[0], rows):
        yield top, rgb[top:top + rows]


def write_image_strips(path: str | os.PathLike, shape: tuple[int, int], strips, *, half: bool = False,
                       inputs=()) -> Path:
    """Write linear RGB to an HDR file (``.exr``, ``.hdr``, ``.pfm``) as it is computed.

    ``strips`` yields ``(top, rows)`` blocks of (n, W, 3) float32 rows, top to bottom, of an image of ``shape``
    (H, W). Memory is one strip. Atomic like :func:`write_image`: the file is read back (in strips) before it
    replaces ``path``, and a failure — including a strip that cannot be written, or values over the half range with
    ``half`` — leaves nothing behind.

    Parameters
    ----------
    path : str or os.PathLike
        The output file: ``.exr`` (zip-compressed), ``.hdr`` or ``.pfm``.
    shape : tuple of int
        (H, W) of the image, in pixels.
    strips : iterable of tuple
        ``(top, rows)`` pairs: ``rows`` an (n, W, 3) array of linear RGB (written as float32), ``top`` its first
        row; each strip must start where the previous one ended, and together they must cover all H rows.
    half : bool, default False
        Store ``.exr`` as half floats (other formats ignore it); values beyond ±65504 are refused.
    inputs : iterable of path, default ()
        As for :func:`write_image`: the command's inputs, which ``path`` may not be.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path, once the checked file has replaced it.

    Raises
    ------
    InputError
        When the extension is not ``.exr``, ``.hdr`` or ``.pfm``, the target cannot be written (a folder, an input,
        a missing folder), the write fails, a value exceeds the half range, or the written file does not read back
        as written (in size, and to the bit except for ``.hdr``).
    UsageError
        When a strip is not (n, W, 3), does not continue the image, or the strips end before its last row.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in HDR_WRITE_FORMATS:
        raise InputError(f"cannot write {path}: streamed writing needs {', '.join(HDR_WRITE_FORMATS)}")
    h, w = shape
    pixel_type = "half" if half and ext == ".exr" else "float"
    spec = oiio.ImageSpec(w, h, 3, pixel_type)
    if ext == ".exr":
        spec.attribute("compression", "zip")
    expected = hashlib.blake2b(digest_size=16)
    with atomic_path(path, inputs, verify=_read_back(path, (h, w), expected, exact=ext != ".hdr")) as tmp:
        with captured_stderr() as said:
            out = oiio.ImageOutput.create(str(tmp))
            if out is None or not out.open(str(tmp), spec):
                reason = _error_text(out) if out is not None else ""
                raise InputError(f"cannot write {path}: {reason or _error_text() or 'OpenImageIO refused it'}")
            ok, written = True, 0
            try:
                for top, rows in strips:
                    rows = _check_rgb(rows)
                    if top != written or rows.shape[1] != w or top + len(rows) > h:
                        raise UsageError(f"write_image_strips: strip at row {top} does not continue a {w}×{h} image")
                    if pixel_type == "half":
                        _check_half(path, rows)
                        rows = rows.astype(np.float16).astype(np.float32)
                    rows = np.ascontiguousarray(rows)
                    ok = out.write_scanlines(top, top + len(rows), 0, rows)
                    if not ok:
                        break
                    _digest(rows, expected)
                    written += len(rows)
                err = _error_text(out)
            finally:
                closed = out.close()
        if ok and written != h:
            raise UsageError(f"write_image_strips: {written} of {h} rows were given")
        if not ok or not closed:  # OpenImageIO's message names the temporary file: name the target instead
            reason = (err or _first_line(*said) or "write failed").replace(str(tmp), str(path))
            raise InputError(f"cannot write {path}: {reason}")
    return path


def _check_half(path: Path, rgb: np.ndarray) -> None:
    if np.nanmax(np.abs(rgb), initial=0.0) > HALF_MAX:
        raise InputError(
            f"cannot write {path} as half floats: values up to {np.nanmax(rgb):.6g} exceed the half range "
            f"({HALF_MAX:g}) and would become infinite; write float32 instead"
        )


def write_image(
    path: str | os.PathLike,
    rgb: np.ndarray,
    *,
    half: bool = False,
    exposure: float = 0.0,
    curve: str = "srgb",
    encoded: bool = False,
    inputs=(),
) -> Path:
    """Write linear RGB (H, W, 3) to ``path``; the extension picks the format (see the module docstring).

    HDR formats store the values as given (``exposure``/``curve`` apply only to ``.png``/``.jpg``; ``encoded``
    says the values are display-encoded already, to be written to 8 bits as they are). ``inputs``: files this
    output must not overwrite. Returns the path.

    Parameters
    ----------
    path : str or os.PathLike
        The output file; its extension picks the format: ``.exr`` (float32, or half), ``.hdr``, ``.pfm``,
        ``.png``, ``.jpg``/``.jpeg``.
    rgb : numpy.ndarray
        Linear RGB radiance (H, W, 3), row 0 at the top (written as float32); display-encoded values in [0, 1]
        with ``encoded``.
    half : bool, default False
        Store ``.exr`` as half floats; values beyond ±65504 are refused.
    exposure : float, default 0.0
        Exposure in stops for ``.png``/``.jpg`` (see :func:`lightprobe.maps.tonemap.tonemap`); ignored for HDR
        formats.
    curve : str, default "srgb"
        Tone curve for ``.png``/``.jpg``: ``"srgb"`` or ``"aces"``; ignored for HDR formats.
    encoded : bool, default False
        For ``.png``/``.jpg``: the values are display-encoded already and are written to 8 bits as they are
        (clipped to [0, 1], NaN as 0), without ``exposure`` or ``curve``.
    inputs : iterable of path, default ()
        Files this output must not overwrite (the command's inputs).

    Returns
    -------
    pathlib.Path
        ``path``, written.

    Raises
    ------
    InputError
        When the extension is not a format it writes, the target cannot be written (a folder, an input, a missing
        folder), the write fails, or the written file does not read back (HDR) or has not its full size (LDR).
    UsageError
        When ``rgb`` is not an (H, W, 3) array with at least one pixel, or (LDR) ``curve`` or ``exposure`` is out of
        its range.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in WRITE_FORMATS:
        raise InputError(f"cannot write {path}: unknown image format {ext or '(none)'}; use one of "
                         f"{', '.join(WRITE_FORMATS)}")
    rgb = _check_rgb(rgb)
    if ext in LDR_WRITE_FORMATS:
        display = np.clip(np.nan_to_num(rgb), 0, 1) if encoded else tonemap(rgb, exposure, curve)
        return write_bytes(path, _encode_ldr(path, display), inputs)
    rows = max(1, _STRIP_BYTES // max(1, 12 * rgb.shape[1]))
    return write_image_strips(path, rgb.shape[:2], _array_strips(rgb, rows), half=half, inputs=inputs)
    return path
