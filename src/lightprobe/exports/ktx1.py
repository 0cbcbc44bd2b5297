"""KTX 1.1 textures (``.ktx``) as Filament's ``cmgen --deploy`` writes them, and read back: the IBL file Filament's
``createIblFromKtx1`` loads (the prefiltered specular cube with its mips, and the irradiance SH in the key/value data)
and the skybox file ``createSkyFromKtx1`` loads (one level).

No maintained Python library writes KTX1 (libktx's binding ``pyktx`` ships only as source); Filament's own writer is
its C++ ``image::Ktx1Bundle``. The layout here is the KTX 1.1 specification's as Filament's ``Ktx1Bundle::serialize``
produces it:

* the identifier ``«KTX 11»\\r\\n\\x1A\\n``; the header: endianness 0x04030201, glType, glTypeSize, glFormat,
  glInternalFormat, glBaseInternalFormat, width, height, pixelDepth 0, numberOfArrayElements 0, numberOfFaces (6 for a
  cube), numberOfMipmapLevels, bytesOfKeyValueData;
* each key/value entry: its byte count (key, NUL, value), the key, a NUL, the value — Filament's values carry no final
  NUL, and Filament's reader takes the value as all the entry's bytes after the key's NUL — padded to 4 bytes;
* for each level, base first: ``imageSize`` (for a non-array cube map the bytes of **one** face, the KTX1 rule), then
  the six faces +X, −X, +Y, −Y, +Z, −Z. Filament writes no cube or mip padding and its reader skips none; the two agree
  with the specification when every face is a multiple of 4 bytes, so other sizes are refused here (only RGB16F at odd
  sizes, e.g. a 1×1 level, has them; cmgen's chains stop at 16×16).

Formats (glType, glTypeSize, glFormat, glInternalFormat, glBaseInternalFormat):

* ``r11f_g11f_b10f`` — cmgen's format for both files: 0x8C3A, 1, RGB, R11F_G11F_B10F, RGB. glType is the *internal
  format's* enum, as cmgen writes it and Filament's ``Ktx1Reader::toPixelDataType`` requires (it maps 0x8C3A to
  ``UINT_10F_11F_11F_REV`` and does not know the GL type 0x8C3B that KTX-Software would write). Texels as
  :func:`lightprobe.exports.packedfloat.encode_b10g11r11`.
* ``rgb16f`` — HALF_FLOAT, 2, RGB, RGB16F, RGB (Filament reads it; its web ``createIblFromKtx1`` logs a warning for
  it because its check compares with 0x822F, RG16F, where RGB16F is 0x881B).
* ``rgba16f`` — HALF_FLOAT, 2, RGBA, RGBA16F, RGBA.
* ``rgba8`` / ``srgb8_alpha8`` — UNSIGNED_BYTE, 1, RGBA, RGBA8 or SRGB8_ALPHA8, RGBA: uint8 levels, already encoded.

The SH: cmgen writes key ``sh``, nine lines ``r g b\\n`` (bands 0..2, index l(l+1)+m order: L00, L1−1, L10, L11, …),
each number as C++ streams print a float (``%g``, 6 significant digits). Filament's ``Ktx1Bundle::
getSphericalHarmonics`` reads 27 numbers with ``strtof``; its web ``createIblFromKtx1`` splits the text on single
whitespace characters and parses the first 27 pieces, so the separators must be exactly one space or newline each.
Which SH convention the nine triples hold (Filament's: irradiance / π, pre-multiplied by the basis constants, in
Filament's frame) is the caller's choice (see :func:`lightprobe.exports.sh.filament_coefficients`).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..util.errors import UsageError, short
from .packedfloat import decode_b10g11r11, encode_b10g11r11
from .texels import (FACES, Cursor, check_chain, check_size, finite_values, key_value_entry, level_shape, padding,
                     read_key_values, source_bytes, with_alpha)

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x31, 0x31, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
ENDIANNESS = 0x04030201
HEADER_BYTES = 64
SH_KEY = "sh"
SH_DIGITS = 6  # C++ ostream's default float precision, what cmgen writes
MAX_KEY_VALUE_BYTES = 1 << 20
HALF_MAX = 65504.0

# OpenGL enums (Filament's Ktx1Bundle constants)
GL_UNSIGNED_BYTE, GL_HALF_FLOAT = 0x1401, 0x140B
GL_RGB, GL_RGBA = 0x1907, 0x1908
GL_R11F_G11F_B10F, GL_UNSIGNED_INT_10F_11F_11F_REV = 0x8C3A, 0x8C3B
GL_RGB16F, GL_RGBA16F, GL_RGBA8, GL_SRGB8_ALPHA8 = 0x881B, 0x881A, 0x8058, 0x8C43


@dataclass(frozen=True)
class GlFormat:
    """One KTX1 texel format: its header fields, texel bytes and channels on the way in."""

    name: str
    gl_type: int
    gl_type_size: int
    gl_format: int
    gl_internal_format: int
    gl_base_internal_format: int
    texel_bytes: int
    channels: tuple[int, ...]


FORMATS = {f.name: f for f in (
    GlFormat("r11f_g11f_b10f", GL_R11F_G11F_B10F, 1, GL_RGB, GL_R11F_G11F_B10F, GL_RGB, 4, (3,)),
    GlFormat("rgb16f", GL_HALF_FLOAT, 2, GL_RGB, GL_RGB16F, GL_RGB, 6, (3,)),
    GlFormat("rgba16f", GL_HALF_FLOAT, 2, GL_RGBA, GL_RGBA16F, GL_RGBA, 8, (3, 4)),
    GlFormat("rgba8", GL_UNSIGNED_BYTE, 1, GL_RGBA, GL_RGBA8, GL_RGBA, 4, (3, 4)),
    GlFormat("srgb8_alpha8", GL_UNSIGNED_BYTE, 1, GL_RGBA, GL_SRGB8_ALPHA8, GL_RGBA, 4, (3, 4)),
)}


@dataclass
class Ktx1Texture:
    """A KTX1 file read back by :func:`read_ktx1`.

    Attributes
    ----------
    format : GlFormat
        The texel format the header names.
    gl_type, gl_type_size, gl_format, gl_internal_format, gl_base_internal_format : int
        The header's GL fields as stored.
    width, height, faces, mip_levels : int
        Level 0's size, 1 or 6 faces, the number of levels.
    key_values : dict
        Key → value bytes as stored.
    level_bytes : list of bytes
        Each level's faces, concatenated, level 0 first.
    levels : list of numpy.ndarray
        Each level decoded, (faces, h, w, C): float64 RGB for ``r11f_g11f_b10f``, float32 for the half formats,
        uint8 RGBA for the 8-bit ones.
    """

    format: GlFormat
    gl_type: int
    gl_type_size: int
    gl_format: int
    gl_internal_format: int
    gl_base_internal_format: int
    width: int
    height: int
    faces: int
    mip_levels: int
    key_values: dict = field(default_factory=dict)
    level_bytes: list = field(default_factory=list)
    levels: list = field(default_factory=list)

    @property
    def sh(self) -> np.ndarray | None:
        """The ``sh`` key's nine RGB triples (9, 3) as Filament parses them, or None without the key.

        Raises
        ------
        InputError
            The key is there but does not hold 27 numbers.
        """
        value = self.key_values.get(SH_KEY)
        return None if value is None else parse_filament_sh(value.rstrip(b"\0").decode("ascii", "replace"))


# ---- the SH text --------------------------------------------------------------------------------------------------
def filament_sh_text(coefficients, digits: int = SH_DIGITS) -> str:
    """Nine RGB SH triples as cmgen writes them in a KTX1's ``sh`` key (and in ``sh.txt``'s numbers).

    Parameters
    ----------
    coefficients : array_like
        (9, 3): bands 0..2 in index order l(l+1)+m (L00, L1−1, L10, L11, L2−2, …), already in the convention the
        engine expects (for Filament: :func:`lightprobe.exports.sh.filament_coefficients`).
    digits : int, default 6
        Significant digits: 6 is what cmgen's C++ stream writes (``%g``); up to 9 keeps a float32 exactly.

    Returns
    -------
    str
        Nine lines ``"r g b\\n"``, numbers in ``%g`` form, separated by exactly one space.

    Raises
    ------
    UsageError
        Not (9, 3), a non-finite value, or ``digits`` outside 1..17.
    """
    c = np.asarray(coefficients, dtype=np.float64)
    if c.shape != (9, 3):
        raise UsageError(f"the Filament SH text takes (9, 3) coefficients, not shape {c.shape}")
    if not np.isfinite(c).all():
        raise UsageError("the Filament SH text cannot hold NaN or infinite coefficients")
    if not 1 <= digits <= 17:
        raise UsageError(f"digits must be 1..17, got {digits}")
    return "".join(" ".join(f"{v:.{digits}g}" for v in row) + "\n" for row in c)


_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")


def parse_filament_sh(text: str) -> np.ndarray:
    """The first 27 numbers of an ``sh`` text, as Filament reads them, as (9, 3).

    Parameters
    ----------
    text : str
        The key's value (or an ``sh.txt`` body of bare numbers).

    Returns
    -------
    numpy.ndarray
        (9, 3) float64.

    Raises
    ------
    InputError
        Fewer than 27 whitespace-separated numbers, or one that is not a finite decimal number.
    """
    from ..util.errors import InputError

    pieces = text.split()[:27]
    if len(pieces) < 27 or not all(_NUMBER.match(p) for p in pieces):
        raise InputError(f"the Filament SH text does not start with 27 numbers: {short(text)}")
    return np.array([float(p) for p in pieces]).reshape(9, 3)


# ---- writing --------------------------------------------------------------------------------------------------------
def _format(name) -> GlFormat:
    if isinstance(name, GlFormat):
        return name
    try:
        return FORMATS[str(name).lower()]
    except KeyError:
        raise UsageError(f"unknown KTX1 format {short(name)}; one of {', '.join(FORMATS)}") from None


def _encode_face(face: np.ndarray, fmt: GlFormat) -> bytes:
    if fmt.gl_type == GL_UNSIGNED_BYTE:
        if face.dtype != np.uint8:
            raise UsageError(f"KTX1 {fmt.name} takes uint8 levels (already encoded), not {face.dtype}")
        return np.ascontiguousarray(with_alpha(face, 255)).tobytes()
    values = finite_values(face, f"KTX1 {fmt.name}")
    if fmt.name == "r11f_g11f_b10f":
        return encode_b10g11r11(values).astype("<u4").tobytes()
    if fmt.gl_format == GL_RGBA:
        values = with_alpha(values, 1.0)
    return np.clip(values, -HALF_MAX, HALF_MAX).astype("<f2").tobytes()


def _key_values(key_values: Mapping[str, str | bytes] | None) -> bytes:
    out = b""
    for key, value in (key_values or {}).items():
        if not isinstance(key, str) or not key or "\0" in key:
            raise UsageError(f"a KTX1 key is a non-empty string without NUL, not {short(key)}")
        if isinstance(value, str):
            value = value.encode("utf-8")  # no final NUL: Filament's setMetadata stores none
        elif not isinstance(value, (bytes, bytearray)):
            raise UsageError(f"KTX1 value of {key} must be str or bytes, not {type(value).__name__}")
        out += key_value_entry(key, bytes(value))
    if len(out) > MAX_KEY_VALUE_BYTES:
        raise UsageError(f"KTX1 key/value data of {len(out)} bytes; at most {MAX_KEY_VALUE_BYTES}")
    return out


def ktx1_bytes(levels, format: str | GlFormat = "r11f_g11f_b10f", *, sh=None,
               key_values: Mapping[str, str | bytes] | None = None) -> bytes:
    """A KTX1 file's bytes, laid out as Filament's ``Ktx1Bundle`` serializes (see the module docstring).

    Parameters
    ----------
    levels : sequence of array_like
        Level 0 first: (6, n, n, C) cube maps (faces +X, −X, +Y, −Y, +Z, −Z in the frame Filament samples in, no
        conversion here; each face's first row is its top) or (h, w, C) 2D images; C 3 for ``r11f_g11f_b10f`` and
        ``rgb16f``, 3 or 4 for the others (alpha 1 or 255 added); uint8 for the 8-bit formats.
    format : str or GlFormat, default "r11f_g11f_b10f"
        One of :data:`FORMATS` (cmgen writes ``r11f_g11f_b10f``).
    sh : array_like, optional
        (9, 3) coefficients for the ``sh`` key, written with :func:`filament_sh_text` (6 digits, as cmgen).
    key_values : mapping of str to str or bytes, optional
        Other entries, written in the given order after ``sh``; str values as UTF-8 without a final NUL.

    Returns
    -------
    bytes
        The whole file.

    Raises
    ------
    UsageError
        An unknown format, a malformed chain (:func:`lightprobe.exports.texels.check_chain`), a face whose byte
        size is not a multiple of 4, NaN values, or a bad key or value (``sh`` given twice, say).
    """
    fmt = _format(format)
    chain = check_chain(levels, fmt.channels, f"KTX1 {fmt.name}")
    entries: dict[str, str | bytes] = {}
    if sh is not None:
        entries[SH_KEY] = filament_sh_text(sh)
    for key, value in (key_values or {}).items():
        if key in entries:
            raise UsageError(f"KTX1 key {key} given twice (as sh= and in key_values)")
        entries[key] = value
    kvd = _key_values(entries)
    header = IDENTIFIER + struct.pack(
        "<13I", ENDIANNESS, fmt.gl_type, fmt.gl_type_size, fmt.gl_format, fmt.gl_internal_format,
        fmt.gl_base_internal_format, chain.width, chain.height, 0, 0, chain.faces, len(chain.levels), len(kvd))
    body = []
    for i, level in enumerate(chain.levels):
        faces = [_encode_face(face, fmt) for face in level]
        if len(faces[0]) % 4:
            h, w = level_shape(chain.width, chain.height, i)
            raise UsageError(f"KTX1 {fmt.name}: level {i}'s {w} × {h} faces are {len(faces[0])} bytes, not a multiple "
                             "of 4, which KTX1 pads and Filament's reader does not; use rgba16f or r11f_g11f_b10f")
        body.append(struct.pack("<I", len(faces[0]) * (1 if chain.faces == FACES else chain.faces)))
        body.extend(faces)
    return header + kvd + b"".join(body)


def write_ktx1(path, levels, format: str | GlFormat = "r11f_g11f_b10f", *, sh=None,
               key_values: Mapping[str, str | bytes] | None = None, inputs=()):
    """Write a KTX1 file atomically (see :func:`ktx1_bytes` for the layout and the parameters).

    Parameters
    ----------
    path : str or path-like
        The ``.ktx`` file to write.
    levels, format, sh, key_values
        As :func:`ktx1_bytes`.
    inputs : iterable of path-like, default ()
        Input files ``path`` must not be.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        As :func:`ktx1_bytes`.
    InputError
        The file cannot be written (it is then untouched).
    """
    from ..util.files import write_bytes

    return write_bytes(path, ktx1_bytes(levels, format, sh=sh, key_values=key_values), inputs)


# ---- reading --------------------------------------------------------------------------------------------------------
def _format_of(gl_type: int, gl_format: int, gl_internal: int) -> GlFormat | None:
    for fmt in FORMATS.values():
        types = (fmt.gl_type, GL_UNSIGNED_INT_10F_11F_11F_REV) if fmt.name == "r11f_g11f_b10f" else (fmt.gl_type,)
        if gl_type in types and gl_format == fmt.gl_format and gl_internal == fmt.gl_internal_format:
            return fmt
    return None


def read_ktx1(source) -> Ktx1Texture:
    """Read a KTX1 file in one of :data:`FORMATS`, checking every length against the file.

    Parameters
    ----------
    source : str, path-like or bytes
        The file or its contents.

    Returns
    -------
    Ktx1Texture
        The header fields, key/values (``.sh`` parses the SH) and every level, raw and decoded.

    Raises
    ------
    InputError
        Anything malformed or outside what lightprobe writes: a wrong identifier or endianness, another format, 3D
        or array textures, sizes beyond :data:`~lightprobe.exports.texels.MAX_SIZE`, key/value data or a level that
        passes the end of the file, or an ``imageSize`` that does not match the level. One line, never an
        ``IndexError`` or ``struct.error``.
    """
    data, label = source_bytes(source, "KTX1")
    cur = Cursor(data, label)
    if cur.span(0, 12, "the identifier") != IDENTIFIER:
        raise cur.fail("it does not start with the KTX 1.1 identifier")
    (endianness, gl_type, type_size, gl_format, gl_internal, gl_base, width, height, depth, arrays, faces, mips,
     kvd_length) = cur.words(12, "13I", "the header")
    if endianness != ENDIANNESS:
        raise cur.fail(f"endianness 0x{endianness:08x} (only little-endian files, 0x04030201, are read)")
    fmt = _format_of(gl_type, gl_format, gl_internal)
    if fmt is None:
        raise cur.fail(f"glType 0x{gl_type:x}, glFormat 0x{gl_format:x}, glInternalFormat 0x{gl_internal:x} is not "
                       f"one of {', '.join(FORMATS)}")
    if depth != 0 or arrays != 0:
        raise cur.fail(f"3D or array textures (pixelDepth {depth}, numberOfArrayElements {arrays}) are not read here")
    height = max(height, 1)  # KTX1 allows 0 for 1D textures
    mips = max(mips, 1)  # 0 asks the loader to generate the mips: the file holds the base level only
    check_size(cur, width, height, faces, mips)
    if kvd_length > MAX_KEY_VALUE_BYTES:
        raise cur.fail(f"{kvd_length} bytes of key/value data (at most {MAX_KEY_VALUE_BYTES} are read)")
    texture = Ktx1Texture(fmt, gl_type, type_size, gl_format, gl_internal, gl_base, width, height, faces, mips,
                          read_key_values(cur, HEADER_BYTES, kvd_length))
    pos = HEADER_BYTES + kvd_length
    for i in range(mips):
        h, w = level_shape(width, height, i)
        face_bytes = h * w * fmt.texel_bytes
        (image_size,) = cur.words(pos, "I", f"level {i}'s imageSize")
        expected = face_bytes if faces == FACES else face_bytes * faces
        if image_size != expected:
            raise cur.fail(f"level {i} has imageSize {image_size}; {w} × {h} of {fmt.name} is {expected}")
        pos += 4
        raw = b""
        for _ in range(faces):
            raw += cur.span(pos, face_bytes, f"level {i}")
            pos += face_bytes + (padding(face_bytes, 4) if faces == FACES else 0)  # cubePadding
        pos += padding(expected, 4)  # mipPadding
        texture.level_bytes.append(raw)
        texture.levels.append(_decode(raw, fmt, (faces, h, w)))
    return texture


def _decode(raw: bytes, fmt: GlFormat, shape: tuple[int, int, int]) -> np.ndarray:
    if fmt.name == "r11f_g11f_b10f":
        return decode_b10g11r11(np.frombuffer(raw, "<u4").reshape(shape))
    if fmt.gl_type == GL_HALF_FLOAT:
        return np.frombuffer(raw, "<f2").reshape(*shape, fmt.texel_bytes // 2).astype(np.float32)
    return np.frombuffer(raw, np.uint8).reshape(*shape, 4).copy()
