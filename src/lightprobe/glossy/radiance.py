"""Reflected radiance and radiance environment maps for any isotropic BRDF (Cabral, Olano & Nemec 1999;
docs/spec.md §4).

Quantity: **radiance** (the map's units): L_r(n; v) = ∫_{n·ω>0} f_r(ω, v; n) L(ω) (n·ω) dω, the light a surface of
normal n sends toward the eye at v (both unit, world frame, leaving the surface).

How it is computed (:func:`reflected_radiance`): the map is resampled (energy-conserving) into a world cube; its
brightest texels (a sun) are taken out as point sources (:func:`lightprobe.glossy.prefilter.split_peaks`); the bounded
rest is box-filtered down to the coarsest level whose texels are at most an eighth of the BRDF's lobe across
(:meth:`~lightprobe.glossy.brdf.BRDF.lobe_width`), within a budget of evaluations; every texel of that level and every
peak is then summed exactly by a compiled kernel (:func:`lightprobe.glossy.brdf_sums.reflected_sums`). Wide lobes read a
coarse level (Lambert: 8² faces), sharp ones a fine one; accuracy against a brute-force sum over every texel of the
full cube is measured in tests/test_radiance.py and the level used is stated with each map.

A **radiance map** for one view v is a ``sphere``-layout image in the view's frame T = [right, up, v]: the texel of
local normal n_local (docs/spec.md §2's n(x, y)) holds L_r(T n_local; v). As an :class:`~lightprobe.maps.EnvMap` its
layout is :class:`~lightprobe.maps.layouts.Sphere` with camera axes T, whose texel direction is the mirror of v about
that normal — so looking the map up at a surface's mirror direction reads that surface's reflected radiance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .brdf import BRDF
from .brdf_sums import reflected_sums
from ..maps import EnvMap, resample
from ..util.errors import UsageError
from ..util.jit import read_only
from ..maps.layouts import CUBE, Sphere
from .prefilter import box_pyramid, box_reduce_to, split_peaks

WORKING_SIZE = 128  # face size of the working cube (0.7° texels)
PEAKS = 64  # brightest texels summed as point sources
TEXELS_PER_LOBE = 8  # a source level's texels are at most lobe_width / 8 across
BUDGET = 1.5e9  # BRDF evaluations per call (points × source texels) above which a coarser level is taken
MAX_MAP_SIZE = 2048
SMOOTH_SIZE = 16  # face size of the smooth environment RS-IBR sums exactly for each view (5.6° texels)


@dataclass(frozen=True, eq=False)
class Lighting:
    """An environment prepared for :func:`reflected_radiance`: the box-filtered pyramid (finest first) of the
    working cube's bounded part, the peaks taken out of it (directions, RGB power ∫L dω), and ``smooth``: the whole
    working cube, peaks included, box-filtered to SMOOTH_SIZE faces (radiance, world frame; what
    :mod:`lightprobe.glossy.rsibr` sums exactly for a new view — :func:`smooth_radiance`)."""

    levels: tuple
    peak_directions: np.ndarray
    peak_power: np.ndarray
    smooth: EnvMap | None = None

    def level_for(self, brdf: BRDF, points: int) -> int:
        """The index of the level :func:`reflected_radiance` sums for ``points`` points.

        The coarsest level whose texels (π/2 / face size across) resolve the lobe — at most
        ``brdf.lobe_width()`` / TEXELS_PER_LOBE (8) across — or, where points × texels would pass BUDGET (1.5e9
        evaluations), the finest the budget allows.

        Parameters
        ----------
        brdf : lightprobe.glossy.brdf.BRDF
            The BRDF; its :meth:`~lightprobe.glossy.brdf.BRDF.lobe_width` sets the texel size wanted.
        points : int
            The number of (normal, view) pairs the sum is for.

        Returns
        -------
        int
            An index into ``levels``: 0 is the working cube, ``len(levels) - 1`` its 1×1 faces.
        """
        wanted = len(self.levels) - 1
        while wanted > 0 and np.pi / 2 / self.levels[wanted].grid[-1] > brdf.lobe_width() / TEXELS_PER_LOBE:
            wanted -= 1
        while wanted < len(self.levels) - 1 and points * self.levels[wanted].data[..., 0].size > BUDGET:
            wanted += 1
        return wanted


def prepare(env: EnvMap, size: int = WORKING_SIZE, peaks: int = PEAKS) -> Lighting:
    """The :class:`Lighting` of ``env`` (radiance, world frame), to compute any number of maps from.

    ``env`` is resampled (energy-conserving) into a ``size`` cube, split into ``peaks`` point sources and a bounded
    rest, and the rest's box-filtered pyramid made; with the whole cube at SMOOTH_SIZE.

    Parameters
    ----------
    env : lightprobe.maps.EnvMap
        The environment, radiance, any layout, world frame; taken as it is when already a cube of ``size``.
    size : int, default WORKING_SIZE (128)
        Face size of the working cube in texels, a power of two (the pyramid halves it down to 1×1).
    peaks : int, default PEAKS (64)
        The brightest texels taken out as point sources (:func:`lightprobe.glossy.prefilter.split_peaks`).

    Returns
    -------
    Lighting
        The pyramid (finest first), the peaks' directions and RGB power, and the smooth cube.

    Raises
    ------
    lightprobe.util.errors.LayoutError
        When ``size`` is not a power of two (a halving meets an odd face size).
    """
    cube = env if env.layout == CUBE and env.grid[-1] == size else resample(env, CUBE, size)
    rest, directions, power = split_peaks(cube, peaks)
    return Lighting(tuple(box_pyramid(rest)), directions, power, _smooth_cube(cube))


def _smooth_cube(cube: EnvMap) -> EnvMap:
    """The cube at SMOOTH_SIZE faces, ∫L dω kept: box-filtered where its faces are a power-of-two multiple of
    SMOOTH_SIZE, else resampled."""
    ratio = cube.grid[-1] // SMOOTH_SIZE
    if cube.grid[-1] % SMOOTH_SIZE == 0 and ratio & (ratio - 1) == 0:
        return box_reduce_to(cube, SMOOTH_SIZE)
    return resample(cube, CUBE, SMOOTH_SIZE)


def smooth_radiance(smooth: EnvMap, brdf: BRDF, normals: np.ndarray, views: np.ndarray) -> np.ndarray:
    """L_r(n; v) of the environment ``smooth`` with every texel summed exactly: no level choice, no peaks.

    The smooth part of a radiance map that :mod:`lightprobe.glossy.rsibr` computes for each new view. Texels without
    light are left out of the sum.

    Parameters
    ----------
    smooth : lightprobe.maps.EnvMap
        The environment, any layout, radiance, world frame (in practice :attr:`Lighting.smooth`).
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF, summed through its compiled kernel.
    normals : numpy.ndarray
        (N, 3) unit surface normals, world frame.
    views : numpy.ndarray
        (N, 3), or one (3,) for every point: unit directions toward the eye, world frame.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 reflected radiance, RGB, in the environment's units.
    """
    normals = read_only(np.asarray(normals, dtype=np.float64).reshape(-1, 3))
    views = read_only(np.broadcast_to(np.asarray(views, dtype=np.float64), normals.shape))
    model, params, table = brdf.kernel()
    out = np.zeros((len(normals), 3))
    dirs, weights = _sources(smooth)
    if len(dirs):
        reflected_sums(model, params, table, normals, views, read_only(dirs), weights, out)
    return out


def _sources(level: EnvMap) -> tuple[np.ndarray, np.ndarray]:
    """A level's texels as sources: unit directions (S, 3) and weights L·Δω (S, 3), texels without light left out."""
    weights = level.data.reshape(-1, 3).astype(np.float64) * level.solid_angles().reshape(-1, 1)
    keep = weights.max(axis=1) > 0
    return np.ascontiguousarray(level.directions().reshape(-1, 3)[keep]), np.ascontiguousarray(weights[keep])


def reflected_radiance(lighting: Lighting | EnvMap, brdf: BRDF, normals: np.ndarray, views: np.ndarray,
                       level: int | None = None) -> np.ndarray:
    """L_r(n; v) (radiance, RGB) at unit ``normals`` seen from unit ``views``, world frame.

    See the module docstring for the method: the texels of one level of the pyramid and the peaks, each summed exactly.
    ``level`` overrides :meth:`Lighting.level_for` (0: every texel of the working cube, the brute-force sum).

    Parameters
    ----------
    lighting : Lighting or lightprobe.maps.EnvMap
        The prepared environment; an EnvMap (radiance, world frame) goes through :func:`prepare`, with its defaults,
        at each call.
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF.
    normals : numpy.ndarray
        (N, 3) unit surface normals, world frame.
    views : numpy.ndarray
        (N, 3), or one (3,) for every point: the unit direction toward the eye, world frame.
    level : int, optional
        The pyramid level summed, from 0 to ``len(lighting.levels) - 1``; default :meth:`Lighting.level_for` of
        ``brdf`` and N.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 reflected radiance, RGB, in the environment's units.

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``level`` outside the pyramid.
    """
    if isinstance(lighting, EnvMap):
        lighting = prepare(lighting)
    normals = read_only(np.asarray(normals, dtype=np.float64).reshape(-1, 3))
    views = read_only(np.broadcast_to(np.asarray(views, dtype=np.float64), normals.shape))
    if level is None:
        level = lighting.level_for(brdf, len(normals))
    if not 0 <= level < len(lighting.levels):
        raise UsageError(f"source level must be from 0 to {len(lighting.levels) - 1}, got {level}")
    model, params, table = brdf.kernel()
    out = np.zeros((len(normals), 3))
    for dirs, weights in (_sources(lighting.levels[level]),
                          (np.ascontiguousarray(lighting.peak_directions), np.ascontiguousarray(lighting.peak_power))):
        if len(dirs):
            part = np.empty_like(out)
            reflected_sums(model, params, table, normals, views, read_only(dirs), weights, part)
            out += part
    return out


# ---- views and their frames -------------------------------------------------------------------------------------
def view_frame(view: np.ndarray) -> np.ndarray:
    """T = [right, up, v] (columns) for the view direction v.

    up is world +Y made perpendicular to v, or world −Z where v is within ~8° of ±Y (|v_y| > 0.99), so every view has
    one (docs/spec.md §4).

    Parameters
    ----------
    view : numpy.ndarray
        (3,) direction toward the eye, world frame; normalised here.

    Returns
    -------
    numpy.ndarray
        (3, 3) float64 rotation whose columns are right, up and v, in the world frame.
    """
    v = np.asarray(view, dtype=np.float64)
    v = v / np.linalg.norm(v)
    hint = np.array([0.0, 1.0, 0.0]) if abs(v[1]) <= 0.99 else np.array([0.0, 0.0, -1.0])
    right = np.cross(hint, v)
    right /= np.linalg.norm(right)
    up = np.cross(v, right)
    return np.stack([right, up, v], axis=1)


def radiance_map(lighting: Lighting | EnvMap, brdf: BRDF, view: np.ndarray, size: int = 256) -> EnvMap:
    """The radiance map of ``brdf`` for one ``view`` (unit, toward the eye, world frame).

    A ``size``² sphere-layout :class:`~lightprobe.maps.EnvMap` whose layout's camera axes are :func:`view_frame` (view);
    texel of local normal n_local holds L_r(T n_local; v); 0 outside the disc.

    Parameters
    ----------
    lighting : Lighting or lightprobe.maps.EnvMap
        The prepared environment; an EnvMap (radiance, world frame) goes through :func:`prepare`, with its defaults,
        first.
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF.
    view : numpy.ndarray
        (3,) direction toward the eye, world frame.
    size : int, default 256
        Texels across, from 2 to MAX_MAP_SIZE (2048).

    Returns
    -------
    lightprobe.maps.EnvMap
        (size, size, 3) float32 radiance, layout :class:`~lightprobe.maps.layouts.Sphere` (T).

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``size`` outside [2, MAX_MAP_SIZE].
    """
    if not 2 <= size <= MAX_MAP_SIZE:
        raise UsageError(f"radiance map size must be from 2 to {MAX_MAP_SIZE}, got {size}")
    frame = view_frame(view)
    layout = Sphere(frame)
    grid = layout.grid_shape(size)
    normals_local = sphere_normals(size)
    inside = layout.valid_mask(grid).reshape(-1)
    data = np.zeros((size * size, 3))
    normals = normals_local.reshape(-1, 3)[inside] @ frame.T
    data[inside] = reflected_radiance(lighting, brdf, normals, frame[:, 2])
    return EnvMap(data.reshape(size, size, 3).astype(np.float32), layout)


def sphere_normals(size: int) -> np.ndarray:
    """Local normals n = (x, y, √(1 − x² − y²)) at the texel centres of a ``size``² sphere map (x right, y up).

    Centres beyond 1 − ½ texel of the centre are pulled in to that radius: on the rim itself n ⊥ v, where every BRDF
    is 0 (the view is at the surface's horizon), which would ring the map with black texels.

    Parameters
    ----------
    size : int
        Texels across the map.

    Returns
    -------
    numpy.ndarray
        (size, size, 3) float64 unit normals in the view's frame (z toward the eye); row 0 is the top (y near +1).
    """
    c = (np.arange(size) + 0.5) / size
    x, y = np.meshgrid(2 * c - 1, 1 - 2 * c)
    r = np.sqrt(x * x + y * y)
    limit = 1 - 1 / size
    scale = np.where(r > limit, limit / np.maximum(r, 1e-300), 1.0)
    x, y = x * scale, y * scale
    return np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0.0, None))], axis=-1)


MAP_BYTES_PER_TEXEL = 12  # a finished map, float32 RGB, kept until the set is written
# one map being computed: its normals (local and world), views, sums and result, float64 RGB each, and their masks
WORKING_BYTES_PER_TEXEL = 256


def radiance_set_bytes(views: int, size: int) -> int:
    """Estimated memory of computing ``views`` radiance maps of ``size``² (:func:`radiance_map` for each view).

    Every finished map is kept until the set is written (:data:`MAP_BYTES_PER_TEXEL` a texel), and one map at a time
    is being computed (:data:`WORKING_BYTES_PER_TEXEL` a texel); the environment's own memory is not included.

    Parameters
    ----------
    views : int
        The number of maps.
    size : int
        Texels across each map.

    Returns
    -------
    int
        Bytes, an exact Python integer.
    """
    texels = int(size) * int(size)
    return int(views) * texels * MAP_BYTES_PER_TEXEL + texels * WORKING_BYTES_PER_TEXEL


def check_views(count: int) -> int:
    """``count`` when it is a number of views :func:`geodesic_views` makes: 12, 42 or 162.

    Those are the icosahedron's vertices and those of its 1- and 2-fold geodesic subdivisions.

    Parameters
    ----------
    count : int
        The number of views asked for.

    Returns
    -------
    int
        ``count`` itself.

    Raises
    ------
    lightprobe.util.errors.UsageError
        Any other number.
    """
    if count not in (12, 42, 162):
        raise UsageError(f"views must be 12, 42 or 162 (the icosahedron and its geodesic subdivisions), got {count}")
    return count


def geodesic_views(count: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The view directions of an icosahedron or its geodesic subdivision, and the triangles of the view mesh.

    The views are an icosahedron's 12 vertices, or those of its 1- or 2-fold geodesic subdivision (42, 162), unit;
    the triangles are counter-clockwise seen from outside.

    Parameters
    ----------
    count : int, default 12
        12, 42 or 162.

    Returns
    -------
    views : numpy.ndarray
        (count, 3) float64 unit view directions, world frame.
    triangles : numpy.ndarray
        (faces, 3) int64 indices into ``views``: 20, 80 or 320 faces.

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``count`` not 12, 42 or 162.
    """
    check_views(count)
    phi = (1 + math.sqrt(5)) / 2
    v = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi], [0, 1, phi],
                  [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]], float)
    faces = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                      [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                      [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    vertices = [tuple(x) for x in v / np.linalg.norm(v, axis=1, keepdims=True)]
    while len(vertices) < count:
        vertices, faces = _subdivide(vertices, faces)
    return np.array(vertices), np.asarray(faces)


def _subdivide(vertices: list, faces: np.ndarray) -> tuple[list, np.ndarray]:
    """Each triangle into four, the new vertices (edge midpoints) pushed onto the unit sphere."""
    vertices = list(vertices)
    midpoint: dict = {}

    def middle(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            m = np.add(vertices[a], vertices[b])
            vertices.append(tuple(m / np.linalg.norm(m)))
            midpoint[key] = len(vertices) - 1
        return midpoint[key]

    out = []
    for a, b, c in faces:
        ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
        out += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    return vertices, np.array(out)
