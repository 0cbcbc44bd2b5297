"""Lighting methods: how a diffuse surface point is shaded under the scene's environment.

A method turns hits into outgoing radiance, ``albedo · E / π`` for Lambertian surfaces, where E is what the method
knows of the irradiance (not /π). Methods are registered in :data:`METHODS`; stochastic ones take a ``seed`` and a
sample budget, so a render is reproducible bit for bit from its seed.

* ``sh`` — SH irradiance (any order, optional window): per pixel at the shading normal, or per vertex and
  interpolated across triangles as the paper's hardware shader did. No shadows: the whole environment lights
  every normal.
* ``brute`` — exact irradiance at the shading normal, integrating every pixel of the map. Also no shadows: it is
  the exact value of what ``sh`` approximates, so their difference is SH's own error.
* ``hybrid`` — the map's area lights summed exactly plus SH of the ambient (:mod:`lightprobe.lights.hybrid`). No
  shadows.
* ``lights`` — Arbree, Walter & Bala 2005: the ambient as SH irradiance plus each area light integrated over its
  disc (uniform radiance: power / solid angle) with ``light_samples`` stratified shadow rays per shading point —
  soft penumbrae. With ``ao`` the ambient is shadowed too (beyond the paper, whose §5 names that as its weakness):
  see :func:`ambient_visibility`.
* ``mediancut`` / ``varmin`` — ``count`` point lights carrying the whole map (Debevec 2005; Viriyothai & Debevec
  2009), one shadow ray each: hard shadows, no separate ambient — what users do today.

Shadow rays leave from the hit nudged along its geometric normal and go through Embree's occlusion query from
compiled kernels that make, trace and sum them on every core (:mod:`lightprobe.render.sampling`,
:mod:`lightprobe.render.embree`); no Python loop per pixel.
"""

from __future__ import annotations

import numpy as np

from ..lights.baselines import check_count, median_cut, variance_minimisation
from ..glossy.brdf import tangent_frame
from ..util.errors import UsageError
from ..lights.hybrid import DEFAULT_AMBIENT_ORDER, hybrid_irradiance
from ..sh.irradiance import brute_irradiance
from ..lights.decompose import LightParams, decompose
from ..glossy.radiance import prepare, reflected_radiance
from ..sh.basis import SHCoeffs, project
from ..maps.tonemap import luminance
from .raycast import Hits, Tracer
from .scene import Scene

MAX_SAMPLES = 1024  # shadow rays per light (or ambient-occlusion rays) per shading point


class PerEnvironment:
    """A value computed once per environment map.

    The key is the map itself, compared by identity: an ``id()`` alone can be reused by a new map once the old one is
    freed, which served one map's value for another.

    Only the last map and its value are kept: a new map replaces them.

    Parameters
    ----------
    make : callable
        Called as ``make(env)`` with the environment map to compute its value.
    """

    def __init__(self, make):
        self.make, self._key, self._value = make, None, None

    def get(self, env):
        """The value for ``env``: ``make(env)`` when ``env`` is not the map of the last call, else the value kept.

        Parameters
        ----------
        env : EnvMap
            The environment map (radiance, world frame), compared by identity (``is``), not by content.

        Returns
        -------
        object
            What ``make`` returned for this very map object.
        """
        if self._key is not env:
            self._value, self._key = self.make(env), env
        return self._value


class Method:
    """Base class: ``shade(scene, tracer, hits)`` → outgoing radiance (len(hits), 3).

    ``glossy`` says whether it shades materials with a BRDF (:attr:`lightprobe.render.scene.Material.glossy`); those
    that do not are refused such scenes.
    """

    name = "method"
    glossy = False

    def shade(self, scene: Scene, tracer: Tracer, hits: Hits) -> np.ndarray:
        """Outgoing radiance toward the eye at every hit.

        Each method implements it (the base raises NotImplementedError). For a Lambertian surface it is
        ``albedo · E / π``, E what the method knows of the irradiance (not divided by π).

        Parameters
        ----------
        scene : Scene
            The scene being rendered; its ``environment`` (radiance, world frame: +Y up, front −Z) is the only light.
        tracer : Tracer
            The scene's ray tracer (:class:`lightprobe.render.raycast.Tracer`), for the methods that cast shadow rays.
        hits : Hits
            The first hits of the camera rays (:class:`lightprobe.render.raycast.Hits`), one row per hit: unit shading
            normals facing the viewer (world frame), albedo (linear RGB), unit directions toward the eye, …

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) outgoing radiance, linear RGB, one row per hit in the order of ``hits``.
        """
        raise NotImplementedError

    def describe(self) -> str:
        """One line naming the method and its options.

        The renderer records it as the ``method`` of the :class:`~lightprobe.render.renderer.Rendering` it returns.

        Returns
        -------
        str
            Here the method's ``name``; the methods with options state them.
        """
        return self.name


class SHMethod(Method):
    """SH irradiance of order ``order`` (``window``: none, hanning, lanczos, auto), per pixel or per vertex.

    Parameters
    ----------
    order : int
        SH order l_max, a whole number ≥ 0: (order + 1)² coefficients. Default 2 (the paper's nine).
    per_vertex : bool
        False (default): E evaluated at each pixel's shading normal. True: at the meshes' vertex normals and
        interpolated across each triangle with the hit's barycentric coordinates, as the paper's hardware shader did.
    window : str
        De-ringing window applied to the radiance coefficients before they are convolved into irradiance: ``none``
        (default), ``hanning``, ``lanczos`` or ``auto`` (:meth:`lightprobe.sh.basis.SHCoeffs.windowed`). Order and
        window are checked when the first environment is projected.
    """

    name = "sh"

    def __init__(self, order: int = 2, per_vertex: bool = False, window: str = "none"):
        self.order, self.per_vertex, self.window = order, per_vertex, window
        self._sh = PerEnvironment(lambda env: project(env, self.order).windowed(self.window).to_irradiance())

    def coefficients(self, scene: Scene) -> SHCoeffs:
        """Irradiance coefficients of the scene's environment (projected once per environment).

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) is projected to order ``order``, windowed by ``window`` and
            convolved into irradiance; the result is kept for this environment map (:class:`PerEnvironment`).

        Returns
        -------
        SHCoeffs
            Irradiance coefficients E_lm (E, not divided by π), world frame, real SH without the Condon–Shortley phase.

        Raises
        ------
        UsageError
            ``order`` is not a whole number ≥ 0, or ``window`` is not one of the windows.
        """
        return self._sh.get(scene.environment)

    def shade(self, scene, tracer, hits):
        """Lambertian radiance ``albedo · max(E, 0) / π`` from the SH irradiance E, with no shadows.

        Per pixel, E is evaluated at each hit's shading normal. Per vertex, it is evaluated at the mesh's vertex normals
        and interpolated with the hit's barycentric coordinates, except where the viewer sees a triangle's back: vertex
        normals face outward, so such a hit takes E per pixel at its flipped normal (the far side's irradiance).

        Parameters
        ----------
        scene : Scene
            Its environment gives the coefficients (:meth:`SHMethod.coefficients`); per vertex, its meshes' vertex
            normals.
        tracer : Tracer
            Not used: SH irradiance casts no rays.
        hits : Hits
            Reads ``normal`` (unit, world frame, facing the viewer) and ``albedo``; per vertex also ``mesh``, ``face``,
            ``barycentric`` and ``back``.

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB.
        """
        e = self.coefficients(scene)
        if not self.per_vertex:
            irradiance = e.evaluate(hits.normal)
        else:
            irradiance = np.empty((len(hits), 3))
            for k, mesh in enumerate(scene.meshes):
                sel = hits.mesh == k
                if sel.any():
                    at_vertices = e.evaluate(mesh.normals)
                    corners = at_vertices[mesh.faces[hits.face[sel]]]  # (n, 3 corners, RGB)
                    irradiance[sel] = np.einsum("ij,ijk->ik", hits.barycentric[sel], corners)
            # vertex normals face outward: a triangle seen from the back takes its far side's irradiance per pixel
            if hits.back.any():
                irradiance[hits.back] = e.evaluate(hits.normal[hits.back])
        return hits.albedo * np.maximum(irradiance, 0.0) / np.pi

    def describe(self):
        """Order, coefficient count, per pixel or per vertex, and the window when there is one.

        Returns
        -------
        str
            E.g. ``SH order 2 (9 coefficients), per pixel``.
        """
        where = "per vertex" if self.per_vertex else "per pixel"
        window = "" if self.window == "none" else f", {self.window} window"
        return f"SH order {self.order} ({(self.order + 1) ** 2} coefficients), {where}{window}"


class BruteMethod(Method):
    """Exact irradiance at every pixel's normal by summing the whole map (no shadows); on a glossy material the
    exact reflected radiance toward each pixel's own view (:func:`lightprobe.glossy.radiance.reflected_radiance`)."""

    name = "brute"
    glossy = True

    def __init__(self):
        self._lighting = PerEnvironment(prepare)

    def shade(self, scene, tracer, hits):
        """Exact outgoing radiance at every hit, with no shadows.

        Lambertian: ``albedo · E / π`` with E summed over every pixel of the map at each hit's normal
        (:func:`lightprobe.sh.irradiance.brute_irradiance`); on a glossy mesh its BRDF's exact reflected radiance toward
        each hit's own view instead.

        Parameters
        ----------
        scene : Scene
            Its environment lights every hit; meshes whose material is glossy are shaded by their BRDF, the environment
            prepared for the radiance sums once per environment (:func:`lightprobe.glossy.radiance.prepare`).
        tracer : Tracer
            Not used: no rays are cast.
        hits : Hits
            Reads ``normal`` (unit, world frame), ``albedo``, ``mesh`` and, on glossy meshes, ``view`` (unit, toward the
            eye).

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB.
        """
        out = hits.albedo * brute_irradiance(scene.environment, hits.normal) / np.pi
        for k, mesh in enumerate(scene.meshes):
            on = np.flatnonzero(hits.mesh == k)
            if mesh.material.glossy and on.size:
                out[on] = reflected_radiance(self._lighting.get(scene.environment), mesh.material.brdf,
                                             hits.normal[on], hits.view[on])
        return out

    def describe(self):
        """What brute force integrates, in words.

        Returns
        -------
        str
            The same line for every instance (the method has no options).
        """
        return ("brute force: the whole map integrated at each pixel's normal, and each glossy pixel's own view "
                "(no shadows)")


class HybridMethod(Method):
    """The lights summed exactly + SH of the ambient at every pixel's normal (no shadows).

    Parameters
    ----------
    order : int
        SH order of the ambient's irradiance. Default :data:`lightprobe.lights.hybrid.DEFAULT_AMBIENT_ORDER` (12).
    params : LightParams or None
        Parameters of the decomposition into lights and ambient (:class:`lightprobe.lights.decompose.LightParams`);
        None: the paper's defaults.
    """

    name = "hybrid"

    def __init__(self, order: int = DEFAULT_AMBIENT_ORDER, params: LightParams | None = None):
        self.order = order
        self._hybrid = PerEnvironment(lambda env: hybrid_irradiance(env, ambient_order=order, params=params))

    def shade(self, scene, tracer, hits):
        """Lambertian radiance from the hybrid irradiance at each hit's normal, with no shadows.

        ``albedo · max(E, 0) / π``, E every light's own pixels summed exactly plus the ambient's SH irradiance
        (:func:`lightprobe.lights.hybrid.hybrid_irradiance`).

        Parameters
        ----------
        scene : Scene
            Its environment is decomposed and its hybrid irradiance made once per environment map.
        tracer : Tracer
            Not used: no rays are cast.
        hits : Hits
            Reads ``normal`` (unit, world frame, facing the viewer) and ``albedo``.

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB.
        """
        return hits.albedo * np.maximum(self._hybrid.get(scene.environment).evaluate(hits.normal), 0.0) / np.pi

    def describe(self):
        """The ambient's SH order, and that there are no shadows.

        Returns
        -------
        str
            E.g. ``hybrid: area lights summed exactly + ambient SH order 12 (no shadows)``.
        """
        return f"hybrid: area lights summed exactly + ambient SH order {self.order} (no shadows)"


def _check_samples(what: str, n) -> None:
    if not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_SAMPLES:
        raise UsageError(f"{what} must be a whole number from 1 to {MAX_SAMPLES}, got {n!r}")


class LightsMethod(Method):
    """Area lights with soft shadows + SH ambient (Arbree, Walter & Bala 2005), optionally ambient occlusion.

    Parameters
    ----------
    light_samples : int
        Stratified shadow rays per light per shading point, a whole number from 1 to :data:`MAX_SAMPLES` (1024).
        Default 16.
    ao : bool
        Shadow the ambient too, by the brightness-weighted visibility of :func:`ambient_visibility`. Default False.
    ao_samples : int
        Occlusion rays per shading point when ``ao`` is on, a whole number from 1 to :data:`MAX_SAMPLES` (checked
        even with ``ao`` off). Default 16.
    seed : int
        Seed of the method's random streams (one for the lights, one for the ambient's rays): the same seed renders
        the same image bit for bit. Default 0.
    order : int
        SH order of the ambient's irradiance. Default :data:`lightprobe.lights.hybrid.DEFAULT_AMBIENT_ORDER` (12).
    params : LightParams or None
        Parameters of the decomposition (:class:`lightprobe.lights.decompose.LightParams`); None: the paper's
        defaults.

    Raises
    ------
    UsageError
        ``light_samples`` or ``ao_samples`` is not a whole number from 1 to :data:`MAX_SAMPLES`.
    """

    name = "lights"

    def __init__(self, light_samples: int = 16, ao: bool = False, ao_samples: int = 16, seed: int = 0,
                 order: int = DEFAULT_AMBIENT_ORDER, params: LightParams | None = None):
        _check_samples("light samples", light_samples)
        _check_samples("ambient-occlusion samples", ao_samples)
        self.light_samples, self.ao, self.ao_samples, self.seed, self.order = light_samples, ao, ao_samples, seed, order
        self._parts = PerEnvironment(lambda env: _lights_parts(env, params, order))

    def decomposition(self, scene: Scene):
        """The scene environment's decomposition (found once per environment).

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) is decomposed with the method's ``params``; the result is shared by
            every ``lights`` method with the same ``params`` and ``order`` on the same map (the last map only).

        Returns
        -------
        Decomposition
            The area lights (world frame) in the order found and the ambient map
            (:class:`lightprobe.lights.decompose.Decomposition`).
        """
        return self._parts.get(scene.environment)[0]

    def shade(self, scene, tracer, hits):
        """Lambertian radiance with soft shadows: the ambient's SH irradiance plus every area light's visible share.

        ``albedo · E / π``: E is the ambient's SH irradiance (clamped at 0, times its visibility with ``ao``) plus, for
        each area light, its uniform radiance times the cap's visible cosine-weighted solid angle at the hit
        (:func:`visible_cosine_over_cap`).

        The random streams are drawn afresh from ``seed`` at every call, one for the lights and one for the ambient's
        rays, so turning ``ao`` on does not move the lights' samples.

        Parameters
        ----------
        scene : Scene
            Its environment's decomposition, ambient SH irradiance and brightness map are made once per environment map.
        tracer : Tracer
            Traces the shadow and occlusion rays, which leave from the hits nudged along their geometric normals
            (:meth:`lightprobe.render.raycast.Tracer.shadow_origins`).
        hits : Hits
            Reads ``normal`` (unit, world frame, facing the viewer), ``albedo``, and ``position`` and ``geometric`` for
            the rays' origins.

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB; without ``ao`` the ambient is never shadowed.
        """
        dec, ambient, brightness = self._parts.get(scene.environment)
        # one stream for the lights, one for the ambient's rays: turning --ao on does not move the lights' samples
        light_rng, ao_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(self.seed).spawn(2))
        origins = tracer.shadow_origins(hits)
        irradiance = np.maximum(ambient.evaluate(hits.normal), 0.0)
        if self.ao:
            irradiance *= ambient_visibility(tracer, origins, hits.normal, brightness, self.ao_samples,
                                             ao_rng)[:, None]
        for light in dec.lights:
            seen = visible_cosine_over_cap(tracer, origins, hits.normal, light.direction, light.radius,
                                           self.light_samples, light_rng)
            irradiance += seen[:, None] * light.radiance[None, :]
        return hits.albedo * irradiance / np.pi

    def describe(self):
        """Shadow rays per light, the ambient's SH order, ambient occlusion when on, and the seed.

        Returns
        -------
        str
            E.g. ``area lights (16 shadow rays each) + ambient SH order 12, seed 0``.
        """
        ao = f", ambient occlusion ({self.ao_samples} rays)" if self.ao else ""
        return (f"area lights ({self.light_samples} shadow rays each) + ambient SH order {self.order}{ao}, "
                f"seed {self.seed}")


_LAST_PARTS: dict = {"env": None, "parts": {}}  # the decompositions of the last environment, by (params, order)


def _lights_parts(env, params: LightParams | None, order: int):
    """The decomposition of ``env``, its ambient's SH irradiance and brightness map — shared by every ``lights``
    method on the same environment (``lights`` and ``lights --ao`` side by side decompose once). Only the last
    environment is kept, compared by identity as :class:`PerEnvironment` does."""
    if _LAST_PARTS["env"] is not env:
        _LAST_PARTS["env"], _LAST_PARTS["parts"] = env, {}
    key = (params or LightParams(), order)
    if key not in _LAST_PARTS["parts"]:
        dec = decompose(env, params)
        _LAST_PARTS["parts"][key] = (dec, project(dec.ambient, order).to_irradiance(), _visibility_map(dec.ambient))
    return _LAST_PARTS["parts"][key]


class PointLightsMethod(Method):
    """``count`` point lights from median cut or variance minimisation, one shadow ray each, no ambient.

    The class's ``name`` chooses the finder: ``mediancut`` here (Debevec 2005), ``varmin`` in
    :class:`VarminMethod` (Viriyothai & Debevec 2009).

    Parameters
    ----------
    count : int
        Point lights to make of the whole map, a whole number from 1 to 4096
        (:func:`lightprobe.lights.baselines.check_count`). Default 16.

    Raises
    ------
    UsageError
        ``count`` is out of range or not a whole number.
    """

    name = "mediancut"
    _finders = {"mediancut": (median_cut, "median cut"), "varmin": (variance_minimisation, "variance minimisation")}

    def __init__(self, count: int = 16):
        check_count(count)
        self.count = count
        find = self._finders[self.name][0]
        self._lights = PerEnvironment(lambda env: find(env, count))

    def shade(self, scene, tracer, hits):
        """Lambertian radiance from the point lights, with hard shadows and no ambient.

        ``albedo · E / π``: E sums, over the lights above the hit's horizon (n·d > 0), (n·d) times the light's power Φ
        (RGB ∫L dω of its region) where its one shadow ray toward the light (at infinity) is free.

        Parameters
        ----------
        scene : Scene
            Its environment's point lights are found once per environment map.
        tracer : Tracer
            Traces one shadow ray per light per hit above that light's horizon, from the hit nudged along its geometric
            normal (:meth:`lightprobe.render.raycast.Tracer.shadow_origins`).
        hits : Hits
            Reads ``normal`` (unit, world frame, facing the viewer) for the cosines, ``albedo``, and ``position`` and
            ``geometric`` for each shadow ray's origin.

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB: 0 where every light is blocked or below the horizon.
        """
        origins = tracer.shadow_origins(hits)
        irradiance = np.zeros((len(hits), 3))
        for light in self._lights.get(scene.environment):
            cosine = hits.normal @ light.direction
            lit = np.nonzero(cosine > 0)[0]
            free = ~tracer.occluded(origins[lit], light.direction[None, :])
            irradiance[lit[free]] += cosine[lit[free], None] * light.power[None, :]
        return hits.albedo * irradiance / np.pi

    def describe(self):
        """The finder, the light count, and that shadows are hard with no ambient.

        Returns
        -------
        str
            E.g. ``median cut: 16 point lights, hard shadows, no ambient``.
        """
        plural = "s" if self.count > 1 else ""
        return f"{self._finders[self.name][1]}: {self.count} point light{plural}, hard shadows, no ambient"


class VarminMethod(PointLightsMethod):
    """:class:`PointLightsMethod` with the lights of variance minimisation (Viriyothai & Debevec 2009).

    Parameters
    ----------
    count : int
        Point lights to make of the whole map, a whole number from 1 to 4096. Default 16.
    """
    name = "varmin"


# ---- sampling ---------------------------------------------------------------------------------------------------
def visible_cosine_over_cap(tracer: Tracer, origins: np.ndarray, normals: np.ndarray, direction: np.ndarray,
                            radius: float, n: int, rng) -> np.ndarray:
    """∫ over the cap (unit ``direction``, angular ``radius``) of max(n·ω, 0) V(ω) dω at each point (sr).

    Times a uniform radiance it is the light's irradiance. Exact where nothing can block the cap (the meshes' planes and
    bounding spheres, :attr:`lightprobe.render.raycast.Tracer.cone_bounds`) and the whole cap is above the shading
    horizon (n·d ≥ sin r): n·d · π sin² r. Zero where it is wholly below (n·d ≤ −sin r). Elsewhere ``n`` stratified
    samples uniform in solid angle, a shadow ray traced for each above the shading horizon
    (:func:`lightprobe.render.sampling.cap_visible`).

    Parameters
    ----------
    tracer : Tracer
        The scene's tracer: its ``cone_bounds`` tell where nothing can block the cap, its Embree scene traces the
        shadow rays.
    origins : numpy.ndarray
        (N, 3) ray origins, world frame: the shading points nudged off their surface
        (:meth:`lightprobe.render.raycast.Tracer.shadow_origins`).
    normals : numpy.ndarray
        (N, 3) unit shading normals, world frame.
    direction : numpy.ndarray
        (3,) unit direction toward the cap's centre (the light), world frame.
    radius : float
        The cap's angular radius in radians, in (0, π/2).
    n : int
        Stratified samples per point where the cap is sampled (the ``lights`` method allows 1 to
        :data:`MAX_SAMPLES`).
    rng : numpy.random.Generator
        Draws the one key of the sampling kernel's random streams: the same generator state gives the same samples.

    Returns
    -------
    numpy.ndarray
        (N,) float64 visible cosine-weighted solid angle (sr); times the light's radiance, its irradiance E (not
        divided by π).

    Raises
    ------
    ValueError
        ``radius`` is not in (0, π/2).
    """
    from .sampling import cap_visible, draw_key

    if not 0 < radius < np.pi / 2:
        raise ValueError(f"a light's angular radius must be in (0, π/2), got {radius!r}")
    axis = np.asarray(direction, dtype=np.float64)
    normals, origins = np.ascontiguousarray(normals, np.float64), np.ascontiguousarray(origins, np.float64)
    t, s = tangent_frame(axis)
    out = np.empty(len(normals))
    if len(out):
        cap_visible(normals, origins, axis, t, s, float(radius), n, *tracer.cone_bounds, draw_key(rng),
                    tracer.embree.handle, out)
    return out


# ---- the ambient's shadows --------------------------------------------------------------------------------------
VISIBILITY_ROWS = 32  # the ambient's brightness map that weights occlusion rays (smooth is what is wanted)


def _visibility_map(ambient) -> np.ndarray:
    """The ambient's luminance on a small lat-long (energy-conserving resampling: a blurred copy), for weighting."""
    from ..maps.layouts import LATLONG

    small = ambient.to(LATLONG, VISIBILITY_ROWS)
    return np.ascontiguousarray(np.maximum(luminance(small.data.astype(np.float64)), 0.0))


def ambient_visibility(tracer: Tracer, origins: np.ndarray, normals: np.ndarray, brightness: np.ndarray, n: int,
                       rng) -> np.ndarray:
    """The shadowed share of each point's ambient irradiance, to multiply its (unshadowed) SH irradiance by.

    Which and why: ``n`` cosine-weighted rays per point (stratified, Malley's method), each weighted by the ambient's
    brightness in its direction — Σ Y(ω) V(ω) / Σ Y(ω), a ratio estimator of ∫ L V cos dω / ∫ L cos dω. Plain
    ambient occlusion (Σ V / n) would darken a point under a bunny as much for a black floor blocked as for a bright
    sky; weighting by the ambient's own brightness (``brightness``: a 32-row blurred lat-long of its luminance, read
    bilinearly) removes that bias where the ambient is directional, and it keeps SH's accuracy exactly where nothing
    is blocked (the ratio is 1). A bent normal would need the same rays and still treat every direction alike.
    Points whose rays all see black get 1 (:func:`lightprobe.render.sampling.cosine_seen`).

    Parameters
    ----------
    tracer : Tracer
        The scene's tracer, whose Embree scene traces the occlusion rays.
    origins, normals : numpy.ndarray
        (N, 3) ray origins and (N, 3) unit shading normals, world frame, as for :func:`visible_cosine_over_cap`.
    brightness : numpy.ndarray
        (H, W) float64 lat-long of the ambient's luminance, rows from +Y down, column 0 at azimuth −π from the
        front −Z; each ray's weight is its bilinear lookup. The ``lights`` method passes :data:`VISIBILITY_ROWS` (32)
        rows, an energy-conserving resampling of the ambient, negative values clamped to 0.
    n : int
        Cosine-weighted rays per point (the ``lights`` method allows 1 to :data:`MAX_SAMPLES`).
    rng : numpy.random.Generator
        Draws the one key of the sampling kernel's random streams.

    Returns
    -------
    numpy.ndarray
        (N,) float64 visibility in [0, 1]: Σ Y V / Σ Y over each point's rays, 1 where every weight is 0.
    """
    from .sampling import cosine_seen, draw_key

    normals, origins = np.ascontiguousarray(normals, np.float64), np.ascontiguousarray(origins, np.float64)
    tangent, bitangent = (np.ascontiguousarray(v) for v in tangent_frame(normals))
    seen, total = np.empty(len(origins)), np.empty(len(origins))
    if len(origins):
        cosine_seen(normals, tangent, bitangent, origins, n, brightness, draw_key(rng), tracer.embree.handle, seen,
                    total)
    return np.where(total > 0, seen / np.where(total > 0, total, 1.0), 1.0)


METHODS = {"sh": SHMethod, "brute": BruteMethod, "hybrid": HybridMethod, "lights": LightsMethod,
           "mediancut": PointLightsMethod, "varmin": VarminMethod}


def all_methods() -> dict:
    """Every rendering method by name: those here and the glossy ones.

    The glossy ones are :mod:`lightprobe.render.glossy`'s, which builds on this module's :class:`Method`.

    Returns
    -------
    dict
        Name → method class: :data:`METHODS` and :data:`lightprobe.render.glossy.GLOSSY_METHODS`, in a new dict.
    """
    from .glossy import GLOSSY_METHODS

    return {**METHODS, **GLOSSY_METHODS}


def method(name: str, **options) -> Method:
    """A method by name with its options (e.g. ``method("sh", order=4, per_vertex=True)``).

    Parameters
    ----------
    name : str
        A name of :func:`all_methods`: ``sh``, ``brute``, ``hybrid``, ``lights``, ``mediancut``, ``varmin``,
        ``direct``, ``rsibr`` or ``splitsum``.
    **options
        Keyword arguments of that method's class (e.g. ``order``, ``per_vertex`` and ``window`` of
        :class:`SHMethod`), checked by its constructor.

    Returns
    -------
    Method
        A new instance of the named method.

    Raises
    ------
    UsageError
        The name is unknown (the message lists the known ones), or the class refuses an option's value.
    """
    known = all_methods()
    try:
        cls = known[name]
    except KeyError:
        raise UsageError(f"unknown method {name!r}; known: {', '.join(known)}") from None
    return cls(**options)
