"""KTX2 and KTX1 containers and the packed-float texel encodings.

References: the encodings against brute force over every code of the format (B10G11R11) and against the
GL_EXT_texture_shared_exponent rules stated as checks (RGB9E5); the KTX2 files read back by npm ktx-parse, an
independent reader; the KTX1 files read back by Filament's own Ktx1Bundle (its web build, in Node). Readers are
fuzzed: any truncation or byte change gives the file back or one InputError.
"""

from __future__ import annotations

import base64
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightprobe.exports.ktx1 import FORMATS, filament_sh_text, ktx1_bytes, parse_filament_sh, read_ktx1, write_ktx1
from lightprobe.exports.ktx2 import IDENTIFIER, VkFormat, format_info, ktx2_bytes, read_ktx2, write_ktx2
from lightprobe.exports.packedfloat import (RGB9E5_MAX, UF10_MAX, UF11_MAX, decode_b10g11r11, decode_rgb9e5,
                                            encode_b10g11r11, encode_rgb9e5)
from lightprobe.util.errors import InputError, UsageError

SH_TEXT_RELATIVE = 5e-6  # cmgen's 6 significant digits: half a unit in the 6th digit
FLOAT32_RELATIVE = 6e-8  # the 27 numbers Filament parses are float32: half an ulp
FLOAT_FORMATS = [VkFormat.R16G16B16A16_SFLOAT, VkFormat.R32G32B32A32_SFLOAT, VkFormat.B10G11R11_UFLOAT_PACK32,
                 VkFormat.E5B9G9R9_UFLOAT_PACK32]
BYTE_FORMATS = [VkFormat.R8G8B8A8_UNORM, VkFormat.R8G8B8A8_SRGB]
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def chain(size: int, count: int, cube: bool, channels: int = 3, seed: int = 0, scale: float = 50.0) -> list:
    rng = np.random.default_rng(seed)
    shape = (lambda n: (6, n, n, channels)) if cube else (lambda n: (max(1, n // 2), n, channels))
    return [rng.uniform(0, scale, shape(max(1, size >> i))) for i in range(count)]


def expected_decoded(levels, fmt: VkFormat) -> list:
    """What a reader must give back for float levels: the format's own rounding of the input."""
    out = []
    for a in levels:
        a = np.asarray(a, np.float64)
        a = a if a.ndim == 4 else a[None]
        if fmt == VkFormat.E5B9G9R9_UFLOAT_PACK32:
            out.append(decode_rgb9e5(encode_rgb9e5(a)))
        elif fmt == VkFormat.B10G11R11_UFLOAT_PACK32:
            out.append(decode_b10g11r11(encode_b10g11r11(a)))
        else:
            rgba = np.concatenate([a, np.ones(a.shape[:-1] + (1,))], -1) if a.shape[-1] == 3 else a
            out.append(rgba.astype(np.float16 if fmt == VkFormat.R16G16B16A16_SFLOAT else np.float32).astype(np.float32))
    return out


# ---- RGB9E5 -------------------------------------------------------------------------------------------------------
def test_rgb9e5_known_words():
    assert encode_rgb9e5([1.0, 1.0, 1.0]) == 256 | 256 << 9 | 256 << 18 | 16 << 27
    assert encode_rgb9e5([0.0, 0.0, 0.0]) == 0
    assert encode_rgb9e5([RGB9E5_MAX, 0, 0]) == 511 | 31 << 27
    assert encode_rgb9e5([np.inf, -5.0, 1e30]) == encode_rgb9e5([RGB9E5_MAX, 0, RGB9E5_MAX])


def test_rgb9e5_round_trips_every_canonical_word_exactly():
    """A word the encoder can make (exponent 0, or a largest mantissa ≥ 256) decodes and encodes back to itself."""
    rng = np.random.default_rng(1)
    mant = rng.integers(0, 512, (200_000, 3))
    exp = rng.integers(0, 32, 200_000)
    canonical = (exp == 0) | (mant.max(axis=1) >= 256)
    words = (mant[:, 0] | mant[:, 1] << 9 | mant[:, 2] << 18 | exp << 27).astype(np.uint32)[canonical]
    np.testing.assert_array_equal(encode_rgb9e5(decode_rgb9e5(words)), words)


def test_rgb9e5_picks_the_smallest_exponent_and_rounds_each_channel_to_half_a_step():
    rng = np.random.default_rng(2)
    x = np.exp(rng.uniform(-25, 11.5, (50_000, 3))) * (rng.random((50_000, 3)) > 0.1)
    words = encode_rgb9e5(x)
    x = np.minimum(x, RGB9E5_MAX)  # larger values are clamped first
    step = np.exp2((words >> 27).astype(np.float64) - 24)
    assert (np.abs(decode_rgb9e5(words) - x) <= 0.5 * step[:, None] * (1 + 1e-12)).all()
    # one exponent less could not hold the largest channel: its mantissa would round to 512 or more
    smaller = (words >> 27) > 0
    assert (np.floor(x.max(axis=1)[smaller] / (step[smaller] / 2) + 0.5) >= 512).all()


def test_rgb9e5_refuses_nan():
    with pytest.raises(UsageError, match="NaN"):
        encode_rgb9e5([[1.0, np.nan, 0.0]])


# ---- B10G11R11 ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bits, mask, largest", [(0, 0x7FF, UF11_MAX), (11, 0x7FF, UF11_MAX), (22, 0x3FF, UF10_MAX)])
def test_b10g11r11_rounds_to_the_nearest_code_ties_to_even(bits, mask, largest):
    codes = np.arange(mask + 1, dtype=np.uint32)
    values = decode_b10g11r11(codes << bits)[:, bits // 11]
    finite = np.isfinite(values)
    codes, values = codes[finite], values[finite]
    assert values.max() == largest
    rgb = np.zeros((len(values), 3))
    rgb[:, bits // 11] = values
    np.testing.assert_array_equal((encode_b10g11r11(rgb) >> bits) & mask, codes)  # every code round trips
    rng = np.random.default_rng(3)
    x = np.concatenate([np.exp(rng.uniform(-20, 11.2, 20_000)), (values[:-1] + values[1:]) / 2])  # with every tie
    distance = np.abs(x[:, None] - values[None, :])
    best = distance.min(axis=1, keepdims=True)
    candidates = np.where(distance == best, codes[None, :], 1 << 20)
    even = np.where((candidates % 2 == 0) & (candidates < 1 << 20), candidates, 1 << 20).min(axis=1)
    want = np.where(even < 1 << 20, even, candidates.min(axis=1))
    rgb = np.zeros((len(x), 3))
    rgb[:, bits // 11] = x
    np.testing.assert_array_equal((encode_b10g11r11(rgb) >> bits) & mask, want)


def test_b10g11r11_clamps_to_finite_and_zero():
    got = decode_b10g11r11(encode_b10g11r11([[np.inf, 1e9, -3.0]]))
    np.testing.assert_array_equal(got, [[UF11_MAX, UF11_MAX, 0.0]])
    with pytest.raises(UsageError, match="NaN"):
        encode_b10g11r11([[np.nan, 0, 0]])


# ---- KTX2 ---------------------------------------------------------------------------------------------------------
@FUZZ
@given(fmt=st.sampled_from(FLOAT_FORMATS + BYTE_FORMATS), cube=st.booleans(), size=st.sampled_from([1, 2, 4, 8, 5]),
       zstd=st.booleans(), data=st.data())
def test_ktx2_round_trips_cubes_and_2d_mips_in_every_format(fmt, cube, size, zstd, data):
    count = data.draw(st.integers(1, size.bit_length()))
    channels = 3 if fmt in (VkFormat.B10G11R11_UFLOAT_PACK32, VkFormat.E5B9G9R9_UFLOAT_PACK32) else \
        data.draw(st.sampled_from([3, 4]))
    levels = chain(size, count, cube, channels, seed=data.draw(st.integers(0, 99)))
    if fmt in BYTE_FORMATS:
        levels = [(a * 5).astype(np.uint8) for a in levels]
    t = read_ktx2(ktx2_bytes(levels, fmt, zstd=zstd, key_values={"lightprobe.quantity": "radiance"}))
    assert (t.vk_format, t.face_count, t.level_count, t.width) == (fmt, 6 if cube else 1, count, size)
    assert t.supercompression == (2 if zstd else 0) and t.text("lightprobe.quantity") == "radiance"
    if fmt in BYTE_FORMATS:
        for got, a in zip(t.levels, levels):
            a = a if cube else a[None]
            np.testing.assert_array_equal(got[..., :channels], a)
            assert (got[..., 3] == 255).all() or channels == 4
    else:
        for got, want in zip(t.levels, expected_decoded(levels, fmt)):
            np.testing.assert_array_equal(got, want)


def test_ktx2_layout_follows_the_specification():
    levels = chain(8, 4, True)
    data = ktx2_bytes(levels, VkFormat.R32G32B32A32_SFLOAT, key_values={"b": "2", "a": b"\x01"})
    assert data[:12] == IDENTIFIER
    vk, type_size, w, h, d, layers, faces, count, scheme = struct.unpack_from("<9I", data, 12)
    assert (vk, type_size, w, h, d, layers, faces, count, scheme) == (109, 4, 8, 8, 0, 0, 6, 4, 0)
    dfd_offset, dfd_length, kvd_offset, kvd_length, sgd_offset, sgd_length = struct.unpack_from("<4I2Q", data, 48)
    assert dfd_offset == 80 + 24 * 4 and kvd_offset == dfd_offset + dfd_length and (sgd_offset, sgd_length) == (0, 0)
    index = [struct.unpack_from("<3Q", data, 80 + 24 * i) for i in range(4)]
    offsets = [o for o, _, _ in index]
    assert offsets == sorted(offsets, reverse=True)  # smallest level first in the file
    assert all(o % 16 == 0 for o in offsets) and offsets[0] + index[0][1] == len(data)
    assert [n for _, n, _ in index] == [6 * 16 * (8 >> i) ** 2 for i in range(4)]
    assert offsets[-1] - (kvd_offset + kvd_length) < 16 and not data[kvd_offset + kvd_length:offsets[-1]].strip(b"\0")
    keys, pos = [], kvd_offset  # sorted by key; each entry padded to 4 with zeros
    while pos < kvd_offset + kvd_length:
        (n,) = struct.unpack_from("<I", data, pos)
        keys.append(data[pos + 4:pos + 4 + n].split(b"\0")[0].decode())
        assert not data[pos + 4 + n:pos + 4 + n + (-n % 4)].strip(b"\0")
        pos += 4 + n + (-n % 4)
    assert keys == ["KTXwriter", "a", "b"]  # a cube map has no KTXorientation
    assert read_ktx2(ktx2_bytes([levels[0][0]])).text("KTXorientation") == "rd"


def test_ktx2_descriptor_matches_khronos_dfdutils():
    """Values KTX-Software's createdfd.c writes for each format (sampleLower/Upper raw uint32)."""
    e5 = format_info(VkFormat.E5B9G9R9_UFLOAT_PACK32)["samples"]
    assert [(s["bit_offset"], s["bit_length"], s["channel_type"], s["lower"], s["upper"]) for s in e5] == [
        (0, 8, 0, 0, 8448), (27, 4, 0x20, 15, 31), (9, 8, 1, 0, 8448), (27, 4, 0x21, 15, 31),
        (18, 8, 2, 0, 8448), (27, 4, 0x22, 15, 31)]
    b10 = format_info(VkFormat.B10G11R11_UFLOAT_PACK32)["samples"]
    assert [(s["bit_offset"], s["bit_length"], s["channel_type"], s["lower"], s["upper"]) for s in b10] == [
        (0, 10, 0x80, 0, 0x3F800000), (11, 10, 0x81, 0, 0x3F800000), (22, 9, 0x82, 0, 0x3F800000)]
    half = format_info(VkFormat.R16G16B16A16_SFLOAT)["samples"]
    assert [s["channel_type"] for s in half] == [0xC0, 0xC1, 0xC2, 0xCF]
    assert {(s["lower"], s["upper"]) for s in half} == {(0xBF800000, 0x3F800000)}
    srgb = format_info(VkFormat.R8G8B8A8_SRGB)
    assert [s["channel_type"] for s in srgb["samples"]] == [0, 1, 2, 0x1F] and srgb["transfer_function"] == 2
    t = read_ktx2(ktx2_bytes(chain(4, 1, True), VkFormat.R16G16B16A16_SFLOAT, zstd=True))
    assert (t.dfd["color_model"], t.dfd["color_primaries"], t.dfd["transfer_function"], t.dfd["version"]) == (1, 1, 1, 2)
    assert t.dfd["bytes_plane"] == [8, 0, 0, 0, 0, 0, 0, 0] and t.dfd["block_size"] == 24 + 16 * 4


def test_ktx2_refuses_bad_levels_keys_and_nan(tmp_path):
    with pytest.raises(UsageError, match="level 1"):
        ktx2_bytes([np.zeros((6, 4, 4, 3)), np.zeros((6, 3, 3, 3))])
    with pytest.raises(UsageError, match="at most 3"):
        ktx2_bytes([np.zeros((6, 4 >> i, 4 >> i, 3)) for i in range(3)] + [np.zeros((6, 1, 1, 3))])
    with pytest.raises(UsageError, match="NaN"):
        ktx2_bytes([np.full((2, 2, 3), np.nan)])
    with pytest.raises(UsageError, match="KTXwriter"):
        ktx2_bytes([np.zeros((2, 2, 3))], key_values={"KTXwriter": "me"})
    with pytest.raises(UsageError, match="unknown KTX2 format"):
        ktx2_bytes([np.zeros((2, 2, 3))], "R8_UNORM")
    with pytest.raises(UsageError, match="uint8"):
        ktx2_bytes([np.zeros((2, 2, 4))], VkFormat.R8G8B8A8_SRGB)
    path = write_ktx2(tmp_path / "a.ktx2", [np.ones((2, 2, 3))], "VK_FORMAT_B10G11R11_UFLOAT_PACK32")
    assert read_ktx2(path).vk_format == VkFormat.B10G11R11_UFLOAT_PACK32


def test_ktx2_float16_clamps_to_its_largest_finite_value():
    t = read_ktx2(ktx2_bytes([np.array([[[1e6, -1e6, np.inf]]])]))
    np.testing.assert_array_equal(t.levels[0][0, 0, 0], [65504, -65504, 65504, 1])


@FUZZ
@given(zstd=st.booleans(), cut=st.integers(0, 10_000), edits=st.lists(st.tuples(st.integers(0, 10_000),
                                                                               st.integers(0, 255)), max_size=6))
def test_ktx2_reader_refuses_hostile_files_in_one_line(zstd, cut, edits):
    data = bytearray(ktx2_bytes(chain(4, 3, True), VkFormat.R16G16B16A16_SFLOAT, zstd=zstd,
                                key_values={"k": "v"}))
    for where, value in edits:
        data[where % len(data)] = value
    data = bytes(data[:len(data) - cut % len(data)] if cut % 3 == 0 else data)
    try:
        read_ktx2(data)
    except InputError as e:
        assert "\n" not in str(e)


def test_ktx2_reader_bounds_stated_sizes_before_allocating():
    data = bytearray(ktx2_bytes(chain(4, 1, True), zstd=True))
    struct.pack_into("<Q", data, 80 + 16, 1 << 40)  # uncompressedByteLength: a terabyte
    with pytest.raises(InputError, match="uncompressedByteLength"):
        read_ktx2(bytes(data))
    data = bytearray(ktx2_bytes(chain(4, 1, True)))
    struct.pack_into("<I", data, 12 + 8, 1 << 30)  # pixelWidth
    with pytest.raises(InputError, match="face"):
        read_ktx2(bytes(data))
    with pytest.raises(InputError, match="identifier"):
        read_ktx2(b"KTX 11" + bytes(100))


# ---- KTX1 ---------------------------------------------------------------------------------------------------------
def test_filament_sh_text_is_what_cmgen_streams():
    sh = np.array([[0.199599, 0.197587, 0.208682], [1e-5, -0.0538860, 123456789.0]] + [[0.5, 1, -2]] * 7)
    text = filament_sh_text(sh)
    assert text.splitlines()[:2] == ["0.199599 0.197587 0.208682", "1e-05 -0.053886 1.23457e+08"]
    assert text.endswith("\n") and text.count("\n") == 9 and "  " not in text
    np.testing.assert_allclose(parse_filament_sh(text), sh, rtol=SH_TEXT_RELATIVE)
    # Filament's own test text (libs/image/tests/test_image.cpp), leading spaces and all
    filament_test = ("0.199599 0.197587 0.208682\n    0.0894955 0.126985 0.187462\n" + "    1 2 3\n" * 7)
    assert parse_filament_sh(filament_test)[1, 0] == 0.0894955
    with pytest.raises(InputError, match="27 numbers"):
        parse_filament_sh("1 2 3")
    with pytest.raises(UsageError, match="NaN"):
        filament_sh_text(np.full((9, 3), np.nan))


@pytest.mark.parametrize("name", list(FORMATS))
def test_ktx1_header_and_levels_are_laid_out_as_filament_serializes(name):
    fmt = FORMATS[name]
    levels = chain(16, 3, True, channels=fmt.channels[0])
    if fmt.gl_type == 0x1401:
        levels = [(a * 5).astype(np.uint8) for a in levels]
    data = ktx1_bytes(levels, name, sh=np.ones((9, 3)))
    fields = struct.unpack_from("<13I", data, 12)
    assert fields == (0x04030201, fmt.gl_type, fmt.gl_type_size, fmt.gl_format, fmt.gl_internal_format,
                      fmt.gl_base_internal_format, 16, 16, 0, 0, 6, 3, fields[12])
    sh_entry = b"sh\0" + filament_sh_text(np.ones((9, 3))).encode()
    assert data[64:68] == struct.pack("<I", len(sh_entry)) and data[68:68 + len(sh_entry)] == sh_entry
    pos = 64 + fields[12]
    for i in range(3):
        face = (16 >> i) ** 2 * fmt.texel_bytes
        assert struct.unpack_from("<I", data, pos)[0] == face  # a non-array cube's imageSize: one face
        pos += 4 + 6 * face  # no cube or mip padding
    assert pos == len(data)
    t = read_ktx1(data)
    assert t.format is fmt and t.mip_levels == 3 and t.faces == 6 and np.array_equal(t.sh, np.ones((9, 3)))


def test_ktx1_r11f_uses_cmgens_gl_type_and_round_trips():
    levels = chain(8, 4, True, seed=4)
    t = read_ktx1(ktx1_bytes(levels))
    assert (t.gl_type, t.gl_type_size, t.gl_format, t.gl_internal_format) == (0x8C3A, 1, 0x1907, 0x8C3A)
    for got, want in zip(t.levels, expected_decoded(levels, VkFormat.B10G11R11_UFLOAT_PACK32)):
        np.testing.assert_array_equal(got, want)
    sky = read_ktx1(ktx1_bytes(chain(8, 1, False), "rgb16f"))
    assert sky.faces == 1 and sky.levels[0].shape == (1, 4, 8, 3)


def test_ktx1_refuses_faces_that_would_need_padding():
    with pytest.raises(UsageError, match="multiple of 4"):
        ktx1_bytes(chain(4, 3, True), "rgb16f")  # the 1×1 level: 6 bytes a face
    ktx1_bytes(chain(4, 3, True), "rgba16f")


@FUZZ
@given(cut=st.integers(0, 10_000), edits=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255)),
                                                  max_size=6))
def test_ktx1_reader_refuses_hostile_files_in_one_line(cut, edits):
    data = bytearray(ktx1_bytes(chain(4, 3, True), sh=np.ones((9, 3)), key_values={"k": "v"}))
    for where, value in edits:
        data[where % len(data)] = value
    data = bytes(data[:len(data) - cut % len(data)] if cut % 3 == 0 else data)
    try:
        t = read_ktx1(data)
        t.sh
    except InputError as e:
        assert "\n" not in str(e)


def test_write_ktx1_writes_atomically(tmp_path):
    path = write_ktx1(tmp_path / "ibl.ktx", chain(4, 3, True), sh=np.zeros((9, 3)))
    assert read_ktx1(path).mip_levels == 3 and not [p for p in tmp_path.iterdir() if p.name != "ibl.ktx"]


# ---- the reference readers ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def node_readers():
    from lightprobe_engines.runtimes import filament_ktx1, ktx_parse, missing_engines

    missing = [m for m in missing_engines() if "node" in m]
    if missing:
        pytest.fail(f"the KTX reference readers need {', '.join(missing)}: run 'bash setup.sh --test'", pytrace=False)
    return ktx_parse, filament_ktx1


def test_ktx_parse_reads_every_format_back_unchanged(tmp_path, node_readers):
    import zstandard

    ktx_parse, _ = node_readers
    files, written = [], []
    for k, fmt in enumerate(FLOAT_FORMATS + BYTE_FORMATS):
        for zstd in (False, True):
            levels = chain(8, 4, k % 2 == 0, seed=k)
            if fmt in BYTE_FORMATS:
                levels = [(a * 5).astype(np.uint8) for a in levels]
            path = write_ktx2(tmp_path / f"{fmt.name}-{zstd}.ktx2", levels, fmt, zstd=zstd,
                              key_values={"lightprobe.frame": "threejs"})
            files.append(path)
            written.append(read_ktx2(path))
    for ours, theirs in zip(written, ktx_parse(files)):
        assert (theirs["vkFormat"], theirs["typeSize"], theirs["pixelWidth"], theirs["pixelHeight"],
                theirs["pixelDepth"], theirs["layerCount"], theirs["faceCount"], theirs["levelCount"],
                theirs["supercompressionScheme"]) == (
            ours.vk_format, ours.type_size, ours.width, ours.height, 0, 0, ours.face_count, ours.level_count,
            ours.supercompression)
        dfd = theirs["dataFormatDescriptor"][0]
        assert (dfd["colorModel"], dfd["colorPrimaries"], dfd["transferFunction"], dfd["flags"]) == (
            1, 1, ours.dfd["transfer_function"], 0)
        assert dfd["bytesPlane"] == ours.dfd["bytes_plane"] and dfd["texelBlockDimension"] == [0, 0, 0, 0]
        assert [(s["bitOffset"], s["bitLength"], s["channelType"], s["sampleLower"] & 0xFFFFFFFF,
                 s["sampleUpper"] & 0xFFFFFFFF) for s in dfd["samples"]] == [
            (s["bit_offset"], s["bit_length"], s["channel_type"], s["lower"], s["upper"])
            for s in format_info(ours.vk_format)["samples"]]
        assert theirs["keyValue"]["KTXwriter"]["text"] == ours.text("KTXwriter").strip()
        assert base64.b64decode(theirs["keyValue"]["lightprobe.frame"]["base64"]) == b"threejs\0"
        for level, raw in zip(theirs["levels"], ours.level_bytes):
            stored = base64.b64decode(level["base64"])
            assert level["uncompressedByteLength"] == len(raw)
            inflated = zstandard.ZstdDecompressor().decompress(stored) if ours.supercompression else stored
            assert inflated == raw


def test_filaments_ktx1bundle_reads_our_ibl_skybox_and_sh(tmp_path, node_readers):
    _, filament_ktx1 = node_readers
    sh = np.random.default_rng(5).normal(size=(9, 3))
    ibl = write_ktx1(tmp_path / "probe_ibl.ktx", chain(16, 5, True, seed=6), sh=sh)
    sky = write_ktx1(tmp_path / "probe_skybox.ktx", chain(16, 1, True, seed=7), "rgba16f")
    ldr = write_ktx1(tmp_path / "ldr.ktx", [(a * 5).astype(np.uint8) for a in chain(8, 1, False)], "srgb8_alpha8")
    for path, theirs in zip((ibl, sky, ldr), filament_ktx1([ibl, sky, ldr])):
        ours = read_ktx1(path)
        assert theirs["info"] == {"endianness": 0x04030201, "glType": ours.gl_type, "glTypeSize": ours.gl_type_size,
                                  "glFormat": ours.gl_format, "glInternalFormat": ours.gl_internal_format,
                                  "glBaseInternalFormat": ours.gl_base_internal_format, "pixelWidth": ours.width,
                                  "pixelHeight": ours.height, "pixelDepth": 0}
        assert theirs["levels"] == ours.mip_levels and theirs["cube"] == (ours.faces == 6)
        assert [base64.b64decode(b) for b in theirs["blobs"]] == ours.level_bytes
    filament_ibl = filament_ktx1([ibl])[0]
    assert filament_ibl["sh"] == filament_sh_text(sh)
    # the 27 numbers Filament's createIblFromKtx1 takes are cmgen's 6-digit text of ours
    np.testing.assert_allclose(np.reshape(filament_ibl["shFloats"], (9, 3)), sh,
                               rtol=SH_TEXT_RELATIVE + FLOAT32_RELATIVE, atol=1e-300)
