"""Hardening: each problem an outside attack or a review found, with a test named after the behaviour it now has.

Subprocess tests run the installed ``lightprobe`` command, so what is checked is what a user's shell sees: the exit
status, every line on stderr (libraries writing to file descriptor 2 included), and the files left behind.
"""

from __future__ import annotations

import json
import os
import re
import resource
import signal
import subprocess
import sys
from fractions import Fraction
from math import comb, pi
from pathlib import Path

import numpy as np
import pytest

from conftest import shared
from lightprobe.cli import build_parser, command_module
from lightprobe.cli.common import ImageSize, Number, NumberList
from lightprobe.maps import EnvMap, check_size, read_envmap
from lightprobe.util.errors import BudgetError, LightprobeError, UsageError
from lightprobe.maps.images import write_image
from lightprobe_engines.peak import run_measured
from lightprobe.maps.layouts import LATLONG
from lightprobe.sh.basis import a_hat, project
from test_cli import assert_clean_failure, run

EXE = str(Path(sys.executable).with_name("lightprobe"))


def lightprobe(*argv, env=None, timeout=120, **kwargs) -> subprocess.CompletedProcess:
    """The installed command in a fresh process; ``env`` adds variables."""
    return subprocess.run([EXE, *map(str, argv)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "LIGHTPROBE_PROGRESS": "0", **(env or {})}, **kwargs)


def clean_failure(res: subprocess.CompletedProcess, *words: str) -> None:
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("lightprobe: error: "), res.stderr[:2000]
    for w in words:
        assert w in res.stderr, res.stderr


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name or p.name.startswith(".lp"))


def grey_map(tmp_path: Path, name: str = "grey.exr", value: float = 1.0, size: int = 16) -> Path:
    return write_image(tmp_path / name, np.full((size, 2 * size, 3), value, np.float32))


# ---- wrong results ----------------------------------------------------------------------------------------------
def exact_a_hat(l: int) -> Fraction:
    """Â_l / (2π) = ∫₀¹ x P_l(x) dx, exactly, from P_l(x) = 2^-l Σ_k (−1)^k C(l,k) C(2l−2k, l) x^(l−2k)."""
    total = Fraction(0)
    for k in range(l // 2 + 1):
        total += Fraction((-1) ** k * comb(l, k) * comb(2 * l - 2 * k, l), 2**l) * Fraction(1, l - 2 * k + 2)
    return total


@pytest.mark.parametrize("l", range(0, 65))
def test_a_hat_equals_the_exact_integral_up_to_the_largest_order(l):
    """Â_l against an independent exact rational value of its defining integral, to the highest order any command
    accepts (sh --order 64). The old int64 code gave Â_24 = 1522.9."""
    exact = float(exact_a_hat(l)) * 2 * pi
    assert a_hat(l) == pytest.approx(exact, rel=1e-13, abs=1e-300)


def test_high_orders_reduce_the_error(capsys):
    code, out, _ = run(capsys, "error", "--order", "2,18,20,22,24", "--window", "none", "--normals", 300, "--json")
    rows = {r["l_max"]: r for r in json.loads(out)}
    assert code == 0
    for l in (18, 20, 22, 24):  # old main: 0.07 %, 0.21 %, 45 %, 27,454 %
        assert rows[l]["paper_mean"] < rows[2]["paper_mean"] / 3 and rows[l]["paper_max"] < 0.01


@pytest.mark.parametrize("field", ["fit", "scale"])
def test_nan_fit_or_scale_is_refused_not_an_empty_scene(tmp_path, field):
    ply = tmp_path / "tri.ply"
    import trimesh

    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(ply)
    (tmp_path / "s.yaml").write_text(f"meshes: [{{file: tri.ply, {field}: .nan}}]\n")
    res = lightprobe("render", tmp_path / "s.yaml", "-o", tmp_path / "r.exr", "--size", "8x8")
    clean_failure(res, f"meshes[0].{field}")
    assert not (tmp_path / "r.exr").exists()


def test_json_output_is_always_valid_json(tmp_path, capsys):
    def strict(text):
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"not JSON: {c}"))

    bad = np.full((8, 16, 3), np.nan, np.float32)
    write_image(tmp_path / "nan.exr", bad)
    code, out, _ = run(capsys, "info", tmp_path / "nan.exr", "--json")
    info = strict(out)
    assert code == 0 and info["nan_pixels"] == 128 and info["integral"] is None and info["mean"] is None
    good = np.ones((8, 16, 3), np.float32)
    partly = good.copy()
    partly[0, 0] = np.nan
    write_image(tmp_path / "a.exr", partly)
    write_image(tmp_path / "b.exr", good)
    code, out, err = run(capsys, "compare", tmp_path / "a.exr", tmp_path / "b.exr", "--json")
    metrics = strict(out)
    assert code == 0 and "replaced by 0 the bad values of 1 NaN" in err
    assert metrics["relative_mse"] == pytest.approx(1 / 128, rel=0.02)  # one black pixel of 128 against white
    code, _, err = run(capsys, "design", "-o", tmp_path / "d.png", "--set", "L1-1=nan")
    assert_clean_failure(code, err, "finite")


def test_stale_sh_cache_serves_each_map_its_own_coefficients():
    """300 freshly made maps in a loop: ids are reused once a map is freed; each render must use its own map."""
    from lightprobe.render.methods import SHMethod
    from lightprobe.render.scene import sphere_scene

    method = SHMethod(2)
    for i in range(300):
        value = 1.0 + i
        env = EnvMap(np.full(LATLONG.grid_shape(4) + (3,), value, np.float32), LATLONG)
        coeffs = method.coefficients(sphere_scene(env, 4))
        assert coeffs.coeffs[0, 0] == pytest.approx(value * np.sqrt(4 * np.pi) * np.pi, rel=1e-5), i
        del env


def test_reference_spp_2_means_2(tmp_path, capsys):
    code, out, _ = run(capsys, "render", "-o", tmp_path / "r.exr", "--size", "8x8", "-m", "reference", "--spp", 2)
    assert code == 0 and ", 2 spp;" in out, out


def test_envmap_owns_its_pixels_and_prints_one_line():
    pixels = np.ones((4, 8, 3), np.float32)
    env = EnvMap(pixels, LATLONG)
    pixels[:] = 7
    assert np.all(env.data == 1) and not env.data.flags.writeable
    with pytest.raises(ValueError):
        env.data[0, 0, 0] = 5
    big = EnvMap(np.zeros((512, 1024, 3), np.float32), LATLONG)
    assert repr(big) == "EnvMap(latlong, grid 512×1024, size 512)"


# ---- losing a user's data ---------------------------------------------------------------------------------------
def _limited_fsize(limit: int):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return set_limit


@pytest.fixture
def full_disk(tmp_path):
    """A folder on a 64 kB tmpfs that is already 40 kB full (root can mount one, as CI runs); elsewhere a plain
    folder, with the write limited by RLIMIT_FSIZE instead (``preexec``)."""
    folder = tmp_path / "full"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                             capture_output=True).returncode == 0
    if mounted:
        (folder / "filler").write_bytes(bytes(40_960))
    yield folder, (None if mounted else _limited_fsize(20_000))
    if mounted:
        subprocess.run(["umount", str(folder)], check=True)


@pytest.mark.parametrize("ext", [".png", ".jpg", ".exr", ".hdr"])
def test_on_a_full_disk_a_good_file_is_never_replaced(full_disk, ext):
    """On a full tmpfs the output cannot be written: one line naming the target, exit 2, the old file intact, no
    temporary file left. (Old main: a truncated PNG renamed over the good file and 'wrote …', exit 0; JPEG:
    libjpeg's own 'Output file write error', exit 1, and its temporary file left.)"""
    folder, preexec = full_disk
    target = folder / f"out{ext}"
    target.write_bytes(b"the user's good file")
    res = lightprobe("convert", shared("polyhaven_1k/rooitou_park_1k.hdr"), target, "--to", "latlong", "--size", 256,
                     preexec_fn=preexec)
    clean_failure(res, "cannot write", str(target))
    assert ".lp" not in res.stderr and ".tmp" not in res.stderr  # the target is named, not a temporary file
    assert target.read_bytes() == b"the user's good file"
    assert leftovers(folder) == []


@pytest.mark.parametrize("ext", [".png", ".jpg", ".exr", ".hdr"])
def test_a_file_size_limit_never_replaces_a_good_file(tmp_path, ext):
    """Under a 20 kB file-size limit the output cannot be written: one line, exit 2, the old file intact, no
    temporary file left (old main: a truncated PNG renamed over the good one and 'wrote …'; JPEG: libjpeg's own
    message, exit 1, the temporary file left)."""
    target = tmp_path / f"out{ext}"
    target.write_bytes(b"the user's good file")
    res = lightprobe("convert", shared("polyhaven_1k/rooitou_park_1k.hdr"), target, "--to", "latlong", "--size", 256,
                     preexec_fn=_limited_fsize(20_000))
    clean_failure(res, "cannot write", str(target))
    assert target.read_bytes() == b"the user's good file"
    assert leftovers(tmp_path) == []


def test_design_on_a_full_disk(tmp_path):
    target = tmp_path / "d.png"
    target.write_bytes(b"keep me")
    res = lightprobe("design", "-o", target, "--size", 64, preexec_fn=_limited_fsize(4000))
    clean_failure(res, "cannot write")
    assert target.read_bytes() == b"keep me" and leftovers(tmp_path) == []


@pytest.mark.parametrize("argv", [
    ["sh", "{src}", "-o", "{src}"],
    ["sh", "{src}", "--json", "-o", "{other}.hdr"],
    ["export", "{src}", "--to", "json", "-o", "{src}"],
    ["design", "{src}", "-o", "{other}.png", "--json", "{src}"],
    ["convert", "{src}", "{src}", "--to", "latlong"],
    ["irradiance", "{src}", "-o", "{src}"],
])
def test_an_output_is_never_an_input_nor_text_over_an_image(tmp_path, argv):
    src = grey_map(tmp_path, "in.exr")
    before = src.read_bytes()
    res = lightprobe(*[a.format(src=src, other=tmp_path / "other") for a in argv])
    clean_failure(res, "refusing")
    assert src.read_bytes() == before and not list(tmp_path.glob("other*")) and leftovers(tmp_path) == []


def _small_env():
    return EnvMap(np.ones(LATLONG.grid_shape(8) + (3,), np.float32), LATLONG)


def test_demo_refuses_a_folder_of_the_users_files(tmp_path):
    from lightprobe.report.demo import run_demo

    out = tmp_path / "mine"
    out.mkdir()
    (out / "index.html").write_text("my page")
    (out / "probe.png").write_bytes(b"my picture")
    with pytest.raises(LightprobeError, match="--force"):
        run_demo(_small_env(), out)
    assert (out / "index.html").read_text() == "my page" and (out / "probe.png").read_bytes() == b"my picture"
    res = lightprobe("demo", "--out", out)
    clean_failure(res, "not a lightprobe report")
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "probe.png"]


def test_demo_replaces_only_a_previous_report_and_only_when_complete(tmp_path, monkeypatch):
    import lightprobe.report.demo as demo

    monkeypatch.setattr(demo, "SECTIONS", [demo.section_probe])

    monkeypatch.setattr(demo, "warm_up", lambda: 0.0)  # no section here needs every kernel
    out = tmp_path / "report"
    demo.run_demo(_small_env(), out)
    assert (out / demo.MARKER).exists() and (out / "index.html").exists()
    (out / "stale.png").write_bytes(b"from an old report")
    demo.run_demo(_small_env(), out)
    assert not (out / "stale.png").exists() and (out / "probe.png").exists()

    def broken(rep):
        rep.picture("half", rep.env.data, "written before the failure")
        raise RuntimeError("a section fails halfway")

    monkeypatch.setattr(demo, "SECTIONS", [demo.section_probe, broken])
    before = sorted(p.name for p in out.iterdir())
    with pytest.raises(RuntimeError):
        demo.run_demo(_small_env(), out)
    assert sorted(p.name for p in out.iterdir()) == before  # the previous report, whole
    assert [p.name for p in tmp_path.iterdir()] == ["report"]  # no half-built folder beside it
    fresh = tmp_path / "fresh"
    with pytest.raises(RuntimeError):
        demo.run_demo(_small_env(), fresh)
    assert not fresh.exists()


def test_sigterm_and_sighup_remove_the_temporary_file(tmp_path):
    script = ("import sys, time\n"
              "from lightprobe.util.files import atomic_path, raise_on_termination, Terminated\n"
              "raise_on_termination()\n"
              "try:\n"
              "    with atomic_path(sys.argv[1]) as tmp:\n"
              "        tmp.write_bytes(b'half')\n"
              "        print('ready', flush=True)\n"
              "        while True:\n"
              "            time.sleep(60)\n"
              "except Terminated as e:\n"
              "    sys.exit(128 + e.signum)\n")
    for sig in (signal.SIGTERM, signal.SIGHUP):
        target = tmp_path / f"out{sig}.exr"
        proc = subprocess.Popen([sys.executable, "-c", script, str(target)], stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == "ready"
        assert len(leftovers(tmp_path)) == 1  # the temporary file exists while it writes
        proc.send_signal(sig)
        assert proc.wait(timeout=30) == 128 + sig
        assert leftovers(tmp_path) == [] and not target.exists()


def test_temporaries_of_killed_processes_are_swept_on_the_next_write(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)
    stale = [tmp_path / f".probe.exr.lp{pid}-0123abcd.tmp.exr", tmp_path / f".report.lp{pid}-89abcdef.tmp"]
    stale[0].write_bytes(b"x" * 1000)
    stale[1].mkdir()
    (stale[1] / "index.html").write_text("half a report")
    alive = tmp_path / f".other.exr.lp{os.getpid()}-0123abcd.tmp.exr"  # ours, in use: kept
    alive.write_bytes(b"y")
    unrelated = tmp_path / ".notes.tmp"
    unrelated.write_text("not ours")
    write_image(tmp_path / "new.exr", np.ones((2, 4, 3), np.float32))
    assert not any(p.exists() for p in stale) and alive.exists() and unrelated.exists()


# ---- tracebacks, hangs and memory -------------------------------------------------------------------------------
def _walk_numeric_options():
    """(command, flag, bad value) for every numeric option of every subcommand, from the parser itself."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    cases = []
    for command, p in sub.choices.items():
        for action in p._actions:
            if isinstance(action.type, (Number, NumberList, ImageSize)):
                cases += [(command, action.option_strings[0], bad) for bad in action.type.bad_examples()]
    return cases


NUMERIC_CASES = _walk_numeric_options()
REQUIRED = {"convert": ["{probe}", "{out}.exr", "--to", "cube"], "irradiance": ["-o", "{out}.exr"],
            "export": ["--to", "json", "-o", "{out}.json"], "design": ["-o", "{out}.png"],
            "render": ["-o", "{out}.exr"]}


def test_the_walk_covers_every_numeric_option():
    flags = {(c, f) for c, f, _ in NUMERIC_CASES}
    assert {("sh", "--order"), ("error", "--order"), ("error", "--normals"), ("irradiance", "--order"),
            ("irradiance", "--size"), ("render", "--order"), ("render", "--spp"), ("render", "--size"),
            ("render", "--exposure"), ("convert", "--exposure"), ("convert", "--size"), ("convert", "--rotate"),
            ("design", "--size")} <= flags


@pytest.mark.parametrize("command,flag,bad", NUMERIC_CASES)
def test_every_numeric_option_refuses_out_of_range(tmp_path, capsys, monkeypatch, command, flag, bad):
    required = [a.format(probe=shared("ict_lowres/grace.hdr"), out=tmp_path / "o") for a in REQUIRED.get(command, [])]
    ran = []
    monkeypatch.setattr(command_module(command), "run", ran.append)
    code, _, err = run(capsys, command, *required, f"{flag}={bad}")
    assert_clean_failure(code, err, flag)
    assert not ran and list(tmp_path.iterdir()) == []  # refused before the command did anything


def test_render_spp_range_depends_on_the_method(tmp_path, capsys):
    code, _, err = run(capsys, "render", "-o", tmp_path / "r.exr", "--spp", 17)
    assert_clean_failure(code, err, "--spp for sh must be within 1..16")


def test_library_exposure_is_bounded():
    from lightprobe.maps.tonemap import tonemap

    for bad in (1024.0, float("nan"), -1e9):
        with pytest.raises(UsageError, match="exposure"):
            tonemap(np.ones((2, 2, 3)), bad)


def test_pixel_counts_are_exact_integers():
    with pytest.raises(BudgetError, match=str(2 * 3037000500**2)):
        check_size(LATLONG, 3037000500)


def test_library_errors_are_the_packages_own():
    from lightprobe.exports.sh import export
    from lightprobe.sh.basis import SHCoeffs

    for call in (lambda: project(_small_env(), -1), lambda: export(SHCoeffs(np.zeros((9, 3))), "nope"),
                 lambda: SHCoeffs(np.zeros((9, 3))).windowed("nope"), lambda: a_hat(-1)):
        with pytest.raises(LightprobeError):
            call()


def test_a_malformed_limit_variable_is_one_line_not_an_import_crash(tmp_path):
    assert lightprobe("--help", env={"LIGHTPROBE_MAX_PIXELS": "abc"}).returncode == 0
    for name in ("LIGHTPROBE_MAX_PIXELS", "LIGHTPROBE_MAX_MEMORY", "LIGHTPROBE_MAX_TRIANGLES"):
        res = lightprobe("render", "-o", tmp_path / "r.exr", "--size", "8x8", env={name: "1.5e3x"})
        clean_failure(res, name)


BAD_SCENES = [
    ("camera: {width: abc}", "camera.width"), ("camera: hello", "camera must be a mapping"),
    ("meshes: 5", "meshes must be a list"), ("probe: 5", "probe must be a file name"),
    ("meshes: [{shape: sphere, radius: big}]", "meshes[0].radius must be a number"),
    ("meshes: [5]", "meshes[0] must be a mapping"), ("camera: {eye: [1, 2]}", "camera.eye must be a list of 3"),
    ("camera: {eye: hello}", "camera.eye"), ("camera: {fov: [1]}", "camera.fov"),
    ("camera: {height: 1.5}", "camera.height must be a whole number"), ("camera: {width: true}", "camera.width"),
    ("ground: hello", "ground must be a mapping"), ("ground: {size: -1}", "ground.size"),
    ("ground: {albedo: red}", "ground.albedo"), ("background: maybe", "background must be true or false"),
    ("rotate: [a, b, c]", "rotate[0] must be a number"), ("meshes: [{shape: cube}]", "meshes[0].shape"),
    ("meshes: [{shape: sphere, center: 1}]", "meshes[0].center"),
    ("meshes: [{shape: torus, minor: .inf}]", "meshes[0].minor"), ("meshes: [{file: 5}]", "meshes[0].file"),
    ("meshes: [{shape: sphere, albedo: [1, 2, nan]}]", "meshes[0].albedo"), ("cameras: {}", "unknown field"),
    ("meshes: [{shape: sphere, radus: 1}]", "unknown field 'radus'"),
]


@pytest.mark.parametrize("text,words", BAD_SCENES)
def test_mistyped_scene_fields_name_the_field(tmp_path, capsys, text, words):
    (tmp_path / "s.yaml").write_text(text + "\n")
    code, _, err = run(capsys, "render", tmp_path / "s.yaml", "-o", tmp_path / "r.exr")
    assert_clean_failure(code, err, words)


def test_a_yaml_alias_bomb_is_refused_at_once_without_echoing_it(tmp_path):
    lines = ['a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]']
    for k in range(1, 9):
        lines.append(f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]")
    lines.append("camera: *a8")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    assert path.stat().st_size < 800
    res = lightprobe("render", path, "-o", tmp_path / "r.exr")
    clean_failure(res, "YAML aliases")
    assert len(res.stderr) < 300


def test_the_triangle_limit_holds_for_the_whole_scene(tmp_path, monkeypatch):
    from lightprobe.render import scenefile

    text = "_s: &s {shape: sphere, radius: 0.1}\nmeshes: [" + ", ".join(["*s"] * 3000) + "]\n"
    (tmp_path / "many.yaml").write_text(text)
    assert (tmp_path / "many.yaml").stat().st_size < 13_000
    res = lightprobe("render", tmp_path / "many.yaml", "-o", tmp_path / "r.exr", "--size", "8x8")
    clean_failure(res, "triangles", "LIGHTPROBE_MAX_TRIANGLES")
    built = []
    monkeypatch.setattr(scenefile, "sphere", lambda *args: built.append(args))
    with pytest.raises(BudgetError, match="LIGHTPROBE_MAX_TRIANGLES"):
        scenefile.load_scene(tmp_path / "many.yaml")
    assert not built  # counted before any sphere is built (it built 976 of them first)


def peak_of(*argv, env=None) -> tuple[subprocess.CompletedProcess, float]:
    """Run the command and return it with its peak resident memory in MiB (lightprobe_engines.peak.run_measured)."""
    return run_measured([EXE, *argv], env={"LIGHTPROBE_PROGRESS": "0", **(env or {})}, timeout=300)


def test_a_decompression_bomb_is_refused_before_it_is_decoded(tmp_path):
    from PIL import Image

    bomb = tmp_path / "bomb.png"
    Image.fromarray(np.zeros((4096, 8192, 3), np.uint8)).save(bomb, optimize=True)
    assert bomb.stat().st_size < 200_000  # ~0.1 MB that decodes to 400 MB of float pixels
    res, peak = peak_of("info", bomb, env={"LIGHTPROBE_MAX_MEMORY": "1G"})
    clean_failure(res, "refusing", "LIGHTPROBE_MAX_MEMORY")
    assert peak < 400, peak


def test_the_hdr_reader_never_allocates_a_short_files_claimed_size(tmp_path):
    """Headers claiming up to 70000 × 70000 pixels on a 100-byte file: refused before allocating (the old test of
    this measured nothing)."""
    from hypothesis import given, settings, strategies as st

    files = []

    @given(w=st.integers(1, 70000), h=st.integers(1, 70000))
    @settings(max_examples=30, deadline=None, database=None)
    def make(w, h):
        path = tmp_path / f"s{len(files)}.hdr"
        path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w) + b"\x02\x02\x00\x10" * 8)
        files.append(path)

    make()
    files.append(tmp_path / "huge.hdr")
    files[-1].write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 11000 +X 12000\n" + b"\x02\x02\x00\x10" * 8)
    script = ("import sys, warnings\nfrom lightprobe.maps.images import read_image\nfrom lightprobe.util.errors import "
              "LightprobeError\nfor p in sys.argv[1:]:\n    try:\n        read_image(p)\n"
              "    except LightprobeError:\n        pass\n")
    res, peak = run_measured([sys.executable, "-c", script, *files], timeout=120)
    assert res.returncode == 0, res.stderr
    assert peak < 300  # MiB; 11000 × 12000 float RGB alone would be 1.5 GB


def test_work_over_the_memory_budget_is_refused_before_it_starts(tmp_path, tmp_path_factory):
    scratch = tmp_path_factory.mktemp("tmpdir")  # the commands' TMPDIR: only what they leave is there
    for argv in (["convert", shared("ict_lowres/grace.hdr"), tmp_path / "c.exr", "--to", "latlong", "--size", 8192],
                 ["render", "-o", tmp_path / "r.exr", "--size", "4096x4096"],
                 ["render", "-o", tmp_path / "m.exr", "--size", "8192x8192", "-m", "reference"]):
        res = lightprobe(*argv, env={"LIGHTPROBE_MAX_MEMORY": "1G", "TMPDIR": str(scratch)})
        clean_failure(res, "refusing", "memory")
    assert list(tmp_path.iterdir()) == []
    assert list(scratch.iterdir()) == []  # no Mitsuba scene folder left behind


def test_the_mitsuba_folder_is_gone_once_the_scene_is_loaded(monkeypatch):
    import tempfile

    from lightprobe.render import reference
    from lightprobe.render.scene import sphere_scene

    seen = []
    real = reference.scene_dict

    def spy(mi, scene, folder, *args):
        seen.append(folder)
        return real(mi, scene, folder, *args)

    monkeypatch.setattr(reference, "scene_dict", spy)
    original_render = reference.mitsuba

    def checking_mitsuba(variant=None):
        mi = original_render(variant)

        class Wrapped:
            def __getattr__(self, name):
                return getattr(mi, name)

            def render(self, *args, **kwargs):
                assert not seen[0].exists(), "the scene folder must be removed before rendering starts"
                return mi.render(*args, **kwargs)

        return Wrapped()

    monkeypatch.setattr(reference, "mitsuba", checking_mitsuba)
    reference.reference_render(sphere_scene(_small_env(), 8), spp=1)
    assert seen and not seen[0].exists() and str(seen[0]).startswith(tempfile.gettempdir())


def test_a_fifo_is_refused_not_waited_on(tmp_path):
    fifo = tmp_path / "probe.hdr"
    os.mkfifo(fifo)
    for argv in (["info", fifo], ["sh", fifo], ["render", fifo, "-o", tmp_path / "r.exr"]):
        res = lightprobe(*argv, timeout=30)
        clean_failure(res, "not a regular file")


def test_image_libraries_never_print_their_own_lines(tmp_path):
    from PIL import Image

    noisy = tmp_path / "noisy.png"
    Image.fromarray(np.full((32, 64, 3), 128, np.uint8)).save(noisy, icc_profile=b"not a real profile" * 8)
    res = lightprobe("info", noisy, "--json")
    assert res.returncode == 0 and res.stderr == "", res.stderr
    blob = noisy.read_bytes()
    (tmp_path / "cut.png").write_bytes(blob[: len(blob) // 2])
    clean_failure(lightprobe("info", tmp_path / "cut.png"), "cannot read")
    jpg = write_image(tmp_path / "x.jpg", np.ones((16, 32, 3), np.float32))
    (tmp_path / "cut.jpg").write_bytes(jpg.read_bytes()[:200])
    res = lightprobe("info", tmp_path / "cut.jpg")
    assert len(res.stderr.splitlines()) <= 1 and "Traceback" not in res.stderr, res.stderr


def test_messages_say_what_is_true(tmp_path, capsys, monkeypatch):
    (tmp_path / "folder.exr").mkdir()
    code, _, err = run(capsys, "convert", shared("ict_lowres/grace.hdr"), tmp_path / "folder.exr", "--to", "cube")
    assert_clean_failure(code, err, "is a folder")
    assert ".tmp" not in err and ".lp" not in err
    code, _, err = run(capsys, "convert", shared("ict_lowres/grace.hdr"), tmp_path / "x.exr", "--to", "cube",
                       "--rotate", "")
    assert_clean_failure(code, err, "--rotate")
    import lightprobe.cli.info as info

    def out_of_memory(args):
        raise MemoryError

    monkeypatch.setattr(info, "run", out_of_memory)
    code, _, err = run(capsys, "info")
    assert_clean_failure(code, err, "out of memory")
    assert "--size" not in err


def test_a_textured_obj_renders_with_its_texture(tmp_path, capsys):
    """An OBJ with UVs and a texture (MTL + PNG) read from files: the rendered quad shows the texture's colours."""
    from PIL import Image

    Image.fromarray(np.tile(np.array([[[230, 20, 20]], [[20, 20, 230]]], np.uint8), (1, 2, 1)).repeat(16, 0).repeat(16, 1)
                    ).save(tmp_path / "tex.png")  # top half red, bottom half blue
    (tmp_path / "quad.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd tex.png\n")
    (tmp_path / "quad.obj").write_text("mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                       "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl m\n"
                                       "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n")
    (tmp_path / "s.yaml").write_text("meshes: [{file: quad.obj}]\nground: false\nbackground: false\n"
                                     "camera: {eye: [0, 0, 3], target: [0, 0, 0], fov: 30, width: 32, height: 32}\n")
    code, _, err = run(capsys, "render", tmp_path / "s.yaml", "-o", tmp_path / "r.exr")
    assert code == 0, err
    from lightprobe.maps.images import read_image

    image = read_image(tmp_path / "r.exr")
    top, bottom = image[8, 16], image[24, 16]
    assert top[0] > 3 * top[2] and bottom[2] > 3 * bottom[0]  # red above, blue below: UVs and v-up kept


# ---- while the CLI is open ----------------------------------------------------------------------------------------
def test_one_versioned_sh_json_schema(tmp_path, capsys):
    code, out, _ = run(capsys, "sh", "--json")
    from_sh = json.loads(out)
    run(capsys, "export", "--to", "json", "-o", tmp_path / "e.json")
    from_export = json.loads((tmp_path / "e.json").read_text())
    assert set(from_sh) == set(from_export) and (from_sh["format"], from_sh["version"]) == ("lightprobe.sh", 2)
    np.testing.assert_allclose(from_sh["coefficients"], from_export["coefficients"], rtol=1e-12)
    code, _, _ = run(capsys, "export", "--sh", tmp_path / "e.json", "--to", "threejs", "-o", tmp_path / "t.json")
    direct = tmp_path / "d.json"
    run(capsys, "export", "--to", "threejs", "-o", direct)
    assert code == 0 and json.loads((tmp_path / "t.json").read_text()) == json.loads(direct.read_text())


def test_the_sh_json_reader_refuses_what_is_not_the_schema():
    from hypothesis import example, given, settings, strategies as st

    from lightprobe.util.errors import InputError
    from lightprobe.sh.basis import SHCoeffs
    from lightprobe.sh.shfile import read_sh_json, sh_json

    good = json.loads(sh_json(SHCoeffs(np.arange(27.0).reshape(9, 3))))
    json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(),
                               lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(), c, max_size=4),
                               max_leaves=12)

    @given(key=st.sampled_from(sorted(good)), value=json_values)
    @example(key="version", value="\n")  # found by this test: the version was echoed with its newline
    @settings(max_examples=150, deadline=None, database=None)
    def mutated(key, value):
        doc = {**good, key: value}
        try:
            sh = read_sh_json(json.dumps(doc))
        except InputError as e:
            assert "\n" not in str(e)
            return
        assert np.isfinite(sh.coeffs).all()

    @given(data=st.binary(max_size=300))
    @settings(max_examples=150, deadline=None, database=None)
    def garbage(data):
        with pytest.raises(InputError):
            read_sh_json(data)

    mutated()
    garbage()
    np.testing.assert_array_equal(read_sh_json(json.dumps(good)).coeffs, np.arange(27.0).reshape(9, 3))


def test_demo_timings_are_warm(tmp_path, monkeypatch):
    """The timed projection runs kernels the warm-up already made: none is compiled or loaded from numba's cache
    inside it (cold, a 1024×512 map's took 1327 ms instead of a few)."""
    import lightprobe.report.demo as demo
    import lightprobe.report.page as page
    from numba.core.dispatcher import Dispatcher

    made, timed = [], []
    compile_, project = Dispatcher.compile, page.project

    def compiling(self, sig):
        before = len(self.overloads)
        entry = compile_(self, sig)
        if len(self.overloads) > before:
            made.append(self.py_func.__name__)
        return entry

    def projecting(*args, **kwargs):
        first = len(made)
        result = project(*args, **kwargs)
        timed.append(made[first:])
        return result

    monkeypatch.setattr(Dispatcher, "compile", compiling)
    monkeypatch.setattr(page, "project", projecting)  # Report.sh, the step the table times
    monkeypatch.setattr(demo, "SECTIONS", [demo.section_sh])
    demo.run_demo(read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr")), tmp_path / "r")
    page = (tmp_path / "r" / "index.html").read_text()
    assert "compiling the numba kernels" in page
    assert re.search(r"SH projection, order 2</td><td>[\d.]+ ms", page)
    assert timed and not any(timed), timed


def test_under_a_process_memory_cap_the_reference_is_refused_not_a_crash(tmp_path):
    """Under ``ulimit -v`` Mitsuba segfaulted at 4096² (exit 139: its own passes of 2³¹ samples); now the address
    space left is checked first, while a small render under the same cap still runs."""
    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (5 << 29, 5 << 29))  # 2.5 GiB

    res = lightprobe("render", "-m", "reference", "--size", "4096x4096", "-o", tmp_path / "big.exr", preexec_fn=cap)
    clean_failure(res, "ulimit -v")
    res = lightprobe("render", "-m", "reference", "--size", "32x32", "--spp", 4, "-o", tmp_path / "small.exr",
                     preexec_fn=cap)
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.exr"]


def test_the_reference_renders_in_bounded_passes(monkeypatch):
    """A white sphere in a white furnace shows radiance 1: rendered in eight one-sample passes (counted) it still
    averages 1 (each pass alone is noisy: Mitsuba samples the emitter and the BSDF)."""
    from lightprobe.render import reference
    from lightprobe.render.scene import sphere_scene

    monkeypatch.setattr(reference, "SAMPLES_PER_PASS", 16 * 16)
    calls = []
    real = reference._render_in_passes

    def spy(mi, loaded, pixels, spp, seed):
        original = mi.render

        def counted(*args, **kwargs):
            calls.append(kwargs["spp"])
            return original(*args, **kwargs)

        mi.render = counted
        try:
            return real(mi, loaded, pixels, spp, seed)
        finally:
            mi.render = original

    monkeypatch.setattr(reference, "_render_in_passes", spy)
    scene = sphere_scene(EnvMap(np.ones(LATLONG.grid_shape(8) + (3,), np.float32), LATLONG), 16)
    result = reference.reference_render(scene, spp=8)
    assert calls == [1] * 8
    assert abs(float(result.image.mean()) - 1.0) < 0.01 and float(np.abs(result.image - 1).max()) < 0.5
