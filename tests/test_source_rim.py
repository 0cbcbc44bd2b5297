"""A disc source read round its rim direction (lightprobe.maps.resampling.fused, SOURCE_RIM_MARK): an angular map or a mirror
ball spreads that one direction over its outer ring, and a target pixel by it reads an arc of the ring ~1/ε long.
Such pixels are sampled in (ρ, α) round the source's rim direction; with the flux correction on every pixel of the
source, a one-pixel sun anywhere keeps its energy — to the rim direction, which was left alone within 20° and came out
up to 3000 % off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightprobe.maps import EnvMap, Resampler, resample
from lightprobe.maps.resampling import fused
from lightprobe.maps.envmap import pixel_directions, pixel_solid_angles
from lightprobe.maps.frames import rotation_from_ypr
from lightprobe.maps.layouts import layout

TURNED = rotation_from_ypr(-40, 25, 5)

PAIRS = [  # (source, size, target, size, rotation)
    ("angular", 128, "latlong", 64, None),
    ("angular", 128, "cube", 32, None),
    ("angular", 128, "sphere", 48, TURNED),
    ("angular", 128, "latlong", 64, rotation_from_ypr(30, -20, 10)),
    ("sphere", 256, "angular", 64, None),
]


def _resampler(source, size, target, out_size, rotation):
    src = layout(source)
    return Resampler(src, src.grid_shape(size), layout(target), out_size, rotation=rotation)


@pytest.mark.parametrize("source, size, target, out_size, rotation", PAIRS)
def test_a_sun_anywhere_in_a_disc_source_keeps_its_energy_to_the_rim_direction(source, size, target, out_size,
                                                                               rotation):
    """Every source pixel, no margin: exact after the correction, whose blends stay small (under 0.4 of a pixel's
    value, against a cap of 0.95 — the flow has little to mend)."""
    r = _resampler(source, size, target, out_size, rotation)
    assert np.nanmax(np.abs(r.energy_gains())) < 1e-5
    assert r._flux.largest_weight < 0.4


def _turning(a, b) -> np.ndarray:
    """The rotation that takes unit direction ``a`` to ``b`` (Rodrigues)."""
    a, b = np.asarray(a, float) / np.linalg.norm(a), np.asarray(b, float) / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


@pytest.mark.parametrize("target, out_size, onto", [
    ("cube", 32, (1, 1, 1)),  # a cube's vertex: three faces meet where the pixel holding it is found
    ("cube", 32, (1, 0, 1)),  # an edge between two faces
    ("latlong", 64, (0, 1, 0)),  # a lat-long's pole: a whole row of pixels round it
    ("sphere", 24, (1, 1, 1)),  # a mirror ball target, turned so its rim is elsewhere: the pixels whose corner
    #                             touches the rim direction (their cells measured 16 a side: 279 % before, 76 % after)
    ("sphere", 32, (0.4012, 0.1487, -0.9038)),  # 25° from the ball's own rim direction, in its long rim pixels
    #                                             (read by the ball's rim rows: 177 %; all taken round it: 12 %)
])
def test_the_rim_direction_anywhere_in_the_target(target, out_size, onto):
    """The angular source's rim direction (+Z) turned onto a cube's vertex and edge, a lat-long's pole, a mirror
    ball's pixels: the pixels round it are still found and every source pixel is exact."""
    turn = _turning((0, 0, 1), onto)  # the target at d shows the source at Rᵀd: the source's +Z shows at R·(+Z)
    r = _resampler("angular", 96, target, out_size, turn)
    assert np.nanmax(np.abs(r.energy_gains())) < 1e-5
    assert r._flux.largest_weight < 0.6  # well inside the cap (0.95), which the 177 % case had reached


def test_the_rim_directions_ring_is_read_evenly_before_the_correction():
    """What the correction is left to mend within 5° of an angular source's rim direction: under 90 % for any pixel
    (the worst are rim slivers of a thousandth of a pixel's solid angle), where the target's own cells left
    −100 … +550 % (angular 256 → lat-long 128), which no capped blend could mend; pixels of a full share within 40 %."""
    src = layout("angular")
    grid = src.grid_shape(256)
    gains = _resampler("angular", 256, "latlong", 128, None).without_flux_correction().energy_gains()
    near = pixel_directions(src, grid) @ src.rim_direction() > math.cos(math.radians(5))
    assert np.nanmax(np.abs(gains[near])) < 0.9
    omega = pixel_solid_angles(src, grid)
    full = near & (omega > 0.25 * np.median(omega[near]))
    assert np.nanmax(np.abs(gains[full])) < 0.4


@pytest.mark.parametrize("source, size, target, out_size, rotation", PAIRS[:3] + PAIRS[4:])
def test_the_cached_taps_equal_the_direct_pass_and_uniform_stays_uniform(source, size, target, out_size, rotation):
    """The pixels round the rim direction listed apart and merged (Resampler._splice) give what resample gives,
    to float32 rounding; a uniform map stays exactly uniform (each pixel's cells are normalised by their sum)."""
    src, tgt = layout(source), layout(target)
    grid = src.grid_shape(size)
    mask = src.valid_mask(grid)[..., None]
    env = EnvMap((np.random.default_rng(1).random(grid + (3,)) * mask).astype(np.float32), src)
    r = _resampler(source, size, target, out_size, rotation)
    direct = resample(env, tgt, out_size, rotation=rotation).data
    assert np.abs(r(env).data - direct).max() < 1e-6 * direct.max()
    uniform = resample(EnvMap(np.ones(grid + (3,), np.float32), src), tgt, out_size, rotation=rotation).data
    assert np.abs(uniform[tgt.valid_mask(tgt.grid_shape(out_size))] - 1.0).max() < 1e-6


def test_the_pixel_holding_the_rim_direction_is_sampled_round_it_to_its_solid_angle():
    """The lat-long pixel that shows an angular source's rim direction (+Z: the equator, straight behind) is sampled
    round that direction, its cells moved to its edges: their solid angles sum to the pixel's within 0.5 %."""
    src, tgt = fused.ANGULAR, fused.LATLONG
    h, w, src_size = 32, 64, 256
    eye = np.eye(3)
    z_row, z_col = h // 2, 0  # +Z: θ = 90°, φ = ±180°, the seam column
    for row, col in ((z_row, z_col), (z_row - 1, w - 1)):
        plan = fused._source_rim_plan(tgt, eye, 0, row, col, h, w, eye, src, eye, src_size)
        m = 1025
        pfs, pxs, pys, pws = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)
        total = fused._source_rim_weight(plan, tgt, eye, 0, row, col, h, w, eye, src, eye, src_size, src_size, pfs,
                                         pxs, pys, pws)
        omega = pixel_solid_angles(layout("latlong"), (h, w))[row, col]
        assert abs(total / omega - 1.0) < 5e-3
    assert plan[0] == 0.0 and plan[4] - plan[3] == pytest.approx(2 * math.pi)  # the whole circle from ρ = 0
