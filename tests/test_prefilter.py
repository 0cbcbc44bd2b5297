"""GGX-prefiltered mip chains (lightprobe.glossy.prefilter): analytic cases and brute-force integration over every texel."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import shared
from lightprobe.maps import EnvMap, read_envmap, resample
from lightprobe.util.errors import UsageError
from lightprobe.maps.frames import BABYLON
from lightprobe.maps.layouts import CUBE, LATLONG
from lightprobe.glossy.prefilter import (babylon_alphas, brute_force_prefiltered, ggx_d, lobe_integral, prefilter_cube,
                                         split_peaks)



def test_babylon_roughness_per_mip_inverts_its_shader_lod():
    """Babylon's shader picks lod = log2(size α) · scale (+ offset 0): each mip's α must give back its index."""
    for scale in (0.8, 1.0):
        alphas = babylon_alphas(256, scale)
        assert len(alphas) == 9 and alphas[0] == 0
        assert np.allclose([np.log2(256 * a) * scale for a in alphas[1:]], range(1, 9))


def test_ggx_distribution_is_normalised():
    """∫ D(h) (n·h) dω_h = 1 for any α (quadrature in cos θ)."""
    x, w = np.polynomial.legendre.leggauss(400)
    mu = 0.5 * (x + 1)  # cos θ_h on [0, 1]
    for alpha in (0.05, 0.3, 1.0, 2.5):
        assert 2 * np.pi * 0.5 * float((ggx_d(mu, alpha) * mu) @ w) == pytest.approx(1, rel=2e-3 if alpha < .1 else 1e-6)


def test_lobe_integral_tends_to_four_for_a_narrow_lobe_and_matches_a_sum_over_the_sphere():
    # n = v = r: dω_l = 4 (v·h) dω_h, so a narrow lobe gives W → 4 ∫ D (n·h) dω_h = 4
    assert lobe_integral(1e-3) == pytest.approx(4, rel=1e-4)
    env = EnvMap(np.ones((1024, 2048, 3), np.float32), LATLONG)
    d, omega = env.directions().reshape(-1, 3), env.solid_angles().reshape(-1)
    r = np.array([0.0, 1.0, 0.0])  # the lobe around the pole, where lat-long pixels are finest
    for alpha in (0.3, 1.0):
        cos_l = d @ r
        brute = float((ggx_d(np.sqrt(np.clip((1 + cos_l) / 2, 0, 1)), alpha) * np.maximum(cos_l, 0) * omega).sum())
        assert lobe_integral(alpha) == pytest.approx(brute, rel=1e-3)


def test_a_uniform_map_stays_exactly_uniform_at_every_level():
    env = EnvMap(np.full((32, 64, 3), 0.7, np.float32), LATLONG)
    chain = prefilter_cube(env, 32)
    assert [level.shape for level in chain.levels] == [(6, 32 >> i, 32 >> i, 3) for i in range(6)]
    for level in chain.levels:
        assert np.allclose(level, 0.7, rtol=1e-5)


def test_a_single_bright_texel_gives_the_ggx_lobe_exactly():
    """One non-zero texel of power Φ at l: every level must equal Φ D(h)(r·l)⁺ / W(α) (the peak path is exact)."""
    data = np.zeros((6, 16, 16, 3), np.float32)
    data[4, 5, 9] = [200.0, 100.0, 50.0]
    cube = EnvMap(data, CUBE)
    chain = prefilter_cube(cube, 16)
    l_dir = cube.directions()[4, 5, 9]
    power = data[4, 5, 9] * cube.solid_angles()[4, 5, 9]
    for i, alpha in enumerate(chain.alphas[1:], start=1):
        r = CUBE.directions(CUBE.grid_shape(16 >> i)).reshape(-1, 3)
        cos_l = r @ l_dir
        expected = (ggx_d(np.sqrt((1 + cos_l) / 2), alpha) * np.maximum(cos_l, 0))[:, None] * power / lobe_integral(alpha)
        assert np.allclose(chain.levels[i].reshape(-1, 3), expected, rtol=1e-4, atol=1e-7 * expected.max()), i


def test_a_bright_texel_split_into_a_near_sum_and_far_harmonics_gives_the_lobe(monkeypatch):
    """The same texel with every level taking the split path of the big chains (the peak's lobe summed within
    2·NEAR_WIDTH·α, the smooth rest through the harmonics): the lobe to 0.5 % of its peak, no texel negative beyond
    that (no ringing)."""
    import lightprobe.glossy.prefilter as prefilter

    monkeypatch.setattr(prefilter, "PEAK_PAIRS", 0)
    data = np.zeros((6, 32, 32, 3), np.float32)
    data[4, 11, 19] = [200.0, 100.0, 50.0]
    cube = EnvMap(data, CUBE)
    chain = prefilter_cube(cube, 32, [0.0, 0.02, 0.05, 0.08, 0.1, 0.3])
    l_dir = cube.directions()[4, 11, 19]
    power = data[4, 11, 19] * cube.solid_angles()[4, 11, 19]
    for i, alpha in enumerate(chain.alphas[1:], start=1):
        r = CUBE.directions(CUBE.grid_shape(32 >> i)).reshape(-1, 3)
        cos_l = r @ l_dir
        expected = (ggx_d(np.sqrt((1 + cos_l) / 2), alpha) * np.maximum(cos_l, 0))[:, None] * power / lobe_integral(alpha)
        assert np.abs(chain.levels[i].reshape(-1, 3) - expected).max() < 5e-3 * expected.max(), i


def test_split_peaks_keeps_the_power():
    env = read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr"))
    cube = resample(env, CUBE, 32)
    clipped, directions, power = split_peaks(cube, 100)
    assert len(directions) <= 100 + 6
    assert np.allclose(clipped.integral() + power.sum(axis=0), cube.integral(), rtol=1e-5)


@pytest.mark.parametrize("probe", ["polyhaven_1k/rooitou_park_1k.hdr", "polyhaven_1k/st_fagans_interior_1k.hdr"])
def test_chain_agrees_with_brute_force_integration_over_every_texel(probe):
    """Each level against the direct sum over every pixel of the probe itself (P_α's definition): within 1 % in the
    median texel and 5 % in the worst. The chain also keeps ∫P dω = ∫L dω to 1 % (the normalised kernel is
    symmetric) on the levels of 4 texels a face or more; a 2×2 face's 24 texels are too coarse a quadrature for that."""
    env = read_envmap(shared(probe))
    _agrees_with_brute_force(env, prefilter_cube(env, 32, frame=BABYLON), 60)


def _agrees_with_brute_force(env, chain, texels, tolerance=(0.01, 0.05)):
    rng = np.random.default_rng(3)
    luminance = np.array([0.2126, 0.7152, 0.0722])
    for i, alpha in enumerate(chain.alphas[1:], start=1):
        s = chain.levels[i].shape[1]
        d = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
        pick = rng.choice(len(d), min(texels, len(d)), replace=False)
        got = chain.levels[i].reshape(-1, 3)[pick] @ luminance
        ref = brute_force_prefiltered(env, chain.frame.to_world(d[pick]), alpha) @ luminance
        error = np.abs(got - ref) / ref
        assert np.median(error) < tolerance[0] and error.max() < tolerance[1], (i, alpha, np.median(error), error.max())
        if s >= 4:
            integral = EnvMap(chain.levels[i], CUBE).integral() @ luminance
            assert integral == pytest.approx(env.integral() @ luminance, rel=0.01), i


def _sky_with_sun(direction, rows=256):
    """A lat-long sky (a smooth gradient, brighter up) with a sun of 0.5° across and 10⁵ times the sky's radiance."""
    env = EnvMap(np.zeros((rows, 2 * rows, 3), np.float32), LATLONG)
    d = env.directions()
    sky = 0.3 + 0.2 * d[..., 1:2] + 0.05 * d[..., 0:1] * np.array([1.0, 0.5, 0.2])
    sun = np.asarray(direction, float) / np.linalg.norm(direction)
    # each pixel near the sun gets the fraction of it the 0.5° disc covers (8×8 subsamples)
    inside = np.arccos(np.clip(d @ sun, -1, 1)) < np.radians(0.25) + 2 * np.pi / rows
    data = sky.astype(np.float32)
    rows_i, cols_i = np.nonzero(inside)
    for row, col in zip(rows_i, cols_i):
        sub = (np.arange(8) + 0.5) / 8
        v, u = np.meshgrid((row + sub) / rows, (col + sub) / (2 * rows), indexing="ij")
        dirs = LATLONG.uv_to_dir(0, u, v)
        covered = float(np.mean(np.arccos(np.clip(dirs @ sun, -1, 1)) < np.radians(0.25)))
        data[row, col] += 1e5 * 0.3 * covered
    return EnvMap(data, LATLONG)


@pytest.mark.parametrize("where, sun", [("next to a cube edge", (1.0, 0.2, 1.01)), ("at the pole", (0.0, 1.0, 0.0)),
                                        ("near the pole", (0.01, 1.0, 0.004))])
def test_a_half_degree_sun_agrees_with_brute_force(where, sun):
    """A sun of 0.5° on a smooth sky, at a cube edge (where the chain's texels are densest) and at the lat-long's pole
    (where its pixels are smallest): every level against brute force over every pixel, as for the probes."""
    env = _sky_with_sun(sun)
    _agrees_with_brute_force(env, prefilter_cube(env, 32), 80)


def test_frame_turns_the_chain():
    """Level 0 in Babylon's frame at direction d is the world map at (x, y, −z) of d."""
    env = read_envmap(shared("polyhaven_1k/venice_sunset_1k.hdr"))
    ours = prefilter_cube(env, 16, frame=BABYLON).levels[2]
    world = prefilter_cube(env, 16).levels[2]
    d = CUBE.directions(CUBE.grid_shape(4)).reshape(-1, 3)
    mirrored = CUBE.sample(world, BABYLON.to_world(d))
    assert np.allclose(ours.reshape(-1, 3), mirrored, rtol=0.05)


@pytest.mark.parametrize("size", [0, 3, 48, 2048])
def test_bad_sizes_are_refused(size):
    env = EnvMap(np.ones((8, 16, 3), np.float32), LATLONG)
    with pytest.raises(UsageError):
        prefilter_cube(env, size)


def test_wrong_number_of_roughness_values_is_refused():
    env = EnvMap(np.ones((8, 16, 3), np.float32), LATLONG)
    with pytest.raises(UsageError):
        prefilter_cube(env, 8, [0.0, 0.1])
    with pytest.raises(UsageError):
        prefilter_cube(env, 2, [0.0, float("nan")])
