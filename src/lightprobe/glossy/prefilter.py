"""GGX-prefiltered radiance cube mip chains: the environment term of the split-sum approximation engines ship.

Quantity: **radiance**, in the map's units. Mip level i of a chain holds, at each texel direction r, the mean of the
environment under the GGX lobe of roughness α_i with the normal and the view both along r (Karis 2013's n = v = r
assumption, the one Babylon.js, Filament and three.js prefilter with):

    P_α(r) = ∫ L(l) D_α(h) (r·l)⁺ dl / ∫ D_α(h) (r·l)⁺ dl,   h = (r + l)/|r + l|,

D_α the normalised GGX distribution with α = roughness² (the engines' "alphaG"). α = 0 is the mirror: the map itself.
Which α each level holds is the engine's choice, so it is an argument; :func:`babylon_alphas` gives Babylon's.

How it is computed: with n = v = r the kernel D_α(h)(r·l)⁺ depends on r·l alone, so each level is a convolution of
the map with a zonal kernel, one multiplication per spherical-harmonic band by the kernel's Legendre coefficient
(:mod:`lightprobe.glossy.zonal`, transforms by ``ducc0``). The brightest texels (a sun) are first taken out as point
sources (:func:`split_peaks`); the bounded rest is analysed once, on the source's own lat-long rings (another layout
is resampled, energy-conserving, to a lat-long first), up to the band the sharpest level needs; each level keeps
the bands whose coefficient is at least BAND_TOLERANCE of band 0 (at least MIN_BANDS) and is evaluated exactly at
its texels' directions. A peak's lobe is summed exactly where a level has few texels; on the big levels, exactly
within 2·NEAR_WIDTH·α of the peak, its smooth far part through the harmonics. Band 0 passes unchanged, so a uniform
map stays uniform; against brute-force integration over every source pixel each level is within 1 % in the median
texel and 5 % in the worst (tests/test_prefilter.py; benchmarks/bench_prefilter.py prints the table per level).

Frames: the chain is a :data:`~lightprobe.maps.layouts.CUBE` map (OpenGL face orientation) of the directions of
``frame``: texel direction d shows the world direction ``frame.to_world(d)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..maps import EnvMap, box_reduce, resample
from ..util.errors import UsageError
from ..maps.frames import WORLD, Frame
from ..maps.layouts import CUBE, LATLONG
from ..util.progress import track

MAX_SIZE = 1024
DEFAULT_SAMPLES = 128  # GGX samples per texel: past 64 the chain moves by under 1 % (tests)
DIRECT_BUDGET = 4e8  # kernel evaluations below which a level is summed exactly instead of sampled
DEFAULT_PEAKS = 1024  # brightest texels summed exactly (see split_peaks)
BAND_TOLERANCE = 3e-3  # kernel coefficient below which a level drops the bands (bench_prefilter: worst texel < 4 %)
PEAK_PAIRS = 2e7  # (texel, peak) pairs up to which a level sums the peaks' whole lobes directly
NEAR_WIDTH = 4.0  # a peak's lobe is summed exactly within 2·NEAR_WIDTH·α of it, the smooth rest in harmonics
MIN_BANDS = 64  # a wide lobe's kink at r·l = 0 decays as a power, not e^(−2αl): it keeps this many bands at least
LOD_BIAS = 1.0  # Křivánek & Colbert's +1: one level blurrier than the sample's solid angle, against aliasing


@dataclass(frozen=True)
class PrefilteredCube:
    """A GGX mip chain: ``levels[i]`` is a (6, s_i, s_i, 3) float32 radiance cube, s_i = size >> i, prefiltered with
    roughness ``alphas[i]`` (α = roughness²), in the directions of ``frame`` (OpenGL cube-face orientation)."""

    levels: tuple[np.ndarray, ...]
    alphas: tuple[float, ...]
    frame: Frame

    @property
    def size(self) -> int:
        """The face size of level 0 (texels across, the ``size`` given to :func:`prefilter_cube`)."""
        return self.levels[0].shape[1]


def babylon_alphas(size: int, lod_generation_scale: float = 0.8, lod_generation_offset: float = 0.0) -> list[float]:
    """The α of each mip of a ``size`` cube as Babylon.js reads it; level 0 is the mirror (α = 0).

    Babylon's shader picks lod = log₂(size·α)·scale + offset, the inverse of what its HDRFiltering writes:
    α_i = 2^((i − offset)/scale)/size. Babylon's own prefilter and ``.env`` files use scale 0.8; its glTF loader sets
    scale = (levels − 1)/log₂ size (1 for a full chain).

    Parameters
    ----------
    size : int
        Face size of level 0 in texels, a power of two.
    lod_generation_scale : float, default 0.8
        Babylon's ``lodGenerationScale``.
    lod_generation_offset : float, default 0.0
        Babylon's ``lodGenerationOffset``.

    Returns
    -------
    list of float
        log₂(size) + 1 values of α (= roughness²), one per level from ``size`` down to 1×1, the first 0.
    """
    levels = int(math.log2(size)) + 1
    return [0.0] + [2.0 ** ((i - lod_generation_offset) / lod_generation_scale) / size for i in range(1, levels)]


def ggx_d(cos_h: np.ndarray, alpha: float) -> np.ndarray:
    """Normalised GGX (Trowbridge–Reitz) distribution D(h) for cos θ_h, ∫ D (n·h) dω_h = 1.

    Unlike :func:`lightprobe.glossy.brdf.ggx_d`, it does not set D to 0 for cos θ_h ≤ 0: the callers pass half vectors
    of the upper hemisphere.

    Parameters
    ----------
    cos_h : numpy.ndarray
        cos θ_h = n·h, any shape.
    alpha : float
        The GGX width α (α = roughness²), > 0.

    Returns
    -------
    numpy.ndarray
        D (sr⁻¹), the shape of ``cos_h``.
    """
    a2 = alpha * alpha
    t = cos_h * cos_h * (a2 - 1) + 1
    return a2 / (np.pi * t * t)


def hammersley(count: int) -> np.ndarray:
    """``count`` points of the Hammersley set on [0, 1)²: ((i + ½)/N, radical inverse of i in base 2).

    Parameters
    ----------
    count : int
        N, the number of points.

    Returns
    -------
    numpy.ndarray
        (N, 2) float64 points, i = 0 … N − 1 in order.
    """
    i = np.arange(count, dtype=np.uint32)
    bits = i.copy()
    bits = ((bits << 16) | (bits >> 16)) & 0xFFFFFFFF
    bits = ((bits & 0x55555555) << 1) | ((bits & 0xAAAAAAAA) >> 1)
    bits = ((bits & 0x33333333) << 2) | ((bits & 0xCCCCCCCC) >> 2)
    bits = ((bits & 0x0F0F0F0F) << 4) | ((bits & 0xF0F0F0F0) >> 4)
    bits = ((bits & 0x00FF00FF) << 8) | ((bits & 0xFF00FF00) >> 8)
    return np.stack([(i + 0.5) / count, bits.astype(np.float64) / 2.0 ** 32], axis=-1)


def tangent_frames(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (t, b) completing each unit normal n to a right-handed basis: t × b = n.

    Without a branch that flips at the equator (Duff et al. 2017): the construction of
    :func:`lightprobe.glossy.brdf.tangent_frame`, here giving the local frame of each lobe about its direction r.

    Parameters
    ----------
    n : numpy.ndarray
        (..., 3) unit vectors (the texel directions r in :func:`prefilter_cube`), in any frame.

    Returns
    -------
    tuple of numpy.ndarray
        t and b, each (..., 3) float64, perpendicular to n and to each other.
    """
    sign = np.where(n[..., 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], axis=-1)
    s = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], axis=-1)
    return t, s


def ggx_half_vectors(alpha: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` half vectors in the local frame (z = normal) distributed as D(h)(n·h), and their cos θ_h.

    The :func:`hammersley` points mapped through the inverse CDF: cos θ_h = √((1 − ξ₀)/(1 + (α² − 1) ξ₀)), azimuth
    2π ξ₁. Deterministic: the same α and count give the same vectors.

    Parameters
    ----------
    alpha : float
        The GGX width α (α = roughness²).
    count : int
        The number of half vectors.

    Returns
    -------
    h : numpy.ndarray
        (count, 3) float64 unit half vectors, z ≥ 0.
    cos_h : numpy.ndarray
        (count,) float64 their z, cos θ_h.
    """
    xi = hammersley(count)
    cos_h = np.sqrt((1 - xi[:, 0]) / (1 + (alpha * alpha - 1) * xi[:, 0]))
    sin_h = np.sqrt(np.maximum(0.0, 1 - cos_h ** 2))
    phi = 2 * np.pi * xi[:, 1]
    return np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=-1), cos_h


def box_pyramid(cube: EnvMap) -> list[EnvMap]:
    """The box-filtered pyramid of a cube map, finest first (each level's ∫L dω is the same).

    Each level halves the faces (:func:`lightprobe.maps.resampling.resampler.box_reduce`) down to 1×1.

    Parameters
    ----------
    cube : lightprobe.maps.EnvMap
        A :data:`~lightprobe.maps.layouts.CUBE` map whose face size is a power of two.

    Returns
    -------
    list of lightprobe.maps.EnvMap
        ``cube`` itself, then each halving, log₂(size) + 1 maps in all.

    Raises
    ------
    lightprobe.util.errors.LayoutError
        When a halving meets an odd face size (the face size is not a power of two).
    """
    levels = [cube]
    while levels[-1].grid[-1] > 1:
        levels.append(box_reduce(levels[-1]))
    return levels


def _direct_level(pyramid: list[EnvMap], alpha: float, outputs: int) -> EnvMap | None:
    """The pyramid level fine enough to sum P_α over directly (texels under α/4 across and at least 16 per face
    edge), if that costs at most DIRECT_BUDGET kernel evaluations for ``outputs`` texels; else None."""
    for level in reversed(pyramid):
        if np.pi / 2 / level.grid[-1] <= alpha / 4 and level.grid[-1] >= min(16, pyramid[0].grid[-1]):
            return level if outputs * level.data[..., 0].size <= DIRECT_BUDGET else None
    return None


def _sampled(r: np.ndarray, samplers: list, pyramid: list[EnvMap], alpha: float, samples: int) -> np.ndarray:
    """P_α at unit directions r (n, 3): the lobe within θ_c of r by filtered importance sampling of the pyramid
    (``samplers``, finest first), the rest by a direct sum over a coarse level with θ_c three of its texels.

    Importance samples of a narrow lobe rarely land in its long tail, yet a bright region 20° away still supplies a
    good part of the value there; a coarse level resolves that smooth far field exactly. Both halves are unnormalised
    estimates of ∫ D (r·l)⁺ L dl, divided by the same estimates for L = 1, so a uniform map stays uniform."""
    far = _far_level(pyramid, len(r))
    cos_c = np.cos(3 * np.pi / 2 / far.grid[-1])
    t, b = tangent_frames(r)
    local, cos_h = ggx_half_vectors(alpha, samples)
    # n = v = r: the pdf of l is D(h)(n·h)/(4 v·h) = D(h)/4, so each sample's weight D (r·l) / pdf is 4 (r·l); it
    # stands for a solid angle 1/(K pdf), looked up at the pyramid level of texels that size
    texel = 4 * np.pi / (6 * pyramid[0].grid[-1] ** 2)
    pdf = np.maximum(ggx_d(cos_h, alpha) / 4, 1e-30)
    lods = np.clip(0.5 * np.log2(1 / (samples * pdf) / texel) + LOD_BIAS, 0, len(samplers) - 1)
    total, weights = np.zeros((len(r), 3)), np.zeros(len(r))
    for k in range(samples):
        h = local[k, 0] * t + local[k, 1] * b + local[k, 2] * r
        l = 2 * np.sum(r * h, axis=-1)[:, None] * h - r  # noqa: E741 - the mirror of r about h
        cos_l = np.sum(r * l, axis=-1)
        w = np.where(cos_l >= cos_c, 4 * np.maximum(cos_l, 0.0) / samples, 0.0)
        lo = int(lods[k])
        f = lods[k] - lo
        value = samplers[lo](l) * (1 - f)
        if f > 0:
            value = value + samplers[min(lo + 1, len(samplers) - 1)](l) * f
        total += w[:, None] * value
        weights += w
    far_total, far_weights = _kernel_sums(r, far, alpha, below=cos_c)
    return (total + far_total) / np.maximum(weights + far_weights, 1e-300)[:, None]


def _far_level(pyramid: list[EnvMap], outputs: int) -> EnvMap:
    """The finest pyramid level a direct sum over ``outputs`` texels can afford (DIRECT_BUDGET evaluations)."""
    for level in pyramid:
        if outputs * level.data[..., 0].size <= DIRECT_BUDGET:
            return level
    return pyramid[-1]


def _kernel_sums(r: np.ndarray, level: EnvMap, alpha: float, below: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Σ_j D_α(h_j) (r·l_j)⁺ L_j dω_j and Σ_j D_α(h_j) (r·l_j)⁺ dω_j over the texels of ``level`` with r·l_j < below
    (all of them by default), for unit r (n, 3)."""
    d = level.directions().reshape(-1, 3)
    omega = level.solid_angles().reshape(-1)
    return _lobe_sums(r, d, omega, level.data.reshape(-1, 3), alpha, below)


def _lobe_sums(r, d, omega, values, alpha, below=2.0) -> tuple[np.ndarray, np.ndarray]:
    from ..maps.lookups import ggx_lobe_sums  # numba loads with the first kernel, not with the package

    out = np.empty((len(r), 4))
    ggx_lobe_sums(np.ascontiguousarray(r, np.float64), np.ascontiguousarray(d.T, np.float32),
                  np.ascontiguousarray(omega, np.float32), np.ascontiguousarray(values.T, np.float32),
                  float(alpha), float(below), out)
    return out[:, :3], out[:, 3]


def lobe_integral(alpha: float) -> float:
    """W(α) = ∫ D_α(h) (r·l)⁺ dω_l, the normaliser of P_α (the same for every r).

    1-D Gauss–Legendre quadrature in the angle θ between r and l, on a grid fine near 0 where the lobe lives.

    Parameters
    ----------
    alpha : float
        The GGX width α (α = roughness²), > 0.

    Returns
    -------
    float
        W(α), dimensionless (D in sr⁻¹ times solid angle).
    """
    x, w = np.polynomial.legendre.leggauss(64)
    edges = np.concatenate([[0.0], np.geomspace(max(alpha, 1e-6) * 1e-3, np.pi / 2, 48)])
    total = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        theta = 0.5 * (b - a) * x + 0.5 * (a + b)
        f = ggx_d(np.cos(theta / 2), alpha) * np.cos(theta) * np.sin(theta)
        total += 0.5 * (b - a) * float(f @ w)
    return 2 * np.pi * total


def split_peaks(cube: EnvMap, count: int) -> tuple[EnvMap, np.ndarray, np.ndarray]:
    """``cube`` = clipped + peaks: the excess over a threshold kept as at most ``count`` point sources.

    Every channel is clipped at the (count+1)-th largest pixel maximum; the excess is kept as point sources
    (directions (m, 3), RGB power L·dω (m, 3)).

    The GGX tails reach far: 20° from a sun, a lobe of α = 0.04 still takes a third of its value from the sun, which
    K importance samples hit too rarely. The peaks are summed exactly instead, the bounded rest sampled.

    Parameters
    ----------
    cube : lightprobe.maps.EnvMap
        The map, radiance, world frame; any layout (in practice the working cube).
    count : int
        The most pixels taken as peaks; ≤ 0, or not fewer than the map's pixels, takes none.

    Returns
    -------
    clipped : lightprobe.maps.EnvMap
        The bounded rest, float32, in ``cube``'s layout (``cube`` itself when no peak is taken).
    directions : numpy.ndarray
        (m, 3) float64 unit directions of the peaks' pixel centres, world frame (m ≤ ``count``).
    power : numpy.ndarray
        (m, 3) float64 RGB power of each peak, the excess radiance times the pixel's solid angle (L·dω).
    """
    data = cube.data.reshape(-1, 3)
    peak = np.maximum(np.maximum(data[:, 0], data[:, 1]), data[:, 2])
    if count <= 0 or len(peak) <= count:
        return cube, np.zeros((0, 3)), np.zeros((0, 3))
    # float32 throughout: the map's own precision, and no float64 copy of a large map (the bake's peak memory)
    threshold = np.partition(peak, len(peak) - count - 1)[len(peak) - count - 1]
    hot = np.flatnonzero(peak > threshold)
    del peak
    excess = data[hot].astype(np.float64) - float(threshold)
    np.maximum(excess, 0.0, out=excess)
    power = excess * _solid_angles_at(cube, hot)[:, None]
    clipped = EnvMap(np.minimum(cube.data, threshold), cube.layout)
    return clipped, _directions_at(cube, hot), power


def _solid_angles_at(env: EnvMap, flat: np.ndarray) -> np.ndarray:
    """The solid angles of the pixels at row-major ``flat`` indices (a lat-long's without a per-pixel table)."""
    if env.layout == LATLONG:
        return LATLONG.solid_angles_of(env.grid, flat)
    return env.solid_angles().reshape(-1)[flat]


def _directions_at(env: EnvMap, flat: np.ndarray) -> np.ndarray:
    """The unit directions (world frame) of the pixels at row-major ``flat`` indices."""
    if env.layout == LATLONG:
        from .zonal import latlong_directions

        return latlong_directions(env.grid, flat)
    return env.directions().reshape(-1, 3)[flat]


def _peak_sums(r: np.ndarray, directions: np.ndarray, power: np.ndarray, alpha: float) -> np.ndarray:
    """Σ_j D_α(h_j) (r·l_j)⁺ Φ_j / W(α) over point sources (directions l_j, power Φ_j), for unit r (n, 3)."""
    if not len(directions):
        return np.zeros((len(r), 3))
    total, _ = _lobe_sums(r, directions, np.ones(len(directions)), power, alpha)
    return total / _lobe_integral(float(alpha))


@lru_cache(maxsize=256)
def _lobe_integral(alpha: float) -> float:
    return lobe_integral(alpha)


def prefilter_cube(env: EnvMap, size: int, alphas: list[float] | None = None, frame: Frame = WORLD,
                   samples: int = DEFAULT_SAMPLES, peaks: int = DEFAULT_PEAKS,
                   tolerance: float = BAND_TOLERANCE) -> PrefilteredCube:
    """The GGX mip chain of ``env`` (radiance): a ``size`` cube and one level per halving down to 1×1.

    Level i is prefiltered with ``alphas[i]`` (default :func:`babylon_alphas`), in the directions of ``frame``.
    Level 0 (α = 0) is the source resampled (energy-conserving) into a cube of ``size`` in ``frame``: the mirror
    image. Every level of α > 0 is P_α of the source map itself (see the module docstring): the brightest ``peaks``
    pixels summed exactly as point sources (:func:`split_peaks`), the rest convolved with the GGX kernel in spherical
    harmonics up to the band where the kernel's coefficient falls below ``tolerance``.

    Parameters
    ----------
    env : lightprobe.maps.EnvMap
        The environment, radiance, any layout, world frame.
    size : int
        Face size of level 0 in texels: a power of two, at most MAX_SIZE (1024).
    alphas : list of float, optional
        One α (= roughness², ≥ 0 and below 1000) per level, log₂(size) + 1 of them; α = 0 is the mirror (the source
        cube box-reduced to the level's size). Default :func:`babylon_alphas` of ``size``.
    frame : lightprobe.maps.frames.Frame, default WORLD
        The frame of the cube's directions: texel direction d shows the world direction ``frame.to_world(d)``.
    samples : int, default DEFAULT_SAMPLES (128)
        Unused by the harmonic method (exact to its band limit); kept so callers that pass it need no change.
    peaks : int, default DEFAULT_PEAKS
        The brightest pixels summed exactly as point sources (:func:`split_peaks`).
    tolerance : float, default BAND_TOLERANCE
        A level keeps the bands whose normalised kernel coefficient is at least this (:func:`~lightprobe.glossy.zonal.
        kernel_band_limit`), up to what the source's pixels hold.

    Returns
    -------
    PrefilteredCube
        ``levels[i]`` a (6, size >> i, size >> i, 3) float32 radiance cube (OpenGL face orientation), with
        ``alphas`` and ``frame``.

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``size`` not a power of two or above MAX_SIZE; ``alphas`` not one per level, or one outside [0, 1000).
    """
    alphas, source = _checked(size, alphas), _mirror(env, size, frame)
    spectrum, limits, peak_dirs, peak_power = _harmonics(env, [a for a in alphas if a > 0], peaks, tolerance)
    turned = None if np.array_equal(frame.to_frame, np.eye(3)) else frame
    levels = []
    for i, alpha in track(list(enumerate(alphas)), "prefiltering GGX mips"):
        s = size >> i
        if alpha == 0:
            levels.append(source.data if i == 0 else box_reduce_to(source, s).data)
            continue
        r = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
        r = r if turned is None else frame.to_world(r)
        coeffs, far, inner = limits[alpha]
        if far is None or len(r) * len(peak_dirs) <= PEAK_PAIRS:  # few pairs: every peak's whole lobe, exactly
            value = spectrum.convolved_at(coeffs, r) + _peak_sums(r, peak_dirs, peak_power, alpha)
        else:
            value = spectrum.convolved_at(coeffs, r, far) + _near_peak_sums(r, peak_dirs, peak_power, alpha, inner)
        levels.append(value.reshape(6, s, s, 3).astype(np.float32))
    return PrefilteredCube(tuple(levels), tuple(float(a) for a in alphas), frame)


def _mirror(env: EnvMap, size: int, frame: Frame) -> EnvMap:
    """The mirror level: ``env`` resampled (energy-conserving) into a ``size`` cube in ``frame``, or itself if it is
    one."""
    same = env.layout == CUBE and env.grid[-1] == size and np.array_equal(frame.to_frame, np.eye(3))
    return env if same else resample(env, CUBE, size, rotation=frame.to_frame)


def _checked(size: int, alphas: list[float] | None) -> list[float]:
    """``alphas`` (default :func:`babylon_alphas`) once ``size`` and they are valid; else UsageError."""
    if size < 1 or size & (size - 1):
        raise UsageError(f"a prefiltered cube needs a power-of-two size, got {size}")
    if size > MAX_SIZE:
        raise UsageError(f"prefiltered cube size must be at most {MAX_SIZE}, got {size}")
    alphas = babylon_alphas(size) if alphas is None else list(alphas)
    count = int(math.log2(size)) + 1
    if len(alphas) != count or any(not (0 <= a < 1e3) for a in alphas):
        raise UsageError(f"a {size} cube has {count} mip levels: give as many roughness values (α ≥ 0)")
    return alphas


def _harmonics(env: EnvMap, alphas: list[float], peaks: int, tolerance: float):
    """The spectrum of ``env`` less its peaks, each α's kernel coefficients cut at its band limit, and the peaks.

    The working lat-long is the source itself when it is one no finer than twice the widest band limit needs (its
    pixel centres are the transform's rings), else the source resampled (energy-conserving) to that: twice, so the
    pixels' own averaging moves the kept bands by little."""
    from .zonal import Spectrum, ggx_legendre, kernel_band_limit, tail_band_limit

    if not alphas:
        return None, {}, np.zeros((0, 3)), np.zeros((0, 3))
    clipped, peak_dirs, peak_power = split_peaks(env, peaks)
    rows = clipped.grid[0] if clipped.layout == LATLONG else max(2, int(math.sqrt(clipped.data[..., 0].size / 2)))
    cap = max(1, rows - 1)
    limits = {}
    for a in set(alphas):
        # a band past 10/α carries under 1e-5 of a GGX kernel (its coefficients fall as e^(−2αl) past the peak)
        whole = ggx_legendre(float(a), min(cap, int(10 / a) + MIN_BANDS))
        coeffs = whole[:min(max(kernel_band_limit(whole, tolerance), MIN_BANDS), len(whole) - 1) + 1]
        inner = NEAR_WIDTH * a
        far = None if 2 * inner >= np.pi / 2 else ggx_legendre(float(a), len(coeffs) - 1, inner)
        limits[a] = (coeffs, far, inner)
    need = max(len(c[0]) - 1 for c in limits.values())
    # the far parts are smooth: their bands die out long before the whole kernels' (the points' transform is cheap)
    point_lmax = max([tail_band_limit(c[1], tolerance * 1e-3) for c in limits.values() if c[1] is not None] or [0])
    if clipped.layout != LATLONG or rows > 4 * (need + 1):
        rows = min(rows, 2 * (need + 1))
        clipped = resample(clipped, LATLONG, rows)
    spectrum = Spectrum(clipped.data, min(need, rows - 1, (2 * rows - 1) // 2))
    del clipped
    spectrum.add_points(peak_dirs, peak_power, point_lmax)
    return spectrum, limits, peak_dirs, peak_power


def _near_peak_sums(r: np.ndarray, directions: np.ndarray, power: np.ndarray, alpha: float,
                    inner: float) -> np.ndarray:
    """Σ_j D_α(h_j)(r·l_j)⁺ w(θ_j) Φ_j / W(α) over the point sources within 2·``inner`` of each r: the near part of
    their lobe (w = 1 − :func:`~lightprobe.glossy.zonal.far_window`; the far part is in the harmonics). The pairs
    come from a k-d tree of the directions r, so the cost is the pairs', not len(r) × len(directions)."""
    from scipy.spatial import cKDTree

    from .zonal import far_window

    out = np.zeros((len(r), 3))
    if not len(directions):
        return out
    reach = 2 * np.sin(inner)  # the chord of 2·inner
    pairs = cKDTree(r).sparse_distance_matrix(cKDTree(directions), reach, output_type="ndarray")
    if not len(pairs):
        return out
    texel, source = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
    cos_l = np.clip(np.einsum("ij,ij->i", r[texel], directions[source]), -1.0, 1.0)
    theta = np.arccos(cos_l)
    weight = ggx_d(np.sqrt((1 + cos_l) / 2), alpha) * np.maximum(cos_l, 0.0) * (1 - far_window(theta, inner))
    for c in range(3):
        out[:, c] = np.bincount(texel, weight * power[source, c], minlength=len(r))
    return out / _lobe_integral(float(alpha))


def _prefilter_sampled(env: EnvMap, size: int, alphas: list[float] | None = None, frame: Frame = WORLD,
                       samples: int = DEFAULT_SAMPLES, peaks: int = DEFAULT_PEAKS) -> PrefilteredCube:
    """:func:`prefilter_cube` by direct sums and filtered importance sampling over the working cube's box pyramid
    (peaks split out): the method before the spherical-harmonic one, kept as the benchmarks' baseline
    (benchmarks/bench_prefilter.py). Same arguments, conventions and result."""
    alphas, source = _checked(size, alphas), _mirror(env, size, frame)
    clipped, peak_dirs, peak_power = split_peaks(source, peaks)
    pyramid = box_pyramid(clipped)
    samplers = None
    levels = []
    for i, alpha in track(list(enumerate(alphas)), "prefiltering GGX mips"):
        s = size >> i
        if alpha == 0:
            levels.append(source.data if i == 0 else box_reduce_to(source, s).data)
            continue
        r = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
        direct = _direct_level(pyramid, alpha, len(r))
        if direct is not None:
            total, weights = _kernel_sums(r, direct, alpha)
            value = total / np.maximum(weights, 1e-300)[:, None]
        else:
            samplers = samplers or [CUBE.sampler(level.data) for level in pyramid]
            value = _sampled(r, samplers, pyramid, alpha, samples)
        value += _peak_sums(r, peak_dirs, peak_power, alpha)
        levels.append(value.reshape(6, s, s, 3).astype(np.float32))
    return PrefilteredCube(tuple(levels), tuple(float(a) for a in alphas), frame)


def brute_force_prefiltered(env: EnvMap, r: np.ndarray, alpha: float) -> np.ndarray:
    """P_α at unit directions ``r`` by direct summation over every pixel of ``env``: the reference for the chains.

    Plain numpy, independent of the compiled and sampled sums :func:`prefilter_cube` uses; exact up to the map's own
    pixel size (a lobe narrower than a pixel sees the pixel). Costs len(r) × pixels kernel evaluations.

    Parameters
    ----------
    env : EnvMap
        Radiance, any layout; ``r`` is in the frame of its directions.
    r : numpy.ndarray
        (n, 3) unit directions (normal = view = r).
    alpha : float
        GGX α = roughness², > 0.

    Returns
    -------
    numpy.ndarray
        (n, 3) float64 prefiltered radiance P_α(r) (the module docstring's definition).
    """
    d = env.directions().reshape(-1, 3)
    omega = env.solid_angles().reshape(-1)
    values = env.data.reshape(-1, 3).astype(np.float64)
    out = np.empty((len(r), 3))
    chunk = max(1, (1 << 22) // len(d))  # directions per pass: the (chunk, pixels) temporaries stay ~100 MB
    for start in range(0, len(r), chunk):
        rr = r[start:start + chunk]
        c = rr @ d.T  # r·l
        # n = v = r, so r·h = (1 + r·l)/|r + l| = √((1 + r·l)/2): no half vector need be formed (at l = −r, where h
        # is undefined, (r·l)⁺ is 0 and so is the weight)
        cos_h = np.sqrt(np.clip(0.5 * (1.0 + c), 0.0, 1.0))
        w = ggx_d(cos_h, alpha) * np.maximum(c, 0.0) * omega
        out[start:start + chunk] = (w @ values) / np.maximum(w.sum(axis=1), 1e-30)[:, None]
    return out


def prefilter_memory(size: int) -> int:
    """Bytes :func:`prefilter_cube` needs at most for a ``size`` cube, beyond the map and the process.

    The float32 source, its clipped copy, pyramid and chain (about 60 bytes per texel), the sampled level 1's float64
    working vectors (about 24 of 3 × 8 bytes per texel) and 64 MiB for the compiled kernels' threads. Measured beyond a
    plain ``export`` (190 MiB): +104 MiB at 256, +333 MiB at 512; this says 144 and 384.

    Parameters
    ----------
    size : int
        Face size of the chain's level 0, in texels.

    Returns
    -------
    int
        The estimate in bytes.
    """
    texels = 6 * size * size
    return texels * 60 + (texels // 4) * 3 * 8 * 24 + (64 << 20)


def box_reduce_to(cube: EnvMap, size: int) -> EnvMap:
    """The cube box-reduced to faces of ``size`` (a power-of-two fraction of its own).

    Each halving keeps ∫L dω; a cube already at most ``size`` across is returned as it is.

    Parameters
    ----------
    cube : lightprobe.maps.EnvMap
        A cube map, radiance.
    size : int
        The face size wanted, in texels: the cube's own divided by a power of two.

    Returns
    -------
    lightprobe.maps.EnvMap
        The reduced cube (``cube`` itself when no halving is needed).
    """
    while cube.grid[-1] > size:
        cube = box_reduce(cube)
    return cube
