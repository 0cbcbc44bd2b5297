"""Hybrid irradiance (area lights summed exactly + SH of the ambient) against brute-force integration: exact on a
sun over a uniform sky, within 1 % mean / 5 % max per normal on the issue's eight probes at the default order."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import shared
from lightprobe import read_envmap
from lightprobe.maps import EnvMap
from lightprobe.lights.hybrid import DEFAULT_AMBIENT_ORDER, hybrid_error_report, hybrid_irradiance
from lightprobe.sh.irradiance import brute_irradiance, error_report, reference_normals
from lightprobe.maps.layouts import LATLONG
from lightprobe.lights.decompose import AreaLight, Decomposition, LightParams


def _sun_over_a_sky(radius_deg: float, rows: int = 128):
    sky = np.full((rows, 2 * rows, 3), [0.2, 0.3, 0.5], np.float32)
    dirs = EnvMap(sky, LATLONG).directions()
    sun_dir = np.array([0.3, 0.25, -0.92]) / np.linalg.norm([0.3, 0.25, -0.92])
    inside = dirs @ sun_dir >= math.cos(math.radians(radius_deg))
    data = sky.copy()
    data[inside] += np.array([900.0, 800.0, 600.0], np.float32)
    return EnvMap(data, LATLONG), EnvMap(sky, LATLONG), sun_dir, math.radians(radius_deg)


def test_a_sun_over_a_uniform_sky_is_exact_for_every_normal():
    """The light's pixels are summed exactly (the linear form n·V where the whole cap is above the horizon, pixel by
    pixel where the horizon cuts it) and a uniform ambient is exact in SH: the hybrid equals brute force to the
    quadrature of the sky — at normals facing the sun, away from it, and cutting it (a wrong horizon bound shows
    there at once)."""
    env, sky, sun_dir, radius = _sun_over_a_sky(6.0)
    solid = 2 * math.pi * (1 - math.cos(radius))
    power = env.integral() - sky.integral()
    light = AreaLight(sun_dir, radius, solid, power, power / solid, 1.0)
    dec = Decomposition([light], sky, LightParams(), env.integral())
    hybrid = hybrid_irradiance(env, dec, ambient_order=2)
    normals = reference_normals(3000)
    cut = np.abs(normals @ sun_dir) < math.sin(radius)
    assert cut.sum() > 100  # the test does reach the normals whose horizon cuts the cap
    np.testing.assert_allclose(hybrid.evaluate(normals), brute_irradiance(env, normals), rtol=2e-4,
                               atol=2e-4 * float(env.integral().max()))


def test_found_lights_keep_the_map_whole_and_a_map_without_lights_is_plain_sh():
    env, _, sun_dir, _ = _sun_over_a_sky(4.0, rows=96)
    hybrid = hybrid_irradiance(env, ambient_order=4)
    assert len(hybrid.lights) >= 1
    normals = reference_normals(500)
    np.testing.assert_allclose(hybrid.evaluate(normals), brute_irradiance(env, normals), rtol=2e-3)
    uniform = EnvMap(np.ones((32, 64, 3), np.float32), LATLONG)
    plain = hybrid_irradiance(uniform, ambient_order=4)
    assert plain.lights == ()
    np.testing.assert_allclose(plain.evaluate(normals), np.pi, rtol=1e-3)  # a 32-row grid's quadrature


PROBES = {
    "grace": "debevec/angular/grace_probe.hdr",
    "eucalyptus grove": "debevec/angular/rnl_probe.hdr",
    "galileo": "debevec/angular/galileo_probe.hdr",
    "kitchen": "debevec/angular/kitchen_probe.hdr",
    "campus": "debevec/angular/campus_probe.hdr",
    "breezeway": "debevec/angular/building_probe.hdr",
    "rooitou park": "polyhaven_1k/rooitou_park_1k.hdr",
    "immenstadter horn": "polyhaven_1k/immenstadter_horn_1k.hdr",
}


@pytest.mark.parametrize("name", PROBES)
def test_hybrid_irradiance_is_within_one_percent_of_brute_force(name):
    """The issue's target over 1500 normals at the default ambient order: per-normal relative error mean < 1 %, max
    < 5 % — where SH9 alone misses by 3–25 % on average and 25–200 % at worst."""
    env = read_envmap(shared(PROBES[name]))
    normals = reference_normals(1500)
    reference = brute_irradiance(env, normals)
    report = hybrid_error_report(env, normals, reference, hybrid_irradiance(env))
    assert report.l_max == DEFAULT_AMBIENT_ORDER and report.method == "hybrid"
    assert report.relative_mean < 0.01 and report.relative_max < 0.05, report
    sh9 = error_report(env, 2, normals=normals, reference=reference)
    assert sh9.relative_mean > 0.02 and sh9.relative_max > 0.2, sh9


def _run(capsys, *argv):
    from lightprobe.cli import main

    code = main([str(a) for a in argv])
    return (code, *capsys.readouterr())


def test_hybrid_from_the_command_line(tmp_path, capsys):
    """``irradiance --method hybrid`` writes a map close to brute force's; ``error --method hybrid`` reports the
    hybrid beside SH alone at each order."""
    src = shared("debevec/angular/kitchen_probe.hdr")
    for method in ("hybrid", "brute"):
        code, _, err = _run(capsys, "irradiance", src, "-o", tmp_path / f"{method}.exr", "--method", method,
                            "--size", 16)
        assert code == 0, err
    hybrid, brute = (read_envmap(tmp_path / f"{m}.exr", "latlong").data for m in ("hybrid", "brute"))
    np.testing.assert_allclose(hybrid, brute, rtol=0.02)
    code, said, err = _run(capsys, "error", src, "--method", "hybrid", "--order", "2,8", "--normals", 300, "--json")
    assert code == 0, err
    rows = {(r["method"], r["l_max"]): r for r in json.loads(said)}
    assert set(rows) == {("sh", 2), ("hybrid", 2), ("sh", 8), ("hybrid", 8)}
    for order in (2, 8):
        assert rows["hybrid", order]["relative_mean"] < rows["sh", order]["relative_mean"]
