"""The balance of a lat-long source's coarsest polar rows (lightprobe.maps.resampling.polar_balance): a row reduced to a few
cells is read through a periodic B-spline whose basis spans a quarter to a half of the circle, and a turned target's
subsamples round the pole weighed the cells unequally — a one-pixel sun in the source's pole row came out +0.46 %
(512×256 → a turned cube of 50), +0.74 % (2048×1024 → turned cubes of 250 and 300) and +0.89 % (a turned lat-long of
60) while the rows' means held. Balanced, every cell of such a row delivers the row's mean."""

from __future__ import annotations

import numpy as np
import pytest

from lightprobe.maps import EnvMap, Resampler, resample
from lightprobe.maps.resampling import fused, polar, polar_balance, resampler as resampling, taps as taps_module
from lightprobe.maps.envmap import pixel_solid_angles
from lightprobe.maps.frames import rotation_from_ypr
from lightprobe.maps.layouts import layout

LATLONG = layout("latlong")
TURN = rotation_from_ypr(30, 40, 50)


def test_a_balance_takes_every_cell_of_a_row_to_its_mean():
    """balance_of on made-up deliveries: the balanced deliveries (its transpose) are each row's mean to float
    rounding, its weights non-negative, and a uniform row stays exactly uniform, a positive one positive."""
    width, height = 64, 12
    found = np.zeros(height, np.int64)
    found[:3] = [4, 3, 1]  # rows of 4, 8 and 32 cells
    found[-1] = 2  # and one of 16 at the other pole
    levels = polar.kernel_levels(found, width)
    offsets, _, total = polar.row_layout(levels, width)
    rng = np.random.default_rng(5)
    per_cell = rng.uniform(0.9, 1.1, total)
    caps = polar_balance.caps(found, width)
    assert [(sign, list(rows)) for sign, rows, _ in caps] == [(1, [0, 1, 2]), (-1, [height - 1])]
    parts = []
    for _, rows, _ in caps:
        first, end = polar_balance.cell_span(found, width, rows)
        parts += polar_balance.balance_of(per_cell[first:end], first, found, width, rows)
    cells = polar_balance.joined(parts)
    assert cells is not None and (cells.right >= 0).all() and (cells.left >= 0).all()
    after = cells.delivered(per_cell)
    for r in (0, 1, 2, height - 1):
        row = slice(offsets[r], offsets[r] + polar.reduced_width(width, int(levels[r])))
        np.testing.assert_allclose(after[row], per_cell[row].mean(), rtol=1e-6)
    assert after.sum() == pytest.approx(per_cell.sum(), rel=1e-12)  # moved, never lost
    assert (cells.apply(np.ones((total, 3), np.float32)) == 1.0).all()
    values = rng.uniform(0.0, 1.0, (total, 3)).astype(np.float32)
    balanced = cells.apply(values.copy())
    assert (balanced >= 0).all()
    # apply and delivered are each other's transpose: Σ D · apply(v) = Σ delivered(D) · v
    assert per_cell @ balanced[:, 0].astype(np.float64) == pytest.approx(after @ values[:, 0].astype(np.float64),
                                                                         rel=1e-6)


@pytest.mark.parametrize("rows, target, size", [(256, "cube", 50), (256, "cube", 40), (512, "cube", 100)])
def test_a_sun_in_a_turned_conversions_pole_rows_keeps_its_energy(rows, target, size):
    """Every source pixel as a one-pixel sun (Resampler.energy_gains): within 0.15 % with the balance; without it
    the pole rows read 0.45–0.47 % (the test can fail)."""
    resampler = Resampler(LATLONG, LATLONG.grid_shape(rows), layout(target), size, rotation=TURN)
    assert resampler._cells is not None
    assert np.abs(resampler.energy_gains()).max() < 1.5e-3
    before = np.abs(resampler.without_cell_balance().energy_gains())
    assert before.max() > 4e-3
    assert np.unravel_index(before.argmax(), before.shape)[0] in (0, rows - 1)  # in a pole row


def test_suns_through_resample_agree_with_the_measure():
    """resample (its balance measured by the adjoint on the pixels by the source's poles alone) gives a sun in a
    pole row the energy Resampler.energy_gains (every tap of every pixel) says: the masked measure misses nothing."""
    rows, size = 256, 50
    grid = LATLONG.grid_shape(rows)
    gains = Resampler(LATLONG, grid, layout("cube"), size, rotation=TURN).energy_gains()
    omega = pixel_solid_angles(LATLONG, grid)
    data = np.zeros(grid + (3,), np.float32)
    for row, col in ((0, 3), (0, 300), (1, 77), (rows - 1, 12), (rows - 2, 500), (10, 100)):
        data[:] = 0.0
        data[row, col] = 1.0
        out = resample(EnvMap(data, LATLONG), layout("cube"), size, rotation=TURN)
        assert out.integral()[0] / omega[row, col] - 1 == pytest.approx(gains[row, col], abs=2e-6)


@pytest.mark.parametrize("target, size, turn", [("cube", 50, TURN), ("latlong", 60, TURN), ("cube", 64, None),
                                                ("angular", 90, rotation_from_ypr(10, 80, 0))])
def test_the_masked_measure_equals_the_whole_adjoint(target, size, turn):
    """_cell_balance's deliveries, summed over the target pixels near_pole keeps, equal the whole adjoint's for
    every cell it balances (the pixels it skips read none of them) — a disc target too, whose rim pixels are long."""
    grid = (256, 512)
    filled = layout(target)
    tgt_grid = filled.grid_shape(size)
    k, steps = resampling.supersampling(LATLONG, grid, filled, tgt_grid, turn, None)
    k_max = resampling.adaptive_rate(LATLONG, filled, k)
    found = polar.polar_levels(steps, grid, k)
    caps = polar_balance.caps(found, grid[1])
    assert len(caps) == 2
    taps = taps_module._Taps(LATLONG, grid, filled, size, k, k_max, steps, turn)
    omega_t = pixel_solid_angles(filled, tgt_grid).reshape(-1)
    whole = np.zeros(taps.source_pixels + taps.reduced_size)
    fused.footprint_delivery(*taps.kernel_args, 0, taps.lines, omega_t, taps.max_taps, whole, 0)
    for sign, rows, angle in caps:
        kept = polar_balance.near_pole(filled, tgt_grid, turn, sign, angle)
        assert kept.size < omega_t.size / 4 or filled.name == "angular"  # most left out (a disc keeps its rim)
        first, end = polar_balance.cell_span(found, grid[1], rows)
        masked = polar_balance._kept_delivery(taps, filled, tgt_grid, kept, taps.source_pixels + first, end - first)
        np.testing.assert_allclose(masked, whole[taps.source_pixels + first:taps.source_pixels + end], rtol=1e-12)


def test_a_uniform_map_stays_exactly_uniform_and_the_cached_path_agrees():
    """Through a balanced conversion a uniform map stays exactly uniform, and the cached weights (Resampler) give
    what resample gives to float32 rounding."""
    grid = LATLONG.grid_shape(256)
    ones = EnvMap(np.ones(grid + (3,), np.float32), LATLONG)
    assert (resample(ones, layout("cube"), 50, rotation=TURN).data == 1.0).all()
    rng = np.random.default_rng(2)
    env = EnvMap(rng.uniform(0.0, 2.0, grid + (3,)).astype(np.float32), LATLONG)
    cached = Resampler(LATLONG, grid, layout("cube"), 50, rotation=TURN)
    assert cached._cells is not None
    np.testing.assert_allclose(cached(env).data, resample(env, layout("cube"), 50, rotation=TURN).data, rtol=2e-6,
                               atol=1e-6)
