"""The point-light baselines (Debevec's median cut, solid-angle weighted): energy kept, regions of equal energy, a
sun found where it is, bad counts refused."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import shared
from lightprobe import read_envmap
from lightprobe.lights.baselines import median_cut, variance_minimisation
from lightprobe.maps import EnvMap
from lightprobe.util.errors import UsageError
from lightprobe.maps.layouts import LATLONG


def test_the_lights_carry_the_whole_map():
    env = read_envmap(shared("debevec/cross/grace_cross.hdr"))
    lights = median_cut(env, 64)
    assert len(lights) == 64
    total = np.sum([light.power for light in lights], axis=0)
    np.testing.assert_allclose(total, env.to(LATLONG, 256).integral(), rtol=1e-12)  # the working map's, exactly
    np.testing.assert_allclose(total, env.integral(), rtol=1e-4)  # the resampling keeps ∫L dω
    assert all(abs(np.linalg.norm(light.direction) - 1) < 1e-12 for light in lights)


def test_regions_of_a_uniform_sky_hold_equal_energy():
    """Each cut halves the luminance power (solid-angle weighted), so a uniform sky's 16 regions hold 1/16 each, to
    the size of one row or column of pixels."""
    env = EnvMap(np.ones((128, 256, 3), np.float32), LATLONG)
    powers = np.array([light.power[0] for light in median_cut(env, 16, rows=128)])
    np.testing.assert_allclose(powers, 4 * np.pi / 16, rtol=0.05)
    assert len(median_cut(env, 1, rows=128)) == 1


def test_the_lights_crowd_onto_a_sun():
    h = 128
    data = np.full((h, 2 * h, 3), 0.05, np.float32)
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = 2 * np.pi * ((np.arange(2 * h) + 0.5) / (2 * h) - 0.5)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], axis=-1)
    sun = np.array([0.4, 0.5, -0.77]) / np.linalg.norm([0.4, 0.5, -0.77])
    inside = dirs @ sun >= np.cos(np.radians(2.0))
    data[inside] = 2000.0
    env = EnvMap(data, LATLONG)
    lights = median_cut(env, 16, rows=128)
    sun_power = float((data[inside, 0] * LATLONG.row_solid_angles((h, 2 * h))[np.nonzero(inside)[0]]).sum())
    near = [light for light in lights if np.degrees(np.arccos(min(1.0, light.direction @ sun))) < 3.0]
    # each cut halves the energy and the sun has 92 % of it: the cuts close in on the sun until its regions are
    # single pixels, which are not cut (so fewer than 16 lights come back)
    assert 4 <= len(near) and len(lights) <= 16
    assert sum(light.power[0] for light in near) >= 0.95 * sun_power


@pytest.mark.parametrize("count", [0, 5000, 2.5, -4, True, "8"])
def test_a_count_that_is_not_a_whole_number_of_lights_is_refused(count):
    with pytest.raises(UsageError, match="whole number of lights from 1 to 4096"):
        median_cut(EnvMap(np.ones((16, 32, 3), np.float32), LATLONG), count)


def _key(light):
    return tuple(np.round(light.direction, 12)) + tuple(np.round(light.power, 9))


def test_any_count_refines_the_last_level_by_energy():
    """12 median-cut lights are the 8 of the third level with the four most energetic regions cut once more: the
    four least energetic of the 8 stand unchanged among the 12, the other four's powers are split between the 8 new
    lights, and the whole map is carried. (A power of two is the paper's own cut, tested above.)"""
    env = read_envmap(shared("debevec/cross/grace_cross.hdr"))
    eight, twelve = median_cut(env, 8), median_cut(env, 12)
    assert len(twelve) == 12
    lum = [float(np.dot(light.power, [0.2126, 0.7152, 0.0722])) for light in eight]
    kept = sorted(range(8), key=lambda i: lum[i])[:4]
    assert {_key(eight[i]) for i in kept} <= {_key(light) for light in twelve}
    np.testing.assert_allclose(np.sum([light.power for light in twelve], axis=0),
                               np.sum([light.power for light in eight], axis=0), rtol=1e-12)
    new = [light for light in twelve if _key(light) not in {_key(eight[i]) for i in kept}]
    assert len(new) == 8
    np.testing.assert_allclose(np.sum([light.power for light in new], axis=0),
                               np.sum([eight[i].power for i in range(8) if i not in kept], axis=0), rtol=1e-12)


def test_variance_minimisation_at_any_count_keeps_the_energy_and_refines():
    """Any count N: N lights carrying the whole map, and each further light lowers the variance it minimises
    (measured independently: energy × squared angle to the nearest light)."""
    env = read_envmap(shared("debevec/cross/grace_cross.hdr"))
    variances = []
    for count in (8, 10, 12, 16):
        lights = variance_minimisation(env, count)
        assert len(lights) == count
        np.testing.assert_allclose(np.sum([light.power for light in lights], axis=0),
                                   env.to(LATLONG, 256).integral(), rtol=1e-12)
        variances.append(_regions_variance(env, lights))
    assert variances == sorted(variances, reverse=True) and variances[-1] < variances[0]


def _regions_variance(env, lights):
    """Σ over pixels of e·angle² to the light standing for them (the nearest), for comparing the two baselines."""
    work = env.to(LATLONG, 64)
    e = np.maximum(work.data[..., 0].astype(np.float64), 0) * LATLONG.row_solid_angles(work.grid)[:, None]
    dirs = work.directions().reshape(-1, 3)
    light_dirs = np.array([light.direction for light in lights])
    angle = np.arccos(np.clip(dirs @ light_dirs.T, -1, 1)).min(axis=1)
    return float((e.ravel() * angle ** 2).sum())


def test_variance_minimisation_keeps_the_energy_and_beats_median_cut_on_variance():
    env = read_envmap(shared("debevec/cross/grace_cross.hdr"))
    vm = variance_minimisation(env, 16)
    assert len(vm) == 16
    np.testing.assert_allclose(np.sum([light.power for light in vm], axis=0), env.to(LATLONG, 256).integral(),
                               rtol=1e-12)
    # what it minimises, measured independently: energy × squared angle from each pixel to its nearest light
    assert _regions_variance(env, vm) < 0.9 * _regions_variance(env, median_cut(env, 16))


def test_variance_minimisation_puts_a_light_on_a_small_sun():
    h = 128
    data = np.full((h, 2 * h, 3), 0.05, np.float32)
    env0 = EnvMap(data, LATLONG)
    dirs = env0.directions()
    sun = np.array([-0.6, 0.3, 0.5]) / np.linalg.norm([-0.6, 0.3, 0.5])
    inside = dirs @ sun >= np.cos(np.radians(3.0))
    data[inside] = 500.0
    env = EnvMap(data, LATLONG)
    lights = variance_minimisation(env, 8, rows=128)
    sun_power = env.integral()[0] - 0.05 * (4 * np.pi - float(env.solid_angles()[inside].sum()))
    near = [light for light in lights if np.degrees(np.arccos(min(1.0, light.direction @ sun))) < 3.0]
    assert near and sum(light.power[0] for light in near) >= 0.9 * sun_power
    # a uniform sky: each region's variance is what it is, every region still split, energy kept
    uniform = variance_minimisation(EnvMap(np.ones((64, 128, 3), np.float32), LATLONG), 16, rows=64)
    assert len(uniform) == 16
    np.testing.assert_allclose(sum(light.power[0] for light in uniform), 4 * np.pi, rtol=1e-3)


def test_variance_minimisation_of_a_black_map_is_one_dark_light():
    lights = variance_minimisation(EnvMap(np.zeros((32, 64, 3), np.float32), LATLONG), 8, rows=32)
    assert len(lights) == 1 and not lights[0].power.any()
