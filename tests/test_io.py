"""Image files: round trips per format, PFM orientation, sRGB decoding, atomic writes, limits, repair."""

from __future__ import annotations

import os
import stat

import numpy as np
import OpenImageIO as oiio
import pytest

from conftest import shared
from lightprobe.maps import images as lpio
from lightprobe.maps import read_envmap
from lightprobe.util.errors import LightprobeError, InputError, LightprobeWarning
from lightprobe.maps.images import read_image, write_image
from lightprobe.maps.tonemap import aces_filmic, srgb_decode, srgb_encode, tonemap


@pytest.fixture
def hdr_pixels():
    rng = np.random.default_rng(3)
    return (rng.random((12, 24, 3)) ** 4 * 1000).astype(np.float32)


@pytest.mark.parametrize("ext", [".exr", ".pfm"])
def test_float_formats_round_trip_exactly(tmp_path, hdr_pixels, ext):
    path = write_image(tmp_path / f"a{ext}", hdr_pixels)
    np.testing.assert_array_equal(read_image(path), hdr_pixels)


def test_half_exr_round_trip(tmp_path, hdr_pixels):
    back = read_image(write_image(tmp_path / "a.exr", hdr_pixels, half=True))
    np.testing.assert_allclose(back, hdr_pixels, rtol=1e-3, atol=1e-4)
    assert oiio.ImageInput.open(str(tmp_path / "a.exr")).spec().format == oiio.TypeDesc("half")


def test_half_overflow_is_refused(tmp_path):
    with pytest.raises(InputError, match="half"):
        write_image(tmp_path / "a.exr", np.full((2, 4, 3), 70000.0, np.float32), half=True)
    assert list(tmp_path.iterdir()) == []


def test_rgbe_round_trip_within_its_precision(tmp_path, hdr_pixels):
    back = read_image(write_image(tmp_path / "a.hdr", hdr_pixels))
    # RGBE keeps 8 mantissa bits of the brightest channel: relative error ≤ 2⁻⁸ of that channel
    assert np.all(np.abs(back - hdr_pixels) <= hdr_pixels.max(axis=-1, keepdims=True) / 128)


def test_pfm_rows_are_read_top_first(tmp_path):
    """A PFM stores its bottom row first; row 0 of what we read must be the top of the picture."""
    w, h = 2, 3
    rows = [np.full((w, 3), r + 1, np.float32) for r in range(h)]  # picture: top row 1, bottom row 3
    body = b"".join(rows[r].tobytes() for r in reversed(range(h)))
    (tmp_path / "t.pfm").write_bytes(b"PF\n%d %d\n-1.0\n" % (w, h) + body)
    np.testing.assert_array_equal(read_image(tmp_path / "t.pfm")[:, 0, 0], [1, 2, 3])
    # and what we write is a standard PFM (bottom row first in the file)
    write_image(tmp_path / "w.pfm", np.stack(rows))
    raw = (tmp_path / "w.pfm").read_bytes()
    np.testing.assert_array_equal(np.frombuffer(raw[-w * h * 12:], np.float32).reshape(h, w, 3)[:, 0, 0], [3, 2, 1])


def test_ldr_files_are_decoded_to_linear(tmp_path):
    img = np.zeros((2, 2, 3), np.uint8)
    img[0, 0] = [255, 128, 0]
    spec = oiio.ImageSpec(2, 2, 3, "uint8")
    out = oiio.ImageOutput.create(str(tmp_path / "a.png"))
    out.open(str(tmp_path / "a.png"), spec)
    out.write_image(img)
    out.close()
    px = read_image(tmp_path / "a.png")
    np.testing.assert_allclose(px[0, 0], [1.0, srgb_decode(np.float32(128 / 255)), 0.0], atol=1e-6)
    assert abs(px[0, 0, 1] - 0.2158605) < 1e-5  # sRGB 128 is 21.6 % linear


def test_png_output_is_tone_mapped(tmp_path):
    lin = np.array([[[0.0, 0.18, 1.0], [4.0, 0.5, 0.01]]], np.float32)
    write_image(tmp_path / "a.png", lin, exposure=1.0)
    got = oiio.ImageInput.open(str(tmp_path / "a.png")).read_image("uint8")
    np.testing.assert_array_equal(got, np.rint(srgb_encode(np.clip(lin * 2, 0, 1)) * 255))


def test_grey_images_become_rgb(tmp_path):
    spec = oiio.ImageSpec(4, 2, 1, "float")
    out = oiio.ImageOutput.create(str(tmp_path / "g.exr"))
    out.open(str(tmp_path / "g.exr"), spec)
    out.write_image(np.arange(8, dtype=np.float32).reshape(2, 4, 1))
    out.close()
    px = read_image(tmp_path / "g.exr")
    assert px.shape == (2, 4, 3) and np.all(px[..., 0] == px[..., 2])


def test_exr_channels_are_taken_by_name(tmp_path):
    spec = oiio.ImageSpec(2, 1, 4, "float")
    spec.channelnames = ("A", "B", "G", "R")
    out = oiio.ImageOutput.create(str(tmp_path / "c.exr"))
    out.open(str(tmp_path / "c.exr"), spec)
    out.write_image(np.array([[[9, 3, 2, 1], [9, 3, 2, 1]]], np.float32))
    out.close()
    np.testing.assert_array_equal(read_image(tmp_path / "c.exr")[0, 0], [1, 2, 3])


def test_real_files_read_with_expected_shapes():
    assert read_image(shared("debevec/angular/grace_probe.hdr")).shape == (1000, 1000, 3)
    assert read_image(shared("debevec/cross/grace_cross.hdr")).shape == (1024, 768, 3)
    exr = read_image(shared("debevec/latlong/grace_latlong.exr"))  # half, B G R order in the file
    assert exr.shape == (512, 1024, 3) and exr.dtype == np.float32


def test_write_is_atomic_and_leaves_nothing_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "out.exr"
    target.write_bytes(b"old contents")

    def broken_create(path):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(lpio.oiio.ImageOutput, "create", broken_create)
    with pytest.raises(RuntimeError):
        write_image(target, np.zeros((2, 4, 3), np.float32))
    assert target.read_bytes() == b"old contents"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]


def test_written_files_have_ordinary_permissions(tmp_path):
    path = write_image(tmp_path / "a.exr", np.zeros((2, 4, 3), np.float32))
    mode = stat.S_IMODE(os.stat(path).st_mode)
    assert mode & 0o044, oct(mode)  # readable by group/others as the umask allows, not mkstemp's 0600


def test_unknown_output_format(tmp_path):
    with pytest.raises(InputError, match="unknown image format"):
        write_image(tmp_path / "a.xyz", np.zeros((2, 4, 3), np.float32))


def test_absurd_header_is_refused_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.hdr"
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 60000 +X 60000\n" + b"\x00" * 64)
    with pytest.raises(LightprobeError, match="limit"):
        read_image(path)
    monkeypatch.setenv("LIGHTPROBE_MAX_PIXELS", "100")
    with pytest.raises(LightprobeError, match="limit"):
        read_image(shared("ict_lowres/grace.hdr"))


def test_missing_and_folder_inputs(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_image(tmp_path / "nope.hdr")
    with pytest.raises(InputError, match="folder"):
        read_image(tmp_path)


def test_bad_pixels_are_repaired_with_a_count(tmp_path):
    px = np.ones((8, 16, 3), np.float32)
    px[0, 0] = np.nan
    px[1, 1, 2] = np.inf
    px[2, 2, 0] = -5
    write_image(tmp_path / "bad.exr", px)
    with pytest.warns(LightprobeWarning, match="1 NaN, 1 infinite and 1 negative"):
        env = read_envmap(tmp_path / "bad.exr")
    assert np.isfinite(env.data).all() and env.data.min() == 0
    raw = read_envmap(tmp_path / "bad.exr", fix=False)
    s = raw.stats()
    assert (s["nan_pixels"], s["inf_pixels"], s["negative_pixels"]) == (1, 1, 1)


def test_tone_curves():
    x = np.array([0.0, 0.18, 1.0, 100.0], np.float32)
    assert tonemap(x, curve="srgb")[-1] > 0.9999
    a = aces_filmic(x)
    assert np.all(np.diff(a) > 0) and a[-1] == 1.0 and abs(aces_filmic(np.float32(0.18)) - 0.2669) < 1e-3
    np.testing.assert_allclose(srgb_decode(srgb_encode(np.linspace(0, 1, 50))), np.linspace(0, 1, 50), atol=1e-6)
