"""KTX 2.0 textures (``.ktx2``): written to the Khronos KTX 2.0 specification and read back, for three.js's
``KTX2Loader``, glTF's ``KHR_texture_basisu``-free uncompressed textures and any Vulkan-style loader.

No maintained Python library writes KTX2: libktx's binding ``pyktx`` ships only as source (it needs the C library
built), and the other PyPI packages read Basis Universal only. So the container is written here, from the
specification, and checked against an independent reader (npm ``ktx-parse``, in the tests).

The file, as written:

* the 12-byte identifier ``«KTX 20»\\r\\n\\x1A\\n``; the header (``vkFormat``, ``typeSize``, size, ``layerCount`` 0,
  ``faceCount`` 1 or 6, ``levelCount``, ``supercompressionScheme`` 0 or 2 = Zstandard); the index; the level index,
  entry 0 for the base level;
* the Data Format Descriptor: one basic block (Khronos, version 2), colour model RGBSDA, primaries BT.709, transfer
  linear (sRGB for ``R8G8B8A8_SRGB``), straight alpha, 1×1×1×1 texel blocks, ``bytesPlane0`` the texel size (kept with
  Zstandard too, as the Khronos Data Format discussion concluded), and the samples KTX-Software's ``vk2dfd`` gives
  each format (float samples with sampleLower/Upper −1.0/1.0 as float bits, 0.0/1.0 for unsigned floats; RGB9E5's
  three 9-bit mantissas with upper 8448 each followed by its shared 5-bit exponent with lower 15 / upper 31);
* the key/value data, sorted by key, each entry padded to 4 bytes: ``KTXwriter`` = ``lightprobe <version>``,
  ``KTXorientation`` = ``rd`` for 2D textures (first row at the top; cube faces have their fixed orientation), and
  the caller's keys. String values end with a NUL;
* the levels, **smallest first** in the file (so a streaming loader can show something early), each starting at a
  multiple of lcm(texel size, 4) and padded with zeros — or, with Zstandard, each level compressed on its own
  (``uncompressedByteLength`` its raw size) and packed with alignment 1. Within a level the cube faces follow each
  other (+X, −X, +Y, −Y, +Z, −Z), without padding between them (KTX2 has none).

Formats: ``R16G16B16A16_SFLOAT`` (float16; RGBA rather than RGB because three.js's KTX2Loader accepts only the RGBA,
RG and R half-float formats — r187's ``FORMAT_MAP`` has no ``R16G16B16_SFLOAT`` — and WebGL has no RGB16F render
target; alpha is 1), ``R32G32B32A32_SFLOAT``, ``E5B9G9R9_UFLOAT_PACK32`` and ``B10G11R11_UFLOAT_PACK32`` (both accepted
by KTX2Loader since r180; see :mod:`lightprobe.exports.packedfloat` for the exact encodings), and
``R8G8B8A8_UNORM`` / ``R8G8B8A8_SRGB`` for 8-bit data (uint8 levels, already encoded). Float values beyond a format's
range are clamped to its largest finite value (float16: ±65504); NaN is refused.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Mapping

import numpy as np

from ..util.errors import UsageError, short
from .packedfloat import decode_b10g11r11, decode_rgb9e5, encode_b10g11r11, encode_rgb9e5
from .texels import (FACES, Cursor, check_chain, check_size, finite_values, key_value_entry, level_shape, padding,
                     read_key_values, source_bytes, with_alpha)

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
HEADER_BYTES = 80  # identifier 12, nine uint32 36, index (4 uint32 + 2 uint64) 32
LEVEL_INDEX_ENTRY = 24  # byteOffset, byteLength, uncompressedByteLength: uint64 each
SUPERCOMPRESSION_NONE = 0
SUPERCOMPRESSION_ZSTD = 2
ZSTD_LEVEL = 19  # high but still quick on IBL-sized data; the file is written once and downloaded many times
MAX_KEY_VALUE_BYTES = 1 << 20  # the key/value data read back is metadata: a megabyte is plenty
HALF_MAX = 65504.0
FLOAT_MAX = float(np.finfo(np.float32).max)

# Khronos Data Format constants (khr_df.h)
DF_VERSION = 2  # KHR_DF_VERSIONNUMBER_1_3
DF_MODEL_RGBSDA = 1
DF_PRIMARIES_BT709 = 1
DF_TRANSFER_LINEAR = 1
DF_TRANSFER_SRGB = 2
DF_ALPHA_STRAIGHT = 0
DF_CHANNEL_R, DF_CHANNEL_G, DF_CHANNEL_B, DF_CHANNEL_A = 0, 1, 2, 15
DF_SAMPLE_LINEAR, DF_SAMPLE_EXPONENT, DF_SAMPLE_SIGNED, DF_SAMPLE_FLOAT = 0x10, 0x20, 0x40, 0x80
_F32_ONE, _F32_MINUS_ONE = 0x3F800000, 0xBF800000


class VkFormat(IntEnum):
    """The Vulkan formats lightprobe writes in KTX2 (their ``VkFormat`` numbers)."""

    R8G8B8A8_UNORM = 37
    R8G8B8A8_SRGB = 43
    R16G16B16A16_SFLOAT = 97
    R32G32B32A32_SFLOAT = 109
    B10G11R11_UFLOAT_PACK32 = 122
    E5B9G9R9_UFLOAT_PACK32 = 123


@dataclass(frozen=True)
class _Spec:
    texel_bytes: int
    type_size: int
    channels: tuple[int, ...]  # channel counts a level may have on the way in
    samples: tuple[tuple[int, int, int, int, int], ...]  # (bitOffset, bitLength − 1, channelType, lower, upper)
    transfer: int = DF_TRANSFER_LINEAR


def _float_samples(bits: int, signed: bool) -> tuple:
    qualifiers = DF_SAMPLE_FLOAT | (DF_SAMPLE_SIGNED if signed else 0)
    lower = _F32_MINUS_ONE if signed else 0
    return tuple((i * bits, bits - 1, channel | qualifiers, lower, _F32_ONE)
                 for i, channel in enumerate((DF_CHANNEL_R, DF_CHANNEL_G, DF_CHANNEL_B, DF_CHANNEL_A)))


def _unorm8_samples(srgb: bool) -> tuple:
    return tuple((8 * i, 7, channel | (DF_SAMPLE_LINEAR if srgb and channel == DF_CHANNEL_A else 0), 0, 255)
                 for i, channel in enumerate((DF_CHANNEL_R, DF_CHANNEL_G, DF_CHANNEL_B, DF_CHANNEL_A)))


_SPECS = {
    VkFormat.R16G16B16A16_SFLOAT: _Spec(8, 2, (3, 4), _float_samples(16, True)),
    VkFormat.R32G32B32A32_SFLOAT: _Spec(16, 4, (3, 4), _float_samples(32, True)),
    VkFormat.B10G11R11_UFLOAT_PACK32: _Spec(4, 4, (3,), (
        (0, 10, DF_CHANNEL_R | DF_SAMPLE_FLOAT, 0, _F32_ONE), (11, 10, DF_CHANNEL_G | DF_SAMPLE_FLOAT, 0, _F32_ONE),
        (22, 9, DF_CHANNEL_B | DF_SAMPLE_FLOAT, 0, _F32_ONE))),
    VkFormat.E5B9G9R9_UFLOAT_PACK32: _Spec(4, 4, (3,), tuple(
        s for i, channel in enumerate((DF_CHANNEL_R, DF_CHANNEL_G, DF_CHANNEL_B))
        for s in ((9 * i, 8, channel, 0, 8448), (27, 4, channel | DF_SAMPLE_EXPONENT, 15, 31)))),
    VkFormat.R8G8B8A8_UNORM: _Spec(4, 1, (3, 4), _unorm8_samples(False)),
    VkFormat.R8G8B8A8_SRGB: _Spec(4, 1, (3, 4), _unorm8_samples(True), DF_TRANSFER_SRGB),
}


@dataclass
class Ktx2Texture:
    """A KTX2 file read back by :func:`read_ktx2`.

    Attributes
    ----------
    vk_format : VkFormat
        The texel format.
    type_size, width, height, depth, layer_count, face_count, level_count, supercompression : int
        The header's fields as stored (``supercompression`` 0 none, 2 Zstandard).
    dfd : dict
        The basic descriptor block: ``vendor_id``, ``descriptor_type``, ``version``, ``block_size``, ``color_model``,
        ``color_primaries``, ``transfer_function``, ``flags``, ``texel_block_dimension`` (4 ints, stored minus 1),
        ``bytes_plane`` (8 ints) and ``samples``, each ``bit_offset``, ``bit_length`` (stored minus 1),
        ``channel_type``, ``sample_position`` (4 ints), ``lower``, ``upper`` (raw uint32).
    key_values : dict
        Key → value bytes as stored (string values keep their final NUL).
    level_bytes : list of bytes
        Each level's uncompressed bytes, level 0 first.
    levels : list of numpy.ndarray
        Each level decoded, (faces, h, w, C): float32 RGBA for the float formats, float64 RGB for the packed ones
        (exact), uint8 RGBA for the 8-bit ones.
    """

    vk_format: VkFormat
    type_size: int
    width: int
    height: int
    depth: int
    layer_count: int
    face_count: int
    level_count: int
    supercompression: int
    dfd: dict
    key_values: dict = field(default_factory=dict)
    level_bytes: list = field(default_factory=list)
    levels: list = field(default_factory=list)

    def text(self, key: str) -> str | None:
        """A key's value as text (UTF-8, the final NUL dropped), or None when the key is absent.

        Parameters
        ----------
        key : str
            The key, e.g. ``"KTXwriter"``.

        Returns
        -------
        str or None
            The value.
        """
        value = self.key_values.get(key)
        return None if value is None else value.rstrip(b"\0").decode("utf-8", "replace")


# ---- writing --------------------------------------------------------------------------------------------------------
def _encode_level(level: np.ndarray, fmt: VkFormat) -> bytes:
    """(faces, h, w, C) → the level's bytes, faces one after the other, rows top first."""
    spec = _SPECS[fmt]
    if fmt in (VkFormat.R8G8B8A8_UNORM, VkFormat.R8G8B8A8_SRGB):
        if level.dtype != np.uint8:
            raise UsageError(f"{fmt.name} takes uint8 levels (already encoded), not {level.dtype}")
        return np.ascontiguousarray(with_alpha(level, 255)).tobytes()
    values = finite_values(level, fmt.name)
    if fmt == VkFormat.E5B9G9R9_UFLOAT_PACK32:
        return encode_rgb9e5(values).astype("<u4").tobytes()
    if fmt == VkFormat.B10G11R11_UFLOAT_PACK32:
        return encode_b10g11r11(values).astype("<u4").tobytes()
    values = with_alpha(values, 1.0)
    if fmt == VkFormat.R16G16B16A16_SFLOAT:
        return np.clip(values, -HALF_MAX, HALF_MAX).astype("<f2").tobytes()
    assert spec.type_size == 4
    return np.clip(values, -FLOAT_MAX, FLOAT_MAX).astype("<f4").tobytes()


def _dfd(fmt: VkFormat) -> bytes:
    spec = _SPECS[fmt]
    block = 24 + 16 * len(spec.samples)
    out = struct.pack("<IIIIII", 4 + block, 0, DF_VERSION | (block << 16),
                      DF_MODEL_RGBSDA | (DF_PRIMARIES_BT709 << 8) | (spec.transfer << 16) | (DF_ALPHA_STRAIGHT << 24),
                      0, spec.texel_bytes) + struct.pack("<I", 0)
    for offset, length, channel, lower, upper in spec.samples:
        out += struct.pack("<IIII", offset | (length << 16) | (channel << 24), 0, lower, upper)
    return out


def _key_values(extra: Mapping[str, str | bytes] | None, cube: bool) -> bytes:
    from .. import __version__

    entries: dict[str, bytes] = {"KTXwriter": f"lightprobe {__version__}".encode() + b"\0"}
    if not cube:
        entries["KTXorientation"] = b"rd\0"
    for key, value in (extra or {}).items():
        if not isinstance(key, str) or not key or "\0" in key:
            raise UsageError(f"a KTX2 key is a non-empty string without NUL, not {short(key)}")
        if key in ("KTXwriter", "KTXorientation"):
            raise UsageError(f"KTX2 key {key} is written by lightprobe itself")
        if isinstance(value, str):
            value = value.encode("utf-8") + b"\0"
        elif not isinstance(value, (bytes, bytearray)):
            raise UsageError(f"KTX2 value of {key} must be str or bytes, not {type(value).__name__}")
        entries[key] = bytes(value)
    out = b""
    for key in sorted(entries, key=lambda k: k.encode("utf-8")):  # sorted by the keys' code points, as required
        out += key_value_entry(key, entries[key])
    if len(out) > MAX_KEY_VALUE_BYTES:
        raise UsageError(f"KTX2 key/value data of {len(out)} bytes; at most {MAX_KEY_VALUE_BYTES}")
    return out


def ktx2_bytes(levels, vk_format: VkFormat | int | str = VkFormat.R16G16B16A16_SFLOAT, *, zstd: bool = False,
               zstd_level: int = ZSTD_LEVEL, key_values: Mapping[str, str | bytes] | None = None) -> bytes:
    """A KTX2 file's bytes for a 2D texture or a cube map with its mip chain.

    Parameters
    ----------
    levels : sequence of array_like
        Level 0 first. A 2D texture's level is (h, w, C), a cube map's (6, n, n, C) with faces +X, −X, +Y, −Y, +Z,
        −Z (the Vulkan/KTX order, in the frame of the engine that will load it: no conversion happens here); each
        image's first row is its top. Level i is ⌊base/2^i⌋ across; any number of levels up to the full chain. C is
        3 or 4 for the float formats (alpha 1 added), 3 for the packed ones, and uint8 with 3 or 4 for the 8-bit ones.
    vk_format : VkFormat, int or str, default R16G16B16A16_SFLOAT
        The texel format (a :class:`VkFormat`, its number or its name).
    zstd : bool, default False
        Supercompress each level with Zstandard (``supercompressionScheme`` 2; needs the ``zstandard`` package).
    zstd_level : int, default 19
        Zstandard's compression level, 1..22.
    key_values : mapping of str to str or bytes, optional
        Extra key/value entries; str values are stored as UTF-8 with a final NUL, bytes as given. ``KTXwriter`` and
        ``KTXorientation`` are lightprobe's own.

    Returns
    -------
    bytes
        The whole file.

    Raises
    ------
    UsageError
        An unknown format, a malformed chain (see :func:`lightprobe.exports.texels.check_chain`), NaN values, a
        bad key or value, or a compression level out of range.
    """
    fmt = _format(vk_format)
    spec = _SPECS[fmt]
    chain = check_chain(levels, spec.channels, f"KTX2 {fmt.name}")
    cube = chain.faces == FACES
    raw = [_encode_level(level, fmt) for level in chain.levels]
    if zstd:
        if not 1 <= zstd_level <= 22:
            raise UsageError(f"zstd_level must be 1..22, got {zstd_level}")
        compressor = _zstandard().ZstdCompressor(level=zstd_level)
        stored, alignment = [compressor.compress(b) for b in raw], 1
    else:
        stored, alignment = raw, spec.texel_bytes * 4 // np.gcd(spec.texel_bytes, 4)  # lcm(texel size, 4)
    dfd_offset = HEADER_BYTES + LEVEL_INDEX_ENTRY * len(raw)
    dfd = _dfd(fmt)
    kvd = _key_values(key_values, cube)
    kvd_offset = dfd_offset + len(dfd)
    end = kvd_offset + len(kvd)
    # levels in the file smallest first; the index lists them base first
    offsets: list[int] = [0] * len(raw)
    body = b""
    for i in reversed(range(len(raw))):
        gap = padding(end + len(body), alignment)
        body += b"\0" * gap
        offsets[i] = end + len(body)
        body += stored[i]
    header = IDENTIFIER + struct.pack(
        "<9I", int(fmt), spec.type_size, chain.width, chain.height, 0, 0, chain.faces,
        len(raw), SUPERCOMPRESSION_ZSTD if zstd else SUPERCOMPRESSION_NONE)
    header += struct.pack("<4I2Q", dfd_offset, len(dfd), kvd_offset if kvd else 0, len(kvd), 0, 0)
    index = b"".join(struct.pack("<3Q", offsets[i], len(stored[i]), len(raw[i])) for i in range(len(raw)))
    return header + index + dfd + kvd + body


def write_ktx2(path, levels, vk_format: VkFormat | int | str = VkFormat.R16G16B16A16_SFLOAT, *, zstd: bool = False,
               zstd_level: int = ZSTD_LEVEL, key_values: Mapping[str, str | bytes] | None = None, inputs=()):
    """Write a KTX2 file atomically (see :func:`ktx2_bytes` for the layout and every parameter).

    Parameters
    ----------
    path : str or path-like
        The ``.ktx2`` file to write.
    levels, vk_format, zstd, zstd_level, key_values
        As :func:`ktx2_bytes`.
    inputs : iterable of path-like, default ()
        Input files ``path`` must not be.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        As :func:`ktx2_bytes`.
    InputError
        The file cannot be written (it is then untouched).
    """
    from ..util.files import write_bytes

    data = ktx2_bytes(levels, vk_format, zstd=zstd, zstd_level=zstd_level, key_values=key_values)
    return write_bytes(path, data, inputs)


def _format(vk_format) -> VkFormat:
    try:
        if isinstance(vk_format, str):
            return VkFormat[vk_format.upper().removeprefix("VK_FORMAT_")]
        return VkFormat(int(vk_format))
    except (KeyError, ValueError, TypeError):
        raise UsageError(f"unknown KTX2 format {short(vk_format)}; one of "
                         f"{', '.join(f.name for f in VkFormat)}") from None


def _zstandard():
    try:
        import zstandard
    except ImportError:  # pragma: no cover - a core dependency
        raise UsageError("Zstandard supercompression needs the zstandard package: pip install zstandard") from None
    return zstandard


# ---- reading --------------------------------------------------------------------------------------------------------
def read_ktx2(source) -> Ktx2Texture:
    """Read a KTX2 file written in one of lightprobe's formats, checking every length against the file.

    Parameters
    ----------
    source : str, path-like or bytes
        The file or its contents.

    Returns
    -------
    Ktx2Texture
        The header, descriptor, key/values and every level (raw and decoded).

    Raises
    ------
    InputError
        Anything malformed or outside what lightprobe writes: a wrong identifier, a format other than
        :class:`VkFormat`, 3D or array textures, sizes beyond :data:`~lightprobe.exports.texels.MAX_SIZE`, a section
        or level outside the file, a level of the wrong length, key/value data that does not parse, or Zstandard data
        that does not inflate to its stated length. One line, never an ``IndexError`` or ``struct.error``.
    """
    data, label = source_bytes(source, "KTX2")
    cur = Cursor(data, label)
    if cur.span(0, 12, "the identifier") != IDENTIFIER:
        raise cur.fail("it does not start with the KTX 2.0 identifier")
    (vk, type_size, width, height, depth, layers, faces, level_count, scheme) = cur.words(12, "9I", "the header")
    dfd_offset, dfd_length, kvd_offset, kvd_length, sgd_offset, sgd_length = cur.words(48, "4I2Q", "the index")
    try:
        fmt = VkFormat(vk)
    except ValueError:
        raise cur.fail(f"vkFormat {vk} is not one lightprobe reads ({', '.join(f.name for f in VkFormat)})") from None
    spec = _SPECS[fmt]
    if type_size != spec.type_size:
        raise cur.fail(f"typeSize {type_size} for {fmt.name}, which has {spec.type_size}")
    if depth != 0 or layers != 0:
        raise cur.fail(f"3D or array textures (pixelDepth {depth}, layerCount {layers}) are not read here")
    check_size(cur, width, height, faces, level_count)
    if scheme not in (SUPERCOMPRESSION_NONE, SUPERCOMPRESSION_ZSTD):
        raise cur.fail(f"supercompressionScheme {scheme} (only 0, none, and 2, Zstandard, are read)")
    if sgd_length:
        raise cur.fail(f"{sgd_length} bytes of supercompression global data, which neither scheme has")
    dfd = _read_dfd(cur, dfd_offset, dfd_length)
    if kvd_length > MAX_KEY_VALUE_BYTES:
        raise cur.fail(f"{kvd_length} bytes of key/value data (at most {MAX_KEY_VALUE_BYTES} are read)")
    key_values = read_key_values(cur, kvd_offset, kvd_length)
    entries = [cur.words(HEADER_BYTES + LEVEL_INDEX_ENTRY * i, "3Q", f"level index entry {i}") for i in range(level_count)]
    texture = Ktx2Texture(fmt, type_size, width, height, depth, layers, faces, level_count, scheme, dfd, key_values)
    for i, (offset, length, uncompressed) in enumerate(entries):
        h, w = level_shape(width, height, i)
        expected = faces * h * w * spec.texel_bytes
        if uncompressed != expected:
            raise cur.fail(f"level {i} has uncompressedByteLength {uncompressed}; {w} × {h} × {faces} face(s) of "
                           f"{fmt.name} is {expected}")
        stored = cur.span(offset, length, f"level {i}")
        if scheme == SUPERCOMPRESSION_NONE:
            if length != expected:
                raise cur.fail(f"level {i} has byteLength {length}, not {expected}")
            raw = stored
        else:
            raw = _inflate(cur, stored, expected, i)
        texture.level_bytes.append(raw)
        texture.levels.append(_decode_level(raw, fmt, (faces, h, w)))
    return texture


def _inflate(cur: Cursor, stored: bytes, expected: int, level: int) -> bytes:
    zstandard = _zstandard()
    try:
        # max_output_size bounds the memory a hostile frame can claim; a frame that states its size is checked too
        raw = zstandard.ZstdDecompressor().decompress(stored, max_output_size=expected)
    except zstandard.ZstdError as e:
        raise cur.fail(f"level {level}'s Zstandard data does not inflate: {str(e)[:120]}") from None
    if len(raw) != expected:
        raise cur.fail(f"level {level} inflates to {len(raw)} bytes, not {expected}")
    return raw


def _decode_level(raw: bytes, fmt: VkFormat, shape: tuple[int, int, int]) -> np.ndarray:
    if fmt == VkFormat.R16G16B16A16_SFLOAT:
        return np.frombuffer(raw, "<f2").reshape(*shape, 4).astype(np.float32)
    if fmt == VkFormat.R32G32B32A32_SFLOAT:
        return np.frombuffer(raw, "<f4").reshape(*shape, 4).astype(np.float32)
    if fmt == VkFormat.E5B9G9R9_UFLOAT_PACK32:
        return decode_rgb9e5(np.frombuffer(raw, "<u4").reshape(shape))
    if fmt == VkFormat.B10G11R11_UFLOAT_PACK32:
        return decode_b10g11r11(np.frombuffer(raw, "<u4").reshape(shape))
    return np.frombuffer(raw, np.uint8).reshape(*shape, 4).copy()


def _read_dfd(cur: Cursor, offset: int, length: int) -> dict:
    if length < 4 + 24 or offset % 4:
        raise cur.fail(f"the data format descriptor ({length} bytes at {offset}) is too short or misaligned")
    (total,) = cur.words(offset, "I", "dfdTotalSize")
    if total != length:
        raise cur.fail(f"dfdTotalSize {total} differs from dfdByteLength {length}")
    w = cur.words(offset + 4, "6I", "the basic descriptor block")
    block_size = w[1] >> 16
    samples_bytes = block_size - 24
    if block_size < 24 or samples_bytes % 16 or 4 + block_size > length:
        raise cur.fail(f"descriptorBlockSize {block_size} does not fit the {length}-byte descriptor")
    dfd = {"vendor_id": w[0] & 0x1FFFF, "descriptor_type": w[0] >> 17, "version": w[1] & 0xFFFF,
           "block_size": block_size, "color_model": w[2] & 0xFF, "color_primaries": (w[2] >> 8) & 0xFF,
           "transfer_function": (w[2] >> 16) & 0xFF, "flags": w[2] >> 24,
           "texel_block_dimension": [(w[3] >> s) & 0xFF for s in (0, 8, 16, 24)],
           "bytes_plane": [(w[4] >> s) & 0xFF for s in (0, 8, 16, 24)] + [(w[5] >> s) & 0xFF for s in (0, 8, 16, 24)],
           "samples": []}
    for k in range(samples_bytes // 16):
        a, b, lower, upper = cur.words(offset + 28 + 16 * k, "4I", f"descriptor sample {k}")
        dfd["samples"].append({"bit_offset": a & 0xFFFF, "bit_length": (a >> 16) & 0xFF, "channel_type": a >> 24,
                               "sample_position": [(b >> s) & 0xFF for s in (0, 8, 16, 24)],
                               "lower": lower, "upper": upper})
    return dfd


def format_info(vk_format: VkFormat | int | str) -> dict:
    """What lightprobe writes for a format: texel bytes, typeSize and the descriptor's samples.

    Parameters
    ----------
    vk_format : VkFormat, int or str
        The format.

    Returns
    -------
    dict
        ``texel_bytes``, ``type_size``, ``transfer_function`` and ``samples`` (as :attr:`Ktx2Texture.dfd` has them).

    Raises
    ------
    UsageError
        An unknown format.
    """
    spec = _SPECS[_format(vk_format)]
    return {"texel_bytes": spec.texel_bytes, "type_size": spec.type_size, "transfer_function": spec.transfer,
            "samples": [{"bit_offset": o, "bit_length": n, "channel_type": c, "sample_position": [0, 0, 0, 0],
                         "lower": lo, "upper": up} for o, n, c, lo, up in spec.samples]}

