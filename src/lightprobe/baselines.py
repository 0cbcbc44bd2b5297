"""The point-light baselines users reach for today, with solid-angle weighting: Debevec's median cut (2005).

Quantities as in :mod:`lightprobe.lights`: directions in the world frame, ``power`` RGB ∫L dω of the region a light
stands for. The map is first resampled (energy-conservingly) to a lat-long working grid; its pixels' luminance ×
solid angle go into a summed-area table, so every region's energy and every candidate cut is O(1) or O(side).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .envmap import EnvMap
from .errors import UsageError
from .layouts import LATLONG
from .tonemap import luminance

MAX_POINT_LIGHTS = 4096


@dataclass(frozen=True)
class PointLight:
    """A directional light: ``direction`` (world, unit; the region's energy centroid) and ``power`` (RGB ∫L dω of
    its region)."""

    direction: np.ndarray
    power: np.ndarray
    radius: float = 0.0  # a point: no cap (what the preview draws is its centre)

    @property
    def yaw_elevation_deg(self) -> tuple[float, float]:
        from .lights import yaw_elevation_deg

        return yaw_elevation_deg(self.direction)


def check_count(count) -> None:
    """Refuse a light count median cut cannot make (a power of two up to :data:`MAX_POINT_LIGHTS`)."""
    if not isinstance(count, (int, np.integer)) or count < 1 or count > MAX_POINT_LIGHTS or count & (count - 1):
        raise UsageError(f"median cut needs a power of two from 1 to {MAX_POINT_LIGHTS} lights, got {count!r}")


def median_cut(env: EnvMap, count: int, rows: int = 256) -> list[PointLight]:
    """Debevec's median cut: split the lat-long map ``log2(count)`` times, every region along its longer side
    (its width measured at its middle latitude, so a polar region is not taken for a wide one) where the luminance
    power on either side is equal; one light per region at its energy centroid, with the region's RGB power. A
    region of one pixel is not cut, so a map whose energy sits in fewer pixels than ``count`` gives fewer lights.
    The powers add up to ∫ of the working map (the resampled map: ∫L dω kept to ~1e-4)."""
    check_count(count)
    work = env if env.layout == LATLONG and env.grid[0] == rows else env.to(LATLONG, rows)
    h, w = work.grid
    omega = LATLONG.row_solid_angles(work.grid)[:, None]
    rgb = work.data.astype(np.float64) * omega[..., None]  # each pixel's RGB ∫L dω
    energy = np.maximum(luminance(rgb), 0.0)
    table = np.zeros((h + 1, w + 1))
    table[1:, 1:] = energy.cumsum(axis=0).cumsum(axis=1)
    regions = [(0, h, 0, w)]  # rows [r0, r1), columns [c0, c1)
    for _ in range(int(math.log2(count))):
        regions = [half for region in regions for half in _split(table, region, h)]
    return [_light(work, rgb, energy, region) for region in regions]


def _sum(table, r0, r1, c0, c1) -> float:
    return float(table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0])


def _split(table, region, h):
    """The two halves of a region, cut across its longer side where its energy is halved (a one-pixel side is not
    cut; a region without energy is cut in the middle)."""
    r0, r1, c0, c1 = region
    middle = math.sin(math.pi * (r0 + r1) / 2 / h)  # the width of a column at the region's middle latitude
    across_columns = (c1 - c0) * middle >= (r1 - r0) / 2  # columns span 2π, rows π: a column is half a row wide
    if across_columns and c1 - c0 < 2:
        across_columns = False
    if not across_columns and r1 - r0 < 2:
        return [region] if c1 - c0 < 2 else _split_columns(table, region)
    return _split_columns(table, region) if across_columns else _split_rows(table, region)


def _split_columns(table, region):
    r0, r1, c0, c1 = region
    cs = np.arange(c0 + 1, c1)  # energy left of each cut, from the table's corners (no loop over columns)
    sums = table[r1, cs] - table[r0, cs] - table[r1, c0] + table[r0, c0]
    cut = c0 + 1 + _halfway(sums, _sum(table, r0, r1, c0, c1))
    return [(r0, r1, c0, cut), (r0, r1, cut, c1)]


def _split_rows(table, region):
    r0, r1, c0, c1 = region
    rs = np.arange(r0 + 1, r1)
    sums = table[rs, c1] - table[r0, c1] - table[rs, c0] + table[r0, c0]
    cut = r0 + 1 + _halfway(sums, _sum(table, r0, r1, c0, c1))
    return [(r0, cut, c0, c1), (cut, r1, c0, c1)]


def _halfway(cumulative: np.ndarray, total: float) -> int:
    """Index of the first partial sum reaching half the total (the middle one when there is no energy)."""
    if total <= 0:
        return (cumulative.size - 1) // 2
    return int(min(np.searchsorted(cumulative, total / 2), cumulative.size - 1))


def _light(work: EnvMap, rgb: np.ndarray, energy: np.ndarray, region) -> PointLight:
    r0, r1, c0, c1 = region
    h, w = work.grid
    theta = (np.arange(r0, r1) + 0.5) / h * np.pi
    phi = 2 * np.pi * ((np.arange(c0, c1) + 0.5) / w - 0.5)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], axis=-1)
    weights = energy[r0:r1, c0:c1]
    centroid = (dirs * (weights[..., None] if weights.sum() > 0 else 1.0)).sum(axis=(0, 1))
    norm = np.linalg.norm(centroid)
    direction = centroid / norm if norm > 0 else dirs[(r1 - r0) // 2, (c1 - c0) // 2]
    return PointLight(direction, rgb[r0:r1, c0:c1].sum(axis=(0, 1)))
