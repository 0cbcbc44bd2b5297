"""Lighting methods: how a diffuse surface point is shaded under the scene's environment.

A method turns hits into outgoing radiance, ``albedo · E / π`` for Lambertian surfaces, where E is what the method
knows of the irradiance. This issue brings two; later ones (area lights with soft shadows, radiance maps) register
more in :data:`METHODS`.

* ``sh`` — SH irradiance (any order, optional window): per pixel at the shading normal, or per vertex and
  interpolated across triangles as the paper's hardware shader did. No shadows: the whole environment lights
  every normal.
* ``brute`` — exact irradiance at the shading normal, integrating every pixel of the map. Also no shadows: it is
  the exact value of what ``sh`` approximates, so their difference is SH's own error.
"""

from __future__ import annotations

import numpy as np

from ..errors import UsageError
from ..irradiance import brute_irradiance
from ..sh import SHCoeffs, project
from .raycast import Hits, Tracer
from .scene import Scene


class Method:
    """Base class: ``shade(scene, tracer, hits)`` → outgoing radiance (len(hits), 3)."""

    name = "method"

    def shade(self, scene: Scene, tracer: Tracer, hits: Hits) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> str:
        return self.name


class SHMethod(Method):
    """SH irradiance of order ``order`` (``window``: none, hanning, lanczos, auto), per pixel or per vertex."""

    name = "sh"

    def __init__(self, order: int = 2, per_vertex: bool = False, window: str = "none"):
        self.order, self.per_vertex, self.window = order, per_vertex, window
        self._cache: tuple[object, SHCoeffs] | None = None

    def coefficients(self, scene: Scene) -> SHCoeffs:
        """Irradiance coefficients of the scene's environment (projected once per environment).

        The cache holds the environment itself and compares identity: an ``id()`` alone can be reused by a new
        map once the old one is freed, which served one map's coefficients for another."""
        if self._cache is None or self._cache[0] is not scene.environment:
            sh = project(scene.environment, self.order).windowed(self.window).to_irradiance()
            self._cache = (scene.environment, sh)
        return self._cache[1]

    def shade(self, scene, tracer, hits):
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
        where = "per vertex" if self.per_vertex else "per pixel"
        window = "" if self.window == "none" else f", {self.window} window"
        return f"SH order {self.order} ({(self.order + 1) ** 2} coefficients), {where}{window}"


class BruteMethod(Method):
    """Exact irradiance at every pixel's normal by summing the whole map (no shadows)."""

    name = "brute"

    def shade(self, scene, tracer, hits):
        return hits.albedo * brute_irradiance(scene.environment, hits.normal) / np.pi

    def describe(self):
        return "brute force: the whole map integrated at each pixel's normal (no shadows)"


METHODS = {"sh": SHMethod, "brute": BruteMethod}


def method(name: str, **options) -> Method:
    """A method by name with its options (e.g. ``method("sh", order=4, per_vertex=True)``)."""
    try:
        cls = METHODS[name]
    except KeyError:
        raise UsageError(f"unknown method {name!r}; known: {', '.join(METHODS)}") from None
    return cls(**options)
