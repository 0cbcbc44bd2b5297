"""The command line: results, and bad input → one line on stderr, exit 2, no traceback, no partial output."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import shared
from lightprobe.cli import main
from lightprobe.maps import read_envmap
from lightprobe.maps.images import write_image


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean_failure(code, err, *words):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lightprobe: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in err, err


def test_info_json_on_the_shipped_probe(capsys):
    code, out, _ = run(capsys, "info", "--json")
    s = json.loads(out)
    assert code == 0 and s["layout"] == "latlong" and (s["width"], s["height"]) == (512, 256)
    assert s["nan_pixels"] == 0 and len(s["integral"]) == 3 and s["integral"][1] > 0


def test_info_reports_bad_pixels_without_repairing(tmp_path, capsys):
    px = np.ones((8, 16, 3), np.float32)
    px[0, 0, 0], px[1, 1, 1], px[2, 2, 2], px[3, 3, 0] = np.nan, np.inf, -1, -2
    write_image(tmp_path / "bad.exr", px)
    code, out, err = run(capsys, "info", tmp_path / "bad.exr", "--json")
    s = json.loads(out)
    assert code == 0 and (s["nan_pixels"], s["inf_pixels"], s["negative_pixels"]) == (1, 1, 2)


def test_convert_writes_the_layout_and_size(tmp_path, capsys):
    out = tmp_path / "c.exr"
    code, text, _ = run(capsys, "convert", shared("debevec/cross/grace_cross.hdr"), out, "--to", "cube", "--size", 32)
    assert code == 0 and out.exists()
    env = read_envmap(out)
    assert env.layout.name == "cube" and env.grid == (6, 32, 32)


def test_convert_rotate_moves_the_sun(tmp_path, capsys):
    src = read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr"))
    run(capsys, "convert", shared("polyhaven_1k/rooitou_park_1k.hdr"), tmp_path / "r.exr", "--to", "latlong",
        "--size", 128, "--rotate", "90,0,0")
    turned = read_envmap(tmp_path / "r.exr")

    def sun(env):
        i = np.unravel_index(np.argmax(env.data[..., 1]), env.grid)
        return env.directions()[i]

    from lightprobe.maps.frames import rotation_from_ypr

    assert np.dot(sun(turned), rotation_from_ypr(90, 0, 0) @ sun(src)) > np.cos(np.radians(2))


@pytest.mark.parametrize("argv,words", [
    (["info", "missing.hdr"], ["no such file"]),
    (["convert", "missing.hdr", "x.exr", "--to", "cube"], ["no such file"]),
    (["convert", "{cross}", "x.exr", "--to", "nope"], ["invalid choice"]),
    (["convert", "{cross}", "x.txt", "--to", "cube"], ["unknown image format"]),
    (["convert", "{cross}", "x.exr", "--to", "cube", "--rotate", "1,2"], ["--rotate", "three numbers"]),
    (["convert", "{cross}", "x.exr", "--to", "cube", "--size", "0"], ["--size"]),
    (["convert", "{cross}", "x.exr", "--to", "cube", "--size", "1000000"], ["--size", "1..65536"]),
    (["convert", "{cross}", "x.exr", "--to", "cube", "--size", "60000"], ["limit"]),
    (["info", "{cross}", "--layout", "latlong"], ["does not fit the latlong layout"]),
    (["info", "{corrupt}"], ["cannot read"]),
    (["info", "{truncated}"], ["cannot read"]),
    (["info", "{odd}"], ["aspect ratio", "--layout"]),
    (["frobnicate"], ["invalid choice"]),
])
def test_bad_input_is_one_clean_line(tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "corrupt.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n\xff\xff")
    blob = shared("ict_lowres/grace.hdr").read_bytes()
    (tmp_path / "truncated.hdr").write_bytes(blob[: len(blob) // 2])
    write_image(tmp_path / "odd.exr", np.ones((10, 13, 3), np.float32))
    names = {"cross": shared("debevec/cross/grace_cross.hdr"), "corrupt": tmp_path / "corrupt.hdr",
             "truncated": tmp_path / "truncated.hdr", "odd": tmp_path / "odd.exr"}
    code, _, err = run(capsys, *[a.format(**names) for a in argv])
    assert_clean_failure(code, err, *words)
    assert not (tmp_path / "x.exr").exists()
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]  # no temporary file left behind


def test_nan_pixels_are_replaced_with_a_one_line_warning(tmp_path, capsys):
    px = np.ones((8, 16, 3), np.float32)
    px[0, :4] = np.nan
    write_image(tmp_path / "nan.exr", px)
    code, _, err = run(capsys, "convert", tmp_path / "nan.exr", tmp_path / "o.exr", "--to", "latlong")
    assert code == 0
    assert err.strip().splitlines() == [
        f"lightprobe: warning: {tmp_path / 'nan.exr'}: replaced by 0 the bad values of 4 NaN, 0 infinite and 0 "
        "negative pixels"]
    assert np.isfinite(read_envmap(tmp_path / "o.exr").data).all()


def test_help_everywhere(capsys):
    for argv in (["--help"], ["info", "--help"], ["convert", "--help"], ["demo", "--help"]):
        code, out, _ = run(capsys, *argv)
        assert code == 0 and "usage:" in out


def test_the_installed_command_fails_cleanly(tmp_path):
    """The real entry point, in a fresh process: exit status 2, one line, no traceback."""
    exe = Path(sys.executable).with_name("lightprobe")
    res = subprocess.run([str(exe), "info", str(tmp_path / "nope.exr")], capture_output=True, text=True,
                         env={**os.environ, "LIGHTPROBE_PROGRESS": "0"})
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr


def test_demo_fails_when_the_reference_fails(tmp_path, monkeypatch):
    """Only a missing Mitsuba is excused in the report; a reference that breaks fails the demo."""
    import lightprobe.report.demo as demo
    from lightprobe.render import reference

    def broken(*args, **kwargs):
        raise RuntimeError("the reference broke")

    monkeypatch.setattr(reference, "reference_render", broken)
    monkeypatch.setattr(demo, "SECTIONS", [demo.section_render])
    monkeypatch.setattr(demo, "warm_up", lambda: 0.0)  # no section here needs every kernel
    with pytest.raises(RuntimeError, match="reference broke"):
        demo.run_demo(read_envmap(shared("ict_lowres/grace.hdr")), tmp_path / "r")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("status", [0, 2, 130])
def test_the_command_exits_quickly_with_its_status_and_its_output(tmp_path, status):
    """``entry`` skips Python's finalisation once numba has run a kernel (an atexit handler registered before it
    does not run: the exit was quick), yet keeps main's exit status, the text it printed without a newline
    (unflushed), and the atexit handlers registered after it (a file they write)."""
    marker, earlier = tmp_path / "handler-ran", tmp_path / "earlier-ran"
    program = f"""
import atexit, sys
atexit.register(lambda: open({str(earlier)!r}, "w").write("ran"))
import lightprobe.cli as cli
from lightprobe.lights.decompose import cap_sums, _row_prefix
import numpy as np

def fake_main():
    out = np.zeros((1, 1))
    cap_sums(_row_prefix(np.ones((4, 8))), (np.arange(4) + 0.5) / 4 * np.pi, np.array([1]), np.array([2]),
             np.array([0.5]), out)  # numba now runs: the quick exit applies
    atexit.register(lambda: open({str(marker)!r}, "w").write("ran"))
    sys.stdout.write(f"sum {{out[0, 0]:.0f}} no newline")
    return {status}

cli.main = fake_main
cli.entry()
"""
    res = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True)
    assert res.returncode == status, res.stderr
    assert res.stdout == "sum 1 no newline" and "numba" not in res.stderr
    assert marker.read_text() == "ran" and not earlier.exists()


def test_the_command_keeps_its_status_when_the_runtime_would_abort_at_teardown(tmp_path):
    """A command that never ran a kernel still ends with main's status: finalisation that would abort the process
    (as Arrow's Parquet reader threads can while their pool is torn down) never runs, the atexit handlers registered
    during the command do."""
    marker = tmp_path / "handler-ran"
    program = f"""
import atexit, os, sys
atexit.register(os.abort)  # stands in for a native library that aborts as the interpreter tears it down
import lightprobe.cli as cli

def fake_main():
    atexit.register(lambda: open({str(marker)!r}, "w").write("ran"))
    print("done")
    return 0

cli.main = fake_main
cli.entry()
"""
    res = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True)
    assert res.returncode == 0 and res.stdout == "done\n", (res.returncode, res.stderr)
    assert marker.read_text() == "ran"


def test_the_console_script_is_the_quick_entry():
    text = (Path(__file__).resolve().parents[1] / "pyproject.toml").read_text()
    assert 'lightprobe = "lightprobe.cli:entry"' in text
