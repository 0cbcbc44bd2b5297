"""An environment map as circular area lights plus an ambient remainder (Arbree, Walter & Bala 2005; docs/spec.md §5).

Quantities: lights are in the **world frame** (docs/spec.md §1: +Y up, front −Z). A light's ``power`` is ∫L dω over
the pixels it took (RGB, radiance × steradians: the same unit as :meth:`lightprobe.maps.EnvMap.integral`), its
``radiance`` that power over its cap's solid angle. The ambient map is the original map, same layout and grid, with
the lights' pixels set to zero — so Σ light power + ∫ ambient dω = ∫ original dω per channel, to float rounding.

How it is fast: the centre–surround responses need the luminance ∫ over caps of 40 radii (20 filter sizes, inner and
outer) around every candidate. On a lat-long working grid each row meets a cap in one azimuth interval
(cos γ = cos θ cos θ_c + sin θ sin θ_c cos Δφ), so a cap sum is one difference of the row's prefix sums per row —
exact for "the pixels whose centres lie in the cap", O(rows) per cap instead of O(pixels). After an extraction only
the candidates within reach of it are recomputed. The lights' pixels and powers are taken from the original map with
its own solid angles, so the layout the probe came in does not change the bookkeeping.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..util import limits
from ..maps import EnvMap, owned
from ..util.errors import UsageError
from ..util.jit import njit
from ..maps.layouts import LATLONG
from ..maps.tonemap import luminance


@dataclass(frozen=True)
class LightParams:
    """The decomposition's parameters; the defaults are the paper's (docs/spec.md §5)."""

    inner_ratio: float = 0.75  # r_i / r_o
    surround_weight: float = 10.0  # the annulus's weight is −surround_weight, the inner cap's +1
    sizes: int = 20  # filter sizes, angular extents 2 r_o in geometric steps …
    min_extent_deg: float = 4.5  # … from this …
    max_extent_deg: float = 45.0  # … to this
    candidate_fraction: float = 0.10  # candidate centres: the brightest fraction of working pixels
    stop_fraction: float = 0.02  # stop when a light has under this share of the lights found before it
    max_lights: int = 256  # a bound on the loop (the stopping rule ends it long before on real maps)
    working_rows: int = 256  # the lat-long working grid (working_rows × 2·working_rows) the responses use

    def check(self) -> None:
        """Refuse parameters outside their ranges, naming every bad one in one message.

        The ranges: 0 < inner ratio < 1; 0 ≤ surround weight ≤ 10⁶; 1 to 200 filter sizes;
        0 < min extent ≤ max extent ≤ 180°; 0 < candidate fraction ≤ 1; 0 ≤ stop fraction < 1; 1 to 10000 lights;
        a working grid of 16 to 4096 rows.

        Raises
        ------
        UsageError
            One or more parameters are out of range.
        """
        bad = []
        if not 0 < self.inner_ratio < 1:
            bad.append(f"inner ratio {self.inner_ratio} (must be in (0, 1))")
        if not 0 <= self.surround_weight <= 1e6:
            bad.append(f"surround weight {self.surround_weight}")
        if not 1 <= self.sizes <= 200:
            bad.append(f"{self.sizes} filter sizes (1 to 200)")
        if not 0 < self.min_extent_deg <= self.max_extent_deg <= 180:
            bad.append(f"filter extents {self.min_extent_deg}°–{self.max_extent_deg}° (0 < min ≤ max ≤ 180)")
        if not 0 < self.candidate_fraction <= 1:
            bad.append(f"candidate fraction {self.candidate_fraction} (0 to 1)")
        if not 0 <= self.stop_fraction < 1:
            bad.append(f"stop fraction {self.stop_fraction} (0 to 1)")
        if not 1 <= self.max_lights <= 10_000:
            bad.append(f"at most {self.max_lights} lights (1 to 10000)")
        if not 16 <= self.working_rows <= 4096:
            bad.append(f"working grid of {self.working_rows} rows (16 to 4096)")
        if bad:
            raise UsageError("bad light-extraction parameters: " + "; ".join(bad))

    def outer_radii(self) -> np.ndarray:
        """r_o of each filter size (radians): extents 2 r_o in geometric steps from min to max.

        Returns
        -------
        numpy.ndarray
            (sizes,) float64 outer radii in radians, from ``min_extent_deg``/2 to ``max_extent_deg``/2.
        """
        extents = np.geomspace(self.min_extent_deg, self.max_extent_deg, self.sizes)
        return np.radians(extents) / 2


@dataclass(frozen=True)
class AreaLight:
    """One circular light: ``direction`` (world, unit), ``radius`` (the cap's angular radius, radians),
    ``solid_angle`` of that cap (2π(1 − cos radius), sr), ``power`` (RGB ∫L dω over the pixels taken) and
    ``radiance`` (power / solid_angle)."""

    direction: np.ndarray
    radius: float
    solid_angle: float
    power: np.ndarray
    radiance: np.ndarray
    response: float  # the filter response that chose it (luminance per radian of filter extent)

    @property
    def yaw_elevation_deg(self) -> tuple[float, float]:
        """(yaw, elevation) of the light's direction in degrees (see :func:`yaw_elevation_deg`)."""
        return yaw_elevation_deg(self.direction)


def yaw_elevation_deg(direction: np.ndarray) -> tuple[float, float]:
    """Yaw (degrees, 0 at the front −Z, positive towards +X) and elevation (degrees above the horizon) of a direction.

    Parameters
    ----------
    direction : numpy.ndarray
        (3,) unit vector (x, y, z) in the world frame (+Y up, front −Z).

    Returns
    -------
    tuple of (float, float)
        Yaw in [−180°, 180°] and elevation in [−90°, 90°].
    """
    x, y, z = direction
    return math.degrees(math.atan2(x, -z)), math.degrees(math.asin(max(-1.0, min(1.0, float(y)))))


@dataclass
class Decomposition:
    """Lights found, in the order found, and the ambient map (the original with their pixels zeroed)."""

    lights: list[AreaLight]
    ambient: EnvMap
    params: LightParams
    total: np.ndarray  # ∫ original dω per channel
    timings: dict[str, float] = field(default_factory=dict)
    # the luminance power of the first light the stopping rule turned away, over that of the lights kept before it
    # (None when the search ended for another reason): how close the rule came to keeping one more
    rejected_share: float | None = None

    @property
    def light_power(self) -> np.ndarray:
        """Σ of the lights' RGB powers (∫L dω), (3,); zeros when there is no light."""
        return np.sum([light.power for light in self.lights], axis=0) if self.lights else np.zeros(3)


def decompose(env: EnvMap, params: LightParams | None = None) -> Decomposition:
    """Find the area lights of ``env`` (any layout) by the centre–surround search of docs/spec.md §5.

    They are returned with the ambient map. Deterministic; a map with nothing brighter than its surroundings gives
    no lights.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout (directions in the world frame).
    params : LightParams, optional
        The search's parameters; default the paper's (:class:`LightParams`).

    Returns
    -------
    Decomposition
        The lights in the order found (world frame, RGB power ∫L dω), the ambient (``env`` with their pixels set
        to 0, same layout and grid, float32), the parameters, ``total`` (∫ ``env`` dω per channel), ``timings``
        (``filter`` and ``extract``, seconds) and ``rejected_share``.

    Raises
    ------
    UsageError
        A parameter is out of range (:meth:`LightParams.check`).
    """
    params = params or LightParams()
    params.check()
    clock = {"start": time.perf_counter()}
    work = _working_grid(env, params.working_rows)
    grid = work.grid
    omega = env.solid_angles()
    dirs = env.directions()
    data = np.array(env.data, dtype=np.float32, copy=True)  # the ambient, as pixels are taken from it
    rows_y = np.maximum(luminance(work.data.astype(np.float64)), 0.0) * LATLONG.row_solid_angles(grid)[:, None]
    outer = params.outer_radii()
    inner = outer * params.inner_ratio
    radii = np.concatenate([inner, outer])
    prefix = _row_prefix(rows_y)
    theta = (np.arange(grid[0]) + 0.5) / grid[0] * np.pi
    cand_rows, cand_cols = _candidates(rows_y, params.candidate_fraction)
    cand_theta, cand_phi = theta[cand_rows], _column_phi(cand_cols, grid[1])
    cand_dirs = _unit(cand_theta, cand_phi)
    responses = np.zeros((cand_rows.size, params.sizes))
    _responses(prefix, theta, cand_rows, cand_cols, radii, inner, outer, params.surround_weight,
               np.arange(cand_rows.size), responses)
    clock["filter"] = time.perf_counter()

    lights: list[AreaLight] = []
    found_luminance, rejected = 0.0, None
    reach = float(outer.max() + inner.max())
    while len(lights) < params.max_lights and responses.size:
        best = int(np.argmax(responses))
        c, k = divmod(best, params.sizes)
        if not responses[c, k] > 0:
            break
        p, r = cand_dirs[c], float(inner[k])
        taken = (dirs @ p >= math.cos(r)) & (omega > 0)
        power = (data[taken].astype(np.float64) * omega[taken, None]).sum(axis=0)
        y = float(luminance(power))
        if lights and y < params.stop_fraction * found_luminance:
            rejected = y / found_luminance
            break  # this light is not kept
        data[taken] = 0.0
        solid = 2 * math.pi * (1 - math.cos(r))
        lights.append(AreaLight(p.copy(), r, solid, power, power / solid, float(responses[c, k])))
        found_luminance += y
        # the working grid loses the same cap; its rows' sums and the responses within reach are redone
        gone = _unit(*np.meshgrid(theta, _column_phi(np.arange(grid[1]), grid[1]), indexing="ij")) @ p >= math.cos(r)
        changed = np.nonzero(gone.any(axis=1))[0]
        rows_y[gone] = 0.0
        prefix[changed] = _row_prefix(rows_y[changed])
        near = np.nonzero(cand_dirs @ p >= math.cos(min(reach, math.pi)))[0]
        _responses(prefix, theta, cand_rows, cand_cols, radii, inner, outer, params.surround_weight, near,
                   responses)
    clock["extract"] = time.perf_counter()
    ambient = EnvMap(owned(data), env.layout)
    timings = {"filter": clock["filter"] - clock["start"], "extract": clock["extract"] - clock["filter"]}
    return Decomposition(lights, ambient, params, env.integral(), timings, rejected)


# ---- the working grid -----------------------------------------------------------------------------------------------
def _working_grid(env: EnvMap, rows: int) -> EnvMap:
    """The map resampled (energy-conservingly, :mod:`lightprobe.maps.resampling`) to a lat-long of ``rows`` ×
    2·rows — up as well as down: the smallest filter's inner cap (1.7° by default) must span several working
    pixels, or its sum counts one pixel or none and a uniform map shows spurious lights. A lat-long of that size
    is used as it is."""
    if env.layout == LATLONG and env.grid[0] == rows:
        return env
    if env.layout == LATLONG and env.grid[0] > rows and env.grid[0] % rows == 0 and \
            (env.grid[0] // rows) & (env.grid[0] // rows - 1) == 0:
        # a power-of-two multiple: exact 2×2 solid-angle-weighted means (∫L dω kept to rounding), ~40× faster
        # than the general resampler's footprint integration, which it equals where the map is smooth
        from ..maps.resampling.resampler import box_reduce

        while env.grid[0] > rows:
            env = box_reduce(env)
        return env
    return env.to(LATLONG, rows)


def _row_prefix(values: np.ndarray) -> np.ndarray:
    """Per row, the prefix sums with a leading 0: (rows, W + 1)."""
    out = np.zeros((values.shape[0], values.shape[1] + 1))
    np.cumsum(values, axis=1, out=out[:, 1:])
    return out


def _column_phi(cols: np.ndarray, w: int) -> np.ndarray:
    """Azimuth of column centres, as :data:`lightprobe.maps.layouts.LATLONG` maps them: φ = 2π((c + ½)/W − ½)."""
    return 2 * np.pi * ((np.asarray(cols) + 0.5) / w - 0.5)


def _unit(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """World directions of polar angle θ (from +Y) and azimuth φ (0 at −Z, towards +X)."""
    st = np.sin(theta)
    return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], axis=-1)


def _candidates(rows_y: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the brightest ``fraction`` of working pixels by luminance (∫Y dω over the pixel's solid
    angle; ties by index), brightest first; none if every pixel has the same luminance (nothing stands out)."""
    h, w = rows_y.shape
    y = (rows_y / LATLONG.row_solid_angles((h, w))[:, None]).ravel()
    if not y.size or y.max() <= y.min() * (1 + 1e-9):  # uniform, up to the rounding of ∫Y dω / dω
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    n = max(1, int(round(fraction * y.size)))
    order = np.argsort(-y, kind="stable")[:n]
    return np.divmod(order, w)


def _responses(prefix, theta, cand_rows, cand_cols, radii, inner, outer, weight, which, out) -> None:
    """out[which] = R_k of docs/spec.md §5 for the candidates ``which``: [I(r_i) − w (I(r_o) − I(r_i))] / (2 r_o)."""
    if which.size == 0:
        return
    # by row, so each row's interval table is built once (stable: equal rows keep their order)
    which = which[np.argsort(cand_rows[which], kind="stable")]
    sums = np.empty((which.size, radii.size))
    threads = min(limits.threads(), max(1, which.size // 256))
    step = -(-which.size // threads)
    rows, cols = np.ascontiguousarray(cand_rows[which]), np.ascontiguousarray(cand_cols[which])
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda s: cap_sums(prefix, theta, rows[s:s + step], cols[s:s + step], radii, sums[s:s + step]),
                      range(0, which.size, step)))
    n = inner.size
    inside, whole = sums[:, :n], sums[:, n:]
    out[which] = (inside - weight * (whole - inside)) / (2 * outer)[None, :]


@njit(cache=True, nogil=True, error_model="numpy")
def cap_sums(prefix, theta, cand_rows, cand_cols, radii, out):  # pragma: no cover - compiled
    """Sums of a lat-long's per-pixel values over caps of every radius around every candidate pixel, into ``out``.

    out[i, k] = Σ of a lat-long's per-pixel values over the pixels whose centres lie within angle radii[k] of the
    centre of pixel (cand_rows[i], cand_cols[i]). ``prefix`` (H, W + 1) holds each row's prefix sums;
    ``theta`` the rows' centre polar angles. Per row the cap is the azimuth interval
    |Δφ| ≤ arccos((cos r − cos θ cos θ_c) / (sin θ sin θ_c)) around the candidate's column; columns are counted by
    their centres. That interval's half-width depends only on the two rows, not on the column, so it is turned
    into integer column offsets once per candidate row (candidates sorted by row pay it once per row) and each cap
    is then two prefix-sum reads per row.

    Parameters
    ----------
    prefix : numpy.ndarray
        (H, W + 1) float64: each row's prefix sums of the lat-long's per-pixel values, with a leading 0.
    theta : numpy.ndarray
        (H,) polar angle of each row's centre, radians from +Y (row r at (r + ½)/H · π).
    cand_rows : numpy.ndarray
        (N,) int64 row of each candidate centre; sorted by row for speed.
    cand_cols : numpy.ndarray
        (N,) int64 column of each candidate centre.
    radii : numpy.ndarray
        (K,) float64 cap radii in radians.
    out : numpy.ndarray
        (N, K) float64, overwritten with the sums.
    """
    h, w = prefix.shape[0], prefix.shape[1] - 1
    nk = radii.shape[0]
    dphi = 2.0 * math.pi / w
    r_max = 0.0
    for k in range(nk):
        r_max = max(r_max, radii[k])
    cos_r = np.cos(radii)
    span = int(math.ceil(r_max / math.pi * h)) + 2
    lo_off = np.empty((2 * span + 1, nk), np.int64)  # per row of the band and radius: first and last column
    hi_off = np.empty((2 * span + 1, nk), np.int64)  # offsets (hi < lo: no pixel; hi − lo + 1 ≥ w: the whole row)
    current, first, last = -1, 0, -1
    for i in range(cand_rows.shape[0]):
        row_c = cand_rows[i]
        if row_c != current:
            current = row_c
            tc = theta[row_c]
            ct, st = math.cos(tc), math.sin(tc)
            first = max(0, int(math.floor((tc - r_max) / math.pi * h)))
            last = min(h - 1, int(math.ceil((tc + r_max) / math.pi * h)))
            for row in range(first, last + 1):
                c_row, s_row = math.cos(theta[row]), math.sin(theta[row])
                denom = s_row * st
                for k in range(nk):
                    if denom <= 1e-300:  # a pole: every pixel of a row is |θ − θ_c| from it
                        inside = abs(theta[row] - tc) <= radii[k]
                        lo_off[row - first, k], hi_off[row - first, k] = (0, w - 1) if inside else (1, 0)
                        continue
                    c = (cos_r[k] - c_row * ct) / denom
                    if c >= 1.0:
                        lo_off[row - first, k], hi_off[row - first, k] = 1, 0
                    elif c <= -1.0:
                        lo_off[row - first, k], hi_off[row - first, k] = 0, w - 1
                    else:
                        half = math.acos(c) / dphi
                        lo_off[row - first, k] = int(math.ceil(-half))
                        hi_off[row - first, k] = int(math.floor(half))
        col = cand_cols[i]
        for k in range(nk):
            out[i, k] = 0.0
        for row in range(first, last + 1):
            full = prefix[row, w]
            for k in range(nk):
                lo, hi = lo_off[row - first, k], hi_off[row - first, k]
                if hi < lo:
                    continue
                if hi - lo + 1 >= w:
                    out[i, k] += full
                    continue
                lo_w, hi_w = (col + lo) % w, (col + hi) % w  # the interval may wrap across the seam
                if lo_w <= hi_w:
                    out[i, k] += prefix[row, hi_w + 1] - prefix[row, lo_w]
                else:
                    out[i, k] += (full - prefix[row, lo_w]) + prefix[row, hi_w + 1]


# ---- the preview ----------------------------------------------------------------------------------------------------
OUTLINE = np.array([0.1, 1.0, 0.2])  # display-encoded colour of a light's cap outline


def preview(env: EnvMap, lights: list[AreaLight], rows: int = 256) -> np.ndarray:
    """The probe as a tone-mapped lat-long image with each light's cap outlined and its centre marked.

    The image is rows × 2·rows, display-encoded float RGB in [0, 1], at the exposure that maps the map's mean
    luminance to the key 0.18; a cap's outline is the pixels within half a pixel of its radius, drawn in
    :data:`OUTLINE`.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout (resampled to the lat-long).
    lights : list of AreaLight
        The lights to draw (world frame); anything with a ``direction`` and an angular ``radius`` in radians will
        do, such as a :class:`~lightprobe.lights.baselines.PointLight`, whose radius 0 shows as a dot.
    rows : int, default 256
        The image's height in pixels; its width is 2·rows.

    Returns
    -------
    numpy.ndarray
        (rows, 2·rows, 3) float64 display-encoded sRGB values in [0, 1].
    """
    from ..maps.tonemap import auto_exposure, tonemap

    work = env.to(LATLONG, rows)
    display = tonemap(work.data, auto_exposure(work.data, work.solid_angles())).astype(np.float64)
    dirs = _unit(*np.meshgrid((np.arange(rows) + 0.5) / rows * np.pi,
                              _column_phi(np.arange(2 * rows), 2 * rows), indexing="ij"))
    pitch = np.pi / rows
    for light in lights:
        angle = np.arccos(np.clip(dirs @ light.direction, -1.0, 1.0))
        ring = np.abs(angle - light.radius) <= 0.5 * pitch / np.maximum(np.sin(angle), 0.5)
        centre = angle <= 0.75 * pitch
        display[ring | centre] = OUTLINE
    return display
