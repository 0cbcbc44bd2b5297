"""``lightprobe bake``: each engine's folder, its manifest, the mappings into each engine's conventions, and the
refusals. The Babylon and glTF files are rendered in Babylon.js itself by tests/test_engines.py (its ``containers``
fixture bakes them)."""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from lightprobe.bake import BakeOptions, bake, parse_engines
from lightprobe.bake.manifest import read_bake_manifest
from lightprobe.bake.source import BakeSource
from lightprobe.maps import EnvMap
from lightprobe.maps.layouts import LATLONG
from lightprobe.util.errors import InputError, LightprobeWarning, UsageError
from lightprobe.util.names import BAKE_ENGINES

LIGHTPROBE = Path(sys.executable).with_name("lightprobe")
# The chain against brute force over every texel (the bound tests/test_prefilter.py holds the prefilter to)
CHAIN_MEDIAN, CHAIN_WORST = 0.01, 0.05
SMALL = dict(size=16, skybox_size=16)


def sunny_map(rows: int = 32, sun=(0.3, 0.8, -0.5), power: float = 20.0) -> EnvMap:
    """A sky gradient (brighter up) with a small bright cap toward ``sun``: lights for --lights to find."""
    d = LATLONG.directions(LATLONG.grid_shape(rows))
    sun = np.asarray(sun) / np.linalg.norm(sun)
    data = np.repeat((0.2 + 0.1 * d[..., 1:2]), 3, axis=-1)
    data[(d @ sun) > math.cos(math.radians(6))] += power
    return EnvMap(data.astype(np.float32), LATLONG)


def baked(tmp_path, engines=BAKE_ENGINES, **options) -> dict[str, Path]:
    tmp_path.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LightprobeWarning)  # RGBD clipping the sun's mirror mip
        return bake(sunny_map(), tmp_path / "bake", BakeOptions(tuple(engines), **{**SMALL, **options}))


def test_every_engine_gets_a_folder_whose_manifest_names_each_file_with_its_hash(tmp_path):
    folders = baked(tmp_path)
    assert sorted(p.name for p in (tmp_path / "bake").iterdir()) == sorted(BAKE_ENGINES)
    for engine, folder in folders.items():
        manifest = read_bake_manifest((folder / "manifest.json").read_text())
        assert manifest["engine"] == engine and manifest["parameters"]["size"] == 16
        listed = {f["path"] for f in manifest["files"]}
        assert listed | {"manifest.json"} == {p.name for p in folder.iterdir()}, (engine, listed)
        assert "USAGE.md" in listed
        for entry in manifest["files"]:
            data = (folder / entry["path"]).read_bytes()
            assert entry["bytes"] == len(data) and entry["sha256"] == hashlib.sha256(data).hexdigest()
            assert entry["quantity"] and entry["frame"]
    assert not list(tmp_path.glob(".bake*")), "a temporary folder was left beside the bake"


def test_the_manifest_reports_the_chain_within_the_prefilters_bounds_against_brute_force(tmp_path):
    manifest = json.loads((baked(tmp_path, ("babylon",))["babylon"] / "manifest.json").read_text())
    levels = manifest["accuracy"]["specular"]["levels"]
    measured = [level for level in levels if level["measured"]]
    assert len(measured) >= 3 and not levels[0]["measured"]
    for level in measured:
        assert level["median"] < CHAIN_MEDIAN and level["worst"] < CHAIN_WORST, level
    sh = manifest["accuracy"]["sh"]
    assert 0 < sh["of_total_mean"] < 0.1 and sh["relative_worst"] >= sh["relative_median"]


def test_godot_panorama_puts_each_direction_where_godots_sky_shader_reads_it(tmp_path):
    """Godot's sky shader reads SKY_COORDS = (atan2(x, −z)/2π wrapped into [0, 1), acos(y)/π): a bright texel at
    each of several directions must be found there in sky.exr (a lat-long left as it is — −Z at the centre —
    puts every one half a turn away)."""
    from lightprobe.maps.images import read_image

    rows = 64
    for d in ([0.0, 0.0, -1.0], [1.0, 0.2, 0.0], [-0.3, -0.5, 0.8], [0.6, 0.7, -0.4]):
        d = np.asarray(d) / np.linalg.norm(d)
        data = np.zeros(LATLONG.grid_shape(rows) + (3,), np.float32)
        _, x, y = LATLONG.pixel_coords(d, LATLONG.grid_shape(rows))
        data[int(y), int(x) % (2 * rows)] = 1.0
        out = tmp_path / f"g{len(list(tmp_path.iterdir()))}"
        bake(EnvMap(data, LATLONG), out, BakeOptions(("godot",), size=16, skybox_size=rows))
        sky = read_image(out / "godot" / "sky.exr")
        u = (math.atan2(d[0], -d[2]) / (2 * math.pi)) % 1.0
        v = math.acos(d[1]) / math.pi
        row, col = np.unravel_index(np.argmax(sky[..., 0]), sky.shape[:2])
        assert abs(row + 0.5 - v * rows) <= 1 and min(abs(col + 0.5 - u * 2 * rows),
                                                        2 * rows - abs(col + 0.5 - u * 2 * rows)) <= 1, (d, row, col)


def test_godot_lights_point_their_minus_z_along_the_light_and_carry_e_over_pi(tmp_path):
    """Each DirectionalLight3D's transform, read as Godot reads the text format (the basis row by row), has its +Z
    toward the light (it shines along −Z); light_energy = E⊥/π; light_color decodes (sRGB) to the linear colour."""
    import re

    from lightprobe.exports.lights import engine_lights
    from lightprobe.maps.frames import WORLD

    folder = baked(tmp_path, ("godot",), lights=True)["godot"]
    scene = (folder / "environment.tscn").read_text()
    manifest = json.loads((folder / "manifest.json").read_text())
    nodes = re.findall(r'type="DirectionalLight3D".*?\ntransform = Transform3D\(([^)]*)\)\nlight_color = '
                       r'Color\(([^)]*)\)\nlight_energy = (\S+)', scene, re.S)
    assert nodes and len(nodes) == len(manifest["lights"])
    for (transform, colour, energy), light in zip(nodes, manifest["lights"]):
        basis = np.array([float(v) for v in transform.split(",")][:9]).reshape(3, 3)
        assert np.allclose(basis @ basis.T, np.eye(3), atol=1e-6) and np.linalg.det(basis) > 0
        assert np.allclose(basis[:, 2], light["toward"], atol=1e-6)
        srgb = np.array([float(v) for v in colour.split(",")][:3])
        linear = np.where(srgb < 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        assert np.allclose(linear, light["colour"], atol=1e-6)
        assert float(energy) == pytest.approx(light["intensity"])
    e_over_pi = engine_lights(BakeSource.from_map(sunny_map(), BakeOptions(("godot",), **SMALL)).lights(), WORLD,
                              over_pi=True)
    assert [round(x["intensity"], 6) for x in e_over_pi] == [round(x["intensity"], 6) for x in manifest["lights"]]
    assert "AT_CUBEMAP_PASS" in (folder / "sky.gdshader").read_text() and (folder / "ambient.exr").is_file()


def test_with_lights_the_diffuse_term_is_the_remainders_and_the_lights_carry_the_sun(tmp_path):
    """--lights: the lights found hold the sun, and the .env's polynomial is the ambient remainder's (dimmer than
    the whole probe's toward the sun)."""
    from lightprobe.exports.containers import read_env_manifest

    with_lights = baked(tmp_path / "a", ("babylon", "gltf", "unity"), lights=True)
    without = baked(tmp_path / "b", ("babylon",))
    manifest = json.loads((with_lights["babylon"] / "manifest.json").read_text())
    assert manifest["lights"] and manifest["parameters"]["lights"]
    sun = np.array(manifest["lights"][0]["toward"])
    assert sun @ (np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])) > 0.99  # Babylon's frame: z mirrored
    x_lit = read_env_manifest((with_lights["babylon"] / "environment.env").read_bytes())["irradiance"]["x"]
    x_all = read_env_manifest((without["babylon"] / "environment.env").read_bytes())["irradiance"]["x"]
    assert abs(x_lit[0]) < 0.5 * abs(x_all[0])
    assert (with_lights["babylon"] / "lights.json").is_file() and (with_lights["unity"] / "LightprobeLights.cs").is_file()
    glb = (with_lights["gltf"] / "environment.glb").read_bytes()
    assert b"KHR_lights_punctual" in glb


def test_the_intensity_scales_every_number(tmp_path):
    one = json.loads((baked(tmp_path / "a", ("unity",))["unity"] / "manifest.json").read_text())
    ten = json.loads((baked(tmp_path / "b", ("unity",), intensity=10.0)["unity"] / "manifest.json").read_text())
    assert np.allclose(ten["source"]["integral"], 10 * np.array(one["source"]["integral"]), rtol=1e-6)


def lightprobe(*argv, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([str(LIGHTPROBE), *map(str, argv)], capture_output=True, text=True, timeout=300, cwd=cwd)


def one_line_failure(res, *words):
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr, res.stderr
    for word in words:
        assert word in res.stderr, res.stderr


@pytest.mark.parametrize("argv, words", [
    (["--for", "unreal"], ["unknown engine unreal"]),
    (["--for", "babylon", "--size", "48"], ["power of two"]),
    (["--for", "babylon", "--size", "2048"], ["16..1024"]),
    (["--for", "babylon", "--mips", "3"], ["full mip chain"]),
    (["--for", "godot", "--skybox-size", "100"], ["power of two"]),
    (["--for", "unity", "--encoding", "unity=rgbm"], ["unity takes no choice"]),
    (["--for", "unity", "--intensity", "0"], ["--intensity"]),
])
def test_bad_requests_are_one_line_and_write_nothing(tmp_path, argv, words):
    res = lightprobe("bake", "-o", tmp_path / "out", *argv)
    one_line_failure(res, *words)
    assert list(tmp_path.iterdir()) == []


def test_a_non_empty_folder_is_refused_unless_forced(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("my notes")
    res = lightprobe("bake", "--for", "godot", "-o", out, "--skybox-size", "16")
    one_line_failure(res, "not empty", "--force")
    assert [p.name for p in out.iterdir()] == ["mine.txt"]
    res = lightprobe("bake", "--for", "godot", "-o", out, "--skybox-size", "16", "--force")
    assert res.returncode == 0, res.stderr
    assert [p.name for p in out.iterdir()] == ["godot"]


def test_a_failure_mid_bake_leaves_the_old_folder_whole_and_nothing_beside_it(tmp_path, monkeypatch):
    import lightprobe.bake.engines.unity as unity

    out = tmp_path / "bake"
    baked(tmp_path, ("godot",))
    before = sorted(p.relative_to(out) for p in out.rglob("*"))

    def broken(source, folder):
        folder.add_text("half.txt", "written before the failure", "none", "none")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(unity, "bake", broken)
    with pytest.raises(OSError, match="No space"):
        bake(sunny_map(), out, BakeOptions(("godot", "unity"), **SMALL), force=True)
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before
    assert [p.name for p in tmp_path.iterdir()] == ["bake"]


def test_engine_lists_parse_to_the_canonical_order():
    assert parse_engines("godot, babylon") == ("babylon", "godot")
    assert parse_engines("all") == BAKE_ENGINES
    with pytest.raises(UsageError, match="unknown engine"):
        parse_engines("babylon,unreal")


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.binary(max_size=300), st.text(max_size=300),
                 st.dictionaries(st.sampled_from(["format", "version", "engine", "generator", "source", "parameters",
                                                  "frame", "files"]),
                                 st.one_of(st.none(), st.integers(), st.text(max_size=8), st.lists(st.dictionaries(
                                     st.sampled_from(["path", "role", "quantity", "encoding", "bytes", "sha256"]),
                                     st.one_of(st.text(max_size=70), st.integers(-2, 99))), max_size=3)),
                                 max_size=8)))
def test_the_manifest_reader_refuses_anything_else_in_one_clear_error(doc):
    text = doc if isinstance(doc, (bytes, str)) else json.dumps(
        {"format": "lightprobe.bake", "version": 1, **doc} if doc.get("format") is None else doc)
    try:
        read_bake_manifest(text)
    except InputError as e:
        assert "\n" not in str(e)


@pytest.mark.parametrize("path", ["../escape.txt", "/etc/passwd", "a/../../b", "./x"])
def test_the_manifest_reader_refuses_paths_that_leave_the_folder(tmp_path, path):
    manifest = json.loads((baked(tmp_path, ("godot",))["godot"] / "manifest.json").read_text())
    manifest["files"][0]["path"] = path
    with pytest.raises(InputError, match="leaves the folder"):
        read_bake_manifest(json.dumps(manifest))


# ---- custom renderers -----------------------------------------------------------------------------------------------
def test_custom_white_furnace_every_texture_holds_the_exact_value(tmp_path):
    """A uniform sky of radiance 1: every specular level is 1, the irradiance cube π, the skybox 1, the SH's L00
    2√π — in every encoding (RGB9E5 and B10G11R11 hold 1 and π to their mantissas; float32 the irradiance sum
    over the 256×128 reduction, within 1e-4 of π)."""
    from lightprobe.exports.ktx2 import read_ktx2

    ones = EnvMap(np.ones(LATLONG.grid_shape(16) + (3,), np.float32), LATLONG)
    for encoding, tolerance in (("rgba16f", 2e-3), ("rgb9e5", 4e-3), ("b10g11r11", 2e-2), ("rgba32f", 2e-4)):
        out = tmp_path / encoding
        folder = bake(ones, out, BakeOptions(("custom",), **SMALL, encodings={"custom": encoding}))["custom"]
        specular = read_ktx2(folder / "specular.ktx2")
        assert specular.face_count == 6 and specular.level_count == 5 and specular.width == 16
        for level in specular.levels:
            assert np.allclose(level[..., :3], 1.0, rtol=tolerance), (encoding, level.min(), level.max())
        assert np.allclose(read_ktx2(folder / "irradiance.ktx2").levels[0][..., :3], np.pi, rtol=tolerance)
        assert np.allclose(read_ktx2(folder / "skybox.ktx2").levels[0][..., :3], 1.0, rtol=tolerance)
        sh = json.loads((folder / "sh.json").read_text())
        assert sh["coefficients"][0][0] == pytest.approx(2 * math.sqrt(math.pi), rel=1e-4)


def test_custom_levels_sit_at_roughness_i_over_levels_minus_one(tmp_path):
    """--mips 3 of a 16 cube: three levels at r = 0, ½, 1 — level 1 equal to prefiltering at α = ¼, the mirror
    level the probe's cube itself."""
    from lightprobe.exports.ktx2 import read_ktx2
    from lightprobe.glossy.prefilter import prefilter_cube

    env = sunny_map(power=2.0)
    folder = bake(env, tmp_path / "b", BakeOptions(("custom",), **SMALL, mips=3,
                                                  encodings={"custom": "rgba32f"}))["custom"]
    manifest = json.loads((folder / "manifest.json").read_text())
    entry = next(f for f in manifest["files"] if f["path"] == "specular.ktx2")
    assert entry["roughness"] == [0.0, 0.5, 1.0] and entry["mips"] == 3
    levels = read_ktx2(folder / "specular.ktx2").levels
    assert len(levels) == 3
    expected = prefilter_cube(env, 16, [0.0, 0.25, 1.0, 1.0, 1.0])
    for got, want in zip(levels, expected.levels):
        assert np.allclose(got[..., :3], want, rtol=1e-5, atol=1e-6)


def test_custom_dfg_table_is_the_same_in_its_three_files(tmp_path):
    from lightprobe.exports.ktx2 import read_ktx2
    from lightprobe.maps.images import read_image

    folder = bake(sunny_map(), tmp_path / "b", BakeOptions(("custom",), **SMALL))["custom"]
    exr = read_image(folder / "dfg.exr")
    # DFG1, DFG2 are albedos in [0, 1]; the sheen albedo with Neubelt's visibility passes 1 at grazing, smooth texels
    assert exr.shape == (128, 128, 3) and 0 <= exr.min() and exr[..., :2].max() <= 1.0
    assert np.allclose(read_ktx2(folder / "dfg.ktx2").levels[0][0, ..., :3], exr, rtol=1e-3, atol=1e-6)
    import OpenImageIO as oiio  # the PNG's 16-bit code values as stored (read_image would decode them as sRGB)

    png = oiio.ImageBuf(str(folder / "dfg.png")).get_pixels(oiio.FLOAT)
    assert np.allclose(png, np.clip(exr, 0, 1), atol=1 / 65535 + 1e-6)
    assert np.all(exr[..., 1] >= exr[..., 0])  # DFG2 = A + B ≥ DFG1 = B


def test_ktx_parse_reads_the_custom_cubes_as_written(tmp_path):
    """npm ktx-parse (the reference reader) finds the cube, its levels and the same bytes."""
    from lightprobe.exports.ktx2 import read_ktx2
    from lightprobe_engines.runtimes import ktx_parse, missing_engines

    if any("node" in m for m in missing_engines()):
        pytest.fail("ktx-parse needs node and engines/node_modules: run 'bash setup.sh --test'", pytrace=False)
    folder = bake(sunny_map(), tmp_path / "b", BakeOptions(("custom",), **SMALL))["custom"]
    files = [folder / name for name in ("specular.ktx2", "irradiance.ktx2", "skybox.ktx2", "dfg.ktx2")]
    import base64

    for path, theirs in zip(files, ktx_parse(files)):
        ours = read_ktx2(path)
        assert (theirs["faceCount"], theirs["levelCount"], theirs["pixelWidth"]) == (
            ours.face_count, ours.level_count, ours.width)
        assert [base64.b64decode(level["base64"]) for level in theirs["levels"]] == ours.level_bytes
