"""Reflection-space image-based rendering (Cabral, Olano & Nemec 1999; docs/spec.md §4): the radiance map of any view,
synthesised from the precomputed maps of the three views around it.

For a new view v_d: the spherical triangle of the view mesh that contains v_d gives three source maps and their
spherical barycentric weights (areas by the Van Oosterom–Strackee formula: ≥ 0, sum 1, a source view's own weight
1). Each destination texel p_d is warped into each source through the BRDF's *central direction* c — the normal
for diffuse-like BRDFs, the mirror direction for specular-like ones: c_world = T_d g_c(p_d), read at
p_s = g_c⁻¹(T_sᵀ c_world), bilinearly. Near a source map's rim the warp degrades (the mirror warp is singular at
c = −v_s, the rim; the normal warp runs out of normals facing v_s), so each source's value is faded by a confidence
that falls smoothly to 0 there, and the weights are renormalised. A view outside every triangle of the mesh (a set
whose triangles do not cover the sphere) is refused by :func:`synthesize`: the nearest triangle's maps, blended with
weights that do not describe the view, would be a wrong map.

Beyond the paper — the smooth part summed exactly (a control variate). The warp's error is not in reading the
sources (exact source values at the warped texels change it by < 0.1 %) but in its premise: the same mirror
direction seen from another view is another n·v, so the lobe is cut by another horizon and masked differently —
98 % of the error sits in the outer ring of the map (n·v < 0.48). That part of the radiance varies smoothly with
the lighting, so it is computed rather than warped: with S(n; v) the radiance of the environment box-filtered to
16² faces (:attr:`lightprobe.glossy.radiance.Lighting.smooth`, summed exactly by
:func:`lightprobe.glossy.radiance.smooth_radiance`), each source contributes L_k − S(·; v_k) at its warped texel, and
S(n_d; v_d) of the new view is added back. Only the detail finer than 5.6° is warped. S of each view is tabulated
over its hemisphere of local normals (a TABLE_SIZE² grid in the Lambert azimuthal equal-area projection, read
bilinearly without trigonometry) — the sources' once per set, the new view's per synthesis; per-point views
(:func:`reflected_by_view`) sum S exactly, the sources' too. For lobes narrower than SMOOTH_MIN_LOBE the cube's
texels show in S as separate highlights and synthesis stays the paper's (:func:`sums_smooth_part`). At 42 views,
GGX α = 0.2 on Grace (64², 100 random views): relative RMSE 7.2 % → 1.7 % (benchmarks/bench_glossy.py).

Quantities: radiance, as the source maps (:mod:`lightprobe.glossy.radiance`); frames: world; the synthesised map is a
``sphere``-layout :class:`~lightprobe.maps.EnvMap` in the frame :func:`lightprobe.glossy.radiance.view_frame` gives v_d,
like the source maps, so it can be compared with the map computed directly for v_d.
"""

from __future__ import annotations

import math
import weakref
from functools import lru_cache

import numpy as np

from ..maps import EnvMap
from ..util.jit import njit, prange, read_only
from ..util.errors import InputError, UsageError
from ..maps.layouts import Sphere
from .radiance import smooth_radiance, sphere_normals, view_frame
from .radiancefile import RadianceSet

FADE_START, FADE_END = 0.1, 0.35  # mirror warp: confidence 0 below this z of the source texel's normal, 1 above
NORMAL_FADE = 0.1  # normal warp: confidence rises from 0 at the source's rim (z = 0) to 1 at this z
TABLE_SIZE = 32  # the smooth part's table over a view's hemisphere: a 32² equal-area grid (5° cells at the centre)
SMOOTH_MIN_LOBE = math.radians(10.0)  # narrower BRDF lobes are synthesised as the paper does (sums_smooth_part)
RHO = math.sqrt(2.0)  # the hemisphere's radius in the Lambert azimuthal equal-area projection


# ---- warps: texel (x, y) on the sphere map's disc ↔ local direction -------------------------------------------
def g_normal(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The local normal of the sphere-map point (x, y) (x right, y up, in [−1, 1]): (x, y, √(1 − x² − y²)).

    Parameters
    ----------
    x : numpy.ndarray
        Horizontal coordinates on the map's disc, right positive, in [−1, 1].
    y : numpy.ndarray
        Vertical coordinates, up positive, in [−1, 1], broadcasting with ``x``.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64 normals in the view's frame (z toward the eye), unit on the disc; off it z is 0.
    """
    return np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0.0, None))], axis=-1)


def g_normal_inverse(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The texture coordinates (s, t) in [0, 1] of local normal n: (n_x/2 + ½, n_y/2 + ½) (t up).

    Parameters
    ----------
    n : numpy.ndarray
        (..., 3) unit normals in the view's frame (z toward the eye); only x and y are read.

    Returns
    -------
    s : numpy.ndarray
        (...) float64, 0 at the map's left edge, 1 at its right.
    t : numpy.ndarray
        (...) float64, 0 at the map's bottom edge, 1 at its top.
    """
    return n[..., 0] / 2 + 0.5, n[..., 1] / 2 + 0.5


def g_mirror(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The local mirror direction of the sphere-map point (x, y): (2xz, 2yz, 2z² − 1), z = √(1 − x² − y²).

    That is the mirror of the view (+z) about the point's normal :func:`g_normal`: the centre reflects back toward
    the eye, the rim to −z.

    Parameters
    ----------
    x : numpy.ndarray
        The points' horizontal coordinates, as :func:`g_normal` takes them.
    y : numpy.ndarray
        Their vertical coordinates (up positive), broadcasting with ``x``.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64 unit mirror directions in the view's frame.
    """
    z = np.sqrt(np.clip(1 - x * x - y * y, 0.0, None))
    return np.stack([2 * x * z, 2 * y * z, 2 * z * z - 1], axis=-1)


def g_mirror_inverse(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The texture coordinates of local mirror direction r: g_normal⁻¹((r_x, r_y, r_z + 1) / |…|).

    The normal halfway between r and the view (+z) gives the texel; r = −z, the rim's single direction, has none
    and reads (½, ½).

    Parameters
    ----------
    r : numpy.ndarray
        (..., 3) unit mirror directions in the view's frame (z toward the eye).

    Returns
    -------
    s : numpy.ndarray
        (...) float64 in [0, 1], rightward.
    t : numpy.ndarray
        (...) float64 in [0, 1], upward.
    """
    h = r + np.array([0.0, 0.0, 1.0])
    return g_normal_inverse(h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300))


# ---- blending -----------------------------------------------------------------------------------------------------
def _excess(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Areas (spherical excess) of the triangles of unit vectors a, b, c (rows): tan(E/2) = |a·(b×c)| /
    (1 + a·b + b·c + c·a) (Van Oosterom & Strackee 1983)."""
    triple = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    return 2 * np.arctan2(triple, 1 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c)
                          + np.einsum("ij,ij->i", c, a))


def blend_weights(views: np.ndarray, triangles: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The three source views (indices) around unit v and their spherical barycentric weights.

    Vertex i weighs the area of the triangle v makes with the other two, over the whole triangle's: ≥ 0, summing to 1.

    Parameters
    ----------
    views : numpy.ndarray
        (N, 3) unit source view directions, world frame (a set's ``views``).
    triangles : numpy.ndarray
        (F, 3) indices into ``views``: the view mesh, counter-clockwise seen from outside.
    v : numpy.ndarray
        (3,) unit view direction, world frame.

    Returns
    -------
    sources : numpy.ndarray
        (3,) indices into ``views``: the vertices of v's triangle.
    weights : numpy.ndarray
        (3,) float64 weights of those sources, in the same order.
    """
    sources, weights = blend_weights_many(views, triangles, np.asarray(v, dtype=np.float64)[None, :])
    return sources[0], weights[0]


def synthesize(rset: RadianceSet, view: np.ndarray, warp: str | None = None, size: int | None = None,
               smooth: bool = True) -> EnvMap:
    """The radiance map for unit ``view`` (world, toward the eye) blended from ``rset``'s three maps around it.

    Warped through ``warp`` (``normal`` or ``mirror``; default the BRDF's central direction). ``smooth``: sum the
    smooth part exactly and warp only the rest (the module docstring) where :func:`sums_smooth_part` says so; False
    warps the whole maps as the paper does. A view equal to a source view returns that source map (a copy) when
    ``size`` is the set's.

    Parameters
    ----------
    rset : lightprobe.glossy.radiancefile.RadianceSet
        A set of views with its triangles (not a single map).
    view : numpy.ndarray
        (3,) direction toward the eye, world frame; normalised here.
    warp : str, optional
        ``"normal"`` or ``"mirror"``; default ``rset.brdf.central``.
    size : int, optional
        Texels across the new map; default the set's size.
    smooth : bool, default True
        Sum the smooth part exactly where :func:`sums_smooth_part` allows; False: the paper's synthesis.

    Returns
    -------
    lightprobe.maps.EnvMap
        (size, size, 3) float32 radiance, layout :class:`~lightprobe.maps.layouts.Sphere` of
        :func:`lightprobe.glossy.radiance.view_frame` (view); 0 outside the disc.

    Raises
    ------
    lightprobe.util.errors.UsageError
        A set without triangles, or a ``warp`` other than ``normal`` and ``mirror``.
    lightprobe.util.errors.InputError
        ``view`` is outside every triangle of the set (a set whose mesh does not cover the sphere): a blend of the
        nearest triangle's maps would be a wrong map, so none is made.
    """
    if rset.triangles is None:
        raise UsageError("synthesis needs a set of views with its triangles (lightprobe radiance --views N)")
    warp = warp or rset.brdf.central
    if warp not in ("normal", "mirror"):
        raise UsageError(f"warp must be normal or mirror, got {warp!r}")
    view = np.asarray(view, dtype=np.float64)
    view = view / np.linalg.norm(view)
    size = size or rset.size
    frame = view_frame(view)
    if _inside_products(rset.views, rset.triangles, view[None, :]).max() < -COVER_TOLERANCE:
        raise InputError(f"the view {', '.join(f'{x:.4g}' for x in view)} is outside every triangle of the set's "
                         "views: no three maps around it to blend (synthesise views the set's mesh covers)")
    sources, weights = blend_weights(rset.views, rset.triangles, view)
    if weights.max() >= 1 - 1e-12 and size == rset.size:
        only = sources[int(np.argmax(weights))]
        if np.allclose(rset.frames[only], frame, atol=1e-12):
            return EnvMap(rset.maps[only].data.copy(), Sphere(frame))
    local, inside = _destination(size, warp)
    out = np.empty((len(local), 3))
    every = np.ones((len(local), 1))
    maps, base = _stacked(rset), np.zeros((1, 3))
    corrected = smooth and sums_smooth_part(rset)
    if corrected:
        maps, base = _residuals(rset, sources), np.empty((len(local), 3))
        _table_values(smooth_table(rset.smooth, rset.brdf, frame), read_only(_destination(size, "normal")[0]),
                      base)
    _blend(read_only(local), frame, maps, (every * sources).astype(np.int64), np.ascontiguousarray(rset.frames),
           every * weights, warp == "mirror", _valid(rset.size), FADE_START, FADE_END, NORMAL_FADE, corrected, base,
           out)
    data = np.zeros((size, size, 3), np.float32)
    data[inside] = out
    return EnvMap(data, Sphere(frame))


def _inside_products(views: np.ndarray, triangles: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(P, F): for each view and triangle the smallest of its triple products [v_i, v_{i+1}, v]: ≥ 0 inside it."""
    a, b, c = views[triangles[:, 0]], views[triangles[:, 1]], views[triangles[:, 2]]
    return np.minimum(np.minimum(v @ np.cross(a, b).T, v @ np.cross(b, c).T), v @ np.cross(c, a).T)


COVER_TOLERANCE = 1e-9  # a view this far outside a triangle's edge (triple product) is still on that edge


def blend_weights_many(views: np.ndarray, triangles: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`blend_weights` for many unit views at once: source indices and weights, a row per view.

    Each view's triangle is the one whose three triple products [v_i, v_{i+1}, v] are all ≥ 0 — the one with the
    largest smallest product, so a view on an edge or a vertex picks one deterministically.

    Parameters
    ----------
    views : numpy.ndarray
        (N, 3) unit source view directions, world frame.
    triangles : numpy.ndarray
        (F, 3) indices into ``views``, counter-clockwise seen from outside.
    v : numpy.ndarray
        (P, 3) unit view directions, world frame.

    Returns
    -------
    sources : numpy.ndarray
        (P, 3) indices into ``views``, each row a triangle of ``triangles``.
    weights : numpy.ndarray
        (P, 3) float64 spherical barycentric weights, ≥ 0, each row summing to 1.
    """
    products = _inside_products(views, triangles, v)
    tri = triangles[np.argmax(products, axis=1)]
    va, vb, vc = views[tri[:, 0]], views[tri[:, 1]], views[tri[:, 2]]
    weights = np.stack([_excess(v, vb, vc), _excess(va, v, vc), _excess(va, vb, v)], axis=1)
    return tri, weights / np.maximum(weights.sum(axis=1, keepdims=True), 1e-300)


def reflected_by_view(rset: RadianceSet, normals: np.ndarray, views: np.ndarray, warp: str | None = None,
                      smooth: bool = True) -> np.ndarray:
    """RS-IBR per point: each point's reflected radiance for its own view.

    Beyond the paper's one map per frame: each point's value is blended from the three source maps around its own
    view, through the warp's central direction of its normal (the normal, or the mirror of its view). Radiance, world
    frame. ``smooth`` as in :func:`synthesize`, the smooth part summed exactly at each point's own normal and view.

    Parameters
    ----------
    rset : lightprobe.glossy.radiancefile.RadianceSet
        A set of views with its triangles.
    normals : numpy.ndarray
        (N, 3) unit surface normals, world frame.
    views : numpy.ndarray
        (N, 3), or one (3,) for every point: unit directions toward the eye, world frame.
    warp : str, optional
        ``"normal"`` or ``"mirror"``; default ``rset.brdf.central``.
    smooth : bool, default True
        Sum the smooth part exactly where :func:`sums_smooth_part` allows; False: warp the whole maps.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 reflected radiance, RGB, in the maps' units.

    Raises
    ------
    lightprobe.util.errors.UsageError
        A set without triangles.
    """
    if rset.triangles is None:
        raise UsageError("RS-IBR needs a set of views with its triangles")
    warp = warp or rset.brdf.central
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    views = np.broadcast_to(np.asarray(views, dtype=np.float64), normals.shape)
    central = normals if warp == "normal" else 2 * np.sum(normals * views, axis=1, keepdims=True) * normals - views
    sources, weights = blend_weights_many(rset.views, rset.triangles, views)
    out = np.empty((len(normals), 3))
    maps, base = _stacked(rset), np.zeros((1, 3))
    corrected = smooth and sums_smooth_part(rset) and len(normals) > 0
    if corrected:
        maps, base = _residuals(rset, sources, exact=True), smooth_radiance(rset.smooth, rset.brdf, normals, views)
    _blend(read_only(central), np.eye(3), maps, np.ascontiguousarray(sources, dtype=np.int64),
           np.ascontiguousarray(rset.frames), np.ascontiguousarray(weights), warp == "mirror", _valid(rset.size),
           FADE_START, FADE_END, NORMAL_FADE, corrected, base, out)
    return out


# ---- the smooth part: tabulated over each view's hemisphere of local normals ---------------------------------------
def sums_smooth_part(rset: RadianceSet) -> bool:
    """Whether synthesis from ``rset`` sums the smooth part exactly (the default).

    It does where the set holds its smooth cube and the BRDF's lobe is at least SMOOTH_MIN_LOBE wide. A narrower lobe
    resolves the cube's 5.6° texels as separate highlights, so S is no longer smooth, its table cannot follow it, and
    the correction adds more error than it takes away (measured: GGX α = 0.05, lobe 5.7°: 15 % → 22 % at 12 views).

    Parameters
    ----------
    rset : lightprobe.glossy.radiancefile.RadianceSet
        The set; its ``smooth`` cube and its BRDF's lobe width decide.

    Returns
    -------
    bool
        True when :func:`synthesize` and :func:`reflected_by_view` with ``smooth=True`` sum the smooth part.
    """
    return rset.smooth is not None and rset.brdf.lobe_width() >= SMOOTH_MIN_LOBE


def _table_normals() -> np.ndarray:
    """Local normals (TABLE_SIZE, TABLE_SIZE, 3) at the cell centres of the table: cell (i, j) at
    (X, Y) = ((j + ½), (i + ½)) · 2√2 / TABLE_SIZE − √2 of the Lambert azimuthal equal-area projection about the view
    (+z): n = (X, Y) √(1 − ρ²/4), z = 1 − ρ²/2, ρ = |(X, Y)|; cells beyond the rim (ρ > √2) take the rim's normal,
    so reads near the rim interpolate rim values."""
    c = (np.arange(TABLE_SIZE) + 0.5) / TABLE_SIZE * 2 * RHO - RHO
    x, y = np.meshgrid(c, c)
    rho = np.sqrt(x * x + y * y)
    scale = np.minimum(1.0, RHO / rho)
    x, y, rho = x * scale, y * scale, np.minimum(rho, RHO)
    lift = np.sqrt(np.clip(1 - rho * rho / 4, 0.0, None))
    return np.stack([x * lift, y * lift, np.clip(1 - rho * rho / 2, 0.0, None)], axis=-1)


def smooth_table(smooth: EnvMap, brdf, frame: np.ndarray) -> np.ndarray:
    """S(T n_local; v) for the view of ``frame`` T (columns right, up, v) at the table's local normals.

    The local normals are :func:`_table_normals`'s, a TABLE_SIZE² equal-area grid over the view's hemisphere; S is
    :func:`lightprobe.glossy.radiance.smooth_radiance` of ``smooth`` (world frame).

    Parameters
    ----------
    smooth : lightprobe.maps.EnvMap
        The environment's smooth cube, radiance, world frame (a set's ``smooth``).
    brdf : lightprobe.glossy.brdf.BRDF
        The set's BRDF.
    frame : numpy.ndarray
        (3, 3) rotation T, columns right, up and the view v (:func:`lightprobe.glossy.radiance.view_frame`).

    Returns
    -------
    numpy.ndarray
        (TABLE_SIZE, TABLE_SIZE, 3) float64 radiance.
    """
    normals = _table_normals().reshape(-1, 3) @ np.asarray(frame).T
    return smooth_radiance(smooth, brdf, normals, frame[:, 2]).reshape(TABLE_SIZE, TABLE_SIZE, 3)


_RESIDUALS: dict = {False: weakref.WeakKeyDictionary(), True: weakref.WeakKeyDictionary()}


def _residuals(rset: RadianceSet, needed, exact: bool = False) -> np.ndarray:
    """The set's maps less their views' smooth parts, L_k − S(·; v_k) at each texel's own normal, as one
    (N, H, W, 3) float32 stack for the kernel, so a bilinear read of the difference samples L and S alike. S as the
    new view's S will be: read from the view's table (:func:`synthesize`, whose new view is tabulated too), or
    summed exactly (``exact``: :func:`reflected_by_view`, which sums each point's exactly) — the two errors then
    cancel (measured at 64²: per-point views 1.1 % with exact residuals, 2.9 % with tabulated ones; a synthesised
    map 1.8 % with tabulated, 3.3 % with exact). Each source's is made the first time it is needed (``needed``:
    source indices) and kept with the set."""
    cache = _RESIDUALS[exact]
    if rset not in cache:
        cache[rset] = (_stacked(rset).copy(), np.zeros(len(rset.maps), bool))
    stack, done = cache[rset]
    todo = [k for k in np.unique(np.asarray(needed, dtype=np.int64)) if not done[k]]
    if todo:
        inside = _valid(rset.size) > 0
        normals = np.ascontiguousarray(sphere_normals(rset.size)[inside])
        values = np.empty((len(normals), 3))
        for k in todo:
            frame = rset.frames[k]
            if exact:
                values = smooth_radiance(rset.smooth, rset.brdf, normals @ frame.T, frame[:, 2])
            else:
                _table_values(smooth_table(rset.smooth, rset.brdf, frame), read_only(normals), values)
            stack[k][inside] -= values.astype(np.float32)
            done[k] = True
    return stack


def map_at_normals(rmap: EnvMap, normals: np.ndarray) -> np.ndarray:
    """A radiance map read at world ``normals``: the texel of local normal Tᵀ n, bilinear.

    docs/spec.md §4's normal-indexed lookup; normals facing away from the map's view are read at its rim.

    Parameters
    ----------
    rmap : lightprobe.maps.EnvMap
        A radiance map: sphere layout whose camera axes are its view's frame T
        (:func:`lightprobe.glossy.radiance.radiance_map`).
    normals : numpy.ndarray
        (N, 3) unit normals, world frame.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 radiance, in the map's units.
    """
    local = np.asarray(normals, dtype=np.float64).reshape(-1, 3) @ rmap.layout.camera_axes
    out = np.empty((len(local), 3))
    size = rmap.data.shape[0]
    _read_normals(np.ascontiguousarray(local), np.ascontiguousarray(rmap.data[None], dtype=np.float32), _valid(size),
                  out)
    return out


@njit(cache=True, inline="always")
def _fetch(maps, k, valid, n0, n1):  # pragma: no cover - compiled
    """Bilinear read (RGB) of sphere image ``maps[k]`` at the texel of local normal (n0, n1, ·), texels off the
    disc left out."""
    h, w = valid.shape
    x, y = (n0 / 2 + 0.5) * w - 0.5, (0.5 - n1 / 2) * h - 0.5
    x0, y0 = int(math.floor(x)), int(math.floor(y))
    fx, fy = x - x0, y - y0
    v0 = v1 = v2 = vw = 0.0
    for dy in range(2):
        for dx in range(2):
            xi, yi = x0 + dx, y0 + dy
            if 0 <= xi < w and 0 <= yi < h and valid[yi, xi] > 0:
                tap = (fx if dx else 1 - fx) * (fy if dy else 1 - fy)
                v0 += tap * maps[k, yi, xi, 0]
                v1 += tap * maps[k, yi, xi, 1]
                v2 += tap * maps[k, yi, xi, 2]
                vw += tap
    if vw > 0:
        return v0 / vw, v1 / vw, v2 / vw
    return v0, v1, v2


@njit(cache=True, parallel=True)
def _read_normals(local, maps, valid, out):  # pragma: no cover - compiled
    for p in prange(local.shape[0]):
        x, y, z = local[p, 0], local[p, 1], local[p, 2]
        r = math.sqrt(x * x + y * y)
        if z < 0 and r > 0:  # facing away from the map's view: the rim in that direction
            x, y = x / r, y / r
        out[p, 0], out[p, 1], out[p, 2] = _fetch(maps, 0, valid, x, y)


@lru_cache(maxsize=8)
def _destination(size: int, warp: str) -> tuple[np.ndarray, np.ndarray]:
    """The local central directions g_c (P, 3) of a ``size``² map's texels on its disc, and which texels those
    are."""
    inside = Sphere().valid_mask((size, size))
    local = sphere_normals(size)[inside]
    if warp == "mirror":
        local = g_mirror(local[:, 0], local[:, 1])
    local = np.ascontiguousarray(local)
    for a in (inside, local):
        a.setflags(write=False)
    return local, inside


_STACKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _stacked(rset: RadianceSet) -> np.ndarray:
    """All the set's maps as one (N, H, W, 3) array for the kernel, made once per set."""
    if rset not in _STACKS:
        _STACKS[rset] = np.ascontiguousarray(np.stack([m.data for m in rset.maps]), dtype=np.float32)
    return _STACKS[rset]


@lru_cache(maxsize=8)
def _valid(size: int) -> np.ndarray:
    out = Sphere().valid_mask((size, size)).astype(np.float64)
    out.setflags(write=False)
    return out


@njit(cache=True, parallel=True)
def _table_values(table, local, out):  # pragma: no cover - compiled
    """out[p] = bilinear read (RGB) of ``table`` (:func:`_table_normals`) at the unit local normal ``local[p]`` on
    the view's side (z ≥ 0): (X, Y) = (x, y) √(2 / (1 + z))."""
    size = table.shape[0]
    for p in prange(local.shape[0]):
        s = math.sqrt(2.0 / (1.0 + local[p, 2])) * size / (2 * RHO)
        x = min(max(local[p, 0] * s + size / 2 - 0.5, 0.0), size - 1.0)
        y = min(max(local[p, 1] * s + size / 2 - 0.5, 0.0), size - 1.0)
        x0, y0 = min(int(x), size - 2), min(int(y), size - 2)
        fx, fy = x - x0, y - y0
        for c in range(3):
            out[p, c] = ((1 - fy) * ((1 - fx) * table[y0, x0, c] + fx * table[y0, x0 + 1, c])
                         + fy * ((1 - fx) * table[y0 + 1, x0, c] + fx * table[y0 + 1, x0 + 1, c]))


@njit(cache=True, inline="always")
def _smooth(x, lo, hi):  # pragma: no cover - compiled
    t = min(max((x - lo) / (hi - lo), 0.0), 1.0)
    return t * t * (3 - 2 * t)


@njit(cache=True, parallel=True)
def _blend(local, frame, maps, sources, frames, weights, mirror, valid, fade_start, fade_end, normal_fade, corrected,
           base, out):  # pragma: no cover - compiled
    """For each point's central direction c = T g (world; ``local`` holds g, ``frame`` T): in each of its three
    sources k (row p of ``sources`` and ``weights``), c_local = T_kᵀ c, the texel
    p_k = g⁻¹(c_local) (normal or mirror warp), its value read bilinearly (texels off the disc left out), faded by
    the confidence of z of p_k's local normal; the weighted values renormalised — or, where no source is
    confident, the value of the source whose disc comes closest (the largest z). ``corrected``: ``maps`` are the
    sources' residuals (:func:`_residuals`) and ``base[p]``, the new view's smooth part, is added to the blend."""
    for p in prange(local.shape[0]):
        total0 = total1 = total2 = weight_sum = 0.0
        best_z, f0, f1, f2 = -1e300, 0.0, 0.0, 0.0
        g0 = frame[0, 0] * local[p, 0] + frame[0, 1] * local[p, 1] + frame[0, 2] * local[p, 2]
        g1 = frame[1, 0] * local[p, 0] + frame[1, 1] * local[p, 1] + frame[1, 2] * local[p, 2]
        g2 = frame[2, 0] * local[p, 0] + frame[2, 1] * local[p, 1] + frame[2, 2] * local[p, 2]
        for j in range(3):
            k = sources[p, j]
            c0 = g0 * frames[k, 0, 0] + g1 * frames[k, 1, 0] + g2 * frames[k, 2, 0]
            c1 = g0 * frames[k, 0, 1] + g1 * frames[k, 1, 1] + g2 * frames[k, 2, 1]
            c2 = g0 * frames[k, 0, 2] + g1 * frames[k, 1, 2] + g2 * frames[k, 2, 2]
            if mirror:  # g_mirror⁻¹: the normal halfway between c and the view (+z)
                norm = math.sqrt(c0 * c0 + c1 * c1 + (c2 + 1) * (c2 + 1))
                if norm < 1e-300:
                    n0, n1, z = 1.0, 0.0, 0.0
                else:
                    n0, n1, z = c0 / norm, c1 / norm, (c2 + 1) / norm
                confidence = _smooth(z, fade_start, fade_end)
            else:
                n0, n1, z = c0, c1, c2
                confidence = _smooth(z, 0.0, normal_fade)
            v0, v1, v2 = _fetch(maps, k, valid, n0, n1)
            c = weights[p, j] * confidence
            total0 += c * v0
            total1 += c * v1
            total2 += c * v2
            weight_sum += c
            if z > best_z:
                best_z, f0, f1, f2 = z, v0, v1, v2
        if weight_sum > 1e-6:
            f0, f1, f2 = total0 / weight_sum, total1 / weight_sum, total2 / weight_sum
        if corrected:  # radiance is ≥ 0; detail subtracted from a source may overshoot where S_d is small
            f0, f1, f2 = max(f0 + base[p, 0], 0.0), max(f1 + base[p, 1], 0.0), max(f2 + base[p, 2], 0.0)
        out[p, 0], out[p, 1], out[p, 2] = f0, f1, f2
