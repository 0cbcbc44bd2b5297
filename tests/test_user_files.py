"""A user's files: no command deletes or overwrites what it did not make.

A folder is replaced only when its manifest says it is ours, an output never lands inside the set a command reads,
a binary container never overwrites an image or another kind of file, the outputs of one command are committed
together or not at all, and a batch's sweep removes only what the batch made.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lightprobe.cli import main
from lightprobe.maps.images import write_image
from test_cli import assert_clean_failure


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative path → bytes): what must not change."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def probe(tmp_path_factory) -> Path:
    """A small latlong map: a dim sky with one bright spot (so that lights finds a light)."""
    img = np.full((16, 32, 3), 0.2, np.float32)
    img[4, 10] = 400.0
    return write_image(tmp_path_factory.mktemp("probe") / "probe.exr", img)


@pytest.fixture(scope="module")
def radiance_set(probe, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("set") / "set"
    assert main(["radiance", str(probe), "--brdf", "lambert", "--size", "8", "-o", str(folder)]) == 0
    return folder


# ---- radiance -o DIR --------------------------------------------------------------------------------------------
def test_radiance_refuses_to_replace_a_folder_whose_manifest_is_not_a_radiance_set(tmp_path, capsys, probe):
    app = tmp_path / "app"
    (app / "src").mkdir(parents=True)
    (app / "manifest.json").write_text('{"name": "my web app", "start_url": "/"}\n')
    (app / "src" / "app.js").write_text("console.log('mine')\n")
    (app / "README.md").write_text("mine\n")
    before = snapshot(app)
    code, _, err = run(capsys, "radiance", probe, "--brdf", "lambert", "--size", 8, "-o", app)
    assert_clean_failure(code, err, "not a radiance-map folder")
    assert snapshot(app) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["app"]


def test_radiance_still_replaces_a_set_it_wrote(tmp_path, capsys, probe):
    out = tmp_path / "set"
    assert run(capsys, "radiance", probe, "--brdf", "lambert", "--size", 8, "-o", out)[0] == 0
    code, _, err = run(capsys, "radiance", probe, "--brdf", "phong:n=20", "--size", 8, "-o", out)
    assert code == 0, err
    assert json.loads((out / "manifest.json").read_text())["brdf"]["spec"] == "phong:n=20"


# ---- radiance --synthesize -o -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["view_000.exr", "smooth.exr", "manifest.exr", "new.exr", "sub/../view_001.exr"])
def test_synthesize_refuses_to_write_inside_the_set_it_reads(capsys, radiance_set, name):
    """One of the set's maps, its smooth cube, its manifest (through OUT.json) or any new file in the folder."""
    before = snapshot(radiance_set)
    (radiance_set / "sub").mkdir(exist_ok=True)
    code, _, err = run(capsys, "radiance", radiance_set, "--synthesize", "0.3,0.5,0.8", "-o", radiance_set / name)
    (radiance_set / "sub").rmdir()
    assert_clean_failure(code, err, "inside the set")
    assert snapshot(radiance_set) == before


def test_synthesize_refuses_a_folder_that_leads_into_the_set(tmp_path, capsys, radiance_set):
    (tmp_path / "alias").symlink_to(radiance_set)
    before = snapshot(radiance_set)
    code, _, err = run(capsys, "radiance", radiance_set, "--synthesize", "0.3,0.5,0.8", "-o",
                       tmp_path / "alias" / "manifest.exr")
    assert_clean_failure(code, err, "inside the set")
    assert snapshot(radiance_set) == before


def test_synthesize_writes_beside_the_set(tmp_path, capsys, radiance_set):
    code, _, err = run(capsys, "radiance", radiance_set, "--synthesize", "0.3,0.5,0.8", "-o", tmp_path / "new.exr")
    assert code == 0, err
    assert (tmp_path / "new.exr").is_file() and (tmp_path / "new.json").is_file()


# ---- export: binary containers ------------------------------------------------------------------------------------
@pytest.mark.parametrize("target, existing, words", [
    ("babylon-env", "image.hdr", "names an image format"),
    ("babylon-env", ".env", "not a file of this kind"),          # a user's dotenv settings
    ("gltf", "scene.glb", "not a file of this kind"),
    ("gltf", "photo.png", "names an image format"),
])
def test_export_container_refuses_to_overwrite_another_kind_of_file(tmp_path, capsys, probe, target, existing,
                                                                    words):
    victim = tmp_path / existing
    if victim.suffix in (".hdr", ".png"):
        write_image(victim, np.ones((4, 8, 3), np.float32))
    else:
        victim.write_text("SECRET=do-not-lose\n")
    before = victim.read_bytes()
    code, _, err = run(capsys, "export", probe, "--to", target, "--specular-size", 8, "-o", victim)
    assert_clean_failure(code, err, words, str(victim))
    assert victim.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [existing]


@pytest.mark.parametrize("target, name", [("babylon-env", "probe.env"), ("gltf", "probe.glb")])
def test_export_container_overwrites_its_own_earlier_output(tmp_path, capsys, probe, target, name):
    out = tmp_path / name
    assert run(capsys, "export", probe, "--to", target, "--specular-size", 8, "-o", out)[0] == 0
    first = out.read_bytes()
    code, _, err = run(capsys, "export", probe, "--to", target, "--specular-size", 16, "-o", out)
    assert code == 0, err
    assert out.read_bytes() != first


def test_export_lights_as_glb_refuses_to_overwrite_another_kind_of_file(tmp_path, capsys, probe):
    assert run(capsys, "lights", probe, "-o", tmp_path / "lights.json")[0] == 0
    victim = tmp_path / "notes.glb"
    victim.write_text("mine\n")
    code, _, err = run(capsys, "export", "--lights", tmp_path / "lights.json", "--to", "gltf", "-o", victim)
    assert_clean_failure(code, err, "not a file of this kind")
    assert victim.read_text() == "mine\n"


# ---- lights: several outputs --------------------------------------------------------------------------------------
def test_lights_leaves_every_old_output_when_a_later_one_fails(tmp_path, capsys, probe):
    """The preview cannot be written (an extension no image format has): the ambient map, written before it, and
    the lights JSON keep their old contents, and no temporary file is left."""
    ambient, lights, preview = tmp_path / "ambient.exr", tmp_path / "lights.json", tmp_path / "preview.xyz"
    ambient.write_bytes(b"the old ambient")
    lights.write_text("the old lights\n")
    code, _, err = run(capsys, "lights", probe, "-o", lights, "--ambient", ambient, "--preview", preview)
    assert_clean_failure(code, err, "preview.xyz")
    assert ambient.read_bytes() == b"the old ambient" and lights.read_text() == "the old lights\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ambient.exr", "lights.json"]


def test_lights_writes_all_its_outputs_together(tmp_path, capsys, probe):
    ambient, lights, preview = tmp_path / "ambient.exr", tmp_path / "lights.json", tmp_path / "preview.png"
    ambient.write_bytes(b"the old ambient")
    code, _, err = run(capsys, "lights", probe, "-o", lights, "--ambient", ambient, "--preview", preview)
    assert code == 0, err
    assert ambient.read_bytes() != b"the old ambient" and json.loads(lights.read_text())["format"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ambient.exr", "lights.json", "preview.png"]


@pytest.mark.parametrize("method", ["arbree2005", "mediancut"])
def test_lights_refuses_the_same_path_given_twice(tmp_path, capsys, probe, method):
    (tmp_path / "sub").mkdir()
    same = tmp_path / "same.png"
    same.write_bytes(b"the old file")
    again = tmp_path / "sub" / ".." / "same.png"
    extra = ["--ambient", same, "--preview", again] if method == "arbree2005" else ["--preview", same, "-o", again]
    argv = ["lights", probe, "--method", method, *extra]
    if method == "arbree2005":
        argv += ["-o", tmp_path / "lights.json"]
    code, _, err = run(capsys, *argv)
    assert_clean_failure(code, err, "twice")
    assert same.read_bytes() == b"the old file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["same.png", "sub"]


def test_compare_leaves_the_old_heatmap_when_the_flip_map_fails(tmp_path, capsys, probe):
    heat = tmp_path / "heat.png"
    heat.write_bytes(b"the old heatmap")
    code, _, err = run(capsys, "compare", probe, probe, "--heatmap", heat, "--flipmap", tmp_path / "flip.xyz")
    assert_clean_failure(code, err, "flip.xyz")
    assert heat.read_bytes() == b"the old heatmap" and sorted(p.name for p in tmp_path.iterdir()) == ["heat.png"]


def test_compare_refuses_the_same_path_given_twice(tmp_path, capsys, probe):
    (tmp_path / "sub").mkdir()
    code, _, err = run(capsys, "compare", probe, probe, "--heatmap", tmp_path / "x.png", "--flipmap",
                       tmp_path / "sub" / ".." / "x.png")
    assert_clean_failure(code, err, "twice")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub"]


# ---- batch --out ----------------------------------------------------------------------------------------------------
def dead_pid() -> int:
    """The id of a process that has exited (a stale temporary's owner)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_batch_refuses_a_folder_without_its_manifest_even_with_a_maps_folder(tmp_path, capsys, probe):
    out = tmp_path / "mine"
    (out / "maps" / "holiday").mkdir(parents=True)
    (out / "maps" / "holiday" / "beach.hdr").write_bytes(b"a user's map")
    (out / "maps" / "holiday" / f".drafts.tmp-{dead_pid()}").mkdir()
    before = snapshot(out)
    code, _, err = run(capsys, "batch", probe, "--out", out, "--jobs", "sh", "--workers", 1)
    assert_clean_failure(code, err, "holds no batch")
    assert snapshot(out) == before and (out / "maps" / "holiday").is_dir()
    assert sorted(p.name for p in (out / "maps" / "holiday").iterdir())[0].startswith(".drafts.tmp-")


def test_batch_sweep_removes_only_what_the_batch_made(tmp_path, capsys, probe):
    out = tmp_path / "run"
    args = ["batch", probe, "--out", out, "--jobs", "sh", "--workers", 1]
    assert run(capsys, *args)[0] == 0
    pid = dead_pid()
    user = out / "maps" / "mine" / f".backup.tmp-{pid}"
    user.mkdir(parents=True)
    (user / "keep.txt").write_text("mine")
    (out / "maps" / "mine" / f".notes.lp{pid}-0123abcd.tmp.txt").write_text("mine too")
    artifact = out / "maps" / "ab" / ("ab" + "0" * 62)
    (artifact / f".radiance.tmp-{pid}").mkdir(parents=True)
    (artifact / f".lights.json.lp{pid}-0123abcd.tmp.json").write_text("half")
    assert run(capsys, *args, "--resume")[0] == 0
    assert (user / "keep.txt").read_text() == "mine"
    assert (out / "maps" / "mine" / f".notes.lp{pid}-0123abcd.tmp.txt").read_text() == "mine too"
    assert list(artifact.iterdir()) == []  # the batch's own leftovers are swept
