"""Memory estimates against measured peaks: each command's estimate (read from its refusal under a 1-byte budget)
must lie between the peak resident memory it really reaches and 3× that — an upper bound that still means something.
"""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import shared
from lightprobe.maps import read_envmap
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import LATLONG
from test_hardening import clean_failure, lightprobe, peak_of


@pytest.fixture(scope="module")
def big_map(tmp_path_factory):
    """A 2048×1024 lat-long map (Rooitou Park, up-sampled), big enough for per-pixel costs to dominate."""
    path = tmp_path_factory.mktemp("limits") / "m2048.exr"
    return write_image(path, read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr")).to("latlong", 1024).data)


@pytest.fixture(scope="module")
def half_map(big_map):
    """The same map at 1024×512."""
    return write_image(big_map.with_name("m1024.exr"), read_envmap(big_map).to("latlong", 512).data)


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
    ["compare", "{half}", "{half}"],  # 1024×512: HDR-FLIP of 2048×1024 takes over 2 minutes here
    ["render", "-o", "{out}/r.exr", "--size", "512x512", "--spp", "2"],
])
def test_memory_estimates_bound_the_measured_peak(big_map, half_map, tmp_path, argv):
    args = [a.format(m=big_map, half=half_map, out=tmp_path) for a in argv]
    estimate = estimate_mib(*args)
    res, peak = peak_of(*args)
    assert res.returncode == 0, res.stderr
    assert peak <= estimate <= 3 * peak, (peak, estimate)


@pytest.mark.parametrize("setting, expected", [("1", 1), (None, None)])
def test_one_thread_setting_for_kernels_and_blas(setting, expected):
    """LIGHTPROBE_THREADS sizes numba's pool and BLAS's before they load; unset, the kernels use every core."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS") and k != "LIGHTPROBE_THREADS"}
    if setting:
        env["LIGHTPROBE_THREADS"] = setting
    script = ("import os, numpy as np, lightprobe as lp, numba\n"
              "env = lp.EnvMap(np.ones((8, 16, 3), np.float32), lp.layout('latlong'))\n"
              "lp.project(env, 2)\n"
              "print(numba.get_num_threads(), os.environ.get('OPENBLAS_NUM_THREADS'))\n")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True).stdout
    threads, blas = out.split()
    if expected:
        assert (int(threads), blas) == (expected, setting)
    else:
        assert int(threads) == min(os.cpu_count(), 64) and blas == "None"


def test_a_malformed_thread_setting_is_one_line(tmp_path):
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = {**os.environ, "LIGHTPROBE_THREADS": "many"}
    res = subprocess.run([str(Path(sys.executable).parent / "lightprobe"), "sh", "--order", "2"], env=env,
                         capture_output=True, text=True)
    assert res.returncode == 2 and res.stderr.strip().splitlines() == [
        "lightprobe: error: LIGHTPROBE_THREADS must be a positive whole number, got 'many'"], res.stderr


def test_the_command_loads_numba_without_scipys_blas(tmp_path):
    """Numba's array support imports scipy.linalg (~26 MiB resident) only to know whether np.dot may compile; the
    command runs lightprobe's kernels alone, none of which uses it, so it loads numba without it — and scipy still
    imports afterwards. A library process (no :func:`lightprobe.util.jit.lean`) keeps numba as numba makes it."""
    import subprocess
    import sys

    src = write_image(tmp_path / "m.exr", np.ones((64, 128, 3), np.float32))
    script = ("import sys\nfrom lightprobe.cli import main\n"
              f"assert main(['convert', {str(src)!r}, {str(tmp_path / 'c.exr')!r}, '--to', 'cube']) == 0\n"
              "import numba.np.arraymath as m\n"
              "print('scipy.linalg' in sys.modules, m._HAVE_BLAS)\n"
              "import scipy.linalg.cython_blas\nprint('importable')\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.stdout.split()[-3:] == ["False", "False", "importable"], out.stderr
    library = ("import sys, numpy as np\nfrom lightprobe.maps import EnvMap\nfrom lightprobe.maps.layouts import layout\n"
               "EnvMap(np.ones((64, 128, 3), np.float32), layout('latlong')).to('cube', 8)\n"
               "import numba.np.arraymath as m\nprint(m._HAVE_BLAS)\n")
    out = subprocess.run([sys.executable, "-c", library], capture_output=True, text=True, timeout=300)
    assert out.stdout.split() == ["True"], out.stderr


@pytest.fixture(scope="module")
def map_4k(tmp_path_factory):
    """A 4096×2048 float32 lat-long map (96 MiB of pixels): the memory case."""
    path = tmp_path_factory.mktemp("limits4k") / "m4096.exr"
    return write_image(path, read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr")).to("latlong", 2048).data)


MAP_4K_MIB = 4096 * 2048 * 3 * 4 / 2**20


@pytest.mark.parametrize("argv, ceiling", [
    (["info", "{m}"], 3.0),
    (["sh", "{m}"], 3.0),
    (["sh", "{m}", "--order", "8"], 3.0),
    (["irradiance", "{m}", "--output", "{out}/e.exr"], 3.0),
    # convert runs the compiled resampler: numba and LLVM (~110 MiB resident without scipy's BLAS, ~70 of it
    # libllvmlite's file pages) + the source (96) + Python, numpy and OpenImageIO (72) made 3.35–3.45× with the
    # polar rows and the strips. It now links its kernels on a small map before reading the big one and lets LLVM's
    # pages go (jit.release_compiler_pages): 2.7–2.8× (2026-12-05). The output is streamed to the file.
    (["convert", "{m}", "{out}/c.exr", "--to", "cube"], 3.0),
    # a cross was one strip: the whole cross image, and 1.2 GB of float64 directions to place its tiles (15.8×)
    (["convert", "{m}", "{out}/x.exr", "--to", "hcross"], 3.0),
], ids=["info", "sh", "sh-order-8", "irradiance", "convert-cube", "convert-hcross"])
def test_peak_memory_on_a_4k_map_stays_within_a_few_maps(map_4k, tmp_path, argv, ceiling):
    """Peak resident memory of the command, in a subprocess (getrusage of the child), against the float32 map. The
    disc targets (36 s each here) are in benchmarks/bench_memory.py, which has every layout."""
    res, peak = peak_of(*[a.format(m=map_4k, out=tmp_path) for a in argv])
    assert res.returncode == 0, res.stderr
    assert peak <= ceiling * MAP_4K_MIB, f"{peak:.0f} MiB = {peak / MAP_4K_MIB:.2f}× the map"


def test_llvm_pages_are_released_and_kernels_still_run():
    """jit.release_compiler_pages drops libllvmlite's resident file pages once the kernels are linked (Linux), and a
    kernel called afterwards — one linked before, and one linked after (its LLVM pages read back) — still works."""
    script = ("import numpy as np\nfrom lightprobe.maps import EnvMap\nfrom lightprobe.maps.layouts import layout\n"
              "from lightprobe.util.jit import release_compiler_pages\n"
              "def file_kib():\n"
              "    return next(int(l.split()[1]) for l in open('/proc/self/status') if l.startswith('RssFile'))\n"
              "env = EnvMap(np.ones((64, 128, 3), np.float32), layout('latlong'))\n"
              "env.to('cube', 8)\nbefore = file_kib()\nadvised = release_compiler_pages()\nafter = file_kib()\n"
              "cube = env.to('cube', 16)\nangular = env.to('angular', 16)\n"
              "print(advised >> 20, (before - after) >> 10, float(cube.data.min()), float(cube.data.max()),"
              " float(angular.integral()[0] / env.integral()[0]))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    advised, dropped, low, high, kept = out.stdout.split()
    assert int(advised) > 50 and int(dropped) > 20, out.stdout  # MiB advised, MiB of file pages gone
    assert float(low) == float(high) == 1.0 and abs(float(kept) - 1) < 1e-5


@pytest.mark.parametrize("target, rows, corrected", [
    ("angular", 2048, False),  # a 4k lat-long into a disc: not flux-corrected, so nor is the small map
    ("sphere", 2048, False),
    ("sphere", 128, True),  # a small one is, and so is the small map it is linked on
    ("cube", 2048, False),
])
def test_kernels_are_linked_on_a_map_that_takes_the_conversions_route(monkeypatch, target, rows, corrected):
    """envmap.link_kernels runs a conversion's kernels on a small map before the big one is read: a lat-long of 64
    rows into a disc would be flux-corrected where a 4k one is not, and linking that correction kept ~5 MiB beside
    the map. The small map takes the same turn as the conversion itself would."""
    from lightprobe.maps.resampling import flux, resampler as resampling
    from lightprobe.maps.layouts import layout

    real = flux._corrected(LATLONG, (rows, 2 * rows), layout(target), None)
    assert real == corrected
    seen = []
    build = flux._flux_stencil

    def spy(source_layout, source_grid, target_layout, *args):
        seen.append((source_grid, flux._corrected(source_layout, source_grid, target_layout, None)))
        return build(source_layout, source_grid, target_layout, *args)

    monkeypatch.setattr(flux, "_flux_stencil", spy)
    size = layout(target).default_size(2 * rows * rows)
    resampling.link_kernels(LATLONG, 2 * rows * rows, layout(target), size)
    assert seen and all(small == corrected for _, small in seen), seen
    assert all(grid[0] <= 256 for grid, _ in seen), seen  # a small map: at most 256 rows
