"""Results that were silently stale or wrong: each now follows its inputs or is refused with one line.

A bake is keyed by everything it reads; a batch gives every input path its own row, hashes the bytes it processed and
never ingests its own artifacts or loops through symbolic links; exports refuse numbers whose engine form is not
finite; BRDF parameters and radiance sets that cannot give a correct map are refused or warned about.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lightprobe.maps.images import write_image
from test_cli import assert_clean_failure, run

EXE = str(Path(sys.executable).with_name("lightprobe"))


def lightprobe(*argv, timeout=120) -> subprocess.CompletedProcess:
    """The installed command in a fresh process."""
    return subprocess.run([EXE, *map(str, argv)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "LIGHTPROBE_PROGRESS": "0"})


def clean_failure(res: subprocess.CompletedProcess, *words: str) -> None:
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("lightprobe: error: "), res.stderr[:2000]
    for w in words:
        assert w in res.stderr, res.stderr


def small_map(path: Path, value: float = 1.0, sun: float = 0.0) -> Path:
    img = np.full((8, 16, 3), value, np.float32)
    img[2, 5] += sun
    return write_image(path, img)


# ---- the viewer's bake cache ---------------------------------------------------------------------------------------
def test_the_bake_cache_key_follows_the_probes_layout(tmp_path):
    from lightprobe.viewer.bake import BakeOptions, cache_folder

    probe = small_map(tmp_path / "probe.exr")
    keys = {cache_folder(probe, None, BakeOptions(), tmp_path, layout) for layout in (None, "latlong", "cross")}
    assert len(keys) == 3


def test_the_bake_cache_key_follows_every_file_a_gltf_or_obj_mesh_loads(tmp_path):
    from lightprobe.viewer.bake import BakeOptions, cache_folder

    probe = small_map(tmp_path / "probe.exr")
    (tmp_path / "my mesh.bin").write_bytes(b"\0" * 36)
    (tmp_path / "tex.png").write_bytes(b"png 1")
    gltf = tmp_path / "mesh.gltf"
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "my%20mesh.bin", "byteLength": 36}],
                                "images": [{"uri": "tex.png"}, {"uri": "data:image/png;base64,AA=="}]}))
    (tmp_path / "mesh.mtl").write_text("newmtl m\nmap_Kd -s 1 1 1 wood.png\n")
    (tmp_path / "wood.png").write_bytes(b"wood 1")
    obj = tmp_path / "mesh.obj"
    obj.write_text("mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    for mesh, changed in ((gltf, "my mesh.bin"), (gltf, "tex.png"), (obj, "mesh.mtl"), (obj, "wood.png")):
        before = cache_folder(probe, mesh, BakeOptions(), tmp_path)
        (tmp_path / changed).write_bytes((tmp_path / changed).read_bytes() + b" changed")
        assert cache_folder(probe, mesh, BakeOptions(), tmp_path) != before, changed


# ---- batch: a row for every input path, of the bytes processed, and never of its own artifacts --------------------
def batch_table(out: Path, name: str) -> list[dict]:
    import pyarrow.parquet as pq

    return pq.read_table(out / name).to_pylist()


def test_batch_gives_every_input_path_its_row_when_inputs_have_the_same_bytes(tmp_path):
    first, twin, late = (small_map(tmp_path / f"{n}.exr", sun=5.0) for n in ("first", "twin", "late"))
    twin.write_bytes(first.read_bytes())
    late.write_bytes(first.read_bytes())
    out = tmp_path / "out"
    res = lightprobe("batch", first, twin, "--out", out, "--jobs", "sh", "--workers", "1")
    assert res.returncode == 0, res.stderr
    res = lightprobe("batch", first, twin, late, "--out", out, "--jobs", "sh", "--workers", "1", "--resume")
    assert res.returncode == 0, res.stderr
    rows = batch_table(out, "results.parquet")
    assert sorted(r["path"] for r in rows) == sorted(str(p) for p in (first, late, twin))
    assert len({r["sha256"] for r in rows}) == 1 and rows[0]["sh"] == rows[1]["sh"] == rows[2]["sh"]
    assert batch_table(out, "errors.parquet") == []


def test_batch_records_no_row_for_a_file_replaced_while_it_was_processed(tmp_path, monkeypatch):
    import lightprobe.maps.files as files
    from lightprobe.batch.task import JobOptions, file_digest, process

    path = small_map(tmp_path / "probe.exr")
    before = file_digest(path)[0]
    read = files.read_envmap_within_budget

    def read_then_replace(*args, **kwargs):
        env = read(*args, **kwargs)
        small_map(tmp_path / "other.exr", value=7.0).replace(path)
        return env

    monkeypatch.setattr(files, "read_envmap_within_budget", read_then_replace)
    result = process(str(path), JobOptions(jobs=("sh",)), str(tmp_path / "out"))
    assert result["kind"] == "error" and "changed while it was processed" in result["message"], result
    assert result["sha256"] == before


def test_batch_resumed_with_its_folder_inside_the_glob_does_not_take_its_own_artifacts_as_inputs(tmp_path):
    tree = tmp_path / "tree"
    tree.mkdir()
    for i in range(2):
        small_map(tree / f"probe{i}.exr", sun=float(i + 1))
    out = tree / "out"
    for resume in ((), ("--resume",), ("--resume",)):
        res = lightprobe("batch", f"{tree}/**", "--out", out, "--jobs", "sh,thumbnail", "--workers", "1", *resume)
        assert res.returncode == 0, res.stderr
    assert sorted(Path(r["path"]).name for r in batch_table(out, "results.parquet")) == ["probe0.exr", "probe1.exr"]
    assert batch_table(out, "errors.parquet") == []


def test_batch_globs_do_not_follow_symbolic_link_loops_and_take_each_file_once(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    small_map(tmp_path / "a" / "b" / "probe.exr")
    os.symlink("..", tmp_path / "a" / "b" / "up")
    os.symlink("../..", tmp_path / "a" / "b" / "top")
    os.symlink("b/probe.exr", tmp_path / "a" / "alias.exr")
    code = ("import json, sys; from lightprobe.batch.inputs import expand_inputs; "
            "print(json.dumps(expand_inputs([sys.argv[1]])))")
    res = subprocess.run([sys.executable, "-c", code, f"{tmp_path}/**/*.exr"], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == [str(tmp_path / "a" / "alias.exr")]


# ---- exports: numbers the readers accept but engines cannot hold -----------------------------------------------------
SH_DOC = {"format": "lightprobe.sh", "version": 2, "quantity": "radiance", "frame": "world", "l_max": 2}


def lights_doc(direction, power, ambient=0.1) -> dict:
    return {"format": "lightprobe.lights", "version": 1, "frame": "world", "method": "arbree2005",
            "lights": [{"direction": direction, "angular_radius_deg": 5, "power": power},
                       {"direction": [1, 0, 0], "angular_radius_deg": 5, "power": [1, 1, 1]}],
            "ambient": {"sh": {**SH_DOC, "coefficients": [[ambient] * 3] * 9}}}


def written_is_valid(path: Path, target: str) -> None:
    """Strict JSON (no NaN or Infinity tokens), or C#/GLSL/text whose numbers are finite 32-bit floats."""
    import re

    text = path.read_text()
    if target in ("unity", "glsl", "filament") and not text.lstrip().startswith("{"):
        numbers = [float(v) for v in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", text)]
        assert not re.search(r"\b(inf|nan|Infinity|NaN)\b", text, re.I), text[:500]
        assert all(abs(v) <= np.finfo(np.float32).max for v in numbers)
    else:
        json.loads(text, parse_constant=lambda token: pytest.fail(f"{token} in {path.name}"))


@pytest.mark.parametrize("target", ["threejs", "filament", "unity", "gltf", "babylon", "glsl"])
def test_export_sh_refuses_coefficients_whose_engine_form_is_not_finite(tmp_path, capsys, target):
    sh = tmp_path / "sh.json"
    sh.write_text(json.dumps({**SH_DOC, "coefficients": [[1e308] * 3] * 9}))
    code, _, err = run(capsys, "export", "--sh", sh, "--to", target, "-o", tmp_path / "out.txt")
    assert_clean_failure(code, err, "too large")
    assert not (tmp_path / "out.txt").exists()


@pytest.mark.parametrize("case", ["power", "ambient", "fits"])
@pytest.mark.parametrize("target", ["threejs", "filament", "unity", "gltf", "babylon"])
def test_export_lights_writes_valid_files_or_refuses_numbers_engines_cannot_hold(tmp_path, capsys, target, case):
    doc = {"power": lights_doc([0, 1, 0], [1e308] * 3), "ambient": lights_doc([0, 1, 0], [1] * 3, ambient=1e300),
           "fits": lights_doc([0, 1, 0], [1e37] * 3, ambient=1e37)}[case]
    source = tmp_path / "lights.json"
    source.write_text(json.dumps(doc))
    out = tmp_path / ("out.gltf" if target == "gltf" else "out.txt")
    code, _, err = run(capsys, "export", "--lights", source, "--to", target, "-o", out)
    if case == "fits":  # (glTF's RGBD cube warns that it clips such radiance)
        assert code == 0 and all(line.startswith("lightprobe: warning:") for line in err.splitlines()), err
        written_is_valid(out, target)
    else:
        assert_clean_failure(code, err, "too large")
        assert not out.exists()


def test_a_light_direction_whose_norm_overflows_keeps_its_direction(tmp_path):
    from lightprobe.exports.lights import export_babylon_lights
    from lightprobe.lights.lightsfile import read_lights_json

    lights = read_lights_json(json.dumps(lights_doc([1e200, 1e200, 0], [1, 1, 1])))
    assert np.allclose(lights.directions[0], [2 ** -0.5, 2 ** -0.5, 0])
    tiny = read_lights_json(json.dumps(lights_doc([0, 0, 1e-300], [1, 1, 1])))
    assert np.allclose(tiny.directions[0], [0, 0, 1])
    found = json.loads(export_babylon_lights(lights))["directionalLights"]
    assert any(np.allclose(light["direction"], [-(2 ** -0.5), -(2 ** -0.5), 0]) for light in found)


# ---- radiance sets: maps that are not numbers, views the set does not cover, BRDFs computed wrongly -----------------
def tiny_set(data: np.ndarray | None = None, triangles=None):
    """A set of the 12 geodesic views with constant maps (``data`` for the first), its mesh or ``triangles``."""
    from lightprobe.glossy.brdf import parse_brdf
    from lightprobe.glossy.radiance import geodesic_views, view_frame
    from lightprobe.glossy.radiancefile import RadianceSet
    from lightprobe.maps import EnvMap
    from lightprobe.maps.layouts import Sphere

    views, mesh = geodesic_views(12)
    frames = np.array([view_frame(v) for v in views])
    maps = [EnvMap(np.full((8, 8, 3), 0.5, np.float32), Sphere(f)) for f in frames]
    if data is not None:
        maps[0] = EnvMap(data, Sphere(frames[0]))
    return RadianceSet(parse_brdf("lambert"), views, frames, tuple(maps), mesh if triangles is None else triangles,
                       {}, None)


def test_synthesize_refuses_a_set_whose_maps_hold_nan_or_infinity(tmp_path, capsys):
    from lightprobe.glossy.radiancefile import write_radiance_set

    data = np.full((8, 8, 3), 0.5, np.float32)
    data[3, 4] = np.nan
    data[4, 4] = np.inf
    write_radiance_set(tmp_path / "set", tiny_set(data))
    code, _, err = run(capsys, "radiance", tmp_path / "set", "--synthesize", "0.1,0.2,1", "-o", tmp_path / "v.exr")
    assert_clean_failure(code, err, "not finite")
    assert not (tmp_path / "v.exr").exists()


def test_synthesize_refuses_a_view_outside_every_triangle_of_the_set():
    from lightprobe.glossy.rsibr import synthesize
    from lightprobe.util.errors import InputError

    full = tiny_set()
    covered = full.triangles[:1]
    partial = tiny_set(triangles=covered)
    inside = full.views[covered[0]].sum(axis=0)
    assert np.isfinite(synthesize(partial, inside).data).all()
    with pytest.raises(InputError, match="outside every triangle"):
        synthesize(partial, -inside)


@pytest.mark.parametrize("spec", ["ggx:alpha=1e-6", "coat:alpha=1e-6,ior=1.5,albedo=0", "plastic:alpha=0.001",
                                  "phong:n=100000", "ggx:alpha=0.2,eta=1e-300,k=0", "ggx:alpha=0.2,eta=1,k=1e300"])
def test_brdf_parameters_whose_maps_cannot_be_computed_correctly_are_refused(spec):
    from lightprobe.glossy.brdf import parse_brdf
    from lightprobe.util.errors import UsageError

    with pytest.raises(UsageError, match="must be in|needs eta in"):
        parse_brdf(spec)


@pytest.mark.parametrize("spec,black", [("ggx:alpha=0.01", False), ("phong:n=20000", False),
                                        ("ggx:alpha=0.2,eta=0.001/1/100,k=100/0/0", False),
                                        ("coat:alpha=0.1,ior=1,albedo=0.5", False), ("ggx:alpha=0.2,ior=1", True),
                                        ("coat:alpha=0.1,ior=1,albedo=0", True), ("ggx:alpha=0.2,eta=1,k=0", True),
                                        ("lambert:albedo=0", True), ("blinn:n=10,ks=0", True)])
def test_brdfs_at_the_ends_of_their_ranges_give_finite_maps_and_black_ones_warn_once(spec, black):
    import warnings

    from lightprobe.glossy.brdf import parse_brdf
    from lightprobe.glossy.radiance import radiance_map
    from lightprobe.maps import EnvMap
    from lightprobe.maps.layouts import LATLONG
    from lightprobe.util.errors import LightprobeWarning

    env = EnvMap(np.repeat(np.linspace(0.2, 1.0, 32, dtype=np.float32)[None, :, None], 16, 0).repeat(3, 2), LATLONG)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = radiance_map(env, parse_brdf(spec), np.array([0.3, 0.4, 0.866]) / np.linalg.norm([0.3, 0.4, 0.866]),
                            8).data
    assert np.isfinite(data).all()
    ours = [w for w in caught if issubclass(w.category, (LightprobeWarning, RuntimeWarning))]  # numpy's: RuntimeWarning
    assert [w.category for w in ours] == ([LightprobeWarning] if black else []), [str(w.message) for w in ours]
    assert (data.max() == 0) == black and data.max() <= 1.0 + 1e-3  # the environment's largest radiance is 1
