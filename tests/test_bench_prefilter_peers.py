"""The pure helpers of benchmarks/bench_prefilter_peers.py: finding a peer's cube frame, and the peers' chain sizes
(the benchmark checks three.js's and Babylon's α per level against what the engines report in every run)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import shared
from lightprobe.maps import read_envmap, resample
from lightprobe.maps.frames import BABYLON, THREEJS
from lightprobe.maps.layouts import CUBE


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        yield importlib.import_module("bench_prefilter_peers")
    finally:
        sys.path.pop(0)


@pytest.mark.parametrize("frame", [THREEJS, BABYLON])
def test_register_finds_the_frame_a_cube_was_made_in(bench, frame):
    """A cube of the map in a known frame (texel d shows the world at frame.to_world(d)) is registered to that frame,
    by a clear margin over the next candidate."""
    env = read_envmap(shared("polyhaven_1k/venice_sunset_1k.hdr"))
    cube = resample(env, CUBE, 32, rotation=frame.to_frame).data
    found, fit, runner_up = bench.register(cube, env, count=2000)
    assert np.allclose(found.to_frame, frame.to_frame), (found.to_frame, fit, runner_up)
    assert fit < 0.05 < runner_up


def test_signed_permutations_are_the_48_cube_symmetries(bench):
    ms = bench.signed_permutations()
    assert len({m.tobytes() for m in ms}) == 48
    assert all(np.allclose(m @ m.T, np.eye(3)) for m in ms)


def test_peer_chain_sizes(bench):
    """glTF-IBL-Sampler's default level count (down to 2×2) and three.js's PMREM face for a panorama width (a quarter,
    a power of two, at least 256)."""
    assert [bench.gltf_sampler_levels(s) for s in (256, 512)] == [8, 9]
    assert [bench.three_pmrem_size(w) for w in (512, 1024, 2048, 3000, 4096)] == [256, 256, 512, 512, 1024]
