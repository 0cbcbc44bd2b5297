"""EnvMap: lookups, conversions between every pair of layouts, rotation — on analytic maps and real probes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from conftest import SPECIAL_DIRECTIONS, random_directions, shared
from lightprobe.maps import EnvMap, box_reduce, from_image, read_envmap, resample, to_image
from lightprobe.maps.frames import rotation_from_ypr, rotation_y
from lightprobe.maps.layouts import LAYOUTS, layout

NAMES = list(LAYOUTS)
SIZES = {"latlong": 96, "angular": 128, "sphere": 128, "cube": 48, "cross": 48, "hcross": 48}
SPOT = np.array([0.48, 0.36, -0.8])  # off every axis and seam: a mirror or a quarter turn would move it


def analytic_map(name: str, fn, size: int | None = None) -> EnvMap:
    lay = layout(name)
    grid = lay.grid_shape(size or SIZES[name])
    d = lay.directions(grid)
    return EnvMap(np.where(lay.valid_mask(grid)[..., None], fn(d), 0.0).astype(np.float32), lay)


def spot_map(name: str = "latlong", direction=SPOT, width_deg: float = 6.0, size: int | None = None) -> EnvMap:
    axis = np.asarray(direction) / np.linalg.norm(direction)
    k = 1 / (1 - np.cos(np.radians(width_deg)))
    return analytic_map(name, lambda d: np.exp(k * (d @ axis - 1))[..., None] * [100.0, 50.0, 25.0], size)


def centroid_direction(env: EnvMap) -> np.ndarray:
    w = (env.data[..., 0] * env.solid_angles())[..., None]
    c = (w * env.directions()).reshape(-1, 3).sum(axis=0)
    return c / np.linalg.norm(c)


def angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1, 1))))


# ---- lookups ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_lookup_is_seam_and_pole_correct(name):
    """A smooth map looked up anywhere — poles, seams, cube edges and corners, the disc rims — stays smooth."""
    fn = lambda d: (1.5 + d @ np.array([0.3, 0.5, -0.4]))[..., None] * np.ones(3)  # noqa: E731
    env = analytic_map(name, fn, size=64 if name in ("cube", "cross", "hcross") else 128)
    d = np.concatenate([random_directions(5000, seed=1), SPECIAL_DIRECTIONS])
    got = env.lookup(d)
    # the mirror ball squeezes the directions around its camera axis into its rim: judge it away from there
    keep = (d[:, 2] > -0.9) if name == "sphere" else np.ones(len(d), bool)  # its rim is −Z
    err = np.abs(got - fn(d))[keep].max()
    assert err < (0.02 if name in ("angular", "sphere") else 0.005), err


def test_latlong_lookup_across_the_pole():
    """Interpolating past the top row reaches the ring across the pole, not the clamped edge."""
    env = analytic_map("latlong", lambda d: (d[..., 0:1] + 2) * np.ones(3), size=16)
    near_pole = np.array([[np.sin(0.02), np.cos(0.02), 0.0], [-np.sin(0.02), np.cos(0.02), 0.0]])
    got = env.lookup(near_pole)[:, 0]
    np.testing.assert_allclose(got, near_pole[:, 0] + 2, atol=0.02)


# ---- conversions --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_uniform_map_stays_uniform(name):
    white = analytic_map("latlong", lambda d: np.ones(d.shape))
    out = white.to(name, SIZES[name])
    valid = out.valid_mask()
    np.testing.assert_allclose(out.data[valid], 1.0, rtol=1e-5)
    np.testing.assert_allclose(out.integral(), 4 * np.pi, rtol=1e-4)


@pytest.mark.parametrize("src,dst", list(itertools.product(NAMES, NAMES)))
def test_bright_spot_keeps_its_direction(src, dst):
    """The proof that no conversion mirrors or rotates: a spot off every axis stays where it was."""
    env = spot_map(src)
    assert angle_deg(centroid_direction(env), SPOT / np.linalg.norm(SPOT)) < 0.5
    out = env.to(dst, SIZES[dst])
    assert angle_deg(centroid_direction(out), centroid_direction(env)) < 0.5
    np.testing.assert_allclose(out.integral(), env.integral(), rtol=5e-3)


@pytest.fixture(scope="module")
def real_probes():
    """Real probes of every input kind, reduced once to test-friendly sizes (box_reduce keeps ∫L dω exactly)."""
    probes = {
        "grace angular": box_reduce(read_envmap(shared("debevec/angular/grace_probe.hdr"))),
        "stpeters cross": box_reduce(read_envmap(shared("debevec/cross/stpeters_cross.hdr"))),
        "grace latlong exr": read_envmap(shared("debevec/latlong/grace_latlong.exr")),
        "rooitou park (sun)": box_reduce(read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr"))),
        "studio small 03": box_reduce(read_envmap(shared("polyhaven_1k/studio_small_03_1k.hdr"))),
    }
    return probes


@pytest.mark.parametrize("probe", ["grace angular", "stpeters cross", "grace latlong exr", "rooitou park (sun)",
                                   "studio small 03"])
@pytest.mark.parametrize("dst", NAMES)
def test_real_probe_conversion_conserves_energy(real_probes, probe, dst):
    env = real_probes[probe]
    out = env.to(dst, SIZES[dst])
    np.testing.assert_allclose(out.integral(), env.integral(), rtol=5e-3)


@pytest.mark.parametrize("src,dst", list(itertools.product(NAMES, NAMES)))
def test_every_layout_pair_conserves_energy_on_a_sunny_probe(real_probes, src, dst):
    """Pairs A → B starting from a real probe with a sun (68 % of its energy in 200 pixels)."""
    a = real_probes["rooitou park (sun)"].to(src, SIZES[src])
    b = a.to(dst, SIZES[dst])
    np.testing.assert_allclose(b.integral(), a.integral(), rtol=5e-3)


def test_default_size_keeps_angular_resolution(real_probes):
    env = real_probes["grace latlong exr"]
    for name in NAMES:
        out = env.to(name) if name != "latlong" else env
        ratio = out.valid_mask().sum() / env.valid_mask().sum()
        assert 0.8 < ratio < 1.25, (name, ratio)


def test_box_reduce_is_exact():
    env = spot_map("cube", size=32)
    half = box_reduce(env)
    assert half.grid == (6, 16, 16)
    np.testing.assert_allclose(half.integral(), env.integral(), rtol=1e-6)


# ---- rotation -----------------------------------------------------------------------------------------------------
def test_rotation_moves_the_light_by_r():
    r = rotation_from_ypr(40, -25, 10)
    env = spot_map("latlong")
    turned = env.rotated(r)
    assert angle_deg(centroid_direction(turned), r @ centroid_direction(env)) < 0.5
    np.testing.assert_allclose(turned.integral(), env.integral(), rtol=5e-3)
    back = turned.rotated(r.T)
    assert angle_deg(centroid_direction(back), centroid_direction(env)) < 0.5


def test_a_transposed_rotation_reuses_the_kernels_compiled_for_its_contiguous_twin():
    """R.T is a Fortran-ordered view; numba compiles per array layout, so handing it on as given compiled every
    resampling kernel a second time (minutes on a fresh install) for the same arithmetic."""
    from lightprobe.maps.resampling import fused
    from lightprobe.util.jit import dispatcher

    r = rotation_from_ypr(40, -25, 10)
    env = spot_map("latlong", size=16)
    np.testing.assert_array_equal(env.rotated(r.T).data, env.rotated(np.ascontiguousarray(r.T)).data)
    kernel = dispatcher(fused.resample_into)
    assert kernel.signatures, "the turned conversion did not run the compiled kernel"
    layouts = {arg.layout for sig in kernel.signatures for arg in sig if hasattr(arg, "layout")}
    assert "F" not in layouts and "A" not in layouts, kernel.signatures


def test_yaw_convention():
    """Positive yaw turns the panorama counter-clockwise seen from above: the front (−Z) moves to −X."""
    env = spot_map("latlong", direction=[0, 0, -1])
    turned = env.rotated((90, 0, 0))
    assert angle_deg(centroid_direction(turned), [-1, 0, 0]) < 0.5
    assert np.allclose(rotation_y(90) @ [0, 0, -1], [-1, 0, 0])


def test_rotation_refuses_mirrors():
    with pytest.raises(ValueError):
        spot_map("latlong").rotated(np.diag([1.0, 1.0, -1.0]))


# ---- files and shapes ---------------------------------------------------------------------------------------------
def test_cube_file_is_a_strip_in_face_order():
    env = analytic_map("cube", lambda d: np.abs(d), size=8)
    strip = to_image(env)
    assert strip.shape == (8, 48, 3)
    np.testing.assert_array_equal(from_image(strip).data, env.data)
    assert strip[4, 4, 0] > 0.95 and strip[4, 8 + 4, 0] > 0.95 and strip[4, 40 + 4, 2] > 0.95  # +X, −X, −Z


def test_resample_refuses_absurd_sizes():
    from lightprobe.util.errors import BudgetError

    with pytest.raises(BudgetError, match="limit"):
        resample(spot_map("latlong", size=8), layout("latlong"), 10**6)


@pytest.mark.parametrize("seed", range(5))
def test_bad_pixel_counts_match_their_definition(seed):
    """The counts (a min/max fast path, then a full count) against the definition written out: pixels with any
    NaN, any ±inf, any negative finite channel (a pixel may count in several), on arrays sprinkled with every
    kind, and none on a clean array (where −0.0 is not negative)."""
    from lightprobe.maps import bad_pixel_counts

    rng = np.random.default_rng(seed)
    px = rng.normal(1.0, 1.0, size=(70000 + seed * 3001, 3)).astype(np.float32)
    for value in (np.nan, np.inf, -np.inf, -0.0):
        index = rng.integers(0, px.size, size=rng.integers(0, 300))
        px.reshape(-1)[index] = value
    nan = np.isnan(px).any(axis=1).sum()
    inf = np.isinf(px).any(axis=1).sum()
    negative = ((px < 0) & np.isfinite(px)).any(axis=1).sum()
    assert bad_pixel_counts(px.reshape(-1, 1, 3)) == {"nan": nan, "inf": inf, "negative": negative}
    clean = np.abs(rng.normal(size=(100, 3))).astype(np.float32)
    clean[0, 0] = -0.0
    assert bad_pixel_counts(clean) == {"nan": 0, "inf": 0, "negative": 0}
