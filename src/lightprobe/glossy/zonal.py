"""Convolution of a lat-long map with a zonal kernel through its spherical harmonics (``ducc0``'s transforms).

A kernel K(r·l) that depends only on the angle between the output direction r and the input direction l acts on the
spherical harmonics of a map one band at a time (the Funk–Hecke theorem): band l is multiplied by

    k_l = 2π ∫ K(cos θ) P_l(cos θ) sin θ dθ / 2π ∫ K(cos θ) sin θ dθ,

the kernel's Legendre coefficient, normalised so that k₀ = 1 (the kernel integrates to 1: band 0, the mean, passes
unchanged, and a uniform map stays uniform to rounding). The GGX lobe of the split sum, D(h)(r·l)⁺ with n = v = r,
is such a kernel (:func:`ggx_legendre`). The convolved map is evaluated exactly (to ``ducc0``'s stated ε) at any
directions, so the cube's texel directions in any frame need no second resampling.

Frames and layout: :class:`Spectrum` reads a :data:`~lightprobe.maps.layouts.LATLONG` map (y up, row 0 at the top,
pixel centres on Fejér's first-rule rings θ_i = (i + ½)π/H) and takes directions in the map's own (world) frame.
Quantity: whatever the map holds (radiance here), in its units.
"""

from __future__ import annotations

import math
import os
from functools import lru_cache

import numpy as np

PANEL_NODES = 16  # Gauss–Legendre nodes per panel of the coefficients' quadrature
PANEL_WIDTH = 8.0  # a panel's width times lmax, radians: 1.3 periods of P_lmax, exact for degree 31 in θ
SYNTHESIS_EPSILON = 1e-7  # ducc0's accuracy for the evaluation at arbitrary directions (relative to the map's scale)


def _threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


@lru_cache(maxsize=4)
def _gauss_legendre(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    return np.polynomial.legendre.leggauss(nodes)


def far_window(theta: np.ndarray, inner: float) -> np.ndarray:
    """1 − w(θ): 0 up to ``inner``, 1 from 2·``inner`` on, the C² step 6x⁵ − 15x⁴ + 10x³ between (x = θ/inner − 1).

    Splits a kernel into a near part K·w, of support θ < 2·inner, and a far part K·(1 − w) as smooth as K is past
    ``inner``, whose Legendre coefficients therefore fall off fast (:func:`ggx_legendre` with ``inner``).

    Parameters
    ----------
    theta : numpy.ndarray
        Angles between r and l, radians, any shape.
    inner : float
        Where the step starts, radians, > 0.

    Returns
    -------
    numpy.ndarray
        1 − w(θ) in [0, 1], float64, the shape of ``theta``.
    """
    x = np.clip(np.asarray(theta) / inner - 1.0, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)


@lru_cache(maxsize=64)
def ggx_legendre(alpha: float, lmax: int, inner: float = 0.0) -> np.ndarray:
    """The normalised Legendre coefficients k_0 … k_lmax of the split-sum GGX kernel D_α(h)(r·l)⁺ (n = v = r).

    With θ the angle between r and l, h is halfway, so cos θ_h = cos(θ/2), and the kernel is zero past θ = π/2.
    The integrals are Gauss–Legendre sums over panels fine near θ = 0 (where a narrow lobe lives: geometric from
    α/1000) and no wider than 8/lmax (16 nodes a panel then resolve P_lmax's oscillation: 1.3 periods); P_l by its three-term
    recurrence. Cached per (α, lmax, inner). With ``inner`` > 0 they are the coefficients of the far part
    K·(1 − w) (:func:`far_window`), still divided by the whole kernel's integral.

    Parameters
    ----------
    alpha : float
        The GGX width α (α = roughness²), > 0.
    lmax : int
        The last band, ≥ 0.
    inner : float, default 0.0
        0: the whole kernel; > 0: its far part past ``inner`` radians (:func:`far_window`).

    Returns
    -------
    numpy.ndarray
        (lmax + 1,) float64; for the whole kernel k_0 = 1, decreasing towards 0 as the band rises (faster the
        wider the lobe).
    """
    from .prefilter import ggx_d

    edges = np.unique(np.concatenate([[0.0], np.geomspace(max(alpha, 1e-6) * 1e-3, np.pi / 2, 48),
                                      np.linspace(0, np.pi / 2, int(math.ceil(np.pi / 2 * max(lmax, 1) / PANEL_WIDTH)) + 1)]))
    if inner > 0:
        edges = np.unique(np.concatenate([edges, np.linspace(inner, 2 * inner, 9)]))
        edges = edges[edges <= np.pi / 2]
    x, w = _gauss_legendre(PANEL_NODES)
    half = 0.5 * np.diff(edges)[:, None]
    theta = (half * x + 0.5 * (edges[:-1] + edges[1:])[:, None]).reshape(-1)
    mu = np.cos(theta)
    weight = (half * w).reshape(-1) * ggx_d(np.cos(theta / 2), alpha) * mu * np.sin(theta)
    total = weight.sum()
    if inner > 0:
        weight = weight * far_window(theta, inner)
    coeffs = np.empty(lmax + 1)
    p_prev, p = np.zeros_like(mu), np.ones_like(mu)
    for band in range(lmax + 1):
        coeffs[band] = weight @ p
        p_prev, p = p, ((2 * band + 1) * mu * p - band * p_prev) / (band + 1)
    return coeffs / total


def kernel_band_limit(coeffs: np.ndarray, tolerance: float) -> int:
    """The first band whose coefficient has fallen below ``tolerance`` (the last band if none has).

    Parameters
    ----------
    coeffs : numpy.ndarray
        Normalised Legendre coefficients, k_0 = 1 (:func:`ggx_legendre`).
    tolerance : float
        The coefficient below which the bands above are dropped.

    Returns
    -------
    int
        The band limit, 0 … len(coeffs) − 1.
    """
    below = np.flatnonzero(np.abs(coeffs) < tolerance)
    return int(below[0]) if len(below) else len(coeffs) - 1


def tail_band_limit(coeffs: np.ndarray, tolerance: float) -> int:
    """The band past which every coefficient stays below ``tolerance`` in magnitude (for coefficients that cross 0).

    Parameters
    ----------
    coeffs : numpy.ndarray
        Legendre coefficients (:func:`ggx_legendre`, e.g. of a far part).
    tolerance : float
        The magnitude below which the bands above are dropped.

    Returns
    -------
    int
        The band limit, 0 … len(coeffs) − 1.
    """
    above = np.flatnonzero(np.abs(coeffs) >= tolerance)
    return int(above[-1]) if len(above) else 0


def spherical_coordinates(directions: np.ndarray) -> np.ndarray:
    """(colatitude, longitude) of unit directions in the lat-long's coordinates, as ``ducc0`` takes locations.

    Colatitude from +y; longitude φ with d = (−sin θ sin φ, cos θ, sin θ cos φ), the
    :data:`~lightprobe.maps.layouts.LATLONG` layout's (column j's centre at φ = (j + ½)2π/W).

    Parameters
    ----------
    directions : numpy.ndarray
        (n, 3) unit vectors, world frame.

    Returns
    -------
    numpy.ndarray
        (n, 2) float64: θ in [0, π], φ in [0, 2π).
    """
    theta = np.arccos(np.clip(directions[:, 1], -1.0, 1.0))
    phi = np.mod(np.arctan2(-directions[:, 0], directions[:, 2]), 2 * np.pi)
    return np.stack([theta, phi], axis=-1)


def latlong_directions(grid: tuple[int, int], flat: np.ndarray) -> np.ndarray:
    """The unit directions of a lat-long's pixel centres at row-major ``flat`` indices: the inverse of
    :func:`spherical_coordinates` at θ = (row + ½)π/H, φ = (column + ½)2π/W.

    Parameters
    ----------
    grid : tuple of int
        (H, W) of the :data:`~lightprobe.maps.layouts.LATLONG` map.
    flat : numpy.ndarray
        Integer indices row × W + column, any shape.

    Returns
    -------
    numpy.ndarray
        float64 unit vectors, world frame, the shape of ``flat`` plus (3,).
    """
    height, width = grid
    row, col = np.divmod(np.asarray(flat), width)
    theta, phi = (row + 0.5) * np.pi / height, (col + 0.5) * 2 * np.pi / width
    return np.stack([-np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], axis=-1)


class Spectrum:
    """The spherical harmonics (bands 0 … ``lmax``) of each channel of a lat-long map.

    Computed by ``ducc0.sht.experimental.analysis_2d`` on the map's own rings (geometry "F1": Fejér's first rule, the
    lat-long's pixel centres, exact for a map band-limited to H − 1).

    Parameters
    ----------
    data : numpy.ndarray
        (H, W, C) a :data:`~lightprobe.maps.layouts.LATLONG` map (any quantity; radiance here), world frame.
    lmax : int
        The last band; at most H − 1 and (W − 1)/2.
    """

    def __init__(self, data: np.ndarray, lmax: int):
        from ducc0.sht.experimental import analysis_2d

        height, width, channels = data.shape
        if lmax > min(height - 1, (width - 1) // 2):
            raise ValueError(f"a {width}×{height} lat-long holds bands up to {min(height - 1, (width - 1) // 2)}")
        self.lmax = lmax
        # complex64, what the transform of the float32 map gives: half the bake's largest buffer; widened per level
        self.alm = np.empty((channels, (lmax + 1) * (lmax + 2) // 2), np.complex64)
        for c in range(channels):
            ring = data[None, :, :, c]
            self.alm[c] = analysis_2d(map=ring, spin=0, lmax=lmax, geometry="F1", phi0=np.pi / width,
                                      nthreads=_threads())[0]
        m = np.arange(lmax + 1)
        self._mstart = (m * (2 * lmax + 1 - m) // 2).astype(np.uintp)  # healpy order: (l, m) at mstart[m] + l
        self.point_alm = None

    def add_points(self, directions: np.ndarray, power: np.ndarray, lmax: int | None = None) -> None:
        """Also hold the spectrum of point sources, Σ_j Φ_j δ(l − l_j), apart from the map's (its own kernel).

        ``ducc0.sht.experimental.adjoint_synthesis_general``: a_lm = Σ_j Φ_j Y*_lm(l_j), exact to ε.

        Parameters
        ----------
        directions : numpy.ndarray
            (m, 3) unit directions l_j, world frame.
        power : numpy.ndarray
            (m, C) Φ_j: radiance times solid angle per channel.
        lmax : int, optional
            The last band to compute (the rest left 0: the kernel they meet has none); default the spectrum's.
        """
        from ducc0.sht.experimental import adjoint_synthesis_general

        lmax = self.lmax if lmax is None else min(lmax, self.lmax)
        self.point_lmax = lmax
        self.point_alm = np.zeros((self.alm.shape[0], (lmax + 1) * (lmax + 2) // 2), np.complex128)
        if not len(directions):
            return
        loc = spherical_coordinates(directions)
        for c in range(self.alm.shape[0]):
            self.point_alm[c] = adjoint_synthesis_general(map=np.ascontiguousarray(power[:, c], np.float64)[None],
                                                          spin=0, lmax=lmax, loc=loc, epsilon=SYNTHESIS_EPSILON,
                                                          nthreads=_threads())[0]

    def convolved_at(self, coeffs: np.ndarray, directions: np.ndarray,
                     point_coeffs: np.ndarray | None = None) -> np.ndarray:
        """The map convolved with the zonal kernel of Legendre coefficients ``coeffs``, at ``directions``.

        Bands past len(coeffs) − 1 (or past the spectrum's lmax) are dropped: choose the coefficients' length where
        the kernel has decayed (:func:`kernel_band_limit`).

        Parameters
        ----------
        coeffs : numpy.ndarray
            (L + 1,) normalised Legendre coefficients (k_0 = 1 keeps the mean).
        directions : numpy.ndarray
            (n, 3) unit vectors, world frame.
        point_coeffs : numpy.ndarray, optional
            The kernel for the points of :meth:`add_points` (the far part of the same kernel), as long as ``coeffs``;
            None leaves the points out.

        Returns
        -------
        numpy.ndarray
            (n, C) float64, the convolved map at each direction.
        """
        from ducc0.sht.experimental import synthesis_general

        lmax = min(len(coeffs) - 1, self.lmax)
        band = self._bands()
        inside = band <= lmax
        scale = np.where(inside, coeffs[np.minimum(band, lmax)], 0.0)
        point_scale = None
        if point_coeffs is not None and self.point_alm is not None:
            # the points' bands (to point_lmax, healpy order of their own) added into the map's, m by m
            small = min(self.point_lmax, lmax)
            point_scale = [(int(self._mstart[m]) + m, int(m * (2 * self.point_lmax + 1 - m) // 2) + m,
                            point_coeffs[m:small + 1]) for m in range(small + 1)]
        loc = spherical_coordinates(directions)
        out = np.empty((len(directions), self.alm.shape[0]))
        for c in range(self.alm.shape[0]):
            alm = self.alm[c] * scale
            for into, start, k in point_scale or ():
                alm[into:into + len(k)] += self.point_alm[c, start:start + len(k)] * k
            out[:, c] = synthesis_general(alm=alm[None], spin=0, lmax=lmax, loc=loc,
                                          mstart=self._mstart[:lmax + 1], epsilon=SYNTHESIS_EPSILON,
                                          nthreads=_threads())[0]
        return out

    def _bands(self) -> np.ndarray:
        """The band l of each coefficient in healpy order (m-major: for m = 0 … lmax, l = m … lmax)."""
        if getattr(self, "_band", None) is None:
            m = np.repeat(np.arange(self.lmax + 1), np.arange(self.lmax + 1, 0, -1))
            self._band = np.arange(len(m)) - self._mstart[m].astype(np.int64)
        return self._band
