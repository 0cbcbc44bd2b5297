"""Layouts: forward/inverse pairs, exact solid angles, the anchor directions, tables that agree."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from conftest import SPECIAL_DIRECTIONS, random_directions
from lightprobe.util.errors import LayoutError
from lightprobe.maps.layouts import ANGULAR, CROSS, CUBE, HCROSS, LATLONG, LAYOUTS, PAD, SPHERE, Sphere, detect_layout, layout
from lightprobe.maps.frames import rotation_from_ypr

ALL = list(LAYOUTS.values())
IDS = list(LAYOUTS)


@pytest.mark.parametrize("lay", ALL, ids=IDS)
def test_direction_pixel_direction_round_trip(lay):
    d = np.concatenate([random_directions(20000), SPECIAL_DIRECTIONS])
    face, u, v = lay.dir_to_uv(d)
    assert np.all((u >= 0) & (u <= 1) & (v >= 0) & (v <= 1))
    back = lay.uv_to_dir(face, u, v)
    # the disc layouts' rim is one direction reached from a whole circle: atan2 there is ill-conditioned
    tol = 1e-6 if lay in (ANGULAR, SPHERE) else 1e-8  # latlong: arccos at the poles
    np.testing.assert_allclose(back, d, atol=tol)


@given(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1))
@settings(max_examples=300, deadline=None)
@example(0.0, 2.225073858507e-311, 1.0)  # found by hypothesis: a denormal away from the angular rim point
@example(0.0, 5.5629288158559875e-158, -1.0)  # found by hypothesis: its square underflows next to the sphere's rim
@example(2.2250738585e-313, 2.2250738585e-313, -1.0)  # found by hypothesis: denormals next to the sphere's rim
def test_round_trip_any_direction(x, y, z):
    d = np.array([x, y, z])
    if np.linalg.norm(d) < 1e-6:
        return
    d /= np.linalg.norm(d)
    for lay in ALL:
        back = lay.uv_to_dir(*lay.dir_to_uv(d))
        assert np.allclose(back, d, atol=1e-6), lay.name


@pytest.mark.parametrize("lay", ALL, ids=IDS)
@pytest.mark.parametrize("size", [8, 33, 64])
def test_pixel_direction_pixel_round_trip(lay, size):
    grid = lay.grid_shape(size)
    face, u, v = lay.pixel_centres(grid)
    mask = lay.valid_mask(grid)
    if lay in (ANGULAR, SPHERE):  # pixels the rim cuts through with their centre outside map to the rim
        mask &= np.hypot(2 * u - 1, 1 - 2 * v) < 1
    f2, u2, v2 = lay.dir_to_uv(lay.directions(grid)[mask])
    np.testing.assert_array_equal(f2, face[mask])
    np.testing.assert_allclose(u2, u[mask], atol=1e-9)
    np.testing.assert_allclose(v2, v[mask], atol=1e-9)


@pytest.mark.parametrize("lay", ALL, ids=IDS)
@pytest.mark.parametrize("size", [16, 64, 256])
def test_solid_angles_sum_to_4pi(lay, size):
    omega = lay.solid_angles(lay.grid_shape(size))
    assert omega.min() >= 0
    assert abs(omega.sum() - 4 * np.pi) < 1e-4


@pytest.mark.parametrize("lay", ALL, ids=IDS)
@pytest.mark.parametrize("size", [9, 41, 300])
def test_solid_angles_of_chosen_pixels_are_the_tables(lay, size):
    """solid_angles_of (a few pixels, computed alone: the polar cells' balance asks it of a 4k disc) gives exactly
    the values of the whole table, invalid pixels' 0 included."""
    grid = lay.grid_shape(size)
    table = lay.solid_angles(grid).reshape(-1)
    flat = np.random.default_rng(size).integers(0, table.size, 3000)
    np.testing.assert_array_equal(lay.solid_angles_of(grid, flat), table[flat])


@pytest.mark.parametrize("lay", ALL, ids=IDS)
def test_solid_angles_match_the_density(lay):
    """Each pixel's solid angle equals ∫ dω/(du dv) over the pixel, integrated independently (fine midpoint rule)."""
    grid = lay.grid_shape(12)
    h, w = grid[-2:]
    m = 40
    sub = (np.arange(m) + 0.5) / m
    face, row, col = np.indices(grid) if lay.faces > 1 else (np.zeros(grid, int), *np.indices(grid))
    u = (col[..., None, None] + sub[None, :]) / w
    v = (row[..., None, None] + sub[:, None]) / h
    f = np.broadcast_to(face[..., None, None], u.shape + ())
    u, v = np.broadcast_arrays(u, v)
    f = np.broadcast_to(face[..., None, None], u.shape)
    numeric = lay.uv_density(f, u, v).mean(axis=(-2, -1)) / (h * w)
    np.testing.assert_allclose(lay.solid_angles(grid), numeric, atol=2e-3 * numeric.max())


def test_spec_anchor_directions():
    """The directions docs/spec.md §2 names, exactly."""
    assert np.allclose(LATLONG.uv_to_dir(0, 0.5, 0.5), [0, 0, -1])  # centre column → −Z (front)
    assert np.allclose(LATLONG.uv_to_dir(0, 0.75, 0.5), [1, 0, 0])  # u = ¾ → +X
    assert np.allclose(LATLONG.uv_to_dir(0, 0.3, 0.0), [0, 1, 0])  # top row → +Y
    assert np.allclose(ANGULAR.uv_to_dir(0, 0.5, 0.5), [0, 0, -1])  # centre → front
    assert np.allclose(ANGULAR.uv_to_dir(0, 1.0, 0.5), [0, 0, 1])  # rim → back
    assert np.allclose(ANGULAR.uv_to_dir(0, 0.75, 0.5), [1, 0, 0])  # half way right → +X
    assert np.allclose(ANGULAR.uv_to_dir(0, 0.5, 0.25), [0, 1, 0])  # half way up → +Y
    assert np.allclose(SPHERE.uv_to_dir(0, 0.5, 0.5), [0, 0, 1])  # mirror ball reflects back toward the camera
    assert np.allclose(SPHERE.uv_to_dir(0, 0.5 + 0.5 * np.sqrt(0.5), 0.5), [1, 0, 0])
    for i, axis in enumerate(np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])):
        assert np.allclose(CUBE.uv_to_dir(i, 0.5, 0.5), axis)
    # cube +Z face: s right → +X, t down → −Y; −Z face: s right → −X
    assert np.allclose(CUBE.uv_to_dir(4, 1.0, 0.5), np.array([1, 0, 1]) / np.sqrt(2))
    assert np.allclose(CUBE.uv_to_dir(4, 0.5, 1.0), np.array([0, -1, 1]) / np.sqrt(2))
    assert np.allclose(CUBE.uv_to_dir(5, 1.0, 0.5), np.array([-1, 0, -1]) / np.sqrt(2))
    # vertical cross: front tile centre → −Z, top tile → +Y, bottom tile (back, upside down) top edge → −Y side
    assert np.allclose(CROSS.uv_to_dir(0, 0.5, 3 / 8), [0, 0, -1])
    assert np.allclose(CROSS.uv_to_dir(0, 0.5, 1 / 8), [0, 1, 0])
    assert np.allclose(CROSS.uv_to_dir(0, 0.5, 7 / 8), [0, 0, 1])
    assert np.allclose(CROSS.uv_to_dir(0, 0.5, 0.75 + 1e-9), np.array([0, -1, 1]) / np.sqrt(2), atol=1e-6)
    assert np.allclose(HCROSS.uv_to_dir(0, 7 / 8, 0.5), [0, 0, 1])


@pytest.mark.parametrize("cross", [CROSS, HCROSS], ids=["cross", "hcross"])
@pytest.mark.parametrize("n", [1, 4, 31])
def test_cross_and_cube_hold_the_same_texels(cross, n):
    """The cross's tile table and the cube's face table (two tables of docs/spec.md §2) describe the same texel centres."""
    faces = np.random.default_rng(n).random((6, n, n, 3)).astype(np.float32)
    image = cross.from_cube(faces)
    np.testing.assert_array_equal(cross.to_cube(image), faces)
    assert (image.sum(axis=-1) > 0).sum() == 6 * n * n  # a bijection onto the six tiles
    grid = cross.grid_shape(n)
    np.testing.assert_array_equal(cross.valid_mask(grid), cross.solid_angles(grid) > 0)
    d_cross = cross.directions(grid)[cross.valid_mask(grid)]
    d_cube = CUBE.directions(CUBE.grid_shape(n)).reshape(-1, 3)
    # same set of directions, up to order
    key = lambda d: np.lexsort(np.round(d, 9).T)  # noqa: E731
    np.testing.assert_allclose(d_cross[key(d_cross)], d_cube[key(d_cube)], atol=1e-12)


@pytest.mark.parametrize("cross", [CROSS, HCROSS], ids=["cross", "hcross"])
@pytest.mark.parametrize("n", [1, 2, 7, 32])
def test_each_tile_texel_shows_its_face_texels_direction(cross, n):
    """to_cube turns each tile by a symmetry of the square found once at 3 texels (cube_layouts._tile_turns): at every
    size each cube texel comes from the cross pixel of the same direction, and from_cube puts it back there."""
    grid = cross.grid_shape(n)
    np.testing.assert_allclose(cross.to_cube(cross.directions(grid)), CUBE.directions(CUBE.grid_shape(n)),
                               atol=1e-12)
    cube_dirs = CUBE.directions(CUBE.grid_shape(n))
    back = cross.from_cube(cube_dirs)
    valid = cross.valid_mask(grid)
    np.testing.assert_allclose(back[valid], cross.directions(grid)[valid], atol=1e-12)
    assert (back[~valid] == 0).all()


def test_sphere_layout_with_camera_axes():
    t = rotation_from_ypr(90, 0, 0)  # camera turned to look along −X
    lay = Sphere(t)
    assert np.allclose(lay.uv_to_dir(0, 0.5, 0.5), t[:, 2])  # centre reflects back toward the camera
    d = random_directions(1000)
    assert np.allclose(lay.uv_to_dir(*lay.dir_to_uv(d)), d, atol=1e-6)
    with pytest.raises(LayoutError):
        Sphere(np.diag([1.0, 1.0, -1.0]))


@pytest.mark.parametrize("w,h,name", [(2048, 1024, "latlong"), (1000, 1000, "angular"), (768, 1024, "cross"),
                                      (1024, 768, "hcross"), (3072, 512, "cube")])
def test_detect_layout(w, h, name):
    assert detect_layout(w, h).name == name


@pytest.mark.parametrize("w,h", [(1000, 999), (300, 200), (7, 1)])
def test_undetectable_aspect_is_a_clear_error(w, h):
    with pytest.raises(LayoutError, match="--layout"):
        detect_layout(w, h)


@pytest.mark.parametrize("lay,grid", [(LATLONG, (100, 100)), (ANGULAR, (100, 90)), (CROSS, (100, 76)),
                                      (CUBE, (5, 8, 8)), (HCROSS, (3, 5))])
def test_grid_that_does_not_fit_is_refused(lay, grid):
    with pytest.raises(LayoutError):
        lay.check_grid(grid)


@pytest.mark.parametrize("n", [4, 5, 16])
def test_a_cubes_corner_padding_holds_each_corner_texel_once(n):
    """Beyond each face corner (the vertex's missing fourth quadrant) the 2×2 padding holds the next face's corner
    block, each of the 24 × 4 corner-block texels exactly once, on the face next round the vertex; the rest of the
    border is the nearest texel, as before."""
    from lightprobe.maps.layout_base import PAD, _padding_index

    cube = LAYOUTS["cube"]
    grid = cube.grid_shape(n)
    border, (face, row, col) = _padding_index(cube, grid, PAD)
    f, r, c = np.nonzero(border)
    beyond_r, beyond_c = (r < PAD) | (r >= n + PAD), (c < PAD) | (c >= n + PAD)
    diagonal = beyond_r & beyond_c
    held = list(zip(face[diagonal], row[diagonal], col[diagonal]))
    assert len(held) == 6 * 4 * PAD * PAD == len(set(held))
    near = lambda x: (x < PAD) | (x >= n - PAD)  # noqa: E731
    assert all(near(rr) and near(cc) for _, rr, cc in held)  # corner-block texels
    assert all(ff != f0 for ff, f0 in zip(face[diagonal], f[diagonal]))  # from another face


@pytest.mark.parametrize("name, n", [("sphere", 64), ("sphere", 101), ("angular", 64), ("angular", 101)])
def test_a_discs_padding_counts_each_pixel_by_its_share(name, n):
    """A disc's padded lookup table: certainty 1 inside the disc, 0 off it, between for the rim pixels. A mirror
    ball's density is constant, so its certainties are the pixels' exact areas in the disc and, times 4 sr per unit
    of disc area, sum to 4π; an angular map's slivers by the rim count less than half their area (its density
    falls to 0 at the rim); no pixel that covers sphere is left out."""
    lay = layout(name)
    grid = lay.grid_shape(n)
    _, valid = lay.padded(np.zeros(grid + (3,), np.float32))
    certainty = valid[0, PAD:-PAD, PAD:-PAD]
    omega = lay.solid_angles(grid)
    assert certainty.dtype == np.float32 and certainty.min() >= 0 and certainty.max() <= 1
    np.testing.assert_array_equal(certainty > 0, omega > 0)
    np.testing.assert_array_equal(valid[0, :PAD], 0)
    rim = (certainty > 0) & (certainty < 1)
    assert rim.sum() > 3 * n  # the rim's ring, about 4n pixels
    if name == "sphere":
        np.testing.assert_allclose((certainty * 16.0 / n**2).sum(), 4 * np.pi, rtol=1e-6)
    else:
        a = np.linspace(-1, 1, 24 * n, endpoint=False) + 1 / (24 * n)  # each pixel's area in the disc, finely
        inside = (np.hypot(a[None, :], a[:, None]) <= 1).reshape(n, 24, n, 24).mean(axis=(1, 3))
        slivers = rim & (inside < 0.2)
        assert slivers.any() and (certainty[slivers] < 0.5 * inside[slivers]).all()


@pytest.mark.parametrize("lay", ALL, ids=IDS)
def test_the_shared_valid_mask_is_the_mask_read_only_and_a_discs_is_not_copied(lay):
    """shared_valid_mask is valid_mask, read-only (a reader cannot spoil a disc's cached table); a disc's is one
    table however often it is asked for — a 4k disc's is 10 MiB, and a conversion used to hold a copy of it."""
    grid = lay.grid_shape(37)
    shared = lay.shared_valid_mask(grid)
    np.testing.assert_array_equal(shared, lay.valid_mask(grid))
    assert not shared.flags.writeable
    with pytest.raises(ValueError):
        shared[(0,) * shared.ndim] = not shared[(0,) * shared.ndim]
    if lay in (ANGULAR, SPHERE):
        assert lay.shared_valid_mask(grid) is shared
        assert lay.valid_mask(grid) is not shared and lay.valid_mask(grid).flags.writeable
