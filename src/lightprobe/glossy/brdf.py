"""Isotropic BRDFs for glossy radiance maps and rendering (Cabral, Olano & Nemec 1999; docs/spec.md §4).

Conventions, the same for every BRDF (these and the layered ones of :mod:`lightprobe.glossy.layered`):

* directions are unit vectors **leaving** the surface, in any one frame shared by all arguments: ``wi`` toward the
  light, ``wo`` toward the eye, ``n`` the surface normal; arrays of shape (..., 3) that broadcast together;
* ``eval(wi, wo, n)`` returns the BRDF value f_r (sr⁻¹, **not** multiplied by the cosine n·wi), linear RGB, shape
  (..., 3); 0 where either direction is below the surface (n·wi ≤ 0 or n·wo ≤ 0): no transmission;
* ``sample(wo, n, u)`` draws incident directions for the uniforms ``u`` (..., 2) in [0, 1)² by importance sampling,
  returning (wi, pdf) with pdf in solid angle (sr⁻¹); samples below the surface have weight 0 in ``eval``;
* ``central`` is the direction the paper's warp is built on: ``"normal"`` for diffuse-like BRDFs, ``"mirror"`` for
  specular-like ones.

GGX (Trowbridge–Reitz) uses the normalised distribution D with α the width (α = roughness² in the engines' terms),
the separable Smith shadowing G1(wi)·G1(wo) and the Fresnel term at the microfacet (h·wi), exactly the model of
Mitsuba 3's ``roughconductor`` with ``distribution: ggx`` (a test renders both). ``f0 = 1`` is no Fresnel at all.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..util.errors import LightprobeWarning, UsageError
from .brdf_sums import _NO_FRESNEL, BLINN, GGX_MODEL, LAMBERT, PHONG, fresnel_table

# RGB complex indices of refraction (η, k) of Mitsuba 3's conductor presets, read from its scalar_rgb variant
# (its spectral data reduced to RGB): the names `conductor=gold` etc. mean exactly what Mitsuba's do.
CONDUCTORS = {
    "gold": ((0.143036, 0.375307, 1.44205), (3.983, 2.38556, 1.60336)),  # Au
    "silver": ((0.155276, 0.116728, 0.138388), (4.82835, 3.12222, 2.1469)),  # Ag
    "copper": ((0.201005, 0.92375, 1.10222), (3.91326, 2.45305, 2.14209)),  # Cu
    "aluminium": ((1.6575, 0.880405, 0.521244), (9.22381, 6.2695, 4.837)),  # Al
    "chromium": ((4.36967, 2.91651, 1.6549), (5.20655, 4.23131, 3.7547)),  # Cr
}
MITSUBA_CONDUCTOR_NAMES = {"gold": "Au", "silver": "Ag", "copper": "Cu", "aluminium": "Al", "chromium": "Cr"}
MAX_EXPONENT = 1e5  # Phong / Blinn–Phong exponents above this are a mirror: use GGX with a small α
# Narrower lobes than these are not resolved by the radiance maps' integration (GGX α = 0.003 overshoots a smooth
# environment's largest value twofold, α = 1e-6 gives a black map; normalised Phong above 2·10⁴ overshoots too).
MIN_ALPHA = 0.01
MAX_PHONG_EXPONENT = 2e4
CONDUCTOR_ETA, CONDUCTOR_K = (1e-3, 100.0), (0.0, 100.0)  # beyond these the exact Fresnel overflows to NaN


# ---- vector helpers ---------------------------------------------------------------------------------------------
def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def reflect(w: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The mirror direction of ``w`` (leaving the surface) about ``n``: 2(n·w)n − w.

    Parameters
    ----------
    w : numpy.ndarray
        (..., 3) unit directions leaving the surface, in any one frame shared with ``n``.
    n : numpy.ndarray
        (..., 3) unit normals (or any unit axis), broadcasting with ``w``.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64 mirror directions, unit when ``w`` and ``n`` are, in the same frame; the broadcast shape.
    """
    return 2 * _dot(n, w)[..., None] * n - w


def tangent_frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors t, s completing unit ``n`` to a right-handed orthonormal frame (t, s, n).

    Duff et al. 2017's branchless construction (its signs follow that of n_z).

    Parameters
    ----------
    n : numpy.ndarray
        (..., 3) unit vectors, in any frame.

    Returns
    -------
    t : numpy.ndarray
        (..., 3) float64 unit tangents, perpendicular to ``n``.
    s : numpy.ndarray
        (..., 3) float64 unit tangents with t × s = n.
    """
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sign = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = np.stack([1 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    s = np.stack([b, sign + y * y * a, -y], axis=-1)
    return t, s


def _about(axis: np.ndarray, cos_t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Directions at polar angle acos(cos_t) and azimuth phi about unit ``axis``."""
    t, s = tangent_frame(np.broadcast_to(axis, np.broadcast_shapes(axis.shape, cos_t.shape + (3,))))
    sin_t = np.sqrt(np.clip(1 - cos_t * cos_t, 0.0, None))
    return (sin_t * np.cos(phi))[..., None] * t + (sin_t * np.sin(phi))[..., None] * s + cos_t[..., None] * axis


def _rgb(value, what: str) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    if not np.isfinite(v).all():
        raise UsageError(f"{what} must be finite, got {value!r}")
    return v


# ---- Fresnel ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Schlick:
    """Schlick's approximation F = f0 + (1 − f0)(1 − cos)⁵, f0 RGB in [0, 1]; f0 = 1 is no Fresnel (F ≡ 1)."""

    f0: tuple = (1.0, 1.0, 1.0)

    def __post_init__(self):
        f0 = _rgb(self.f0, "f0")
        if (f0 < 0).any() or (f0 > 1).any():
            raise UsageError(f"f0 must be in [0, 1], got {self.f0!r}")
        object.__setattr__(self, "f0", tuple(f0))

    def __call__(self, cos: np.ndarray) -> np.ndarray:
        f0 = np.asarray(self.f0)
        c = np.clip(cos, 0.0, 1.0)[..., None]
        return f0 + (1 - f0) * (1 - c) ** 5


@dataclass(frozen=True)
class Dielectric:
    """Exact unpolarised Fresnel reflectance from outside (index 1) onto a dielectric of relative index ``eta``."""

    eta: float = 1.5

    def __post_init__(self):
        if not (math.isfinite(self.eta) and 1.0 <= self.eta <= 10.0):
            raise UsageError(f"a dielectric's eta must be in [1, 10], got {self.eta!r}")

    def __call__(self, cos: np.ndarray) -> np.ndarray:
        if self.eta == 1.0:  # no interface: nothing is reflected (the formula is 0/0 at grazing angles)
            return np.zeros(np.shape(cos) + (3,))
        c = np.clip(cos, 0.0, 1.0)
        sin_t2 = (1 - c * c) / (self.eta * self.eta)
        cos_t = np.sqrt(np.clip(1 - sin_t2, 0.0, None))
        rs = (c - self.eta * cos_t) / (c + self.eta * cos_t)
        rp = (self.eta * c - cos_t) / (self.eta * c + cos_t)
        f = 0.5 * (rs * rs + rp * rp)
        return np.repeat(f[..., None], 3, axis=-1)


@dataclass(frozen=True)
class Conductor:
    """Exact unpolarised Fresnel reflectance of a conductor of complex index η + ik (RGB each), from outside (index
    1): the full s/p formula (as Mitsuba's ``fresnel_conductor``), not Schlick."""

    eta: tuple = CONDUCTORS["gold"][0]
    k: tuple = CONDUCTORS["gold"][1]

    def __post_init__(self):
        eta, k = _rgb(self.eta, "eta"), _rgb(self.k, "k")
        (elo, ehi), (klo, khi) = CONDUCTOR_ETA, CONDUCTOR_K
        if (eta < elo).any() or (eta > ehi).any() or (k < klo).any() or (k > khi).any():
            raise UsageError(f"a conductor needs eta in [{elo:g}, {ehi:g}] and k in [{klo:g}, {khi:g}], got "
                             f"eta={self.eta!r}, k={self.k!r}")
        object.__setattr__(self, "eta", tuple(eta))
        object.__setattr__(self, "k", tuple(k))

    def __call__(self, cos: np.ndarray) -> np.ndarray:
        c = np.clip(cos, 0.0, 1.0)[..., None]
        eta = np.asarray(self.eta) + 1j * np.asarray(self.k)
        c2 = c * c
        sin2 = 1 - c2
        root = np.sqrt(eta * eta - sin2)  # η cos θ_t, complex
        with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 at grazing angles where η = 1, k = 0
            rs = (c - root) / (c + root)
            rp = (eta * eta * c - root) / (eta * eta * c + root)
        f = 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)
        return np.where(eta == 1, 0.0, f)  # no interface in that channel: nothing is reflected


# ---- the BRDFs --------------------------------------------------------------------------------------------------
class BRDF:
    """Base class: see the module's conventions. Subclasses set ``name``, ``central`` and ``params()``."""

    name = "brdf"
    central = "normal"

    def eval(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The BRDF value f_r(wi, wo; n) (sr⁻¹, linear RGB), **not** multiplied by the cosine n·wi.

        0 where either direction is below the surface (n·wi ≤ 0 or n·wo ≤ 0): no transmission. Each subclass states its
        formula.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions leaving the surface toward the light.
        wo : numpy.ndarray
            (..., 3) unit directions leaving the surface toward the eye.
        n : numpy.ndarray
            (..., 3) unit surface normals. The three arrays are in any one frame and broadcast together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r, in the broadcast shape of the arguments.
        """
        raise NotImplementedError

    def sample(self, wo: np.ndarray, n: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Incident directions drawn for the uniforms ``u`` by importance sampling, and their density.

        Samples may fall below the surface; :meth:`eval` gives them weight 0.

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions leaving the surface toward the eye.
        n : numpy.ndarray
            (..., 3) unit surface normals, in the frame of ``wo``.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)², one pair per sample, broadcasting with ``wo`` and ``n``.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit incident directions (toward the light), in the frame of ``n``.
        pdf : numpy.ndarray
            (...,) float64 density of each ``wi`` in solid angle (sr⁻¹), the value :meth:`pdf` gives.
        """
        raise NotImplementedError

    def pdf(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The density in solid angle (sr⁻¹) with which :meth:`sample` draws ``wi`` for the view ``wo``.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions (toward the light).
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye.
        n : numpy.ndarray
            (..., 3) unit surface normals; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density, ≥ 0.
        """
        raise NotImplementedError

    def params(self) -> dict:
        """The parameters of this BRDF, keyed as :func:`parse_brdf` reads them.

        :meth:`spec` and :meth:`describe` are built from them. A subclass may leave out a parameter at its neutral
        value (a white albedo, ks = 1, no Fresnel).

        Returns
        -------
        dict
            Parameter name → value (a float, an RGB tuple or a conductor's name); empty for the base class.
        """
        return {}

    def kernel(self) -> tuple[int, np.ndarray, np.ndarray]:
        """(model number, parameters, Fresnel table) for the compiled sums.

        What :func:`~lightprobe.glossy.brdf_sums.reflected_sums` and the other kernels of
        :mod:`lightprobe.glossy.brdf_sums` read in place of the class.

        Returns
        -------
        model : int
            One of ``LAMBERT``, ``PHONG``, ``BLINN``, ``GGX_MODEL``, ``COAT``, ``PLASTIC``
            (:mod:`lightprobe.glossy.brdf_sums`).
        params : numpy.ndarray
            (P,) float64: the numbers the compiled formula of that model reads (each subclass says which).
        table : numpy.ndarray
            (M, 3) float64 Fresnel table over cos ∈ [0, 1] (:func:`~lightprobe.glossy.brdf_sums.fresnel_table`), or
            (2, 3) ones for no Fresnel.
        """
        raise NotImplementedError

    def lobe_width(self) -> float:
        """A characteristic angular width (radians) of f·cos about the central direction.

        It says how fine a map must be to resolve the lobe (texels a quarter of it or finer).

        Returns
        -------
        float
            The width in radians, at most π/2.
        """
        raise NotImplementedError

    def spec(self) -> str:
        """The ``name:key=value,…`` text :func:`parse_brdf` reads back to this BRDF.

        Returns
        -------
        str
            ``name`` alone when :meth:`params` is empty; RGB values written r/g/b.
        """
        items = ",".join(f"{k}={_spec_value(v)}" for k, v in self.params().items())
        return f"{self.name}:{items}" if items else self.name

    def describe(self) -> dict:
        """The BRDF as a dict: its ``name``, ``central`` direction and :meth:`params`.

        A radiance-set manifest stores it as its ``brdf`` object, beside :meth:`spec`
        (:func:`lightprobe.glossy.radiancefile.manifest`).

        Returns
        -------
        dict
            ``{"name": …, "central": "normal" or "mirror", **params}``.
        """
        return {"name": self.name, "central": self.central, **self.params()}

    def __repr__(self):
        return f"<BRDF {self.spec()}>"


def _spec_value(v) -> str:
    if isinstance(v, (tuple, list)):
        return "/".join(f"{x:g}" for x in v)
    return f"{v:g}" if isinstance(v, float) else str(v)


def _above(wi, wo, n):
    return (_dot(n, wi) > 0) & (_dot(n, wo) > 0)


def _cosine_sample(n: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cos_t = np.sqrt(1 - u[..., 0])
    wi = _about(n, cos_t, 2 * np.pi * u[..., 1])
    return wi, cos_t / np.pi


@dataclass(repr=False)
class Lambert(BRDF):
    """f = albedo / π. Directional albedo exactly ``albedo`` at every view."""

    albedo: tuple = (1.0, 1.0, 1.0)
    name = "lambert"
    central = "normal"

    def __post_init__(self):
        a = _rgb(self.albedo, "albedo")
        if (a < 0).any() or (a > 1).any():
            raise UsageError(f"albedo must be in [0, 1], got {self.albedo!r}")
        self.albedo = tuple(a)

    def eval(self, wi, wo, n):
        """f_r = albedo / π (sr⁻¹, RGB) where wi and wo are both above the surface, else 0.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light; only their side of the surface matters.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; only their side of the surface matters.
        n : numpy.ndarray
            (..., 3) unit normals, in the frame of ``wi`` and ``wo`` and broadcasting with them.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64: albedo / π, or 0 below the surface.
        """
        return np.where(_above(wi, wo, n)[..., None], np.asarray(self.albedo) / np.pi, 0.0)

    def sample(self, wo, n, u):
        """Cosine-weighted directions about ``n``: cos θ = √(1 − u₀), azimuth 2π u₁, density cos θ / π.

        Parameters
        ----------
        wo : numpy.ndarray
            View directions; unused, as the cosine lobe does not depend on the view.
        n : numpy.ndarray
            (..., 3) unit normals: the axis of the lobe.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)², broadcasting with ``n``.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit directions, all above the surface, in the frame of ``n``.
        pdf : numpy.ndarray
            (...,) float64 cos θ / π (sr⁻¹).
        """
        return _cosine_sample(n, u)

    def pdf(self, wi, wo, n):
        """max(n·wi, 0) / π (sr⁻¹): the cosine lobe :meth:`sample` draws, the same for every view.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions.
        wo : numpy.ndarray
            View directions; unused.
        n : numpy.ndarray
            (..., 3) unit normals, in the frame of ``wi``, broadcasting with it.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density; 0 below the surface.
        """
        return np.maximum(_dot(n, wi), 0.0) / np.pi

    def params(self):
        """``{}`` for a white albedo, else ``{"albedo": (r, g, b)}``.

        Returns
        -------
        dict
            The albedo, when it is not (1, 1, 1).
        """
        return {} if self.albedo == (1.0, 1.0, 1.0) else {"albedo": self.albedo}

    def kernel(self):
        """``LAMBERT``, the albedo and no Fresnel term, for :func:`~lightprobe.glossy.brdf_sums.reflected_sums`.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``LAMBERT``; the albedo, (3,) float64; the (2, 3) table of ones (no Fresnel).
        """
        return LAMBERT, np.array(self.albedo), _NO_FRESNEL

    def lobe_width(self):
        """π/2: the cosine lobe spans the whole hemisphere about the normal.

        Returns
        -------
        float
            π/2 radians.
        """
        return np.pi / 2


def _exponent(value, what: str, most: float = MAX_EXPONENT) -> float:
    value = float(value)
    if not (math.isfinite(value) and 0.0 <= value <= most):
        raise UsageError(f"{what} exponent n must be in [0, {most:g}], got {value!r}")
    return value


@dataclass(repr=False)
class Phong(BRDF):
    """Normalised Phong (Lafortune & Willems 1994): f = ks (n + 2)/(2π) · max(0, r·wi)ⁿ, r the mirror of wo.
    Its albedo is ks at normal view and falls toward grazing views, where the lobe dips below the surface."""

    n: float = 50.0
    ks: float = 1.0
    name = "phong"
    central = "mirror"

    def __post_init__(self):
        self.n = _exponent(self.n, "Phong", MAX_PHONG_EXPONENT)
        if not 0 <= self.ks <= 1:
            raise UsageError(f"ks must be in [0, 1], got {self.ks!r}")

    def eval(self, wi, wo, n):
        """f_r = ks (n + 2)/(2π) · max(0, r·wi)ⁿ, r the mirror of ``wo`` about the normal; 0 below the surface.

        Grey (the same in R, G and B), sr⁻¹.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light, compared with the mirror direction r.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, mirrored about ``n`` to the lobe's axis r.
        n : numpy.ndarray
            (..., 3) unit normals: the mirror's and the horizon's; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r, the same in the three channels.
        """
        c = np.maximum(_dot(reflect(wo, n), wi), 0.0)
        f = self.ks * (self.n + 2) / (2 * np.pi) * c ** self.n
        return np.where(_above(wi, wo, n), f, 0.0)[..., None] * np.ones(3)

    def sample(self, wo, n, u):
        """Directions about the mirror r of ``wo``: cos θ = u₀^(1/(n+1)) from r, azimuth 2π u₁.

        Part of the lobe about r can lie below the surface (grazing views): those samples keep their density and have
        weight 0 in :meth:`eval`.

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, mirrored about ``n`` to the axis r.
        n : numpy.ndarray
            (..., 3) unit normals about which ``wo`` is mirrored, in its frame.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)²: u₀ sets the angle from r, u₁ the azimuth about it.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit directions in the lobe about r.
        pdf : numpy.ndarray
            (...,) float64 (n + 1)/(2π) cosⁿ of their angle from r (sr⁻¹).
        """
        cos_t = u[..., 0] ** (1 / (self.n + 1))
        wi = _about(reflect(wo, n), cos_t, 2 * np.pi * u[..., 1])
        return wi, self.pdf(wi, wo, n)

    def pdf(self, wi, wo, n):
        """(n + 1)/(2π) · max(0, r·wi)ⁿ (sr⁻¹), r the mirror of ``wo``: the density of :meth:`sample`.

        A density over the whole sphere: directions below the surface are not set to 0.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions, measured from r.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, mirrored about ``n`` to r.
        n : numpy.ndarray
            (..., 3) unit normals of the mirror; the three arrays in one frame.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density of the cosⁿ lobe about r.
        """
        c = np.maximum(_dot(reflect(wo, n), wi), 0.0)
        return (self.n + 1) / (2 * np.pi) * c ** self.n

    def params(self):
        """The exponent ``n``, and ``ks`` unless it is 1: ``phong:n=…`` or ``phong:n=…,ks=…``.

        Returns
        -------
        dict
            ``{"n": n}``, or with ``"ks"`` too.
        """
        return {"n": self.n} if self.ks == 1 else {"n": self.n, "ks": self.ks}

    def kernel(self):
        """``PHONG`` with the parameters [n, ks] and no Fresnel term, for the compiled sums.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``PHONG``; [n, ks] as (2,) float64; the (2, 3) table of ones.
        """
        return PHONG, np.array([self.n, self.ks]), _NO_FRESNEL

    def lobe_width(self):
        """√(2/n) radians about the mirror direction, at most π/2.

        Returns
        -------
        float
            min(π/2, √(2/n)), radians.
        """
        return min(np.pi / 2, math.sqrt(2 / max(self.n, 1e-9)))


@dataclass(repr=False)
class BlinnPhong(BRDF):
    """Normalised Blinn–Phong: f = ks · c_n · (n·h)ⁿ, h the half vector, with the exact normalisation at normal view
    c_n = (n + 2)(n + 4) / (8π (2^(−n/2) + n)) (Giesen 2009), so the albedo is exactly ks there; the common
    (n + 8)/(8π) is its large-n limit and reflects more than comes in (1.07 at n = 5)."""

    n: float = 50.0
    ks: float = 1.0
    name = "blinn"
    central = "mirror"

    def __post_init__(self):
        self.n = _exponent(self.n, "Blinn–Phong")
        if not 0 <= self.ks <= 1:
            raise UsageError(f"ks must be in [0, 1], got {self.ks!r}")

    def eval(self, wi, wo, n):
        """f_r = ks · c_n · max(n·h, 0)ⁿ, h = (wi + wo)/|wi + wo| the half vector; 0 below the surface.

        c_n is the exact normalisation of the class docstring. Grey (the same in R, G and B), sr⁻¹.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light; with ``wo`` they make the half vector h.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, the other half of h.
        n : numpy.ndarray
            (..., 3) unit normals, compared with h; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r, grey: ks · c_n · (n·h)ⁿ, or 0.
        """
        h = _unit(wi + wo)
        norm = (self.n + 2) * (self.n + 4) / (8 * np.pi * (2 ** (-self.n / 2) + self.n))
        f = self.ks * norm * np.maximum(_dot(n, h), 0.0) ** self.n
        return np.where(_above(wi, wo, n), f, 0.0)[..., None] * np.ones(3)

    def sample(self, wo, n, u):
        """Half vectors h about ``n`` (cos θ_h = u₀^(1/(n+1)), azimuth 2π u₁) and wi the mirror of ``wo`` about h.

        h has the density (n + 1)/(2π) (n·h)ⁿ; :meth:`pdf` turns it into the density of wi. Directions that fall below
        the surface have weight 0 in :meth:`eval`.

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, reflected about each sampled h.
        n : numpy.ndarray
            (..., 3) unit normals: the axis about which h is drawn.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)²: u₀ sets h's angle from ``n``, u₁ its azimuth.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit mirrors of ``wo`` about the sampled half vectors.
        pdf : numpy.ndarray
            (...,) float64 their :meth:`pdf` (sr⁻¹), through the Jacobian 1/(4 |wo·h|).
        """
        cos_h = u[..., 0] ** (1 / (self.n + 1))
        h = _about(n, cos_h, 2 * np.pi * u[..., 1])
        wi = reflect(wo, h)
        return wi, self.pdf(wi, wo, n)

    def pdf(self, wi, wo, n):
        """p_h / (4 |wo·h|) (sr⁻¹), p_h = (n + 1)/(2π) max(n·h, 0)ⁿ: the half-vector density as a density of wi.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions; with ``wo`` they make h = (wi + wo)/|wi + wo|.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; |wo·h| is the Jacobian's cosine.
        n : numpy.ndarray
            (..., 3) unit normals, the axis of the (n·h)ⁿ lobe; the three arrays in one frame.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density, not set to 0 where wi is below the surface.
        """
        h = _unit(wi + wo)
        p_h = (self.n + 1) / (2 * np.pi) * np.maximum(_dot(n, h), 0.0) ** self.n
        return p_h / np.maximum(4 * np.abs(_dot(wo, h)), 1e-300)

    def params(self):
        """The exponent ``n``, and ``ks`` unless it is 1: ``blinn:n=…`` or ``blinn:n=…,ks=…``.

        Returns
        -------
        dict
            The Blinn–Phong exponent ``n``, with ``"ks"`` when it is not 1.
        """
        return {"n": self.n} if self.ks == 1 else {"n": self.n, "ks": self.ks}

    def kernel(self):
        """``BLINN`` with the parameters [n, ks · c_n] (the normalisation folded in) and no Fresnel term.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``BLINN``; [n, ks · c_n] as (2,) float64; the (2, 3) table of ones.
        """
        norm = (self.n + 2) * (self.n + 4) / (8 * np.pi * (2 ** (-self.n / 2) + self.n))
        return BLINN, np.array([self.n, self.ks * norm]), _NO_FRESNEL

    def lobe_width(self):
        """2√(2/n) radians, at most π/2: twice :class:`Phong`'s, as wi turns twice as far as the half vector.

        Returns
        -------
        float
            min(π/2, 2√(2/n)), radians.
        """
        return min(np.pi / 2, 2 * math.sqrt(2 / max(self.n, 1e-9)))


def ggx_d(cos_h: np.ndarray, alpha: float) -> np.ndarray:
    """The normalised GGX distribution D(h) (∫ D cos θ_h dω_h = 1).

    Parameters
    ----------
    cos_h : numpy.ndarray
        cos θ_h = n·h, any shape; D is 0 where it is ≤ 0.
    alpha : float
        The width α (α = roughness² in the engines' terms), > 0; :class:`GGX` takes it in [:data:`MIN_ALPHA`, 1].

    Returns
    -------
    numpy.ndarray
        D (sr⁻¹), float64, the shape of ``cos_h``.
    """
    c2 = np.clip(cos_h, 0.0, 1.0) ** 2
    a2 = alpha * alpha
    return np.where(cos_h > 0, a2 / (np.pi * (c2 * (a2 - 1) + 1) ** 2), 0.0)


def smith_g1(cos: np.ndarray, alpha: float) -> np.ndarray:
    """GGX Smith masking G1(w) = 2 cos / (cos + √(α² + (1 − α²) cos²)), cos = n·w (0 below the surface).

    Parameters
    ----------
    cos : numpy.ndarray
        cos = n·w of the direction w, any shape.
    alpha : float
        The GGX width α (α = roughness²), as in :func:`ggx_d`.

    Returns
    -------
    numpy.ndarray
        G1 in [0, 1], float64, the shape of ``cos``.
    """
    c = np.clip(cos, 0.0, 1.0)
    a2 = alpha * alpha
    return np.where(cos > 0, 2 * c / np.maximum(c + np.sqrt(a2 + (1 - a2) * c * c), 1e-300), 0.0)


def _alpha(value) -> float:
    value = float(value)
    if not (math.isfinite(value) and MIN_ALPHA <= value <= 1.0):
        raise UsageError(f"GGX alpha must be in [{MIN_ALPHA:g}, 1], got {value!r}")
    return value


@dataclass(repr=False)
class GGX(BRDF):
    """Microfacet reflection: f = D(h) G1(wi) G1(wo) F(h·wi) / (4 (n·wi)(n·wo)) — Mitsuba 3's ``roughconductor``
    (GGX, same α; the uncorrelated Smith G it uses). ``fresnel`` is :class:`Schlick` (f0 = 1 by default: no
    Fresnel), :class:`Dielectric` or :class:`Conductor`. Sampled by D(h) cos θ_h."""

    alpha: float = 0.2
    fresnel: object = field(default_factory=Schlick)
    name = "ggx"
    central = "mirror"

    def __post_init__(self):
        self.alpha = _alpha(self.alpha)

    def eval(self, wi, wo, n):
        """f_r = D(h) G1(wi) G1(wo) F(h·wi) / (4 (n·wi)(n·wo)), h the half vector of wi and wo; 0 below the surface.

        RGB through the Fresnel term (grey without one), sr⁻¹.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light; the Fresnel term is taken at h·wi.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, masked by G1(wo).
        n : numpy.ndarray
            (..., 3) unit macro-surface normals, the axis of D; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r, coloured by the Fresnel term.
        """
        h = _unit(wi + wo)
        cos_i, cos_o = _dot(n, wi), _dot(n, wo)
        dg = ggx_d(_dot(n, h), self.alpha) * smith_g1(cos_i, self.alpha) * smith_g1(cos_o, self.alpha)
        f = np.where(_above(wi, wo, n), dg / np.maximum(4 * cos_i * cos_o, 1e-300), 0.0)
        return f[..., None] * self.fresnel(_dot(h, wi))

    def sample(self, wo, n, u):
        """Half vectors h distributed as D(h) cos θ_h about ``n``, and wi the mirror of ``wo`` about h.

        cos θ_h = √((1 − u₀)/(1 + (α² − 1) u₀)), azimuth 2π u₁. Directions that fall below the surface have weight 0 in
        :meth:`eval`.

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye, reflected about each sampled microfacet normal h.
        n : numpy.ndarray
            (..., 3) unit macro-surface normals, the axis of D.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)²: u₀ sets cos θ_h, u₁ the azimuth of h.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit mirrors of ``wo`` about the sampled microfacet normals.
        pdf : numpy.ndarray
            (...,) float64 their :meth:`pdf`, D(h) cos θ_h / (4 |wo·h|) (sr⁻¹).
        """
        a2 = self.alpha * self.alpha
        cos_h = np.sqrt((1 - u[..., 0]) / (1 + (a2 - 1) * u[..., 0]))
        h = _about(n, cos_h, 2 * np.pi * u[..., 1])
        wi = reflect(wo, h)
        return wi, self.pdf(wi, wo, n)

    def pdf(self, wi, wo, n):
        """D(h) (n·h)⁺ / (4 |wo·h|) (sr⁻¹): the density of :meth:`sample`'s half vectors, as a density of wi.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions; with ``wo`` they make the microfacet normal h.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; the Jacobian divides by 4 |wo·h|.
        n : numpy.ndarray
            (..., 3) unit macro-surface normals, the axis of D; the three arrays in one frame.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density; 0 where h is below the surface (n·h ≤ 0).
        """
        h = _unit(wi + wo)
        cos_h = _dot(n, h)
        return ggx_d(cos_h, self.alpha) * np.maximum(cos_h, 0.0) / np.maximum(4 * np.abs(_dot(wo, h)), 1e-300)

    def params(self):
        """α, and the Fresnel term as :func:`parse_brdf` reads it: ``f0``, ``ior``, ``conductor`` or ``eta`` and ``k``.

        ``f0`` appears only when it is not 1 (one number when grey, else its r, g, b); a conductor is named when its
        (η, k) is one of CONDUCTORS, else given as ``eta`` and ``k``.

        Returns
        -------
        dict
            ``{"alpha": α}`` plus the Fresnel's entries.
        """
        out = {"alpha": self.alpha}
        fr = self.fresnel
        if isinstance(fr, Schlick):
            if fr.f0 != (1.0, 1.0, 1.0):
                out["f0"] = fr.f0 if len(set(fr.f0)) > 1 else fr.f0[0]
        elif isinstance(fr, Dielectric):
            out["ior"] = fr.eta
        else:
            name = next((k for k, v in CONDUCTORS.items() if v == (fr.eta, fr.k)), None)
            out.update({"conductor": name} if name else {"eta": fr.eta, "k": fr.k})
        return out

    def kernel(self):
        """``GGX_MODEL`` with the parameter [α] and the Fresnel term tabulated.

        The table is :func:`~lightprobe.glossy.brdf_sums.fresnel_table`'s; Schlick's with f0 = 1 is the (2, 3) table of
        ones: no Fresnel.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``GGX_MODEL``; [α] as (1,) float64; the Fresnel table, (FRESNEL_STEPS + 1, 3) or (2, 3) float64.
        """
        constant = isinstance(self.fresnel, Schlick) and self.fresnel.f0 == (1.0, 1.0, 1.0)
        return GGX_MODEL, np.array([self.alpha]), _NO_FRESNEL if constant else fresnel_table(self.fresnel)

    def lobe_width(self):
        """2α radians about the mirror direction, at most π/2.

        Returns
        -------
        float
            min(π/2, 2α), radians.
        """
        return min(np.pi / 2, 2 * self.alpha)


# ---- names ------------------------------------------------------------------------------------------------------
def _number(key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"BRDF parameter {key} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise UsageError(f"BRDF parameter {key} must be finite, got {text!r}")
    return value


def _triple(key: str, text: str):
    parts = [_number(key, p) for p in text.split("/")]
    if len(parts) not in (1, 3):
        raise UsageError(f"BRDF parameter {key} takes one number or three as r/g/b, got {text!r}")
    return parts[0] if len(parts) == 1 else tuple(parts)


def parse_brdf(spec: str) -> BRDF:
    """A BRDF from the text ``name:key=value,…`` (what :meth:`BRDF.spec` writes).

    For example ``lambert``, ``phong:n=50``, ``blinn:n=50``, ``ggx:alpha=0.2,f0=0.04``, ``ggx:alpha=0.2,conductor=gold``
    or ``…,eta=0.2/0.4/1.4,k=4/2.4/1.6``, ``ggx:alpha=0.2,ior=1.5`` (exact dielectric),
    ``coat:alpha=0.1,ior=1.5,albedo=0.5/0.1/0.1``, ``plastic:alpha=0.1,ior=1.49,albedo=0.5/0.1/0.1`` (Mitsuba's
    roughplastic). RGB values are one number or r/g/b. A parameter left out takes its class's default (``ggx``:
    α = 0.2 and f0 = 1, no Fresnel). The ranges are those computed correctly: α in [:data:`MIN_ALPHA`, 1], a Phong
    exponent up to :data:`MAX_PHONG_EXPONENT` (Blinn–Phong :data:`MAX_EXPONENT`), a conductor's η and k within
    :data:`CONDUCTOR_ETA` and :data:`CONDUCTOR_K`. A BRDF that reflects no light (albedo or ks 0, an index of 1)
    gives black maps: a :class:`~lightprobe.util.errors.LightprobeWarning` says so.

    Parameters
    ----------
    spec : str
        The text; spaces around it and around each ``key=value`` are ignored.

    Returns
    -------
    BRDF
        A :class:`Lambert`, :class:`Phong`, :class:`BlinnPhong`, :class:`GGX`, or a layered
        :class:`~lightprobe.glossy.layered.Coat` or :class:`~lightprobe.glossy.layered.Plastic`.

    Raises
    ------
    lightprobe.util.errors.UsageError
        An unknown name or conductor; a parameter that is not ``key=value``, given twice, not the model's, not a
        finite number, or out of its range; an RGB value of other than one or three numbers; more than one Fresnel
        term for ``ggx``, or one of ``eta`` and ``k`` without the other.
    """
    from .layered import Coat, Plastic  # built on this module's GGX and Lambert: imported here, not at the top

    models = {"lambert": Lambert, "phong": Phong, "blinn": BlinnPhong, "ggx": GGX, "coat": Coat, "plastic": Plastic}
    name, _, rest = str(spec).strip().partition(":")
    if name not in models:
        raise UsageError(f"unknown BRDF {name!r}; known: {', '.join(models)}")
    options: dict[str, str] = {}
    for item in filter(None, (p.strip() for p in rest.split(","))):
        key, eq, value = item.partition("=")
        if not eq or not key.strip() or not value.strip():
            raise UsageError(f"BRDF parameters are key=value, got {item!r} in {spec!r}")
        if key.strip() in options:
            raise UsageError(f"BRDF parameter {key.strip()} given twice in {spec!r}")
        options[key.strip()] = value.strip()
    allowed = {"lambert": {"albedo"}, "phong": {"n", "ks"}, "blinn": {"n", "ks"},
               "ggx": {"alpha", "f0", "ior", "conductor", "eta", "k"}, "coat": {"alpha", "ior", "albedo"},
               "plastic": {"alpha", "ior", "albedo"}}[name]
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise UsageError(f"{name} has no parameter {unknown[0]!r}; it takes {', '.join(sorted(allowed))}")
    if name == "ggx":
        brdf = GGX(_number("alpha", options.get("alpha", "0.2")), _fresnel(options))
    else:
        values = {k: (_triple(k, v) if k == "albedo" else _number(k, v)) for k, v in options.items()}
        brdf = models[name](**values)
    if _reflects_nothing(brdf):
        warnings.warn(f"BRDF {spec.strip()!r} reflects no light: its maps are black", LightprobeWarning,
                      stacklevel=2)
    return brdf


def _reflects_nothing(brdf: BRDF) -> bool:
    """f_r is 0 at a few pairs of directions: at normal, oblique and grazing views, toward the mirror and the normal
    (an albedo of 0, ks 0, or a Fresnel term of no interface)."""
    t = np.array([0.0, 0.5, 1.2, 0.0, 0.5, 1.2])
    wo = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=1)
    wi = np.concatenate([wo[:3] * [-1, -1, 1], np.tile([0.0, 0.0, 1.0], (3, 1))])
    return not np.any(brdf.eval(wi, wo, np.tile([0.0, 0.0, 1.0], (len(t), 1))))


def _fresnel(options: dict):
    chosen = [k for k in ("f0", "ior", "conductor") if k in options] + (["eta/k"] if {"eta", "k"} & set(options)
                                                                          else [])
    if len(chosen) > 1:
        raise UsageError(f"ggx takes one Fresnel: f0, ior, conductor or eta with k (got {', '.join(chosen)})")
    if "ior" in options:
        return Dielectric(_number("ior", options["ior"]))
    if "conductor" in options:
        if options["conductor"] not in CONDUCTORS:
            raise UsageError(f"unknown conductor {options['conductor']!r}; known: {', '.join(CONDUCTORS)}")
        return Conductor(*CONDUCTORS[options["conductor"]])
    if "eta" in options or "k" in options:
        if not {"eta", "k"} <= set(options):
            raise UsageError("a conductor needs both eta and k")
        return Conductor(_triple("eta", options["eta"]), _triple("k", options["k"]))
    return Schlick(_triple("f0", options.get("f0", "1")))
