"""Memory estimates against measured peaks: each command's estimate (read from its refusal under a 1-byte budget)
must lie between the peak resident memory it really reaches and 3× that — an upper bound that still means something.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import shared
from lightprobe.envmap import read_envmap
from lightprobe.io import write_image
from test_hardening import clean_failure, lightprobe, peak_of


@pytest.fixture(scope="module")
def big_map(tmp_path_factory):
    """A 2048×1024 lat-long map (Rooitou Park, up-sampled), big enough for per-pixel costs to dominate."""
    path = tmp_path_factory.mktemp("limits") / "m2048.exr"
    return write_image(path, read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr")).to("latlong", 1024).data)


def estimate_mib(*argv) -> float:
    res = lightprobe(*argv, env={"LIGHTPROBE_MAX_MEMORY": "1"})
    clean_failure(res, "LIGHTPROBE_MAX_MEMORY")
    value, unit = re.search(r"needs about ([\d.]+) (MiB|GiB)", res.stderr).groups()
    return float(value) * (1024 if unit == "GiB" else 1)


@pytest.mark.parametrize("argv", [
    ["info", "{m}"],
    ["sh", "{m}", "--order", "4"],
    ["convert", "{m}", "{out}/c.exr", "--to", "cube", "--size", "256"],
    ["convert", "{m}", "{out}/a.png", "--to", "angular", "--size", "1024"],
    ["error", "{m}", "--order", "2", "--normals", "100"],
    ["compare", "{m}", "{m}"],
    ["render", "-o", "{out}/r.exr", "--size", "512x512", "--spp", "2"],
])
def test_memory_estimates_bound_the_measured_peak(big_map, tmp_path, argv):
    args = [a.format(m=big_map, out=tmp_path) for a in argv]
    estimate = estimate_mib(*args)
    res, peak = peak_of(*args)
    assert res.returncode == 0, res.stderr
    assert peak <= estimate <= 3 * peak, (peak, estimate)
