"""A cube source's texel balance (lightprobe.maps.resampling.balance): the integrals of the B-spline reconstruction's bases
against brute force, the balance making each texel carry its own solid angle, and conversions from cubes keeping a
one-texel sun's energy where the reconstruction used to lose it."""

from __future__ import annotations

import numpy as np
import pytest

from lightprobe.maps import EnvMap, Resampler, resample
from lightprobe.maps.resampling import balance
from lightprobe.maps.envmap import pixel_solid_angles
from lightprobe.maps.layouts import CUBE, LATLONG, layout


def brute_force_integrals(n: int, fine: int) -> np.ndarray:
    """I_j of face 0's texels, measured: each texel as a one-texel map, looked up through the plain B-spline
    sampler (no balance) at the centres of a cube ``fine`` times finer, summed with those texels' exact solid
    angles. Face-aligned fine texels never straddle an edge, where the density has its kink."""
    grid = CUBE.grid_shape(n * fine)
    d = CUBE.uv_to_dir(*CUBE.pixel_centres(grid)).reshape(-1, 3)
    omega = pixel_solid_angles(CUBE, grid).ravel()
    out = np.empty((n, n))
    for r in range(n):
        for c in range(n):
            sun = np.zeros((6, n, n, 1), np.float32)
            sun[0, r, c] = 1.0
            out[r, c] = omega @ CUBE.sampler(sun, "bspline")(d)[:, 0].astype(np.float64)
    return out


def test_the_texel_integrals_are_the_reconstructions_own():
    """face_texel_integrals (Gauss–Legendre on half texels, banded) equals the reconstruction integrated by brute
    force — edge, vertex and interior texels alike, the padding's copies included — and the bases are a partition
    of unity: their integrals sum to 4π."""
    n = 8
    mine = balance.face_texel_integrals(n)
    measured = brute_force_integrals(n, 24)  # the fine midpoint rule is ~4e-5 off at 24 (1.6e-4 at 12)
    omega = pixel_solid_angles(CUBE, (6, n, n))[0]
    np.testing.assert_allclose(mine / omega - 1, measured / omega - 1, rtol=0, atol=1e-4)
    assert np.abs(mine / omega - 1).max() > 0.02  # what the balance is for: 2–3 % off at 8 texels a side
    for size in (4, 9, 64):
        assert 6 * balance.face_texel_integrals(size).sum() == pytest.approx(4 * np.pi, rel=1e-8)  # 7e-9 at 4


@pytest.mark.parametrize("n", [4, 9, 64, 300])
def test_balanced_texels_carry_their_solid_angle(n):
    """Through the balance, each texel's effective integral is its solid angle (before: up to +0.8 % at 64 texels,
    +3.3 % at 16, 0.26 % at any size from the padding's nearest-texel rounding)."""
    integrals = np.broadcast_to(balance.face_texel_integrals(n), (6, n, n))
    omega = pixel_solid_angles(CUBE, (6, n, n))
    delivered = balance.balance_of(n).delivered(integrals)
    np.testing.assert_allclose(delivered, omega, rtol=5e-8)
    assert np.abs(integrals / omega - 1).max() > 2e-3


def test_the_balance_is_a_small_convex_blend():
    """The blends are convex — a uniform map stays uniform to the bit, a sun or any positive map stays positive —
    and small: at most 10 % of a neighbour at 4–8 texels a side, 3.3 % at 16, 2.2 % from 32 to 1024; the compiled
    pass equals numpy's."""
    for n, most in ((4, 0.11), (16, 0.035), (64, 0.022), (160, 0.022)):
        b = balance.balance_of(n)
        weights = np.stack([b.row_up, b.row_down, b.column_up, b.column_down])
        assert weights.min() >= 0 and weights.max() < most
        assert (b.row_up + b.row_down).max() < 1 and (b.column_up + b.column_down).max() < 1
        uniform = np.full((6, n, n, 3), 2.5, np.float32)
        assert np.array_equal(balance.balanced_faces(uniform), uniform)
        sun = np.zeros((6, n, n, 3), np.float32)
        sun[2, 0, n // 3] = 1e6
        out = balance.balanced_faces(sun)
        assert out.min() >= 0 and out[2, 0, n // 3, 0] > (1 - 2 * most) * 1e6  # it stays where it was
    noise = np.random.default_rng(4).random((6, 160, 160, 3)).astype(np.float32)
    compiled = balance.balanced_faces(noise)
    b = balance.balance_of(160)

    def blended(face, up, down):  # the blends along a face's second axis, in numpy
        step = face[:, 1:] - face[:, :-1]
        out = face.copy()
        out[:, :-1] += up[:, :-1, None] * step
        out[:, 1:] -= down[:, 1:, None] * step
        return out

    by_numpy = np.stack([blended(blended(face.transpose(1, 0, 2), b.column_up.T, b.column_down.T).transpose(1, 0, 2),
                                 b.row_up, b.row_down) for face in noise])
    np.testing.assert_array_equal(compiled, by_numpy)


@pytest.mark.parametrize("target, out_size, ceiling, before", [
    ("cube", 64, 0.0020, 0.0086),
    ("latlong", 64, 0.0020, 0.0077),
])
def test_a_sun_in_any_cube_texel_keeps_its_energy(target, out_size, ceiling, before):
    """Every texel of a 64-texel cube as a one-texel sun (energy_gains), into a cube of the same size and a
    lat-long: within the 0.2 % bar now (the worst was the edge and vertex texels, 0.86 % and 0.77 %) — and the
    same texels' suns put through resample directly."""
    gains = Resampler(CUBE, (6, 64, 64), layout(target), out_size).energy_gains()
    assert np.abs(gains).max() < ceiling < before
    omega = pixel_solid_angles(CUBE, (6, 64, 64))
    for texel in [(0, 0, 0), (1, 0, 21), (2, 1, 30), (5, 63, 63), (4, 32, 32)]:
        sun = np.zeros((6, 64, 64, 3), np.float32)
        sun[texel] = 1.0 / omega[texel]
        out = resample(EnvMap(sun, CUBE), layout(target), out_size).integral()[0]
        assert out - 1 == pytest.approx(gains[texel], abs=2e-6) and abs(out - 1) < ceiling


def test_a_cross_source_is_balanced_as_its_cube():
    """A cross is read as its cube faces: the same balance, the same output as the cube itself."""
    cube = EnvMap(np.random.default_rng(5).random((6, 32, 32, 3)).astype(np.float32), CUBE)
    cross = layout("cross")
    as_cross = EnvMap(cross.from_cube(cube.data), cross)
    np.testing.assert_array_equal(resample(as_cross, LATLONG, 32).data, resample(cube, LATLONG, 32).data)
    gains = Resampler(cross, as_cross.grid, LATLONG, 32).energy_gains()
    np.testing.assert_array_equal(gains, Resampler(CUBE, cube.grid, LATLONG, 32).energy_gains())
