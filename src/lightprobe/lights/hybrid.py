"""Hybrid irradiance: the area lights integrated exactly over their pixels, plus SH of the ambient (no shadows).

Quantities as in :mod:`lightprobe.sh.irradiance`: E(n) is irradiance (not /π), normals world-frame unit vectors.

Why it is accurate where SH alone is not: the lights hold the map's high frequencies (a sun is what makes SH9 ring
and miss by tens of percent); what is left, the ambient, is smooth enough for a low order. Why it is fast: a light's
pixels all lie within its cap (radius r around d), so for a normal with n·d ≥ sin r every one of them is above the
horizon and its clamped cosine is the plain cosine — the light's irradiance is the linear form n·V with
V = Σ L ω Δω over its pixels, exactly. Only the normals whose horizon cuts a cap (|n·d| < sin r) sum that light's
pixels one by one; those with n·d ≤ −sin r get nothing from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..maps import EnvMap
from ..sh.irradiance import ErrorReport, IrradianceMap, compare_irradiance, irradiance_map_of
from .decompose import Decomposition, LightParams, decompose
from ..sh.basis import SHCoeffs, project

# The ambient's SH order by default: the least that keeps the hybrid within 1 % mean / 5 % max of brute force on
# the eight probes of tests/test_hybrid.py (outdoor maps with a bright horizon need more than order 2: the horizon
# is a sharp edge the lights do not take).
DEFAULT_AMBIENT_ORDER = 12


@dataclass(frozen=True, eq=False)
class LightPixels:
    """One light's pixels as the irradiance sum needs them: ``direction`` and ``radius`` (its cap), ``moment`` (3, 3)
    with moment[c] = Σ L_c ω Δω (world frame), and the pixels themselves as (3, S) float32 directions and L·Δω."""

    direction: np.ndarray
    radius: float
    moment: np.ndarray
    dirs_t: np.ndarray
    weights_t: np.ndarray


@dataclass(frozen=True, eq=False)
class HybridIrradiance:
    """E(n) = ambient SH irradiance (order ``ambient.l_max``) + Σ over lights of their exact clamped-cosine sums.

    ``ambient`` holds *irradiance* coefficients (already convolved with the clamped cosine: Â_l applied once)."""

    ambient: SHCoeffs
    lights: tuple[LightPixels, ...]

    def evaluate(self, normals: np.ndarray) -> np.ndarray:
        """Irradiance E (not /π) at world-frame unit normals (..., 3); returns (..., 3).

        Parameters
        ----------
        normals : numpy.ndarray
            (..., 3) unit normals in the world frame (+Y up, front −Z).

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 RGB irradiance E: the ambient's SH irradiance plus each light's exact clamped-cosine
            sum (no shadows).
        """
        from ..maps.lookups import clamped_cosine_sums

        normals = np.asarray(normals, dtype=np.float64)
        n = normals.reshape(-1, 3)
        out = np.asarray(self.ambient.evaluate(n), dtype=np.float64).reshape(-1, 3).copy()
        for light in self.lights:
            cos_to = n @ light.direction
            bound = math.sin(light.radius)
            above = cos_to >= bound
            out[above] += n[above] @ light.moment.T
            cut = np.nonzero(np.abs(cos_to) < bound)[0]
            if cut.size:
                part = np.zeros((cut.size, 3))
                clamped_cosine_sums(np.ascontiguousarray(n[cut]), light.dirs_t, light.weights_t, part)
                out[cut] += part
        return out.reshape(normals.shape[:-1] + (3,))


def hybrid_irradiance(env: EnvMap, decomposition: Decomposition | None = None,
                      ambient_order: int = DEFAULT_AMBIENT_ORDER, params: LightParams | None = None
                      ) -> HybridIrradiance:
    """The hybrid irradiance of ``env`` (any layout): each light's own pixels and the ambient's SH.

    The decomposition (found here with ``params`` unless given — it must be of this very map) is split into each
    light's own pixels (a pixel belongs to the first light whose cap holds it, as the extraction took them) and the
    ambient's SH of order ``ambient_order``.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    decomposition : Decomposition, optional
        :func:`~lightprobe.lights.decompose.decompose` of this very ``env`` (not checked); default found here.
    ambient_order : int, default DEFAULT_AMBIENT_ORDER
        The SH order of the ambient (12: within 1 % mean / 5 % max of brute force on the test probes).
    params : LightParams, optional
        The search's parameters when the decomposition is found here (ignored otherwise); default the paper's.

    Returns
    -------
    HybridIrradiance
        The ambient as irradiance SH (world frame) and the lights' pixels, ready to evaluate.

    Raises
    ------
    UsageError
        A search parameter is out of range.
    """
    dec = decomposition if decomposition is not None else decompose(env, params)
    ambient = project(dec.ambient, ambient_order).to_irradiance()
    dirs = env.directions().reshape(-1, 3)
    weighted = (env.data.astype(np.float64) - dec.ambient.data).reshape(-1, 3) * env.solid_angles().reshape(-1, 1)
    free = np.any(weighted != 0, axis=1)
    lights = []
    for light in dec.lights:
        mine = free & (dirs @ light.direction >= math.cos(light.radius))
        free &= ~mine
        d, w = dirs[mine], weighted[mine]
        lights.append(LightPixels(np.asarray(light.direction, dtype=np.float64), float(light.radius), w.T @ d,
                                  np.ascontiguousarray(d.T, dtype=np.float32),
                                  np.ascontiguousarray(w.T, dtype=np.float32)))
    return HybridIrradiance(ambient, tuple(lights))


def hybrid_irradiance_map(env: EnvMap, target, size: int, ambient_order: int = DEFAULT_AMBIENT_ORDER,
                          hybrid: HybridIrradiance | None = None) -> IrradianceMap:
    """An irradiance map (E, not /π) of ``env`` by the hybrid, in layout ``target`` of ``size``.

    The counterpart of :func:`lightprobe.sh.irradiance.irradiance_map` for ``method="hybrid"``.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    target : str or Layout
        The output layout: a name of :data:`lightprobe.maps.layouts.LAYOUTS` or a
        :class:`~lightprobe.maps.layouts.Layout`.
    size : int
        The output size, ≥ 1, as the layout defines it (the height of a lat-long, the face edge of a cube).
    ambient_order : int, default DEFAULT_AMBIENT_ORDER
        The ambient's SH order when the hybrid is made here (ignored when ``hybrid`` is given).
    hybrid : HybridIrradiance, optional
        :func:`hybrid_irradiance` of this ``env``, to reuse it; default made here with the paper's parameters.

    Returns
    -------
    IrradianceMap
        float32 irradiance E per texel, the texel's direction taken as the world-frame normal; texels outside the
        layout's valid area are 0; method ``hybrid``.

    Raises
    ------
    LayoutError
        ``target`` is not a known layout, or ``size`` is below 1.
    """
    hybrid = hybrid or hybrid_irradiance(env, ambient_order=ambient_order)
    return irradiance_map_of(hybrid.evaluate, target, size, "hybrid")


def hybrid_error_report(env: EnvMap, normals: np.ndarray, reference: np.ndarray, hybrid: HybridIrradiance
                        ) -> ErrorReport:
    """Both error measures of docs/spec.md §3 for the hybrid at ``normals``, against brute force ``reference`` (RGB).

    Parameters
    ----------
    env : EnvMap
        The environment the hybrid was made from (its integral normalises the ``paper_*`` measures).
    normals : numpy.ndarray
        (N, 3) world-frame unit normals.
    reference : numpy.ndarray
        (N, 3) brute-force RGB irradiance E (not divided by π) at ``normals``
        (:func:`lightprobe.sh.irradiance.brute_irradiance`).
    hybrid : HybridIrradiance
        The hybrid of ``env``.

    Returns
    -------
    ErrorReport
        Method ``hybrid``, ``l_max`` the ambient's order, window ``none``.
    """
    return compare_irradiance(env, hybrid.evaluate(normals), reference, hybrid.ambient.l_max, "none", "hybrid")
