"""Hostile input for every reader: random bytes, truncated and mutated real files. Always a clean InputError (or a
valid image), never another exception, a crash or a hang."""

from __future__ import annotations

import functools
import warnings
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import shared
from lightprobe.maps import read_envmap
from lightprobe.util.errors import LightprobeError, LightprobeWarning
from lightprobe.maps.images import read_image, write_image

FUZZ = settings(max_examples=60, deadline=5000, suppress_health_check=[HealthCheck.function_scoped_fixture])
EXTENSIONS = [".hdr", ".exr", ".pfm", ".png", ".jpg"]


def _read_or_clean_error(path):
    try:
        with warnings.catch_warnings():  # repairing NaN or negative pixels is expected here, not noise
            warnings.simplefilter("ignore", LightprobeWarning)
            img = read_envmap(path, fix=True)
    except LightprobeError as e:
        assert "\n" not in str(e) and str(e)
        return None
    assert img.data.dtype == np.float32 and np.isfinite(img.data).all()
    return img


@functools.cache
def sample_bytes(ext: str) -> bytes:
    """A small real file of each readable format (not a fixture: hypothesis would print all its bytes)."""
    if ext == ".hdr":
        return shared("ict_lowres/grace.hdr").read_bytes()
    px = read_image(shared("ict_lowres/grace.hdr"))[::4, ::4]  # 64×32, a real probe
    with tempfile.TemporaryDirectory() as folder:
        return write_image(Path(folder) / f"s{ext}", px).read_bytes()


@pytest.mark.parametrize("ext", EXTENSIONS)
@given(data=st.binary(min_size=0, max_size=2048))
@FUZZ
def test_random_bytes(tmp_path, ext, data):
    path = tmp_path / f"r{ext}"
    path.write_bytes(data)
    _read_or_clean_error(path)


@pytest.mark.parametrize("ext", EXTENSIONS)
@given(cut=st.floats(0.0, 0.98))
@FUZZ
def test_truncated_real_files(tmp_path, ext, cut):
    blob = sample_bytes(ext)
    path = tmp_path / f"t{ext}"
    path.write_bytes(blob[: int(len(blob) * cut)])
    _read_or_clean_error(path)


@pytest.mark.parametrize("ext", EXTENSIONS)
@given(edits=st.lists(st.tuples(st.integers(0, 255), st.integers(0, 255)), min_size=1, max_size=8))
@FUZZ
def test_mutated_headers(tmp_path, ext, edits):
    blob = bytearray(sample_bytes(ext))
    for pos, value in edits:
        blob[pos % min(len(blob), 160)] = value  # the first bytes hold the header
    path = tmp_path / f"m{ext}"
    path.write_bytes(bytes(blob))
    _read_or_clean_error(path)


@given(w=st.integers(1, 70000), h=st.integers(1, 70000))
@settings(max_examples=40, deadline=5000, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_hdr_header_sizes(tmp_path, w, h):
    """Any claimed size: a clean refusal or a valid image, never another exception. (That no memory of the claimed
    size is allocated is measured in test_hardening.py::test_the_hdr_reader_never_allocates_…)"""
    path = tmp_path / "s.hdr"
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w) + b"\x02\x02\x00\x10" * 8)
    _read_or_clean_error(path)


@functools.lru_cache(maxsize=1)
def _env_file() -> bytes:
    from lightprobe.exports.containers import babylon_env
    from lightprobe.maps import EnvMap
    from lightprobe.maps.layouts import LATLONG
    from lightprobe.sh.basis import project

    env = EnvMap(np.ones((8, 16, 3), np.float32), LATLONG)
    return babylon_env(env, project(env, 2), 2)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=st.lists(st.tuples(st.integers(0, 4095), st.integers(0, 255)), min_size=0, max_size=8),
       cut=st.integers(0, 4096))
def test_env_manifest_reader_returns_a_manifest_or_one_clear_error(edits, cut):
    """Babylon .env bytes cut short and with bytes changed: a dict, or InputError — never another exception."""
    from lightprobe.exports.containers import read_env_manifest

    data = bytearray(_env_file()[:cut] if cut < 4096 else _env_file())
    for position, value in edits:
        if position < len(data):
            data[position] = value
    try:
        manifest = read_env_manifest(bytes(data))
    except LightprobeError as e:
        assert "\n" not in str(e)
    else:
        assert isinstance(manifest, dict) and manifest["binaryDataPosition"] <= len(data)
