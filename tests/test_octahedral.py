"""The octahedral layouts: Godot's plain map and pbrt-v4's equal-area map, against the engines' own formulas
(restated here from their sources), their exact solid angles against brute-force integration, and resampling into
and out of them with the guarantees the other layouts have."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import SPECIAL_DIRECTIONS, random_directions
from lightprobe.cli import main
from lightprobe.maps import EnvMap, Resampler, read_envmap
from lightprobe.maps.layouts import LATLONG, LAYOUTS, OCTAHEDRAL, OCTAHEDRAL_EA, layout
from lightprobe.maps.octahedral_layouts import PBRT_FROM_WORLD, folded
from lightprobe.maps.resampling import fused
from lightprobe.util.names import LAYOUTS as LAYOUT_NAMES

OCTAHEDRALS = [OCTAHEDRAL, OCTAHEDRAL_EA]
IDS = ["octahedral", "octahedral-ea"]
FORMULA_TOL = 1e-12  # the engines' formulas and ours: the same arithmetic up to rounding
SOLID_ANGLE_SUM_RTOL = 1e-13  # Σ Ω = 4π to float64 rounding of N² terms
BRUTE_FORCE_RTOL = 2e-5  # a pixel's exact Ω against 160 × 160 midpoints of the density (the folds kink it: O(h²))
JACOBIAN_RTOL = 1e-6  # the density against central differences of uv_to_dir (step 1e-5)
ENERGY_RTOL = 2e-3  # docs/resampling.md's bar: a one-pixel sun keeps ∫L dω within 0.2 %
FLUX_RTOL = 1e-5  # flux-corrected conversions: exact to float rounding (tests/test_flux.py holds the same)


# ---- the engines' formulas, restated from their sources -------------------------------------------------------------

def godot_vec3_to_oct(n: np.ndarray) -> np.ndarray:
    """Godot's ``vec3_to_oct`` (servers/rendering/renderer_rd/shaders/oct_inc.glsl): the texture coordinate of a
    world direction (Godot's world frame is +Y up, −Z forward, as lightprobe's)."""
    n = n / np.abs(n).sum(axis=-1, keepdims=True)
    x, y = n[..., 0], n[..., 1]
    wrap_x = (1 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0)
    wrap_y = (1 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0)
    lower = n[..., 2] < 0
    return np.stack([np.where(lower, wrap_x, x), np.where(lower, wrap_y, y)], axis=-1) * 0.5 + 0.5


def pbrt_equal_area_square_to_sphere(p: np.ndarray) -> np.ndarray:
    """pbrt-v4's ``EqualAreaSquareToSphere`` (src/pbrt/util/math.cpp): a point of [0, 1]² → a direction in pbrt's
    light frame (+Z up)."""
    u, v = 2 * p[..., 0] - 1, 2 * p[..., 1] - 1
    up, vp = np.abs(u), np.abs(v)
    signed_distance = 1 - (up + vp)
    r = 1 - np.abs(signed_distance)
    phi = np.where(r == 0, 1.0, (vp - up) / np.where(r == 0, 1.0, r) + 1) * np.pi / 4
    z = np.copysign(1 - r * r, signed_distance)
    ring = r * np.sqrt(np.maximum(2 - r * r, 0.0))
    return np.stack([np.copysign(np.cos(phi), u) * ring, np.copysign(np.sin(phi), v) * ring, z], axis=-1)


def engine_texel(lay, d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) where the engine reads direction d (world frame) in an N × N map of ``lay``: Godot's
    ``vec3_to_oct``, or pbrt's square point found by inverting ``EqualAreaSquareToSphere`` on a fine grid."""
    if lay is OCTAHEDRAL:
        uv = godot_vec3_to_oct(d)
    else:
        m = 1024
        centres = (np.arange(m) + 0.5) / m
        grid = np.stack(np.meshgrid(centres, centres, indexing="xy"), axis=-1).reshape(-1, 2)
        dirs = pbrt_equal_area_square_to_sphere(grid) @ PBRT_FROM_WORLD  # pbrt's frame → world: the transpose
        uv = grid[np.argmax(d @ dirs.T, axis=1)]  # the nearest of 1024² points: well inside its N × N texel
    return np.floor(uv[..., 1] * n).astype(int), np.floor(uv[..., 0] * n).astype(int)


# ---- orientation --------------------------------------------------------------------------------------------------

def test_the_octahedral_map_is_godots_vec3_to_oct():
    """Every direction lands where Godot's shader reads it; the anchors: centre +Z, the bottom edge's middle +Y
    (texture row 0 is the top), the right edge's middle +X, the corners −Z."""
    d = np.concatenate([random_directions(5000, seed=4), SPECIAL_DIRECTIONS])
    _, u, v = OCTAHEDRAL.dir_to_uv(d)
    np.testing.assert_allclose(np.stack([u, v], -1), godot_vec3_to_oct(d), atol=FORMULA_TOL)
    anchors = {(0.5, 0.5): (0, 0, 1), (0.5, 1.0): (0, 1, 0), (0.5, 0.0): (0, -1, 0), (1.0, 0.5): (1, 0, 0),
               (0.0, 0.5): (-1, 0, 0), (0.0, 0.0): (0, 0, -1), (1.0, 1.0): (0, 0, -1)}
    for (u, v), want in anchors.items():
        np.testing.assert_allclose(OCTAHEDRAL.uv_to_dir(0, np.array(u), np.array(v)), want, atol=FORMULA_TOL)


def test_the_equal_area_map_is_pbrts_in_pbrts_frame():
    """uv_to_dir is pbrt's EqualAreaSquareToSphere turned from pbrt's frame, (x, y, z)_pbrt = (z, −x, y)_world; in
    that frame pbrt's lat-long convention (imgtool makeequiarea: u = φ/2π, φ = atan2(y, x), v = θ/π from +Z) puts
    every direction where lightprobe's lat-long has it. Centre: +Y (up)."""
    rng = np.random.default_rng(5)
    p = rng.random((5000, 2))
    world = OCTAHEDRAL_EA.uv_to_dir(0, p[:, 0], p[:, 1])
    np.testing.assert_allclose(world @ PBRT_FROM_WORLD.T, pbrt_equal_area_square_to_sphere(p), atol=FORMULA_TOL)
    _, u, v = OCTAHEDRAL_EA.dir_to_uv(world)
    np.testing.assert_allclose(np.stack([u, v], -1), p, atol=1e-9)
    local = world @ PBRT_FROM_WORLD.T
    pbrt_u = np.mod(np.arctan2(local[:, 1], local[:, 0]), 2 * np.pi) / (2 * np.pi)
    pbrt_v = np.arccos(np.clip(local[:, 2], -1, 1)) / np.pi
    _, lp_u, lp_v = LATLONG.dir_to_uv(world)
    np.testing.assert_allclose(np.abs(np.mod(pbrt_u - lp_u + 0.5, 1.0) - 0.5), 0, atol=1e-9)
    np.testing.assert_allclose(pbrt_v, lp_v, atol=1e-9)
    np.testing.assert_allclose(OCTAHEDRAL_EA.uv_to_dir(0, np.array(0.5), np.array(0.5)), (0, 1, 0), atol=1e-15)


@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
def test_past_the_edges_the_map_folds_as_the_engines_wrap(lay):
    """Past an edge the square continues mirrored (Godot's oct_to_vec3_with_border, pbrt's WrapEqualAreaSquare):
    a point ε past the right edge is the point ε inside it, upside down; past a corner, the point as far inside the
    opposite corner (every corner is one direction)."""
    u, v = np.array([1.03, -0.02, 0.4, 0.7, 1.01]), np.array([0.3, 0.8, -0.05, 1.06, 1.02])
    fu, fv = folded(u, v)
    np.testing.assert_allclose(fu, [0.97, 0.02, 0.6, 0.3, 0.01])  # past a corner: the opposite corner
    np.testing.assert_allclose(fv, [0.7, 0.2, 0.05, 0.94, 0.02])
    np.testing.assert_allclose(lay.uv_to_dir(0, u, v), lay.uv_to_dir(0, fu, fv), atol=FORMULA_TOL)
    edge = np.linspace(0.01, 0.99, 50)  # the edge is one seam: its two halves are the same directions
    np.testing.assert_allclose(lay.uv_to_dir(0, np.ones(50), edge), lay.uv_to_dir(0, np.ones(50), 1 - edge),
                               atol=1e-12)


def _sun_map(directions, h: int = 64) -> EnvMap:
    """A lat-long sky of 0.05 with a one-pixel sun of 10× its power at each of ``directions``."""
    data = np.full((h, 2 * h, 3), 0.05, np.float32)
    for d in directions:
        _, x, y = LATLONG.pixel_coords(np.asarray(d, float) / np.linalg.norm(d), (h, 2 * h))
        row, col = int(np.clip(np.rint(y), 0, h - 1)), int(np.rint(x)) % (2 * h)
        data[row, col] += 10 * 0.05 * 4 * np.pi / LATLONG.row_solid_angles((h, 2 * h))[row]
    return EnvMap(data, LATLONG)


# Three lat-long 64 pixel centres in three octants, off every axis, fold and diagonal, each within 0.2 texels of a
# texel centre of both 32 × 32 octahedral maps (so the engine's texel is not a tie): the suns are exactly there.
SUNS = LATLONG.directions((64, 128))[[11, 24, 45], [77, 114, 46]]


def _suns_where_the_engine_reads(image: np.ndarray, lay, n: int) -> bool:
    """Whether each sun is the brightest texel of its 3 × 3 neighbourhood at the texel the engine reads it from."""
    rows, cols = engine_texel(lay, SUNS, n)
    for r, c in zip(rows, cols):
        block = image[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2, 1]
        if not (image[r, c, 1] >= block.max() and image[r, c, 1] > 10 * 0.05):
            return False
    return True


@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
def test_suns_land_at_the_texel_the_engine_reads_and_a_mirror_or_a_turn_fails(lay):
    """A lat-long with three one-pixel suns, converted: each sun is at the texel Godot's (pbrt's) formula reads
    its direction from. The same map mirrored either way, transposed or turned a quarter fails that check."""
    n = 32
    _, x, y = lay.pixel_coords(SUNS, (n, n))
    assert (np.abs(np.stack([x, y]) - np.rint(np.stack([x, y]))) < 0.2).all()  # each well inside its texel: no tie
    image = _sun_map(SUNS).to(lay, n).data
    assert _suns_where_the_engine_reads(image, lay, n)
    for wrong in (image[:, ::-1], image[::-1], image.transpose(1, 0, 2), np.rot90(image), np.rot90(image, 2)):
        assert not _suns_where_the_engine_reads(np.ascontiguousarray(wrong), lay, n)


# ---- exact solid angles -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
@pytest.mark.parametrize("n", [1, 2, 3, 8, 9, 33, 128])
def test_solid_angles_sum_to_four_pi(lay, n):
    omega = lay.solid_angles((n, n))
    assert omega.shape == (n, n) and (omega > 0).all()
    assert omega.sum() == pytest.approx(4 * np.pi, rel=SOLID_ANGLE_SUM_RTOL)


@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
@pytest.mark.parametrize("n", [6, 7])
def test_each_pixels_solid_angle_is_its_brute_force_integral(lay, n):
    """Each pixel's Ω against 160 × 160 midpoints of dω/(du dv) over it (odd N: the middle row and column straddle
    the axes, cut there too); and that density against the area of uv_to_dir's own Jacobian, so neither the density
    nor the table is taken on trust."""
    m = 160
    sub = (np.arange(n)[:, None] + (np.arange(m) + 0.5)[None, :] / m).ravel() / n
    u, v = np.meshgrid(sub, sub, indexing="xy")
    brute = lay.uv_density(0, u, v).reshape(n, m, n, m).mean(axis=(1, 3)) / n**2
    np.testing.assert_allclose(lay.solid_angles((n, n)), brute, rtol=BRUTE_FORCE_RTOL)
    rng = np.random.default_rng(n)
    pu, pv, h = rng.uniform(0.01, 0.99, 400), rng.uniform(0.01, 0.99, 400), 1e-5
    du = (lay.uv_to_dir(0, pu + h, pv) - lay.uv_to_dir(0, pu - h, pv)) / (2 * h)
    dv = (lay.uv_to_dir(0, pu, pv + h) - lay.uv_to_dir(0, pu, pv - h)) / (2 * h)
    kink = np.minimum(np.abs(np.abs(2 * pu - 1) + np.abs(2 * pv - 1) - 1), np.minimum(np.abs(2 * pu - 1),
                                                                                     np.abs(2 * pv - 1))) < 1e-4
    jacobian = np.linalg.norm(np.cross(du, dv), axis=-1)
    np.testing.assert_allclose(jacobian[~kink], lay.uv_density(0, pu, pv)[~kink], rtol=JACOBIAN_RTOL)


def test_the_equal_area_map_gives_every_pixel_the_same_solid_angle():
    omega = OCTAHEDRAL_EA.solid_angles((16, 16))
    assert (omega == 4 * np.pi / 256).all()
    np.testing.assert_array_equal(OCTAHEDRAL_EA.solid_angles_of((16, 16), np.array([0, 17, 255])), 4 * np.pi / 256)


def test_the_plain_maps_pixels_follow_its_eightfold_symmetry():
    """Mirrors in s and t and the swap of s and t are symmetries of the octahedron: the table has them; its centre
    pixels (a face's middle) are the largest, 3^1.5 ≈ 5.2 times the density at the vertices."""
    omega = OCTAHEDRAL.solid_angles((40, 40))
    np.testing.assert_allclose(omega, omega[::-1], rtol=1e-12)
    np.testing.assert_allclose(omega, omega[:, ::-1], rtol=1e-12)
    np.testing.assert_allclose(omega, omega.T, rtol=1e-12)
    assert 4.5 < omega.max() / omega.min() < 5.2


# ---- registry and the command line --------------------------------------------------------------------------------

def test_the_layouts_are_registered_by_name():
    assert LAYOUT_NAMES[-2:] == ("octahedral", "octahedral-ea")
    assert layout("octahedral") is OCTAHEDRAL and layout("octahedral-ea") is OCTAHEDRAL_EA
    assert LAYOUTS["octahedral"].grid_shape(64) == (64, 64) and fused.CODES["octahedral-ea"] == fused.OCTAHEDRAL_EA


def test_convert_writes_and_info_reads_an_equal_area_map(tmp_path, capsys):
    src = tmp_path / "sky.exr"
    _sun_map(SUNS, 32).save(src)
    out = tmp_path / "ea.exr"
    assert main(["convert", str(src), str(out), "--to", "octahedral-ea", "--size", "24"]) == 0
    capsys.readouterr()
    assert main(["info", str(out), "--layout", "octahedral-ea", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["layout"] == "octahedral-ea" and (report["width"], report["height"]) == (24, 24)
    back = read_envmap(out, "octahedral-ea")
    np.testing.assert_allclose(back.integral(), read_envmap(src).integral(), rtol=ENERGY_RTOL)


# ---- resampling ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
def test_a_uniform_map_stays_exactly_uniform_into_and_out_of_them(lay):
    flat = EnvMap(np.full((32, 64, 3), 2.5, np.float32), LATLONG)
    into = flat.to(lay, 24)
    np.testing.assert_array_equal(into.data, np.float32(2.5))
    for target in ("cube", "latlong", "octahedral", "octahedral-ea"):
        np.testing.assert_allclose(into.to(target, 12).data[layout(target).valid_mask(layout(target).grid_shape(12))],
                                   2.5, rtol=1e-6)


@pytest.mark.parametrize("source, size, target, out_size, bound", [
    ("latlong", 64, "octahedral", 32, ENERGY_RTOL), ("latlong", 128, "octahedral", 96, ENERGY_RTOL),
    ("latlong", 64, "octahedral-ea", 48, FLUX_RTOL),
    ("cube", 16, "octahedral", 24, FLUX_RTOL), ("octahedral", 32, "latlong", 24, FLUX_RTOL),
    ("octahedral-ea", 32, "cube", 12, FLUX_RTOL), ("octahedral", 24, "octahedral-ea", 24, FLUX_RTOL),
    ("octahedral-ea", 24, "sphere", 24, FLUX_RTOL),
])
def test_a_sun_in_any_pixel_keeps_its_energy(source, size, target, out_size, bound):
    """Resampler.energy_gains: the energy a one-pixel sun in every source pixel comes out with (docs/resampling.md).
    From a lat-long into Godot's map, within the 0.2 % bar by the rates alone; into pbrt's equal-area map (whose
    axes fold through its poles) and from either map (or a cube), flux-corrected: exact to float rounding."""
    src = layout(source)
    gains = Resampler(src, src.grid_shape(size), layout(target), out_size).energy_gains()
    assert np.isfinite(gains).all() and np.abs(gains).max() < bound, f"{100 * np.abs(gains).max():.4f} %"


@pytest.mark.parametrize("lay", OCTAHEDRALS, ids=IDS)
def test_the_kernel_formulas_are_the_layouts_pairs(lay):
    """The compiled kernel's per-point formulas give uv_to_dir, uv_density and pixel_coords."""
    kind, n = fused.CODES[lay.name], 40
    rng = np.random.default_rng(3)
    u, v = rng.random(300), rng.random(300)
    want_d, want_density = lay.uv_to_dir(0, u, v), lay.uv_density(0, u, v)
    _, want_x, want_y = lay.pixel_coords(want_d, (n, n))
    for i in range(300):
        x, y, z, density = fused.target_direction.py_func(kind, np.eye(3), 0, u[i], v[i])
        np.testing.assert_allclose(np.array([x, y, z]) / np.linalg.norm([x, y, z]), want_d[i], atol=FORMULA_TOL)
        assert density == pytest.approx(want_density[i], rel=FORMULA_TOL)
        f, px, py = fused.source_position.py_func(kind, np.eye(3), 3 * x, 3 * y, 3 * z, n, n)
        assert f == 0 and (px, py) == pytest.approx((want_x[i], want_y[i]), abs=1e-9)
