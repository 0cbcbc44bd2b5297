"""Irradiance: eq. 12/13 against the general formula, brute force against analytic cases, the paper's error claim."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import random_directions, shared
from lightprobe.maps import EnvMap, box_reduce, read_envmap
from lightprobe.sh.irradiance import brute_irradiance, error_report, irradiance_map, irradiance_matrices, irradiance_polynomial, irradiance_quadratic, reference_normals
from lightprobe.maps.layouts import LATLONG
from lightprobe.sh.basis import SHCoeffs, project


def test_matrix_and_polynomial_forms_equal_the_general_formula():
    sh = SHCoeffs(np.random.default_rng(4).normal(size=(16, 3)))  # bands above 2 must be ignored by both forms
    n = random_directions(1000)
    general = sh.truncated(2).to_irradiance().evaluate(n)
    np.testing.assert_allclose(irradiance_quadratic(irradiance_matrices(sh), n), general, atol=1e-13)
    np.testing.assert_allclose(irradiance_polynomial(sh, n), general, atol=1e-13)
    m = irradiance_matrices(sh)
    assert np.allclose(m, np.transpose(m, (0, 2, 1)))  # symmetric, as eq. 12


def test_brute_force_white_furnace_and_half_sky():
    grid = LATLONG.grid_shape(64)
    d = LATLONG.directions(grid)
    white = EnvMap(np.ones(grid + (3,)), LATLONG)
    n = random_directions(200)
    np.testing.assert_allclose(brute_irradiance(white, n), np.pi, rtol=1e-3)
    sky = EnvMap(np.where(d[..., 1:2] > 0, 1.0, 0.0) * np.ones(3), LATLONG)  # uniform upper hemisphere
    cos_t = n[:, 1]
    expected = np.pi * (1 + cos_t) / 2  # irradiance of a uniform hemisphere of radiance 1, tilted normal
    np.testing.assert_allclose(brute_irradiance(sky, n)[:, 0], expected, atol=2e-2)


def test_brute_force_equals_sh_for_band_limited_light():
    """Light that has no energy above band 2 has SH9 irradiance equal to the truth (cosine kills nothing)."""
    rng = np.random.default_rng(8)
    truth = rng.normal(size=(9, 3)) * 0.3
    truth[0] = 4.0
    grid = LATLONG.grid_shape(128)
    env = EnvMap(SHCoeffs(truth).evaluate(LATLONG.directions(grid)), LATLONG)
    n = random_directions(100)
    np.testing.assert_allclose(brute_irradiance(env, n), SHCoeffs(truth).to_irradiance().evaluate(n), rtol=2e-3)


@pytest.fixture(scope="module")
def grace():
    return box_reduce(read_envmap(shared("debevec/angular/grace_probe.hdr")))


DEBEVEC = ["angular/beach_probe.hdr", "angular/building_probe.hdr", "angular/campus_probe.hdr",
           "angular/galileo_probe.hdr", "angular/grace_probe.hdr", "angular/kitchen_probe.hdr",
           "angular/rnl_probe.hdr", "angular/uffizi0_probe.hdr", "cross/stpeters_cross.hdr"]


@pytest.mark.parametrize("probe", DEBEVEC)
def test_paper_error_claim_on_every_debevec_probe(probe):
    """Order 2: mean under 1 %, max under 5 % of total intensity (the paper's claim), while the per-normal relative
    error — what a person sees on the dark side — is several times larger (docs/spec.md §3: 2–7 % mean, 25–80 % max)."""
    env = box_reduce(read_envmap(shared(f"debevec/{probe}")))
    normals = reference_normals(800)
    r = error_report(env, 2, normals=normals)
    assert r.paper_mean < 0.01 and r.paper_max < 0.05
    expected = independent_errors(box_reduce(env), normals)  # a quarter of the pixels keeps it quick
    ours = error_report(box_reduce(env), 2, normals=normals)
    for got, want in zip((ours.paper_mean, ours.paper_max, ours.relative_mean, ours.relative_max), expected):
        # 1e-5: two float32-fed sums of the same error; at 1e-6 the beach probe's paper mean (1.3e-2) fell 1.5e-6 off
        # on this machine at 7158b7a as at its successor (the last bits depend on the machine's BLAS and kernels)
        assert got == pytest.approx(want, rel=1e-5)
    assert ours.relative_mean > 2 * ours.paper_mean  # the dark side: per-normal error well above the paper's


def independent_errors(env, normals):
    """docs/spec.md §3's four error figures of order-2 SH, computed here without lightprobe's SH or kernels: the nine
    basis polynomials written out, Â_l = π, 2π/3, π/4, brute force as one numpy sum over all pixels, Rec. 709
    luminance. Only the pixel directions and solid angles come from lightprobe (tested on their own)."""
    d = env.directions().reshape(-1, 3)
    weighted = env.data.reshape(-1, 3).astype(np.float64) * env.solid_angles().reshape(-1, 1)
    lum = np.array([0.2126, 0.7152, 0.0722])

    def polynomials(v):  # Y_lm for l ≤ 2, no Condon–Shortley phase, exact constants
        x, y, z = v[:, 0], v[:, 1], v[:, 2]
        k0, k1, k2 = 0.5 / np.sqrt(np.pi), 0.5 * np.sqrt(3 / np.pi), 0.5 * np.sqrt(15 / np.pi)
        return np.stack([k0 + 0 * x, k1 * y, k1 * z, k1 * x, k2 * x * y, k2 * y * z,
                         0.25 * np.sqrt(5 / np.pi) * (3 * z * z - 1), k2 * x * z, k2 / 2 * (x * x - y * y)], axis=1)

    coeffs = polynomials(d).T @ weighted  # (9, 3) L_lm
    a_hat = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)
    e_sh = (polynomials(normals) * a_hat) @ coeffs @ lum
    e_ref = np.concatenate([np.maximum(chunk @ d.T, 0) @ weighted for chunk in np.array_split(normals, 8)]) @ lum
    total = weighted.sum(axis=0) @ lum
    diff = np.abs(e_sh - e_ref)
    rel = diff / np.maximum(e_ref, 1e-12 * total)
    return diff.mean() / total, diff.max() / total, rel.mean(), rel.max()


def test_error_falls_with_order_and_windows_cost_accuracy(grace):
    normals = reference_normals(600)
    ref = brute_irradiance(grace, normals)
    sh = project(grace, 6)
    errs = [error_report(grace, l, normals=normals, reference=ref, sh=sh).paper_mean for l in (2, 4, 6)]
    assert errs[0] > errs[1] > errs[2]
    plain = error_report(grace, 2, "none", normals, ref, sh)
    hann = error_report(grace, 2, "hanning", normals, ref, sh)
    assert hann.paper_mean > plain.paper_mean


def test_irradiance_map_sh_against_brute(grace):
    sh_map = irradiance_map(grace, "latlong", 16, "sh", 6)
    brute = irradiance_map(grace, "latlong", 16, "brute")
    rel = np.abs(sh_map.data - brute.data).mean() / brute.data.mean()
    assert rel < 0.02
