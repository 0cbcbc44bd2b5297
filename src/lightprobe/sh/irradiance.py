"""Irradiance environment maps (Ramamoorthi & Hanrahan 2001): SH and brute force, the matrix form, error measures.

Quantities: E(n) is **irradiance** at a surface with normal n, E(n) = ∫ L(ω) max(n·ω, 0) dω (not divided by π; a
Lambertian surface of albedo ρ reflects radiance ρ E / π). Normals are world-frame unit vectors unless a function
says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..util.errors import UsageError
from ..maps import EnvMap
from ..maps.layouts import Layout, layout as layout_named
from ..util.progress import track
from .basis import SHCoeffs, _sample_directions, project
from ..maps.tonemap import luminance

# Paper eq. 12 constants, exactly: each is Â_l times a basis normalisation (0.429043, 0.511664, 0.743125, 0.886227,
# 0.247708 as printed).
C1 = (np.pi / 4) * 0.25 * np.sqrt(15 / np.pi)  # Â_2 · N(Y22)
C2 = (np.pi / 6) * np.sqrt(3 / np.pi)  # Â_1 · N(Y1m) / 2 (the polynomial carries 2·c2)
C3 = (np.pi / 4) * 0.75 * np.sqrt(5 / np.pi)  # Â_2 · 3 N(Y20)
C4 = np.sqrt(np.pi) / 2  # Â_0 · N(Y00)
C5 = (np.pi / 4) * 0.25 * np.sqrt(5 / np.pi)  # Â_2 · N(Y20)


# ---- brute force ----------------------------------------------------------------------------------------------------
def brute_irradiance(env: EnvMap, normals: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """E(n) = Σ_pixels L(d_p) max(n·d_p, 0) Δω_p for every normal (..., 3): the reference, O(T·S).

    A compiled kernel sums all pixels with light for each normal (float32 products, float64 totals: ~1e-7
    relative); normals go in chunks so long runs show progress.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout, with its exact per-pixel solid angles.
    normals : numpy.ndarray
        (..., 3) world-frame unit normals (+Y up, front −Z).
    chunk : int, default 4096
        Normals per call of the kernel (one progress step each).

    Returns
    -------
    numpy.ndarray
        (..., 3) float64: irradiance E at each normal, RGB, not divided by π.
    """
    from ..maps.lookups import clamped_cosine_sums  # numba loads with the first kernel, not with the package

    normals = np.asarray(normals, dtype=np.float64)
    n = np.ascontiguousarray(normals.reshape(-1, 3))
    dirs_t, weights_t = _light_samples(env)
    out = np.zeros((n.shape[0], 3))
    chunks = range(0, n.shape[0], chunk)
    for start in track(chunks, "brute-force irradiance", total=len(chunks)):
        clamped_cosine_sums(n[start:start + chunk], dirs_t, weights_t, out[start:start + chunk])
    return out.reshape(normals.shape[:-1] + (3,))


def _light_samples(env: EnvMap) -> tuple[np.ndarray, np.ndarray]:
    """Directions and L·Δω of every pixel that carries light, as (3, S) float32 arrays for the kernel."""
    weighted = env.data.reshape(-1, 3) * env.solid_angles().reshape(-1, 1)
    keep = np.any(weighted != 0, axis=1)
    dirs_t = np.ascontiguousarray(env.directions().reshape(-1, 3)[keep].T, dtype=np.float32)
    return dirs_t, np.ascontiguousarray(weighted[keep].T, dtype=np.float32)


# ---- the matrix form (eqs. 11–13) -----------------------------------------------------------------------------------
def irradiance_matrices(sh: SHCoeffs) -> np.ndarray:
    """The 3×4×4 matrices M of eq. 12 (one per colour channel) with E(n) = (n, 1)ᵀ M (n, 1), n in ``sh.frame``.

    Needs radiance coefficients with l_max ≥ 2 (only bands ≤ 2 enter).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients L_lm, l_max ≥ 2, in any frame; the matrices act on normals of that frame.

    Returns
    -------
    numpy.ndarray
        (3, 4, 4) float64: M for R, G and B; the quadratic form gives irradiance E (not divided by π).

    Raises
    ------
    UsageError
        The coefficients are irradiance, or their order is below 2.
    """
    if sh.quantity != "radiance" or sh.l_max < 2:
        raise UsageError("the matrix form needs radiance coefficients up to band 2 at least")
    L = sh.coeffs  # noqa: N806 - the paper's notation
    i = {name: k for k, name in enumerate(["00", "1-1", "10", "11", "2-2", "2-1", "20", "21", "22"])}

    def c(key):
        return L[i[key]]

    m = np.array([
        [C1 * c("22"), C1 * c("2-2"), C1 * c("21"), C2 * c("11")],
        [C1 * c("2-2"), -C1 * c("22"), C1 * c("2-1"), C2 * c("1-1")],
        [C1 * c("21"), C1 * c("2-1"), C3 * c("20"), C2 * c("10")],
        [C2 * c("11"), C2 * c("1-1"), C2 * c("10"), C4 * c("00") - C5 * c("20")],
    ])  # (4, 4, 3)
    return np.moveaxis(m, -1, 0)


def irradiance_quadratic(m: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """E(n) = (n, 1)ᵀ M (n, 1) per channel, normals (..., 3) in the matrices' frame; returns (..., 3).

    Parameters
    ----------
    m : numpy.ndarray
        (3, 4, 4) matrices of :func:`irradiance_matrices`, one per channel.
    normals : numpy.ndarray
        (..., 3) unit normals in the frame the matrices were made in (``sh.frame``).

    Returns
    -------
    numpy.ndarray
        (..., 3): irradiance E at each normal, RGB, not divided by π.
    """
    n4 = np.concatenate([normals, np.ones(np.shape(normals)[:-1] + (1,))], axis=-1)
    return np.einsum("...i,cij,...j->...c", n4, m, n4)


def irradiance_polynomial(sh: SHCoeffs, normals: np.ndarray) -> np.ndarray:
    """Eq. 13 as a shader writes it, normals in ``sh.frame``; returns (..., 3).

    E(n) = c1 L22 (x²−y²) + c3 L20 z² + c4 L00 − c5 L20 + 2c1 (L2−2 xy + L21 xz + L2−1 yz)
    + 2c2 (L11 x + L1−1 y + L10 z), with the constants :data:`C1` … :data:`C5` of eq. 12.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients L_lm with l_max ≥ 2; only the first nine are used (neither the quantity nor the
        order is checked here).
    normals : numpy.ndarray
        (..., 3) unit normals (x, y, z) in ``sh.frame``.

    Returns
    -------
    numpy.ndarray
        (..., 3): irradiance E at each normal, RGB, not divided by π.
    """
    L = sh.coeffs  # noqa: N806
    x, y, z = (np.asarray(normals)[..., k, None] for k in range(3))
    return (C1 * L[8] * (x * x - y * y) + C3 * L[6] * z * z + C4 * L[0] - C5 * L[6]
            + 2 * C1 * (L[4] * x * y + L[7] * x * z + L[5] * y * z)
            + 2 * C2 * (L[3] * x + L[1] * y + L[2] * z))


# ---- irradiance maps ------------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class IrradianceMap:
    """Irradiance E (not /π) for every texel's direction taken as a surface normal, stored in ``layout``."""

    data: np.ndarray
    layout: Layout
    method: str

    def to_envmap_image(self) -> EnvMap:
        """The same pixels as an :class:`EnvMap` container, for writing files (values are irradiance).

        Returns
        -------
        EnvMap
            The map's data (irradiance E, not divided by π, per texel normal) in its layout.
        """
        return EnvMap(self.data, self.layout)


def irradiance_map(env: EnvMap, target: str | Layout, size: int, method: str = "sh", l_max: int = 2,
                   window: str = "none", sh: SHCoeffs | None = None) -> IrradianceMap:
    """An irradiance map of ``env`` in layout ``target`` of ``size``, by SH or by brute force.

    ``sh`` (order l_max, optional window) or ``brute`` (the exact integral per texel).

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    target : str or Layout
        The output layout: a name of :data:`lightprobe.maps.layouts.LAYOUTS` (``latlong``, ``cube``, …) or a
        :class:`~lightprobe.maps.layouts.Layout`.
    size : int
        The output size, ≥ 1, as layouts define it: the height for ``latlong``, ``angular`` and ``sphere``, the
        face edge for ``cube``, ``cross`` and ``hcross``.
    method : str, default "sh"
        ``sh``: evaluate SH irradiance; ``brute``: the exact sum over ``env``'s pixels per texel (slow).
    l_max : int, default 2
        The SH order with ``sh`` when the coefficients are projected here (ignored when ``sh`` is given, and by
        ``brute``).
    window : str, default "none"
        The de-ringing window with ``sh`` (``none``, ``hanning``, ``lanczos``, ``auto``; at its default width).
    sh : SHCoeffs, optional
        Radiance coefficients of ``env``, to reuse a projection; they are windowed and convolved here.

    Returns
    -------
    IrradianceMap
        float32 irradiance E (not divided by π) per texel, the texel's direction taken as the world-frame normal;
        texels outside the layout's valid area are 0.

    Raises
    ------
    UsageError
        ``method`` is neither ``sh`` nor ``brute``, ``window`` is unknown, or ``sh`` holds irradiance.
    LayoutError
        ``target`` is not a known layout, or ``size`` is below 1.
    """
    if method == "sh":
        coeffs = (sh or project(env, l_max)).windowed(window).to_irradiance()
        return irradiance_map_of(coeffs.evaluate, target, size, method)
    if method == "brute":
        return irradiance_map_of(lambda normals: brute_irradiance(env, normals), target, size, method)
    raise UsageError(f"unknown method {method!r}; use sh or brute")


def irradiance_map_of(irradiance, target: str | Layout, size: int, method: str) -> IrradianceMap:
    """The map of ``irradiance(normals)`` over every texel direction of layout ``target`` of ``size``.

    ``irradiance(normals)`` gives E at world-frame unit normals (..., 3); texels outside the layout's valid area
    are 0.

    Parameters
    ----------
    irradiance : callable
        Maps (..., 3) world-frame unit normals to (..., 3) RGB irradiance E (not divided by π), e.g.
        :meth:`~lightprobe.sh.basis.SHCoeffs.evaluate` of irradiance coefficients. It is called once, with the
        directions of every texel of the grid.
    target : str or Layout
        The output layout: a name of :data:`lightprobe.maps.layouts.LAYOUTS` or a
        :class:`~lightprobe.maps.layouts.Layout`.
    size : int
        The output size, ≥ 1, as the layout defines it (the height of a lat-long, the face edge of a cube).
    method : str
        The label the map carries (``sh``, ``brute``, ``hybrid``).

    Returns
    -------
    IrradianceMap
        The values as float32, 0 outside the layout's valid area.

    Raises
    ------
    LayoutError
        ``target`` is not a known layout, or ``size`` is below 1.
    """
    lay = layout_named(target)
    grid = lay.grid_shape(size)
    values = irradiance(lay.directions(grid))
    return IrradianceMap(np.where(lay.valid_mask(grid)[..., None], values, 0.0).astype(np.float32), lay, method)


# ---- error analysis -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ErrorReport:
    """An irradiance method against brute force on luminance, over normals spread uniformly on the sphere.

    The error measures of docs/spec.md §3: SH of order ``l_max`` with ``window`` (method ``sh``), or the hybrid of
    :mod:`lightprobe.lights.hybrid` (lights exact, ambient SH of order ``l_max``)."""

    l_max: int
    window: str
    paper_mean: float  # |E − E_ref| / ∫L dω (fraction of the total intensity)
    paper_max: float
    relative_mean: float  # |E − E_ref| / E_ref (per normal)
    relative_max: float
    negative_fraction: float  # share of normals where the irradiance is negative in any channel (ringing)
    method: str = "sh"


def reference_normals(count: int = 2000) -> np.ndarray:
    """``count`` normals spread uniformly over the sphere (Fibonacci lattice).

    Parameters
    ----------
    count : int, default 2000
        How many normals.

    Returns
    -------
    numpy.ndarray
        (count, 3) float64 unit vectors, the same for the same ``count`` (deterministic); usable as world-frame
        normals.
    """
    return _sample_directions(count)


def error_report(env: EnvMap, l_max: int = 2, window: str = "none", normals: np.ndarray | None = None,
                 reference: np.ndarray | None = None, sh: SHCoeffs | None = None) -> ErrorReport:
    """Both error measures of SH irradiance (order ``l_max``, ``window``) against the brute-force reference.

    ``reference`` (brute-force E at ``normals``) and ``sh`` (coefficients of order ≥ l_max) may be passed in to
    share work between several reports.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    l_max : int, default 2
        The SH order evaluated (higher bands of ``sh`` are cut off).
    window : str, default "none"
        The de-ringing window (``none``, ``hanning``, ``lanczos``, ``auto``; at its default width).
    normals : numpy.ndarray, optional
        (N, 3) world-frame unit normals to compare at; default :func:`reference_normals` (2000).
    reference : numpy.ndarray, optional
        (N, 3) brute-force irradiance E (not divided by π) at ``normals``; default computed here by
        :func:`brute_irradiance`.
    sh : SHCoeffs, optional
        Radiance coefficients of ``env`` of order ≥ ``l_max``; default projected here.

    Returns
    -------
    ErrorReport
        Method ``sh``, with ``l_max`` and the window's label.

    Raises
    ------
    UsageError
        ``window`` is unknown, or ``sh`` holds irradiance.
    """
    normals = reference_normals() if normals is None else normals
    reference = brute_irradiance(env, normals) if reference is None else reference
    coeffs = (sh or project(env, l_max)).truncated(l_max).windowed(window)
    return compare_irradiance(env, coeffs.to_irradiance().evaluate(normals), reference, l_max, coeffs.window)


def compare_irradiance(env: EnvMap, irradiance: np.ndarray, reference: np.ndarray, l_max: int, window: str = "none",
                       method: str = "sh") -> ErrorReport:
    """The error measures of any method's RGB irradiance at the normals where ``reference`` (brute force) was taken.

    On luminance Y: ``paper_*`` are |E − E_ref| over ∫Y dω of ``env`` (the share of the total intensity),
    ``relative_*`` are |E − E_ref| / E_ref per normal (E_ref at least 1e-12 of that total), ``negative_fraction``
    the share of normals where any channel of ``irradiance`` is negative.

    Parameters
    ----------
    env : EnvMap
        The environment both were computed from; only its integral ∫L dω is used.
    irradiance : numpy.ndarray
        (N, 3) the method's RGB irradiance E (not divided by π) at the normals.
    reference : numpy.ndarray
        (N, 3) brute-force RGB irradiance E at the same normals.
    l_max : int
        The SH order to record in the report (the ambient's, for the hybrid).
    window : str, default "none"
        The window label to record.
    method : str, default "sh"
        The method label to record (``sh``, ``hybrid``).

    Returns
    -------
    ErrorReport
        Mean and maximum of both measures, and the negative fraction.
    """
    e, e_ref = luminance(irradiance), luminance(reference)
    total = float(luminance(env.integral()))
    diff = np.abs(e - e_ref)
    rel = diff / np.maximum(e_ref, 1e-12 * total)
    return ErrorReport(l_max, window, float(diff.mean() / total), float(diff.max() / total), float(rel.mean()),
                       float(rel.max()), float(np.mean((irradiance < 0).any(axis=-1))), method)
