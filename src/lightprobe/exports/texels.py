"""What the KTX containers share: the mip chain a caller hands in (checked once), and bounded reading of a file.

A texture is a list of levels, ``levels[0]`` the base: a 2D texture's level is an (h, w, C) array, a cube map's a
(6, n, n, C) array with the faces in the order Vulkan, OpenGL and both KTX versions fix (+X, −X, +Y, −Y, +Z, −Z),
each face's rows first to last as the file stores them (KTX: the first row is the top of the face image, the
``rd`` orientation). Level i is ⌊base/2^i⌋ texels across (at least 1), and a chain has at most ⌊log₂ base⌋ + 1
levels.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..util.errors import InputError, UsageError, short

MAX_SIZE = 16384  # texels across a level 0 (the largest 2D/cube size GPUs guarantee is smaller still)
MAX_FILE_BYTES = 1 << 31  # the most a KTX file read here may hold (a 16k cube of RGBA32F is 6 GiB: never baked)
FACES = 6


@dataclass(frozen=True)
class Chain:
    """A checked mip chain: ``levels`` (each (faces, h, w, C), faces 1 or 6), base ``width`` × ``height``."""

    levels: tuple[np.ndarray, ...]
    width: int
    height: int
    faces: int


def level_shape(width: int, height: int, level: int) -> tuple[int, int]:
    """(h, w) of mip ``level`` of a ``width`` × ``height`` base: each halved and floored, at least 1.

    Parameters
    ----------
    width, height : int
        Level 0's size in texels.
    level : int
        The mip level, 0 the base.

    Returns
    -------
    tuple of int
        (height, width) of that level.
    """
    return max(1, height >> level), max(1, width >> level)


def max_levels(width: int, height: int) -> int:
    """⌊log₂ max(width, height)⌋ + 1: the most levels a chain of that base has.

    Parameters
    ----------
    width, height : int
        Level 0's size in texels (≥ 1).

    Returns
    -------
    int
        The full chain's length.
    """
    return max(width, height).bit_length()


def check_chain(levels, channels: tuple[int, ...], what: str) -> Chain:
    """Check a mip chain as the writers take it (see the module docstring) and give it one shape.

    Parameters
    ----------
    levels : sequence of array_like
        ``levels[0]`` the base; each (h, w, C) for a 2D texture or (6, n, n, C) for a cube map, all of one kind.
    channels : tuple of int
        The channel counts C accepted.
    what : str
        The format's name, for messages.

    Returns
    -------
    Chain
        The levels as (faces, h, w, C) arrays (views, not copies), the base size and the face count.

    Raises
    ------
    UsageError
        No levels, more than a full chain, a level of the wrong size or channel count, a cube level that is not 6
        square faces, a base larger than :data:`MAX_SIZE`, or levels of mixed kinds.
    """
    if isinstance(levels, np.ndarray) or not hasattr(levels, "__len__") or len(levels) == 0:
        raise UsageError(f"{what}: levels must be a non-empty list of arrays, level 0 first")
    arrays = [np.asarray(a) for a in levels]
    ndim = arrays[0].ndim
    if ndim not in (3, 4) or any(a.ndim != ndim for a in arrays):
        raise UsageError(f"{what}: each level must be (h, w, C) for a 2D texture or (6, n, n, C) for a cube map, "
                         f"all alike; got shapes {short([a.shape for a in arrays])}")
    shaped = [a[None] if ndim == 3 else a for a in arrays]
    faces, height, width = shaped[0].shape[:3]
    if ndim == 4 and (faces != FACES or height != width):
        raise UsageError(f"{what}: a cube map level is 6 square faces (6, n, n, C), not {shaped[0].shape}")
    if not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise UsageError(f"{what}: level 0 is {width} × {height}; 1..{MAX_SIZE} texels across are accepted")
    if len(shaped) > max_levels(width, height):
        raise UsageError(f"{what}: {len(shaped)} levels for a {width} × {height} base, at most "
                         f"{max_levels(width, height)}")
    for i, a in enumerate(shaped):
        want = (faces, *level_shape(width, height, i))
        if a.shape[:3] != want or a.shape[3] not in channels:
            raise UsageError(f"{what}: level {i} must be {_shape_text(want, ndim)} with {' or '.join(map(str, channels))}"
                             f" channels, not {arrays[i].shape}")
    return Chain(tuple(shaped), width, height, faces)


def _shape_text(want: tuple[int, int, int], ndim: int) -> str:
    return f"({want[1]}, {want[2]}, C)" if ndim == 3 else f"(6, {want[1]}, {want[2]}, C)"


def source_bytes(source, what: str) -> tuple[bytes, str]:
    """The bytes of a KTX file given as a path or as bytes, and its name for messages.

    Parameters
    ----------
    source : str, path-like, bytes, bytearray or memoryview
        A file (at most :data:`MAX_FILE_BYTES`) or its contents.
    what : str
        The container ("KTX2", "KTX1"), for messages.

    Returns
    -------
    tuple
        (the bytes, a label such as ``"KTX2 file probe.ktx2"`` or ``"KTX2 data"``).

    Raises
    ------
    InputError
        The file cannot be read.
    BudgetError
        The file is larger than :data:`MAX_FILE_BYTES`.
    UsageError
        ``source`` is neither a path nor bytes.
    """
    if isinstance(source, (bytes, bytearray, memoryview)):
        return bytes(source), f"{what} data"
    if isinstance(source, (str, os.PathLike)):
        from ..util.files import read_bounded

        return read_bounded(source, MAX_FILE_BYTES, f"{what} file"), f"{what} file {Path(source).name}"
    raise UsageError(f"a {what} source is a path or bytes, not {type(source).__name__}")


class Cursor:
    """Little-endian reads from a byte string that never pass its end: a short read raises InputError."""

    def __init__(self, data: bytes, label: str):
        self.data, self.label = data, label

    def fail(self, message: str) -> InputError:
        """The error for a malformed file.

        Parameters
        ----------
        message : str
            What is wrong, one line.

        Returns
        -------
        InputError
            ``"<label> is not valid: <message>"``, for the caller to raise.
        """
        return InputError(f"{self.label} is not valid: {message}")

    def span(self, offset: int, length: int, what: str) -> bytes:
        """``length`` bytes at ``offset``.

        Parameters
        ----------
        offset, length : int
            Where and how many.
        what : str
            What they are, for the message.

        Returns
        -------
        bytes
            The bytes.

        Raises
        ------
        InputError
            They are not all in the data.
        """
        if offset < 0 or length < 0 or offset + length > len(self.data):
            raise self.fail(f"{what} (bytes {offset}..{offset + length}) passes the end of the {len(self.data)} bytes")
        return self.data[offset:offset + length]

    def words(self, offset: int, fmt: str, what: str) -> tuple:
        """``struct.unpack('<' + fmt)`` at ``offset``, bounds checked.

        Parameters
        ----------
        offset : int
            Where.
        fmt : str
            A :mod:`struct` format without its byte-order prefix.
        what : str
            What the fields are, for the message.

        Returns
        -------
        tuple
            The values.

        Raises
        ------
        InputError
            They pass the end of the data.
        """
        return struct.unpack("<" + fmt, self.span(offset, struct.calcsize("<" + fmt), what))


def check_size(cur: Cursor, width: int, height: int, faces: int, levels: int) -> None:
    """Refuse a header whose texture is not one lightprobe reads: 1 or 6 faces, 1..MAX_SIZE across, square cube
    faces, 1..a full chain of levels.

    Parameters
    ----------
    cur : Cursor
        The file (for the message).
    width, height, faces, levels : int
        The header's values.

    Raises
    ------
    InputError
        Any of them out of range.
    """
    if faces not in (1, FACES) or not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise cur.fail(f"{faces} face(s) of {width} × {height} texels (1 or 6 faces, 1..{MAX_SIZE} across)")
    if faces == FACES and width != height:
        raise cur.fail(f"a cube map of {width} × {height} faces (they must be square)")
    if not 1 <= levels <= max_levels(width, height):
        raise cur.fail(f"{levels} mip levels for a {width} × {height} base")


def finite_values(level, what: str) -> np.ndarray:
    """A level as float64, refused with one line when any value is NaN.

    Parameters
    ----------
    level : array_like
        Texel values.
    what : str
        The format's name, for the message.

    Returns
    -------
    numpy.ndarray
        ``level`` as float64 (±∞ kept: each format clamps it).

    Raises
    ------
    UsageError
        A value is NaN.
    """
    values = np.asarray(level, dtype=np.float64)
    nan = int(np.isnan(values).sum())
    if nan:
        raise UsageError(f"{what} cannot hold NaN: {nan} value(s) of a level are NaN")
    return values


def with_alpha(values: np.ndarray, opaque) -> np.ndarray:
    """(..., 3) values with a fourth channel ``opaque`` (1 for floats, 255 for bytes); (..., 4) as they are.

    Parameters
    ----------
    values : numpy.ndarray
        (..., 3) or (..., 4).
    opaque : int or float
        The alpha to add.

    Returns
    -------
    numpy.ndarray
        (..., 4) of ``values``' dtype.
    """
    if values.shape[-1] == 4:
        return values
    return np.concatenate([values, np.full(values.shape[:-1] + (1,), opaque, values.dtype)], axis=-1)


def key_value_entry(key: str, value: bytes) -> bytes:
    """One key/value entry as both KTX versions store it: uint32 byte count, key, NUL, value, zeros to 4 bytes.

    Parameters
    ----------
    key : str
        The key (UTF-8, no NUL).
    value : bytes
        The value as stored.

    Returns
    -------
    bytes
        The entry with its padding.
    """
    body = key.encode("utf-8") + b"\0" + value
    return struct.pack("<I", len(body)) + body + b"\0" * padding(len(body), 4)


def padding(length: int, alignment: int) -> int:
    """Bytes to add after ``length`` to reach a multiple of ``alignment``.

    Parameters
    ----------
    length : int
        Bytes so far (≥ 0).
    alignment : int
        The alignment (≥ 1).

    Returns
    -------
    int
        0 ≤ padding < alignment.
    """
    return -length % alignment


def read_key_values(cur: Cursor, offset: int, length: int) -> dict[str, bytes]:
    """The key/value entries KTX1 and KTX2 share: each a uint32 byte count, the key, a NUL, the value, padded to 4.

    Parameters
    ----------
    cur : Cursor
        The file.
    offset, length : int
        Where the key/value data lies (the caller has bounded ``length``).

    Returns
    -------
    dict
        Key (str) → value bytes, as stored.

    Raises
    ------
    InputError
        The data passes the end of the file, an entry passes the end of the data or lacks the NUL after its key,
        or a key is not UTF-8.
    """
    block = cur.span(offset, length, "the key/value data")
    out: dict[str, bytes] = {}
    pos = 0
    while pos < length:
        if pos + 4 > length:
            raise cur.fail(f"a key/value entry's length at byte {pos} of the key/value data is cut off")
        (size,) = struct.unpack_from("<I", block, pos)
        entry = block[pos + 4:pos + 4 + size]
        if len(entry) != size or b"\0" not in entry:
            raise cur.fail(f"the key/value entry at byte {pos} ({size} bytes) passes the end or has no NUL after its key")
        key, value = entry.split(b"\0", 1)
        try:
            name = key.decode("utf-8")
        except UnicodeDecodeError:
            raise cur.fail(f"a key/value key is not UTF-8: {short(key)}") from None
        out[name] = value
        pos += 4 + size + padding(size, 4)
    return out
