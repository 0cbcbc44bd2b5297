"""Light exports by each engine's own formula (the engines that run here are in test_engine_lights.py): a directional
light of E⊥ = P (1 + cos r)/2 is exact for every normal that sees the whole cap; a cap folded into SH is its
projection; Filament gets one SUN and the rest in its SH; Unity's intensity is E⊥/π; the reader refuses bad files
with one clear error."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightprobe.maps import EnvMap
from lightprobe.util.errors import InputError
from lightprobe.exports.sh import filament_coefficients
from lightprobe.sh.irradiance import brute_irradiance, reference_normals
from lightprobe.maps.layouts import LATLONG
from lightprobe.exports.lights import ambient_sh, cap_sh, export_lights, gltf_lights, perpendicular_irradiance
from lightprobe.lights.lightsfile import LightSet, read_lights_json
from lightprobe.sh.basis import SHCoeffs, project
from lightprobe.maps.frames import WORLD


def _cap_map(d, radius, radiance, rows=512):
    env = EnvMap(np.zeros(LATLONG.grid_shape(rows) + (3,), np.float32), LATLONG)
    data = np.zeros_like(env.data)
    data[env.directions() @ d >= math.cos(radius)] = radiance
    return EnvMap(data, LATLONG)


def test_a_directional_light_of_e_perp_is_exact_where_the_whole_cap_is_above_the_horizon():
    d = np.array([0.2, 0.9, -0.3]) / np.linalg.norm([0.2, 0.9, -0.3])
    radius = math.radians(12.0)
    env = _cap_map(d, radius, [3.0, 2.0, 1.0])
    power = env.integral()
    normals = reference_normals(600)
    sees_all = normals @ d >= math.sin(radius)
    exact = brute_irradiance(env, normals[sees_all])
    directional = (normals[sees_all] @ d)[:, None] * perpendicular_irradiance(radius, power)[None, :]
    np.testing.assert_allclose(directional, exact, rtol=3e-3)  # the cap's rasterisation in the 512-row map
    # the point-light formula (E⊥ = P) would be off by (1 − cos r)/2 ≈ 1.1 % here: the test can tell
    assert abs((1 + math.cos(radius)) / 2 - 1) > 0.01


def test_a_folded_cap_is_its_projection():
    d = np.array([-0.4, 0.1, 0.9]) / np.linalg.norm([-0.4, 0.1, 0.9])
    radius = math.radians(8.0)
    env = _cap_map(d, radius, [5.0, 4.0, 3.0])
    ours = cap_sh(d, radius, env.integral(), 6).coeffs
    np.testing.assert_allclose(ours, project(env, 6).coeffs, atol=2e-3 * np.abs(ours).max())
    point = cap_sh(d, 0.0, np.ones(3), 2).coeffs
    assert point[0, 0] == pytest.approx(0.5 * math.sqrt(1 / math.pi))  # P Y00


def _lights(n_lights=3, ambient=True) -> LightSet:
    rng = np.random.default_rng(4)
    d = rng.normal(size=(n_lights, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sh = SHCoeffs(rng.normal(size=(16, 3)) * 0.1 + np.array([[1.0, 1, 1]] + [[0, 0, 0]] * 15), WORLD, "radiance")
    return LightSet(d, np.radians([3.0, 30.0, 0.0][:n_lights]), rng.uniform(1, 10, (n_lights, 3)),
                    sh if ambient else None, "arbree2005")


def test_filament_gets_one_sun_and_the_other_lights_in_its_sh():
    lights = _lights()
    doc = json.loads(export_lights(lights, "filament"))
    brightest = int(np.argmax([perpendicular_irradiance(r, p).max() for r, p in zip(lights.radii, lights.powers)]))
    others = [i for i in range(3) if i != brightest]
    np.testing.assert_allclose(doc["irradiance"], filament_coefficients(ambient_sh(lights, others)), rtol=1e-12)
    sun = doc["sun"]
    np.testing.assert_allclose(sun["direction"], -lights.directions[brightest], atol=1e-12)  # it travels away
    e = perpendicular_irradiance(lights.radii[brightest], lights.powers[brightest])
    np.testing.assert_allclose(np.array(sun["color"]) * sun["intensity"], e, rtol=1e-12)
    assert 0.25 <= sun["sunAngularRadius"] <= 20 and doc["folded_into_irradiance"] == 2


def test_unity_intensity_is_e_perp_over_pi_and_babylon_takes_every_light():
    lights = _lights()
    text = export_lights(lights, "unity")
    e = [perpendicular_irradiance(r, p).max() / math.pi for r, p in zip(lights.radii, lights.powers)]
    for value in e:
        assert f"intensity = {value:.9g}f" in text
    assert text.count("LightType.Directional") == 3 and "RenderSettings.ambientProbe = sh" in text
    doc = json.loads(export_lights(lights, "babylon"))
    assert len(doc["directionalLights"]) == 3 and doc["maxSimultaneousLights"] == 4
    for light in doc["directionalLights"]:
        assert abs(np.linalg.norm(light["direction"]) - 1) < 1e-12 and max(light["diffuse"]) == pytest.approx(1)


def test_gltf_has_punctual_lights_on_rotated_nodes_and_the_ambient():
    lights = _lights()
    document, images = gltf_lights(lights, 8)
    assert {"KHR_lights_punctual", "EXT_lights_image_based"} <= set(document["extensionsUsed"])
    assert len(document["extensions"]["KHR_lights_punctual"]["lights"]) == 3 and images
    for node in document["nodes"]:
        q = np.array(node["rotation"])
        assert abs(np.linalg.norm(q) - 1) < 1e-12
    without = gltf_lights(_lights(ambient=False), 8)[0]  # a file whose lights carry the whole map: no ambient
    assert np.allclose(without["extensions"]["EXT_lights_image_based"]["lights"][0]["irradianceCoefficients"], 0)


def _document() -> dict:
    return {"format": "lightprobe.lights", "version": 1, "frame": "world", "method": "arbree2005",
            "lights": [{"direction": [0, 1, 0], "angular_radius_deg": 5.0, "power": [1.0, 2.0, 3.0]}],
            "ambient": {"sh": {"format": "lightprobe.sh", "version": 2, "quantity": "radiance", "frame": "world",
                               "l_max": 0, "coefficients": [[1.0, 1.0, 1.0]]}}}


def test_the_reader_takes_a_document_and_refuses_bad_fields():
    lights = read_lights_json(json.dumps(_document()))
    assert lights.radii[0] == pytest.approx(math.radians(5)) and lights.ambient.l_max == 0
    for field, value in (("frame", "babylon"), ("version", 2), ("lights", {}), ("ambient", [1])):
        doc = _document()
        doc[field] = value
        with pytest.raises(InputError, match="cannot read"):
            read_lights_json(json.dumps(doc))
    for key, value in (("direction", [0, 0, 0]), ("direction", [1, 2]), ("angular_radius_deg", 91),
                       ("power", [1, -1, 0]), ("power", [1e400, 0, 0]), ("angular_radius_deg", True)):
        doc = _document()
        doc["lights"][0][key] = value
        with pytest.raises(InputError, match="cannot read"):
            read_lights_json(json.dumps(doc).replace("Infinity", "1e999"))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=st.lists(st.tuples(st.integers(0, 400), st.integers(32, 126)), min_size=0, max_size=6),
       cut=st.integers(0, 400))
def test_the_reader_returns_lights_or_one_clear_error(edits, cut):
    text = bytearray(json.dumps(_document()).encode())
    for at, byte in edits:
        text[at % len(text)] = byte
    text = bytes(text[: max(1, len(text) - cut)]) if cut % 3 == 0 else bytes(text)
    try:
        lights = read_lights_json(text)
    except InputError as e:
        assert str(e).startswith("cannot read") and "\n" not in str(e)
    else:
        assert np.isfinite(lights.directions).all() and (lights.powers >= 0).all()


def _run(capsys, *argv):
    from lightprobe.cli import main

    code = main([str(a) for a in argv])
    return (code, *capsys.readouterr())


def test_export_lights_refusals(tmp_path, capsys):
    good = tmp_path / "lights.json"
    good.write_text(json.dumps(_document()))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    for argv in (["--to", "glsl", "-o", tmp_path / "x.txt"], ["--to", "gltf", "-o", tmp_path / "x.json"],
                 ["--to", "threejs", "--frame", "world", "-o", tmp_path / "x.json"]):
        code, _, err = _run(capsys, "export", "--lights", good, *argv)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
    code, _, err = _run(capsys, "export", "--lights", bad, "--to", "threejs", "-o", tmp_path / "y.json")
    assert code != 0 and len(err.strip().splitlines()) == 1 and not (tmp_path / "y.json").exists(), err
    code, said, err = _run(capsys, "export", "--lights", good, "--to", "unity", "-o", tmp_path / "ok.cs")
    assert code == 0 and "LightType.Directional" in (tmp_path / "ok.cs").read_text(), err
