"""Layered BRDFs: a clear coat over a diffuse base (:class:`Coat`) and Mitsuba 3's roughplastic (:class:`Plastic`).

The conventions are :mod:`lightprobe.glossy.brdf`'s (directions leaving the surface in one frame, f_r in sr⁻¹ not
multiplied by n·wi, 0 below the surface, ``sample`` returning densities in solid angle). Both models are GGX reflection
off the coat (:class:`~lightprobe.glossy.brdf.GGX` with a :class:`~lightprobe.glossy.brdf.Dielectric` Fresnel term)
plus the base seen through it; they differ in how the light crosses the coat: :class:`Coat` by the smooth interface's
1 − F, :class:`Plastic` by the rough interface's tabulated transmittance and the light it sends back inside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .brdf import BRDF, GGX, Dielectric, Lambert, _above, _alpha, _cosine_sample, _dot, smith_g1
from .brdf_sums import COAT, PLASTIC, fresnel_table


@dataclass(repr=False)
class Coat(BRDF):
    """A clear coat over a diffuse base: GGX reflection off a dielectric of index ``ior`` (exact Fresnel), plus the
    base's Lambertian albedo seen through the coat twice, f = f_GGX + (1 − F(n·wi))(1 − F(n·wo)) albedo/π.
    Energy: what the coat reflects at a view is at most F of it, and the base gets at most the rest (≤ 1, tested)."""

    alpha: float = 0.1
    ior: float = 1.5
    albedo: tuple = (0.5, 0.5, 0.5)
    name = "coat"
    central = "mirror"

    def __post_init__(self):
        self.alpha = _alpha(self.alpha)
        self._coat = GGX(self.alpha, Dielectric(float(self.ior)))
        self._base = Lambert(self.albedo)
        self.albedo = self._base.albedo

    def _through(self, cos):
        return 1 - self._coat.fresnel(cos)

    def eval(self, wi, wo, n):
        """f_r = f_GGX + (1 − F(n·wi))(1 − F(n·wo)) albedo/π: the coat's reflection plus the base seen through it.

        F is the coat's exact dielectric Fresnel term; both parts are 0 below the surface. RGB, sr⁻¹.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light; the light reaches the base through 1 − F(n·wi).
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; the base's light leaves through 1 − F(n·wo).
        n : numpy.ndarray
            (..., 3) unit normals, of both the coat and the base; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r: the coat's part plus the base's.
        """
        base = self._base.eval(wi, wo, n) * self._through(_dot(n, wi)) * self._through(_dot(n, wo))
        return self._coat.eval(wi, wo, n) + base

    def specular_share(self, wo, n) -> np.ndarray:
        """The probability of sampling the coat's lobe: its Fresnel weight at the view (at least 0.1, at most 0.9).

        That weight is twice the coat's Fresnel reflectance F(n·wo) (a dielectric's: the same in R, G and B), clipped to
        [0.1, 0.9].

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye.
        n : numpy.ndarray
            (..., 3) unit normals, in the frame of ``wo``, broadcasting with it.

        Returns
        -------
        numpy.ndarray
            (...,) float64 probabilities in [0.1, 0.9].
        """
        return np.clip(self._coat.fresnel(_dot(n, wo))[..., 0] * 2, 0.1, 0.9)

    def sample(self, wo, n, u):
        """The coat's GGX lobe with probability :meth:`specular_share`, else the base's cosine lobe about ``n``.

        u₀ picks the lobe and is stretched back to [0, 1) within the part that picked it, so each lobe gets well-spread
        uniforms; the density returned is the mixture's (:meth:`pdf`).

        Parameters
        ----------
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; they set the share and the coat's mirror lobe.
        n : numpy.ndarray
            (..., 3) unit normals, the axis of both lobes, in the frame of ``wo``.
        u : numpy.ndarray
            (..., 2) uniforms in [0, 1)²: u₀ picks the lobe (and is reused within it), u₁ the azimuth.

        Returns
        -------
        wi : numpy.ndarray
            (..., 3) float64 unit directions from whichever lobe was picked.
        pdf : numpy.ndarray
            (...,) float64 the mixture's density of each (sr⁻¹).
        """
        share = self.specular_share(wo, n)
        pick = u[..., 0] < share
        # the picked half of u[..., 0] stretched back to [0, 1): each lobe gets well-spread uniforms
        u0 = np.where(pick, u[..., 0] / share, (u[..., 0] - share) / (1 - share))
        v = np.stack(np.broadcast_arrays(np.clip(u0, 0.0, 1 - 1e-12), u[..., 1]), axis=-1)
        wi = np.where(pick[..., None], self._coat.sample(wo, n, v)[0], _cosine_sample(n, v)[0])
        return wi, self.pdf(wi, wo, n)

    def pdf(self, wi, wo, n):
        """share · p_GGX + (1 − share) · p_cosine (sr⁻¹), share the :meth:`specular_share` at the view.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit incident directions, weighed by both lobes.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; they set the share.
        n : numpy.ndarray
            (..., 3) unit normals, the axis of D and of the cosine lobe; the three arrays in one frame.

        Returns
        -------
        numpy.ndarray
            (...,) float64 density of the mixture.
        """
        share = self.specular_share(wo, n)
        return share * self._coat.pdf(wi, wo, n) + (1 - share) * self._base.pdf(wi, wo, n)

    def params(self):
        """α, ``ior`` and the base's ``albedo``, always all three.

        Returns
        -------
        dict
            ``{"alpha": α, "ior": ior, "albedo": (r, g, b)}``.
        """
        return {"alpha": self.alpha, "ior": float(self.ior), "albedo": self.albedo}

    def kernel(self):
        """``COAT`` with the parameters [α, albedo r, g, b] and the coat's dielectric Fresnel term tabulated.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``COAT``; (4,) float64 parameters; the (FRESNEL_STEPS + 1, 3) float64 table of
            :func:`~lightprobe.glossy.brdf_sums.fresnel_table`.
        """
        return COAT, np.array([self.alpha, *self.albedo]), fresnel_table(self._coat.fresnel)

    def lobe_width(self):
        """The coat's GGX lobe width, min(π/2, 2α) radians; the base's cosine lobe does not count.

        Returns
        -------
        float
            Radians.
        """
        return self._coat.lobe_width()


PLASTIC_STEPS = 64  # μ samples of the plastic's tabulated coat transmittance (as Mitsuba's roughplastic)
PLASTIC_QUADRATURE = 128  # per axis: (cos θ_h, φ) midpoint quadrature of the coat's reflectance at each μ


def _fresnel_either_side(cos: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised dielectric Fresnel reflectance for relative index ``eta`` on either side (eta < 1: from inside,
    total internal reflection past the critical angle)."""
    c = np.clip(cos, 0.0, 1.0)
    sin_t2 = (1 - c * c) / (eta * eta)
    cos_t = np.sqrt(np.clip(1 - sin_t2, 0.0, None))
    rs = (c - eta * cos_t) / np.maximum(c + eta * cos_t, 1e-300)
    rp = (eta * c - cos_t) / np.maximum(eta * c + cos_t, 1e-300)
    return np.where(sin_t2 >= 1, 1.0, 0.5 * (rs * rs + rp * rp))


def _half_vector_quadrature(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Half vectors (K·2K, 3) at the midpoints of equal-probability cells of D cos θ_h, and their cos θ_h: a
    quadrature of ∫ g(h) D(h) cos θ_h dω_h = mean of g over them."""
    k = PLASTIC_QUADRATURE
    a2 = alpha * alpha
    u = (np.arange(k) + 0.5) / k
    cos_h = np.sqrt((1 - u) / (1 + (a2 - 1) * u))
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * np.pi
    sin_h = np.sqrt(1 - cos_h ** 2)
    h = np.stack(np.broadcast_arrays(sin_h[:, None] * np.cos(phi), sin_h[:, None] * np.sin(phi),
                                     cos_h[:, None]), axis=-1).reshape(-1, 3)
    return h, np.repeat(cos_h, 2 * k)


def rough_dielectric_albedo(alpha: float, eta: float, mu: np.ndarray, transmitted: bool) -> np.ndarray:
    """The share of light arriving at cos θ = μ that a rough GGX dielectric interface reflects or lets through.

    Light comes from the side of index 1, relative index ``eta`` beyond. The interface reflects it (``transmitted``
    False) or refracts it through (True): over microfacets m seen from wi (density G1(wi) (wi·m) D(m) / μ), the mean
    of F · G1(reflected) or (1 − F) · G1(refracted) — the single-scattering albedos Mitsuba tabulates for
    roughplastic. Midpoint quadrature over m.

    Parameters
    ----------
    alpha : float
        The interface's GGX width α (α = roughness²), in (0, 1].
    eta : float
        Relative index of refraction beyond the interface; below 1 for light from inside (total internal reflection
        past the critical angle).
    mu : numpy.ndarray
        (M,) cosines μ of the incident direction to the normal, in (0, 1].
    transmitted : bool
        False for the share reflected, True for the share refracted through.

    Returns
    -------
    numpy.ndarray
        (M,) float64 shares in [0, 1].
    """
    h, cos_h = _half_vector_quadrature(alpha)
    out = np.empty(len(mu))
    for i, m in enumerate(np.asarray(mu, dtype=np.float64)):
        wi = np.array([np.sqrt(max(0.0, 1 - m * m)), 0.0, m])
        c = h @ wi
        visible = np.where(c > 0, smith_g1(np.array(m), alpha) * c / (m * cos_h), 0.0)
        fresnel = _fresnel_either_side(c, eta)
        if transmitted:
            cos_t = np.sqrt(np.clip(1 - (1 - c * c) / (eta * eta), 0.0, None))
            w = -wi / eta + (c / eta - cos_t)[:, None] * h  # into the far side: w·h = −cos_t, w_z < 0
            value = (1 - fresnel) * smith_g1(-w[:, 2], alpha) * (w[:, 2] < 0)
        else:
            w = 2 * c[:, None] * h - wi
            value = fresnel * smith_g1(w[:, 2], alpha)
        out[i] = float(np.mean(visible * value))
    return out


@dataclass(repr=False)
class Plastic(Coat):
    """Mitsuba 3's ``roughplastic`` (GGX, same α, interior index ``ior`` over exterior 1, ``albedo`` its
    diffuse_reflectance, linear): GGX reflection off the dielectric, plus the diffuse base seen through it,
    f = f_GGX + albedo / (1 − R_int) · t(μ_i) t(μ_o) / (π η²) — t(μ) the rough interface's transmittance from
    outside, R_int = 2 ∫ R(μ; 1/η) μ dμ the light it sends back inside (:func:`rough_dielectric_albedo`; both
    tabulated at 64 μ and read linearly, as Mitsuba does)."""

    alpha: float = 0.1
    ior: float = 1.49
    albedo: tuple = (0.5, 0.5, 0.5)
    name = "plastic"

    def __post_init__(self):
        super().__post_init__()
        mu = np.maximum(np.arange(PLASTIC_STEPS) / (PLASTIC_STEPS - 1), 1e-6)
        self._transmittance = rough_dielectric_albedo(self.alpha, float(self.ior), mu, transmitted=True)
        internal = 2 * float(np.mean(rough_dielectric_albedo(self.alpha, 1 / float(self.ior), mu, False) * mu))
        self._diffuse = np.asarray(self.albedo) / (1 - internal) / (np.pi * float(self.ior) ** 2)

    def _through_coat(self, cos: np.ndarray) -> np.ndarray:
        x = np.clip(cos, 0.0, 1.0) * (PLASTIC_STEPS - 1)
        i = np.minimum(x.astype(int), PLASTIC_STEPS - 2)
        t = x - i
        return self._transmittance[i] * (1 - t) + self._transmittance[i + 1] * t

    def eval(self, wi, wo, n):
        """f_r = f_GGX + albedo / (1 − R_int) · t(μ_i) t(μ_o) / (π η²), μ = n·w; 0 below the surface.

        t is tabulated at 64 μ and read linearly, as Mitsuba does. RGB, sr⁻¹.

        Parameters
        ----------
        wi : numpy.ndarray
            (..., 3) unit directions toward the light; μ_i = n·wi.
        wo : numpy.ndarray
            (..., 3) unit directions toward the eye; μ_o = n·wo.
        n : numpy.ndarray
            (..., 3) unit normals of the interface and the base; the three arrays in one frame, broadcasting together.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 f_r: the interface's reflection plus the diffuse part.
        """
        cos_i, cos_o = _dot(n, wi), _dot(n, wo)
        base = np.where(_above(wi, wo, n), self._through_coat(cos_i) * self._through_coat(cos_o), 0.0)
        return self._coat.eval(wi, wo, n) + base[..., None] * self._diffuse

    def kernel(self):
        """``PLASTIC`` with [α, d_r, d_g, d_b], d = albedo / ((1 − R_int) π η²), and a table of F and t(μ).

        Column 0 of the table is the dielectric's Fresnel term F, column 1 the interface's transmittance t(μ), both at
        the cosines of :func:`~lightprobe.glossy.brdf_sums.fresnel_table`.

        Returns
        -------
        tuple of (int, numpy.ndarray, numpy.ndarray)
            ``PLASTIC``; (4,) float64 parameters; the (FRESNEL_STEPS + 1, 3) float64 table.
        """
        table = fresnel_table(self._coat.fresnel)
        table[:, 1] = self._through_coat(np.linspace(0.0, 1.0, len(table)))  # column 0: F; column 1: t(μ)
        return PLASTIC, np.array([self.alpha, *self._diffuse]), table
