"""Rendering methods for glossy materials (Cabral, Olano & Nemec 1999, and the split-sum baseline engines ship).

Every method here shades a scene's glossy meshes (:attr:`lightprobe.render.scene.Material.glossy`) by its own
means and its Lambertian meshes exactly (brute-force irradiance, no shadows), so glossy and diffuse surfaces share
one scene. No method casts shadows or interreflections (the radiance-map methods' assumption, docs/spec.md §4):
compare them with Mitsuba's direct lighting of convex objects or read the difference as what they leave out.

* ``direct`` — the exact radiance map for the camera's view (eye − target), read at each pixel's normal: the
  paper's one map per frame, computed instead of synthesised (the orthographic approximation, no blending error).
* ``rsibr`` — reflection-space IBR: radiance maps at ``views`` geodesic view directions, baked once per
  environment and BRDF; per frame one map synthesised for the camera's view (the paper), or with
  ``per_pixel_view`` each pixel's own view blended from the three maps around it (removing the orthographic
  approximation).
* ``splitsum`` — Karis 2013 as Filament and three.js do it: the environment prefiltered with the GGX lobe of the
  material's α under n = v = r (:func:`lightprobe.glossy.prefilter.prefilter_cube`), read at the mirror direction,
  times F0·A(n·v) + B(n·v), the DFG terms of the same GGX (F0 = the material's Fresnel at normal incidence,
  Schlick's curve from there). GGX materials only.
"""

from __future__ import annotations

import numpy as np

from ..glossy.brdf import GGX, BRDF, Schlick, reflect
from ..util.errors import UsageError
from ..sh.irradiance import brute_irradiance
from ..glossy.prefilter import hammersley, prefilter_cube
from ..glossy.radiance import check_views, geodesic_views, prepare, radiance_map
from ..glossy.radiancefile import RadianceSet, radiance_set
from ..glossy.rsibr import SMOOTH_MIN_LOBE, map_at_normals, reflected_by_view, synthesize
from .methods import Method, PerEnvironment

DEFAULT_MAP_SIZE = 128
MAX_MAP_SIZE = 1024
SPLITSUM_CUBE = 128  # face size of the prefiltered cube
DFG_STEPS, DFG_SAMPLES = 64, 4096


def camera_view(scene) -> np.ndarray:
    """The unit direction from the camera's target toward its eye: the one view of a frame's radiance map.

    Parameters
    ----------
    scene : Scene
        Its camera's ``eye`` and ``target`` (world frame) are read.

    Returns
    -------
    numpy.ndarray
        (3,) float64 unit vector, world frame: (eye − target) / |eye − target|.
    """
    d = np.asarray(scene.camera.eye, dtype=np.float64) - np.asarray(scene.camera.target, dtype=np.float64)
    return d / np.linalg.norm(d)


class GlossyMethod(Method):
    """Base: Lambertian meshes by brute-force irradiance, glossy ones by :meth:`GlossyMethod.reflected`."""

    glossy = True

    def __init__(self):
        self._cache = PerEnvironment(lambda env: {})

    def cached(self, scene, key, make):
        """A value made once per environment and ``key`` (a BRDF's spec, a view, …).

        The store belongs to the last environment map only (compared by identity,
        :class:`lightprobe.render.methods.PerEnvironment`): another map starts an empty one.

        Parameters
        ----------
        scene : Scene
            Its ``environment`` selects the store.
        key : hashable
            Names the value within that environment's store.
        make : callable
            Called with no arguments to make the value when ``key`` is not in the store yet.

        Returns
        -------
        object
            The stored value: what ``make`` returned, at this call or an earlier one.
        """
        store = self._cache.get(scene.environment)
        if key not in store:
            store[key] = make()
        return store[key]

    def shade(self, scene, tracer, hits):
        """Outgoing radiance at every hit: glossy meshes by their BRDF, Lambertian ones exactly, no shadows.

        A hit on a glossy mesh takes :meth:`GlossyMethod.reflected` toward its own view; one on a Lambertian mesh takes
        ``albedo · E / π``, E the brute-force irradiance at its normal
        (:func:`lightprobe.sh.irradiance.brute_irradiance`).

        Parameters
        ----------
        scene : Scene
            Its environment lights the hits; each mesh's material chooses how its hits are shaded.
        tracer : Tracer
            Not used: the glossy methods cast no rays.
        hits : Hits
            Reads ``mesh``, ``normal`` (unit, world frame, facing the viewer), ``view`` (unit, toward the eye) and
            ``albedo``.

        Returns
        -------
        numpy.ndarray
            (len(hits), 3) float64 outgoing radiance, linear RGB.
        """
        out = np.zeros((len(hits), 3))
        for k, mesh in enumerate(scene.meshes):
            on = np.flatnonzero(hits.mesh == k)
            if not on.size:
                continue
            if mesh.material.glossy:
                out[on] = self.reflected(scene, mesh.material.brdf, hits.normal[on], hits.view[on])
            else:
                out[on] = hits.albedo[on] * brute_irradiance(scene.environment, hits.normal[on]) / np.pi
        return out

    def reflected(self, scene, brdf: BRDF, normals: np.ndarray, views: np.ndarray) -> np.ndarray:
        """Reflected radiance L_r of ``brdf`` at unit ``normals`` seen from unit ``views``.

        Each glossy method implements it (the base raises NotImplementedError).

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) lights the surface; its camera gives the view of the one-map
            methods.
        brdf : BRDF
            The material's BRDF (:class:`lightprobe.glossy.brdf.BRDF`).
        normals : numpy.ndarray
            (N, 3) float64 unit shading normals, world frame, facing the viewer.
        views : numpy.ndarray
            (N, 3) float64 unit directions from each point toward the eye, world frame.

        Returns
        -------
        numpy.ndarray
            (N, 3) reflected radiance, linear RGB.
        """
        raise NotImplementedError

    def lighting(self, scene):
        """The scene's environment prepared for the radiance sums, once per environment.

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) is prepared by :func:`lightprobe.glossy.radiance.prepare`.

        Returns
        -------
        Lighting
            The :class:`lightprobe.glossy.radiance.Lighting` of the environment, kept under the key ``"lighting"``.
        """
        return self.cached(scene, "lighting", lambda: prepare(scene.environment))


def _check_size(size) -> int:
    if not isinstance(size, (int, np.integer)) or not 8 <= size <= MAX_MAP_SIZE:
        raise UsageError(f"radiance map size must be a whole number from 8 to {MAX_MAP_SIZE}, got {size!r}")
    return int(size)


class DirectMethod(GlossyMethod):
    """The exact radiance map of the camera's view, read at each pixel's normal.

    Parameters
    ----------
    map_size : int
        Texels on a side of the radiance map, a whole number from 8 to :data:`MAX_MAP_SIZE` (1024). Default
        :data:`DEFAULT_MAP_SIZE` (128).

    Raises
    ------
    UsageError
        ``map_size`` is out of range or not a whole number.
    """

    name = "direct"

    def __init__(self, map_size: int = DEFAULT_MAP_SIZE):
        super().__init__()
        self.map_size = _check_size(map_size)

    def reflected(self, scene, brdf, normals, views):
        """L_r read at each normal from the exact radiance map of the camera's view (the orthographic approximation).

        Every point takes the frame's one view (:func:`camera_view`), not its own: ``views`` is not used. The map
        (:func:`lightprobe.glossy.radiance.radiance_map`) is made once per environment, BRDF, view and map size.

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) and its camera's view.
        brdf : BRDF
            The material's BRDF; its spec is part of the cached map's key.
        normals : numpy.ndarray
            (N, 3) unit shading normals, world frame, read bilinearly from the map
            (:func:`lightprobe.glossy.rsibr.map_at_normals`).
        views : numpy.ndarray
            (N, 3) unit directions toward the eye; not used.

        Returns
        -------
        numpy.ndarray
            (N, 3) float64 reflected radiance, linear RGB.
        """
        v = camera_view(scene)
        rmap = self.cached(scene, ("direct", brdf.spec(), tuple(v), self.map_size),
                           lambda: radiance_map(self.lighting(scene), brdf, v, self.map_size))
        return map_at_normals(rmap, normals)

    def describe(self):
        """The map's size, and that it is the exact map of the camera's view.

        Returns
        -------
        str
            E.g. ``direct: the exact 128² radiance map of the camera's view, read at each normal``.
        """
        return f"direct: the exact {self.map_size}² radiance map of the camera's view, read at each normal"


class RSIBRMethod(GlossyMethod):
    """Reflection-space IBR from ``views`` precomputed maps (see the module docstring).

    Parameters
    ----------
    views : int
        Source radiance maps, at the vertices of an icosahedron or of its geodesic subdivisions: 12 (default), 42 or
        162 (:func:`lightprobe.glossy.radiance.check_views`).
    map_size : int
        Texels on a side of each source map, a whole number from 8 to :data:`MAX_MAP_SIZE` (1024). Default
        :data:`DEFAULT_MAP_SIZE` (128).
    per_pixel_view : bool
        False (default): one map synthesised per frame for the camera's view (the paper). True: each pixel's own view
        blended from the three maps around it (removing the orthographic approximation).
    warp : str or None
        The direction the maps are warped through: ``normal`` or ``mirror``; None (default) the BRDF's own central
        direction.
    smooth : bool
        True (default): the smooth part of the lighting summed exactly and only the rest warped
        (:func:`lightprobe.glossy.rsibr.synthesize`); False warps the whole maps as the paper does.

    Raises
    ------
    UsageError
        ``views`` is not 12, 42 or 162, ``map_size`` is out of range, or ``warp`` is not one of the warps.
    """

    name = "rsibr"

    def __init__(self, views: int = 12, map_size: int = DEFAULT_MAP_SIZE, per_pixel_view: bool = False,
                 warp: str | None = None, smooth: bool = True):
        super().__init__()
        self.views, self.map_size = check_views(views), _check_size(map_size)
        self.per_pixel_view, self.warp, self.smooth = bool(per_pixel_view), warp, bool(smooth)
        if warp not in (None, "normal", "mirror"):
            raise UsageError(f"warp must be normal or mirror, got {warp!r}")

    def radiance_set(self, scene, brdf: BRDF) -> RadianceSet:
        """The set of source maps of ``brdf`` under the scene's environment (baked once per environment).

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) is prepared once (:meth:`GlossyMethod.lighting`).
        brdf : BRDF
            The material's BRDF; its spec, with ``views`` and ``map_size``, keys the cached set.

        Returns
        -------
        RadianceSet
            ``views`` radiance maps of ``map_size``² at the geodesic views (sphere layout, frames of
            :func:`lightprobe.glossy.radiance.view_frame`), radiance, world frame, with the view mesh's triangles
            (:class:`lightprobe.glossy.radiancefile.RadianceSet`).
        """
        return self.cached(scene, ("set", brdf.spec(), self.views, self.map_size), lambda: radiance_set(
            self.lighting(scene), brdf, *geodesic_views(self.views), self.map_size))

    def reflected(self, scene, brdf, normals, views):
        """L_r by reflection-space IBR from the source maps of ``brdf``.

        With ``per_pixel_view`` each point's own view is blended from the three source maps around it
        (:func:`lightprobe.glossy.rsibr.reflected_by_view`); otherwise one map is synthesised for the camera's view
        (:func:`camera_view`, :func:`lightprobe.glossy.rsibr.synthesize`) and read at each normal, and ``views`` is not
        used.

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) and, for one map per frame, its camera's view.
        brdf : BRDF
            The material's BRDF, whose source maps are baked once per environment (:meth:`RSIBRMethod.radiance_set`).
        normals : numpy.ndarray
            (N, 3) unit shading normals, world frame, facing the viewer.
        views : numpy.ndarray
            (N, 3) unit directions from each point toward the eye, world frame (read with ``per_pixel_view`` only).

        Returns
        -------
        numpy.ndarray
            (N, 3) reflected radiance, linear RGB.
        """
        rset = self.radiance_set(scene, brdf)
        if self.per_pixel_view:
            return reflected_by_view(rset, normals, views, self.warp, self.smooth)
        return map_at_normals(synthesize(rset, camera_view(scene), self.warp, smooth=self.smooth), normals)

    def describe(self):
        """The number and size of the maps, one map per frame or per pixel, the warp and the synthesis.

        Returns
        -------
        str
            E.g. ``rsibr: 12 radiance maps 128², one map per frame (central warp, smooth part summed exactly …)``.
        """
        how = "each pixel's own view blended" if self.per_pixel_view else "one map per frame"
        part = (f"smooth part summed exactly for lobes ≥ {np.degrees(SMOOTH_MIN_LOBE):.0f}°" if self.smooth
                else "the paper's synthesis")
        return (f"rsibr: {self.views} radiance maps {self.map_size}², {how} ({self.warp or 'central'} warp, "
                f"{part})")


def dfg_terms(alpha: float, steps: int = DFG_STEPS, samples: int = DFG_SAMPLES) -> np.ndarray:
    """(steps, 2): A and B of the split sum at n·v = (i + ½)/steps.

    A = ∫ f_GGX(F = 1) cos · (1 − F_c) and B = ∫ f_GGX(F = 1) cos · F_c with F_c = (1 − h·wi)⁵, so that
    ∫ f cos = F0·A + B under Schlick's Fresnel. Importance-sampled with the same stratified uniforms at every n·v.

    Parameters
    ----------
    alpha : float
        GGX roughness α (as :class:`lightprobe.glossy.brdf.GGX` takes it).
    steps : int
        Rows of the table, row i at n·v = (i + ½)/steps. Default :data:`DFG_STEPS` (64), the row count
        :class:`SplitSumMethod` interpolates.
    samples : int
        Importance samples per row (Hammersley points, the same at every row). Default :data:`DFG_SAMPLES` (4096).

    Returns
    -------
    numpy.ndarray
        (steps, 2) float64: column 0 is A, column 1 is B (dimensionless).
    """
    brdf = GGX(alpha)
    mu = (np.arange(steps) + 0.5) / steps
    n = np.array([0.0, 0.0, 1.0])
    wo = np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], axis=-1)[:, None, :]
    u = hammersley(samples)[None]
    wi, pdf = brdf.sample(wo, n, u)
    f = brdf.eval(wi, wo, n)[..., 0] * np.maximum(wi[..., 2], 0.0)
    weight = np.where(pdf > 0, f / np.where(pdf > 0, pdf, 1.0), 0.0)
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    fc = (1 - np.clip(np.sum(h * wi, axis=-1), 0.0, 1.0)) ** 5
    return np.stack([(weight * (1 - fc)).mean(axis=1), (weight * fc).mean(axis=1)], axis=1)


def splitsum_cube(env, alpha: float, size: int):
    """The environment prefiltered with the GGX lobe of ``alpha`` under n = v = r: the split sum's first factor.

    A ``size``² cube (radiance, world frame); every mip level is prefiltered with the same α and the finest is kept.

    Parameters
    ----------
    env : EnvMap
        The environment, radiance, world frame, any layout (resampled, energy-conserving, into the cube).
    alpha : float
        GGX roughness α of the lobe.
    size : int
        Face size of the cube in texels, a power of two (:func:`lightprobe.glossy.prefilter.prefilter_cube`).

    Returns
    -------
    EnvMap
        The prefiltered cube, layout :data:`lightprobe.maps.layouts.CUBE`, radiance, world frame.

    Raises
    ------
    UsageError
        ``size`` is not a power of two, or beyond the prefilter's largest size.
    """
    from ..maps import EnvMap
    from ..maps.layouts import CUBE

    levels = int(np.log2(size)) + 1
    return EnvMap(prefilter_cube(env, size, [alpha] * levels).levels[0], CUBE)


class SplitSumMethod(GlossyMethod):
    """Karis's split sum (see the module docstring).

    Parameters
    ----------
    cube_size : int
        Face size of the prefiltered cube in texels, a power of two from 8 to 512. Default :data:`SPLITSUM_CUBE`
        (128).

    Raises
    ------
    UsageError
        ``cube_size`` is not a power of two from 8 to 512.
    """

    name = "splitsum"

    def __init__(self, cube_size: int = SPLITSUM_CUBE):
        super().__init__()
        if cube_size < 8 or cube_size & (cube_size - 1) or cube_size > 512:
            raise UsageError(f"splitsum cube size must be a power of two from 8 to 512, got {cube_size!r}")
        self.cube_size = cube_size

    def reflected(self, scene, brdf, normals, views):
        """L_r ≈ prefiltered(r) · (F0·A(n·v) + B(n·v)), r the mirror of the view about the normal.

        The prefiltered cube (:func:`splitsum_cube`) is read bilinearly at r; A and B (:func:`dfg_terms`) are
        interpolated linearly at n·v clamped to [0, 1]; F0 is :func:`normal_reflectance`. Cube and table are made once
        per environment and α.

        Parameters
        ----------
        scene : Scene
            Its environment (radiance, world frame) is prefiltered.
        brdf : GGX
            The material's BRDF, a :class:`lightprobe.glossy.brdf.GGX`: its α and its Fresnel at normal incidence.
        normals : numpy.ndarray
            (N, 3) unit shading normals, world frame, facing the viewer.
        views : numpy.ndarray
            (N, 3) unit directions from each point toward the eye, world frame.

        Returns
        -------
        numpy.ndarray
            (N, 3) reflected radiance, linear RGB.

        Raises
        ------
        UsageError
            ``brdf`` is not GGX: the split sum is defined for GGX only.
        """
        if not isinstance(brdf, GGX):
            raise UsageError(f"splitsum is defined for GGX materials, not {brdf.spec()}")
        cube = self.cached(scene, ("prefiltered", brdf.alpha, self.cube_size),
                           lambda: splitsum_cube(scene.environment, brdf.alpha, self.cube_size))
        dfg = self.cached(scene, ("dfg", brdf.alpha), lambda: dfg_terms(brdf.alpha))
        mu = np.clip(np.sum(normals * views, axis=1), 0.0, 1.0)
        x = np.clip(mu * DFG_STEPS - 0.5, 0, DFG_STEPS - 1)
        i = np.minimum(x.astype(int), DFG_STEPS - 2)
        t = (x - i)[:, None]
        a_b = dfg[i] * (1 - t) + dfg[i + 1] * t
        f0 = normal_reflectance(brdf)
        specular = f0[None, :] * a_b[:, :1] + a_b[:, 1:]
        return cube.lookup(reflect(views, normals)) * specular

    def describe(self):
        """The cube's size and the split sum's two factors.

        Returns
        -------
        str
            E.g. ``splitsum: GGX-prefiltered 128² cube × (F0·A + B) (Karis 2013)``.
        """
        return f"splitsum: GGX-prefiltered {self.cube_size}² cube × (F0·A + B) (Karis 2013)"


def normal_reflectance(brdf: GGX) -> np.ndarray:
    """F0, the material's Fresnel at normal incidence (RGB): where the engines' Schlick curve starts.

    Parameters
    ----------
    brdf : GGX
        A GGX BRDF: Schlick's Fresnel gives its ``f0`` as it is, any other Fresnel is evaluated at cos = 1.

    Returns
    -------
    numpy.ndarray
        (3,) F0 per RGB channel.
    """
    if isinstance(brdf.fresnel, Schlick):
        return np.asarray(brdf.fresnel.f0)
    return brdf.fresnel(np.array([1.0]))[0]


GLOSSY_METHODS = {"direct": DirectMethod, "rsibr": RSIBRMethod, "splitsum": SplitSumMethod}
