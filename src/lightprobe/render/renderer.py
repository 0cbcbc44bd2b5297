"""The project's renderer: primary rays through Embree, per-pixel shading by a pluggable lighting method.

Output is linear RGB radiance (H, W, 3) float32 with a box filter over spp × spp stratified samples per pixel;
pixels whose rays miss show the environment (bilinear lookup) when the scene's ``background`` is on, else 0.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..util.errors import BudgetError, UsageError
from ..util.limits import check_memory, max_triangles
from .methods import Method
from .raycast import Tracer
from .scene import Scene


@dataclass(frozen=True, eq=False)
class Rendering:
    """A rendered image with what made it.

    ``image`` radiance (H, W, 3), ``coverage`` the fraction of each pixel's samples that hit geometry, ``seconds``
    per stage.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W, 3) float32 linear RGB radiance, row 0 the image's top.
    coverage : numpy.ndarray
        (H, W) float32 in [0, 1]: the share of each pixel's samples that hit geometry.
    method : str
        What made it: the lighting method's :meth:`~lightprobe.render.methods.Method.describe`, or the reference's
        description.
    seconds : dict
        Seconds per stage by name (the renderer's ``rays``, ``intersect`` and ``shade``; the reference's ``load`` and
        ``render``).
    """

    image: np.ndarray
    coverage: np.ndarray
    method: str
    seconds: dict[str, float] = field(default_factory=dict)


# Peak bytes per camera sample: rays, hits with their attributes, shading temporaries (measured in
# tests/test_limits.py), and per triangle: our arrays and Embree's BVH.
BYTES_PER_SAMPLE = 400  # ~315 B measured
BYTES_PER_TRIANGLE = 200


def render_memory(width: int, height: int, spp: int, triangles: int) -> int:
    """Estimated memory (bytes, beyond the process itself) of :func:`render`.

    For a width × height image with spp × spp samples per pixel: :data:`BYTES_PER_SAMPLE` per camera sample plus
    :data:`BYTES_PER_TRIANGLE` per triangle.

    Parameters
    ----------
    width : int
        Image width in pixels.
    height : int
        Image height in pixels.
    spp : int
        Samples per pixel along each axis (spp² per pixel).
    triangles : int
        Triangles of the scene.

    Returns
    -------
    int
        The estimate in bytes.
    """
    return width * height * spp * spp * BYTES_PER_SAMPLE + triangles * BYTES_PER_TRIANGLE


def render(scene: Scene, method: Method, spp: int = 1, tracer: Tracer | None = None) -> Rendering:
    """Render ``scene`` lit by ``method``; ``spp`` is the per-axis supersampling (spp² samples per pixel).

    The estimated memory is checked against the budget (:mod:`lightprobe.util.limits`) before any ray is cast.

    Parameters
    ----------
    scene : Scene
        The scene: meshes, camera and environment (radiance, world frame).
    method : Method
        Shades the hits (:mod:`lightprobe.render.methods`, :mod:`lightprobe.render.glossy`); a scene with a glossy
        material needs a method that shades glossy surfaces.
    spp : int
        Samples per pixel along each axis, from 1 to 16, box-filtered. Default 1.
    tracer : Tracer or None
        A tracer of this very scene to reuse (its acceleration structures); None (default) builds one.

    Returns
    -------
    Rendering
        The image (H, W, 3) float32 radiance (misses show the environment when the scene's ``background`` is on,
        else 0), each pixel's coverage, the method's description and the seconds of ``rays``, ``intersect`` and
        ``shade``.

    Raises
    ------
    UsageError
        ``spp`` is out of range, or a glossy material meets a method that shades Lambertian surfaces only.
    BudgetError
        The scene has more triangles than ``LIGHTPROBE_MAX_TRIANGLES``, or the estimated memory is over the budget.
    """
    if not 1 <= spp <= 16:
        raise UsageError("spp must be within 1..16")
    if scene.triangle_count > max_triangles():
        raise BudgetError(f"refusing the scene: {scene.triangle_count} triangles is over the limit of "
                          f"{max_triangles()} (set LIGHTPROBE_MAX_TRIANGLES to raise it)")
    check_memory(render_memory(scene.camera.width, scene.camera.height, spp, scene.triangle_count), f"rendering {scene.camera.width}x{scene.camera.height} at {spp}x{spp} "
                                            "samples per pixel", kernels=True)
    glossy = [m for m in scene.meshes if m.material.glossy]
    if glossy and not method.glossy:
        raise UsageError(f"the {method.name} method shades Lambertian surfaces only, and mesh {glossy[0].name!r} is "
                         f"{glossy[0].material.brdf.spec()}: render it with brute or the reference")
    seconds = {}
    t0 = time.perf_counter()
    tracer = tracer or Tracer(scene)
    cam = scene.camera
    origins, dirs = cam.rays(spp)
    flat_dirs = dirs.reshape(-1, 3)
    seconds["rays"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    hits = tracer.first_hits(origins.reshape(-1, 3), flat_dirs)
    seconds["intersect"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    radiance = np.zeros((flat_dirs.shape[0], 3))
    hit_mask = np.zeros(flat_dirs.shape[0], dtype=bool)
    hit_mask[hits.ray] = True
    if scene.background and (~hit_mask).any():
        radiance[~hit_mask] = scene.environment.lookup(flat_dirs[~hit_mask])
    if len(hits):
        radiance[hits.ray] = method.shade(scene, tracer, hits)
    seconds["shade"] = time.perf_counter() - t0
    n = spp * spp
    image = radiance.reshape(cam.height, cam.width, n, 3).mean(axis=2).astype(np.float32)
    coverage = hit_mask.reshape(cam.height, cam.width, n).mean(axis=2).astype(np.float32)
    return Rendering(image, coverage, method.describe(), seconds)
