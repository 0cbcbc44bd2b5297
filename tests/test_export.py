"""Engine exports, each evaluated with that engine's own reconstruction formula (written here from the engines'
documentation and shader code, independently of lightprobe.exports.sh), against two golden cases:

* white furnace: uniform radiance 1 → E = π, E/π = 1 for every normal;
* a point light of power Φ from direction s → E(n) = Φ (¼ + ½ cos γ + 5/32 (3cos²γ − 1)), the clamped-cosine series
  to band 2 (Σ Â_l (2l+1)/4π P_l(cos γ)), independent of any basis or sign convention.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from conftest import random_directions
from lightprobe.exports.sh import TARGETS, export
from lightprobe.sh.basis import SHCoeffs, delta_light

SUN = np.array([0.35, 0.75, -0.56])
SUN /= np.linalg.norm(SUN)
POWER = np.array([3.0, 2.0, 1.0])
NORMALS = random_directions(400, seed=3)  # world frame


def furnace() -> SHCoeffs:
    c = np.zeros((9, 3))
    c[0] = np.sqrt(4 * np.pi)  # uniform radiance 1
    return SHCoeffs(c)


def expected_over_pi(case: str) -> np.ndarray:
    if case == "furnace":
        return np.ones((len(NORMALS), 3))
    g = NORMALS @ SUN
    return (0.25 + 0.5 * g + 5 / 32 * (3 * g * g - 1))[:, None] * POWER / np.pi


def source(case: str) -> SHCoeffs:
    return furnace() if case == "furnace" else delta_light(SUN, POWER)


UNITY_FLIP = np.array([1.0, 1.0, -1.0])  # world → Unity / Babylon (left-handed, +Z forward)


# ---- the engines' reconstruction formulas ---------------------------------------------------------------------------
THREEJS_OF_WORLD = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # three's equirectUv: (−z, y, x)


def threejs_irradiance_over_pi(text: str) -> np.ndarray:
    """three.js SphericalHarmonics3.getIrradianceAt (E), then the Lambert BRDF 1/π, at the normal as three.js
    places it when it shows the same panorama (u = atan(z, x)/2π + ½: world (x, y, z) is three's (−z, y, x))."""
    sh = np.array(json.loads(text)["object"]["sh"]).reshape(9, 3)
    n3 = NORMALS @ THREEJS_OF_WORLD.T
    x, y, z = (n3[:, k, None] for k in range(3))
    e = (sh[0] * 0.886227 + sh[1] * 2 * 0.511664 * y + sh[2] * 2 * 0.511664 * z + sh[3] * 2 * 0.511664 * x
         + sh[4] * 2 * 0.429043 * x * y + sh[5] * 2 * 0.429043 * y * z + sh[6] * (0.743125 * z * z - 0.247708)
         + sh[7] * 2 * 0.429043 * x * z + sh[8] * 0.429043 * (x * x - y * y))
    return e / np.pi


def filament_irradiance_over_pi(text: str) -> np.ndarray:
    """Filament's shader: the bare polynomial over pre-scaled sh.txt values (which already include 1/π)."""
    rows = re.findall(r"\(\s*([-\d.]+),\s*([-\d.]+),\s*([-\d.]+)\);\s*// (L\S+), irradiance, pre-scaled base", text)
    assert [r[3] for r in rows] == ["L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"]
    sh = np.array([[float(v) for v in r[:3]] for r in rows])
    x, y, z = (NORMALS[:, k, None] for k in range(3))
    return (sh[0] + sh[1] * y + sh[2] * z + sh[3] * x + sh[4] * y * x + sh[5] * y * z
            + sh[6] * (3 * z * z - 1) + sh[7] * z * x + sh[8] * (x * x - y * y))


def unity_irradiance_over_pi(text: str) -> np.ndarray:
    """Unity ShadeSH9 with unity_SHA/B/C built from SphericalHarmonicsL2 (normal in Unity's frame)."""
    values = {(int(c), int(i)): float(v) for c, i, v in re.findall(r"sh\[(\d), (\d)\] = ([-\d.e+]+)f;", text)}
    assert len(values) == 27
    n = NORMALS * UNITY_FLIP
    out = np.zeros((len(n), 3))
    for ch in range(3):
        s = [values[(ch, i)] for i in range(9)]
        sha = np.array([s[3], s[1], s[2], s[0] - s[6]])
        shb = np.array([s[4], s[5], 3 * s[6], s[7]])
        n1 = np.concatenate([n, np.ones((len(n), 1))], axis=1)
        vb = n[:, [0, 1, 2, 2]] * n[:, [1, 2, 2, 0]]  # normal.xyzz * normal.yzzx
        vc = n[:, 0] ** 2 - n[:, 1] ** 2
        out[:, ch] = n1 @ sha + vb @ shb + s[8] * vc
    return out


def babylon_from_harmonics(h: np.ndarray) -> dict:
    """Babylon's SphericalPolynomial.FromHarmonics as written (CS-phase harmonics → polynomial, ÷π included;
    its 0.886277 misprint is 5.6e-5 relative, inside the tolerance)."""
    p = {"x": -1.02333 * h[3], "y": -1.02333 * h[1], "z": 1.02333 * h[2],
         "xx": 0.886277 * h[0] - 0.247708 * h[6] + 0.429043 * h[8],
         "yy": 0.886277 * h[0] - 0.247708 * h[6] - 0.429043 * h[8],
         "zz": 0.886277 * h[0] + 0.495417 * h[6],
         "yz": -0.858086 * h[5], "zx": -0.858086 * h[7], "xy": 0.858086 * h[4]}
    return {k: v / np.pi for k, v in p.items()}


def babylon_default_shader_over_pi(p: dict, n: np.ndarray) -> np.ndarray:
    """What Babylon's default PBR path (useSphericalHarmonics) renders from a SphericalPolynomial: its
    preScaledHarmonics = SphericalHarmonics.FromPolynomial (constants as in Babylon's source) × the
    SH3ylmBasisConstants, evaluated by the shader's computeEnvironmentIrradiance. Returns E/π."""
    h = [0.376127 * p["xx"] + 0.376127 * p["yy"] + 0.376126 * p["zz"], -0.977204 * p["y"], 0.977204 * p["z"],
         -0.977204 * p["x"], 1.16538 * p["xy"], -1.16538 * p["yz"],
         1.34567 * p["zz"] - 0.672834 * p["xx"] - 0.672834 * p["yy"], -1.16538 * p["zx"],
         1.16538 * p["xx"] - 1.16538 * p["yy"]]
    k = [np.sqrt(1 / (4 * np.pi)), -np.sqrt(3 / (4 * np.pi)), np.sqrt(3 / (4 * np.pi)), -np.sqrt(3 / (4 * np.pi)),
         np.sqrt(15 / (4 * np.pi)), -np.sqrt(15 / (4 * np.pi)), np.sqrt(5 / (16 * np.pi)),
         -np.sqrt(15 / (4 * np.pi)), np.sqrt(15 / (16 * np.pi))]
    s = [np.pi * k[i] * h[i] for i in range(9)]
    x, y, z = (n[:, j, None] for j in range(3))
    return (s[0] + s[1] * y + s[2] * z + s[3] * x + s[4] * y * x + s[5] * y * z + s[6] * (3 * z * z - 1)
            + s[7] * z * x + s[8] * (x * x - y * y))


def babylon_irradiance_over_pi(text: str) -> np.ndarray:
    """The polynomial through Babylon's default shader path; the harmonics field must be what that path uses."""
    data = json.loads(text)
    p = {k: np.array(v) for k, v in zip(data["polynomial_order"], data["polynomial"])}
    shaded = babylon_default_shader_over_pi(p, NORMALS * UNITY_FLIP)
    again = babylon_default_shader_over_pi(babylon_from_harmonics(np.array(data["harmonics"])), NORMALS * UNITY_FLIP)
    np.testing.assert_allclose(shaded, again, rtol=2e-4, atol=2e-5 * np.abs(shaded).max())
    return shaded


def gltf_babylon_irradiance_over_pi(text: str) -> np.ndarray:
    """Babylon's EXT_lights_image_based loader: FromArray → ÷π (convertIrradianceToLambertianRadiance) →
    FromHarmonics, then its default shader path; no handedness change (normals in Babylon's frame)."""
    light = json.loads(text)["extensions"]["EXT_lights_image_based"]["lights"][0]
    c = np.array(light["irradianceCoefficients"]) / np.pi
    return babylon_default_shader_over_pi(babylon_from_harmonics(c), NORMALS * UNITY_FLIP)


def gltf_literal_irradiance_over_pi(text: str) -> np.ndarray:
    """irradianceCoefficients read literally as irradiance SH E_lm in the CS-phase basis: E(n) = Σ E_lm Y^CS_lm(n)."""
    c = np.array(json.loads(text)["extensions"]["EXT_lights_image_based"]["lights"][0]["irradianceCoefficients"])
    x, y, z = (NORMALS[:, k, None] for k in range(3))
    y_cs = [0.282095, -0.488603 * y, 0.488603 * z, -0.488603 * x, 1.092548 * x * y, -1.092548 * y * z,
            0.315392 * (3 * z * z - 1), -1.092548 * x * z, 0.546274 * (x * x - y * y)]
    return sum(c[i] * y_cs[i] for i in range(9)) / np.pi


def glsl_irradiance_over_pi(text: str) -> np.ndarray:
    """Run the GLSL snippet's arithmetic: its constants and return expression evaluated as written."""
    env = {}
    for var, body in re.findall(r"const vec3 (\w+) = vec3\(([^)]*)\);", text):
        env[var] = np.array([float(v) for v in body.split(",")])
    for var, val in re.findall(r"const float (\w+) = ([-\d.e+]+);", text):
        env[var] = float(val)
    expr = re.search(r"return (.*?);", text, re.S).group(1)
    env.update({"n": None})
    x, y, z = (NORMALS[:, k, None] for k in range(3))
    expr = expr.replace("n.x", "x").replace("n.y", "y").replace("n.z", "z")
    return eval(f"({expr})", {}, {**env, "x": x, "y": y, "z": z}) / np.pi  # noqa: S307 - our own snippet


def json_irradiance_over_pi(text: str) -> np.ndarray:
    """lightprobe's JSON read as its schema says (radiance L_lm, world frame, no CS phase, flat order), evaluated
    with the explicit band ≤ 2 polynomials and Â_l = π, 2π/3, π/4 — not with lightprobe's own SHCoeffs."""
    data = json.loads(text)
    assert (data["format"], data["version"], data["frame"], data["quantity"]) == ("lightprobe.sh", 2, "world",
                                                                                  "radiance")
    c = np.array(data["coefficients"])[:9]
    x, y, z = (NORMALS[:, k, None] for k in range(3))
    basis = [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
             0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)]
    a_hat = [np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5
    return sum(a_hat[i] * c[i] * basis[i] for i in range(9)) / np.pi


EVALUATORS = {
    "json": (json_irradiance_over_pi, {}),
    "threejs": (threejs_irradiance_over_pi, {}),
    "filament": (filament_irradiance_over_pi, {}),
    "unity": (unity_irradiance_over_pi, {}),
    "gltf": (gltf_babylon_irradiance_over_pi, {"gltf_scaling": "irradiance"}),
    "gltf-literal": (gltf_literal_irradiance_over_pi, {"gltf_scaling": "irradiance", "frame": "gltf"}),
    "babylon": (babylon_irradiance_over_pi, {}),
    "glsl": (glsl_irradiance_over_pi, {}),
}


@pytest.mark.parametrize("case", ["furnace", "point light"])
@pytest.mark.parametrize("target", list(EVALUATORS))
def test_export_golden(target, case):
    evaluate, options = EVALUATORS[target]
    text = export(source(case), target.split("-")[0], **options)
    got = evaluate(text)
    # printed engine constants carry 6 digits; Babylon's 0.886277 misprint is 5.6e-5
    np.testing.assert_allclose(got, expected_over_pi(case), rtol=2e-4, atol=2e-5 * POWER.max())


def test_every_target_has_a_golden_test():
    assert set(TARGETS) <= {t.split("-")[0] for t in EVALUATORS}


def test_filament_text_is_exactly_cmgen_format():
    lines = export(furnace(), "filament").splitlines()
    assert lines[0] == "( 1.000000000000000,  1.000000000000000,  1.000000000000000); // L00, irradiance, pre-scaled base"
    assert lines[1] == "( 0.000000000000000,  0.000000000000000,  0.000000000000000); // L1-1, irradiance, pre-scaled base"
    assert len(lines) == 9 and lines[8].endswith("// L22, irradiance, pre-scaled base")


def test_exports_refuse_irradiance_input():
    with pytest.raises(ValueError, match="radiance"):
        export(furnace().to_irradiance(), "threejs")


def test_a_mirror_frame_is_not_a_rotation():
    """Unity's frame flips z: the light from world −Z (front) must light Unity normals facing +Z."""
    front = delta_light([0, 0, -1], [1, 1, 1])
    text = export(front, "unity")
    values = {(int(c), int(i)): float(v) for c, i, v in re.findall(r"sh\[(\d), (\d)\] = ([-\d.e+]+)f;", text)}
    assert values[(0, 2)] > 0  # L10 (z) positive in Unity's frame: the light is at Unity +Z
