"""The point-light baselines users reach for today, with solid-angle weighting: Debevec's median cut (2005) and
Viriyothai & Debevec's variance minimisation (2009).

Quantities as in :mod:`lightprobe.lights.decompose`: directions in the world frame, ``power`` RGB ∫L dω of the
region a light stands for. The map is first resampled (energy-conservingly) to a lat-long working grid; its pixels'
luminance × solid angle go into summed-area tables, so every region's energy and every candidate cut is O(1) or
O(side).

Both split every region at each step, so both give 2^k lights; they differ in where a region is cut. Median cut
halves the energy across the longer side; variance minimisation tries every cut of either side and takes the one
whose two halves have the least summed energy-weighted variance of direction, Σ e·|x − centroid|², i.e. the cut
after which each light best stands for the pixels it replaces.

Any other count N (the papers give only powers of two; a user comparing with N area lights wants N): the
⌊log₂ N⌋ whole levels of cuts, then one more cut of the N − 2^⌊log₂ N⌋ regions that most need it — for median
cut the ones with the most energy, for variance minimisation the ones with the largest variance — so a power of
two gives exactly the papers' lights, and N + 1 lights refine N's (:func:`_regions`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..maps import EnvMap
from ..util.errors import UsageError
from ..maps.layouts import LATLONG
from ..maps.tonemap import luminance

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
        """(yaw, elevation) of the direction in degrees (:func:`lightprobe.lights.decompose.yaw_elevation_deg`)."""
        from .decompose import yaw_elevation_deg

        return yaw_elevation_deg(self.direction)


def check_count(count) -> None:
    """Refuse a light count the baselines cannot make: a whole number from 1 to :data:`MAX_POINT_LIGHTS`.

    Parameters
    ----------
    count : int
        The number of lights asked for: a Python or numpy integer (not a bool), 1 to 4096.

    Raises
    ------
    UsageError
        ``count`` is not such a number.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= MAX_POINT_LIGHTS:
        raise UsageError(f"median cut and variance minimisation need a whole number of lights from 1 to "
                         f"{MAX_POINT_LIGHTS}, got {count!r}")


def _regions(grid: tuple[int, int], count: int, split, need) -> list[tuple[int, int, int, int]]:
    """``count`` regions (rows [r0, r1), columns [c0, c1)) of a lat-long grid: ``split(region)`` applied to every
    region ⌊log₂ count⌋ times, then once more to the count − 2^⌊log₂ count⌋ regions of highest ``need(region)``
    (ties: the first), each region's halves taking its place. A region that cannot be cut stays whole, so a map
    whose energy sits in few pixels gives fewer lights."""
    h, w = grid
    regions = [(0, h, 0, w)]
    levels = int(count).bit_length() - 1
    for _ in range(levels):
        regions = [half for region in regions for half in split(region)]
    extra = count - (1 << levels)
    if extra:
        needs = np.array([need(region) for region in regions], np.float64)
        chosen = set(np.argsort(-needs, kind="stable")[:extra].tolist())
        regions = [half for i, region in enumerate(regions) for half in (split(region) if i in chosen else [region])]
    return regions


def _working(env: EnvMap, rows: int) -> tuple[EnvMap, np.ndarray, np.ndarray]:
    """The lat-long working map, each pixel's RGB ∫L dω, and its luminance power (clamped at 0)."""
    work = env if env.layout == LATLONG and env.grid[0] == rows else env.to(LATLONG, rows)
    omega = LATLONG.row_solid_angles(work.grid)[:, None]
    rgb = work.data.astype(np.float64) * omega[..., None]
    return work, rgb, np.maximum(luminance(rgb), 0.0)


def _table(values: np.ndarray) -> np.ndarray:
    """Summed-area table with a zero first row and column: region sums are four lookups."""
    table = np.zeros((values.shape[0] + 1, values.shape[1] + 1))
    table[1:, 1:] = values.cumsum(axis=0).cumsum(axis=1)
    return table


def median_cut(env: EnvMap, count: int, rows: int = 256) -> list[PointLight]:
    """Debevec's median cut: ``count`` point lights, one per region of the map cut where its energy halves.

    Split the lat-long map ``log2(count)`` times, every region along its longer side
    (its width measured at its middle latitude, so a polar region is not taken for a wide one) where the luminance
    power on either side is equal; one light per region at its energy centroid, with the region's RGB power. A
    count that is not a power of two cuts its last level's most energetic regions only (:func:`_regions`). A
    region of one pixel is not cut, so a map whose energy sits in fewer pixels than ``count`` gives fewer lights.
    The powers add up to ∫ of the working map (the resampled map: ∫L dω kept to ~1e-4).

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    count : int
        The number of lights, 1 to :data:`MAX_POINT_LIGHTS`; any count, not only powers of two.
    rows : int, default 256
        Rows of the lat-long working grid (rows × 2·rows) the cuts are made on; ``env`` is resampled to it unless
        it already is a lat-long of that many rows.

    Returns
    -------
    list of PointLight
        At most ``count`` lights, one per region in the order the cuts leave them (not sorted by power), each at
        its region's energy centroid (a world-frame unit vector) with the region's RGB power ∫L dω.

    Raises
    ------
    UsageError
        ``count`` is not a whole number from 1 to :data:`MAX_POINT_LIGHTS` (:func:`check_count`).
    """
    check_count(count)
    work, rgb, energy = _working(env, rows)
    h, w = work.grid
    table = _table(energy)
    regions = _regions(work.grid, count, lambda region: _split(table, region, h),
                       lambda region: _sum(table, *region))
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


def variance_minimisation(env: EnvMap, count: int, rows: int = 256) -> list[PointLight]:
    """Viriyothai & Debevec's variance minimisation: ``count`` point lights, one per region of least-variance cuts.

    Split the lat-long map ``log2(count)`` times, every region by
    the cut (any row or column boundary inside it) that minimises the two halves' summed variance
    Σ e·((sin θ_m·(φ − φ̄))² + (θ − θ̄)²) — e the pixels' luminance power, θ_m each half's middle latitude, so
    distances are angles on the sphere near that latitude. A count that is not a power of two cuts its last
    level's regions of largest variance only (:func:`_regions`). One light per region at its energy centroid with
    the region's RGB power (Σ = ∫ of the working map). A region of one pixel, or one without energy, is not cut.

    Parameters
    ----------
    env : EnvMap
        The probe, linear RGB radiance in any layout; its luminance power drives the variance.
    count : int
        How many lights, from 1 to :data:`MAX_POINT_LIGHTS` (4096); a count between powers of two splits only the
        highest-variance regions of the last level.
    rows : int, default 256
        Height of the lat-long grid the variance tables are built on (width 2·rows).

    Returns
    -------
    list of PointLight
        Up to ``count`` directional lights (fewer where regions cannot be cut), listed region by region: direction
        the energy-weighted mean over the region (world frame, unit), power the region's RGB ∫L dω.

    Raises
    ------
    UsageError
        The count is a bool, not an integer, or outside 1..4096.
    """
    check_count(count)
    work, rgb, energy = _working(env, rows)
    h, w = work.grid
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = (np.arange(w) + 0.5) / w * 2 * np.pi
    tables = _Moments(energy, theta, phi)
    regions = _regions(work.grid, count, tables.split, lambda region: float(tables.variance(*region)))
    return [_light(work, rgb, energy, region) for region in regions]


class _Moments:
    """Summed-area tables of e, eφ, eφ², eθ, eθ² (float64): any region's variance in O(1), every cut of one side
    of a region in O(side)."""

    def __init__(self, energy: np.ndarray, theta: np.ndarray, phi: np.ndarray):
        t, p = theta[:, None], phi[None, :]
        self.h = energy.shape[0]
        self.e, self.ep, self.epp = _table(energy), _table(energy * p), _table(energy * p * p)
        self.et, self.ett = _table(energy * t), _table(energy * t * t)

    def variance(self, r0, r1, c0, c1):
        """Energy-weighted variance of the regions rows [r0, r1) × columns [c0, c1) (arrays broadcast)."""
        def box(table):
            return table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0]

        e = box(self.e)
        safe = np.where(e > 0, e, 1.0)
        across = box(self.epp) - box(self.ep) ** 2 / safe
        down = box(self.ett) - box(self.et) ** 2 / safe
        width = np.sin(np.pi * (np.asarray(r0) + r1) / 2 / self.h)
        return np.where(e > 0, np.maximum(width * width * across, 0.0) + np.maximum(down, 0.0), 0.0)

    def split(self, region):
        r0, r1, c0, c1 = region
        if r1 - r0 < 2 and c1 - c0 < 2 or self.variance(r0, r1, c0, c1) <= 0:
            return [region]
        best, cut = np.inf, None
        if c1 - c0 >= 2:
            cs = np.arange(c0 + 1, c1)
            cost = self.variance(r0, r1, c0, cs) + self.variance(r0, r1, cs, c1)
            k = int(np.argmin(cost))
            best, cut = cost[k], [(r0, r1, c0, int(cs[k])), (r0, r1, int(cs[k]), c1)]
        if r1 - r0 >= 2:
            rs = np.arange(r0 + 1, r1)
            cost = self.variance(r0, rs, c0, c1) + self.variance(rs, r1, c0, c1)
            k = int(np.argmin(cost))
            if cost[k] < best:
                cut = [(r0, int(rs[k]), c0, c1), (int(rs[k]), r1, c0, c1)]
        return cut


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
