"""The BRDFs' compiled sums: f_r · cos by model number, the reflected radiance of many sources, and the albedo.

Conventions, those of :mod:`lightprobe.glossy.brdf`: directions are unit vectors **leaving** the surface, in one
frame shared by all arguments; f_r is in sr⁻¹, linear RGB, 0 where either direction is below the surface. A BRDF
reaches the kernels as its :meth:`~lightprobe.glossy.brdf.BRDF.kernel`: a model number (``LAMBERT`` … ``PLASTIC``),
its float64 parameters and its Fresnel term tabulated over cos ∈ [0, 1] (:func:`fresnel_table`), so each formula
exists twice — the classes' numpy ``eval`` and :func:`brdf_times_cosine` here, tested equal. :func:`directional_albedo`
is the independent estimate, by importance sampling the classes themselves.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..util.jit import njit, prange

if TYPE_CHECKING:
    from .brdf import BRDF


LAMBERT, PHONG, BLINN, GGX_MODEL, COAT, PLASTIC = range(6)  # model numbers of the compiled evaluation
FRESNEL_STEPS = 16384  # entries of the tabulated Fresnel term over cos ∈ [0, 1] (read linearly: within 1e-5)
_NO_FRESNEL = np.ones((2, 3))


def fresnel_table(fresnel) -> np.ndarray:
    """F(cos) RGB at cos = i / FRESNEL_STEPS, i = 0 … FRESNEL_STEPS, from the exact formula.

    The compiled sums read it linearly, so the Fresnel formulas exist once, here in numpy.

    Parameters
    ----------
    fresnel : lightprobe.glossy.brdf.Schlick or lightprobe.glossy.brdf.Dielectric or lightprobe.glossy.brdf.Conductor
        The Fresnel term: called with an array of cosines, it returns their (..., 3) RGB reflectance.

    Returns
    -------
    numpy.ndarray
        (FRESNEL_STEPS + 1, 3) C-contiguous float64 reflectances.
    """
    return np.ascontiguousarray(fresnel(np.linspace(0.0, 1.0, FRESNEL_STEPS + 1)), dtype=np.float64)


@njit(cache=True, inline="always")
def _table(table, cos, c):  # pragma: no cover - compiled
    if table.shape[0] == 2 and table[0, c] == table[1, c]:  # a constant (no Fresnel: F = 1)
        return table[0, c]
    x = min(max(cos, 0.0), 1.0) * (table.shape[0] - 1)
    i = min(int(x), table.shape[0] - 2)
    t = x - i
    return table[i, c] * (1 - t) + table[i + 1, c] * t


@njit(cache=True, inline="always")
def _g1(cos, a2):  # pragma: no cover - compiled
    return 2 * cos / (cos + math.sqrt(a2 + (1 - a2) * cos * cos))


@njit(cache=True, inline="always")
def _view_term(model, p, co):  # pragma: no cover - compiled
    """G1(wo) / (4 n·wo) of the microfacet models (GGX, coat), 0 for the others or a view below the surface."""
    if (model != GGX_MODEL and model != COAT and model != PLASTIC) or co <= 0.0:
        return 0.0
    return _g1(co, p[0] * p[0]) / (4 * co)


@njit(cache=True, inline="always")
def brdf_times_cosine(model, p, table, i0, i1, i2, o0, o1, o2, n0, n1, n2, view_term, out):  # pragma: no cover
    """out[:] = f_r(wi, wo; n) · (n·wi) for one pair, the model numbered ``model`` with parameters ``p``.

    ``model``, ``p`` and ``table`` are the classes' ``kernel()``; 0 below the surface. The same formulas as the
    classes' ``eval``, tested equal. ``view_term`` is :func:`_view_term` of n·wo (the part that depends on the view
    only, made once per point).

    Parameters
    ----------
    model : int
        The model number, ``LAMBERT`` … ``PLASTIC``.
    p : numpy.ndarray
        The model's float64 parameters.
    table : numpy.ndarray
        (M, 3) float64 Fresnel table (for ``PLASTIC``: column 0 F, column 1 t(μ)).
    i0, i1, i2 : float
        wi, unit, toward the light.
    o0, o1, o2 : float
        wo, unit, toward the eye.
    n0, n1, n2 : float
        The unit normal; wi, wo and n in one frame.
    view_term : float
        :func:`_view_term` of this model at n·wo.
    out : numpy.ndarray
        (3,) float64, overwritten with f_r · (n·wi) in RGB.
    """
    ci, co = n0 * i0 + n1 * i1 + n2 * i2, n0 * o0 + n1 * o1 + n2 * o2
    if ci <= 0.0 or co <= 0.0:
        out[0] = out[1] = out[2] = 0.0
        return
    if model == LAMBERT:
        for c in range(3):
            out[c] = p[c] / math.pi * ci
        return
    if model == PHONG:
        r = 2 * co * n0 * i0 + 2 * co * n1 * i1 + 2 * co * n2 * i2 - (o0 * i0 + o1 * i1 + o2 * i2)  # r·wi
        v = p[1] * (p[0] + 2) / (2 * math.pi) * max(r, 0.0) ** p[0] * ci
        out[0] = out[1] = out[2] = v
        return
    # the half vector h = (wi + wo)/|wi + wo| through dot products: |wi + wo| = √(2 + 2 wi·wo), n·h = (n·wi + n·wo)
    # / |wi + wo|, h·wi = (1 + wi·wo) / |wi + wo|
    io = i0 * o0 + i1 * o1 + i2 * o2
    norm = math.sqrt(max(2.0 + 2.0 * io, 1e-300))
    ch = max((ci + co) / norm, 0.0)
    if model == BLINN:
        v = p[1] * ch ** p[0] * ci
        out[0] = out[1] = out[2] = v
        return
    a2 = p[0] * p[0]
    d = a2 / (math.pi * (ch * ch * (a2 - 1) + 1) ** 2) if ch > 0 else 0.0
    spec = d * _g1(ci, a2) * view_term  # times n·wi already: D G1(wi) G1(wo) / (4 n·wo)
    hi = (1.0 + io) / norm
    if model == PLASTIC:  # table column 0: the dielectric's F, column 1: the coat's transmittance t(μ)
        f = spec * _table(table, hi, 0)
        through = _table(table, ci, 1) * _table(table, co, 1) * ci
        for c in range(3):
            out[c] = f + through * p[1 + c]
        return
    for c in range(3):
        out[c] = spec * _table(table, hi, c)
    if model == COAT:
        for c in range(3):
            through = (1 - _table(table, ci, c)) * (1 - _table(table, co, c))
            out[c] += through * p[1 + c] / math.pi * ci


@njit(cache=True, parallel=True)
def _eval_cosine_many(model, p, table, wi, wo, n, out):  # pragma: no cover - compiled
    for k in prange(wi.shape[0]):
        value = np.empty(3)
        co = wo[k, 0] * n[k, 0] + wo[k, 1] * n[k, 1] + wo[k, 2] * n[k, 2]
        brdf_times_cosine(model, p, table, wi[k, 0], wi[k, 1], wi[k, 2], wo[k, 0], wo[k, 1], wo[k, 2], n[k, 0],
                          n[k, 1], n[k, 2], _view_term(model, p, co), value)
        out[k, 0], out[k, 1], out[k, 2] = value[0], value[1], value[2]


def compiled_eval_cosine(brdf: BRDF, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
    """f_r · (n·wi) by the compiled path, for (..., 3) arrays that broadcast (tests hold it to ``eval``).

    Parameters
    ----------
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF, evaluated through its :meth:`~lightprobe.glossy.brdf.BRDF.kernel`.
    wi : numpy.ndarray
        (..., 3) unit directions toward the light.
    wo : numpy.ndarray
        (..., 3) unit directions toward the eye.
    n : numpy.ndarray
        (..., 3) unit normals; the three arrays in one frame, broadcasting together.

    Returns
    -------
    numpy.ndarray
        (M, 3) float64 f_r · (n·wi), the broadcast shape's leading dimensions flattened into M; 0 below the surface.
    """
    wi, wo, n = (np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3) for a in np.broadcast_arrays(wi, wo, n))
    out = np.empty((len(wi), 3))
    _eval_cosine_many(*brdf.kernel(), wi, wo, n, out)
    return out


@njit(cache=True, parallel=True)
def reflected_sums(model, p, table, normals, views, dirs, weighted, out):  # pragma: no cover - compiled
    """out[t] = Σ_s f_r(d_s, v_t; n_t) (n_t·d_s)⁺ W_s for every point t, summed exactly — O(points × sources).

    That is the reflected radiance at each point of sources of (RGB) weight W_s = L_s Δω_s in unit directions d_s;
    sources below a point's surface (n_t·d_s ≤ 0) are skipped.

    Parameters
    ----------
    model : int
        The model number of ``brdf.kernel()``.
    p : numpy.ndarray
        The model's float64 parameters (``brdf.kernel()``).
    table : numpy.ndarray
        (M, 3) float64 Fresnel table (``brdf.kernel()``).
    normals : numpy.ndarray
        (T, 3) float64 unit normals n_t, one per point.
    views : numpy.ndarray
        (T, 3) float64 unit directions v_t from each point toward the eye.
    dirs : numpy.ndarray
        (S, 3) float64 unit directions d_s toward the sources; normals, views and dirs in one frame (the world frame in
        :mod:`lightprobe.glossy.radiance`).
    weighted : numpy.ndarray
        (S, 3) float64 W_s = L_s Δω_s: radiance times solid angle (sr).
    out : numpy.ndarray
        (T, 3) float64, overwritten with the reflected radiance, in the units of L.
    """
    for t in prange(normals.shape[0]):
        value = np.empty(3)
        acc0 = acc1 = acc2 = 0.0
        n0, n1, n2 = normals[t, 0], normals[t, 1], normals[t, 2]
        o0, o1, o2 = views[t, 0], views[t, 1], views[t, 2]
        view_term = _view_term(model, p, n0 * o0 + n1 * o1 + n2 * o2)
        for s in range(dirs.shape[0]):
            if n0 * dirs[s, 0] + n1 * dirs[s, 1] + n2 * dirs[s, 2] <= 0.0:
                continue
            brdf_times_cosine(model, p, table, dirs[s, 0], dirs[s, 1], dirs[s, 2], o0, o1, o2, n0, n1, n2, view_term,
                              value)
            acc0 += value[0] * weighted[s, 0]
            acc1 += value[1] * weighted[s, 1]
            acc2 += value[2] * weighted[s, 2]
        out[t, 0], out[t, 1], out[t, 2] = acc0, acc1, acc2


# ---- the albedo, estimated ----------------------------------------------------------------------------------------
def directional_albedo(brdf: BRDF, cos_view: np.ndarray, samples: int = 4096, seed: int = 0) -> np.ndarray:
    """ρ(wo) = ∫ f_r(wi, wo) (n·wi) dwi, RGB, at views with n·wo = ``cos_view``, by importance sampling the BRDF.

    ``samples`` stratified samples of :meth:`~lightprobe.glossy.brdf.BRDF.sample` per view (a white furnace: the
    light reflected under a uniform sky of radiance 1). The normal is +z and the views lie in the x–z plane.

    Parameters
    ----------
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF (its ``sample`` and ``eval``).
    cos_view : numpy.ndarray
        (M,) cosines n·wo of the views, in [0, 1].
    samples : int, default 4096
        Samples per view, rounded up to a square: a ⌈√samples⌉² grid of strata, each jittered once.
    seed : int, default 0
        Seed of the jitter (:func:`numpy.random.default_rng`).

    Returns
    -------
    numpy.ndarray
        (M, 3) float64 albedo ρ per view.
    """
    cos_view = np.asarray(cos_view, dtype=np.float64)
    n = np.array([0.0, 0.0, 1.0])
    wo = np.stack([np.sqrt(1 - cos_view ** 2), np.zeros_like(cos_view), cos_view], axis=-1)[:, None, :]
    side = int(math.ceil(math.sqrt(samples)))
    rng = np.random.default_rng(seed)
    grid = (np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2)
            + rng.random((side * side, 2))) / side
    wi, pdf = brdf.sample(wo, n, grid[None, :, :])
    f = brdf.eval(wi, wo, n) * np.maximum(wi[..., 2], 0.0)[..., None]
    weight = np.where(pdf[..., None] > 0, f / np.where(pdf > 0, pdf, 1.0)[..., None], 0.0)
    return weight.mean(axis=1)
