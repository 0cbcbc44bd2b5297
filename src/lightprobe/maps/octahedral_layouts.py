"""Octahedral layouts: the plain octahedral map as Godot stores its radiance maps, and Clarberg's equal-area
octahedral map as pbrt-v4 stores environment maps, with exact per-pixel solid angles (conventions in
:mod:`lightprobe.maps.layouts`).

Both unfold the sphere into one N × N square: the square's inner diamond |s| + |t| ≤ 1 (s, t ∈ [−1, 1]) is one
hemisphere, the four corner triangles the other, folded out across the diamond's edges. Past the square's edges the
map continues by the same fold (a point just past the right edge is the point just inside it, mirrored top to
bottom), so the padding and a lookup's taps are seamless like a lat-long's.

* ``octahedral`` — Godot 4's radiance "octmap" (``servers/rendering/renderer_rd/shaders/oct_inc.glsl``:
  ``vec3_to_oct`` / ``oct_to_vec3``, sampled with the world-space reflection vector, the sky unrotated). Godot's world
  frame is lightprobe's (+Y up, front −Z, right +X), so the map's own axes are the world's: texture coordinate
  ``(x, y)/(|x| + |y| + |z|) · ½ + ½`` for z ≥ 0. Godot's texture coordinate (0, 0) is texel row 0, the image's top
  row, so in the stored image the centre is **+Z** (behind the default camera), the middle of the **bottom** edge
  **+Y** (up), the middle of the top edge −Y, the right edge's middle +X, the left's −X, and the four corners −Z (the
  front). Godot keeps a border of texels round its octmaps (``vec3_to_oct_with_border``); this layout is the square
  without it.
* ``octahedral-ea`` — pbrt-v4's equal-area map (``EqualAreaSquareToSphere`` / ``EqualAreaSphereToSquare`` in
  ``src/pbrt/util/math.cpp``, after Clarberg, "Fast Equal-Area Mapping of the (Hemi)Sphere using SIMD", 2008), which
  ``ImageInfiniteLight`` reads with pixel (x, y) at ((x + ½)/N, (y + ½)/N) and row 0 the file's first (top) row. pbrt's
  frame is left-handed with +Z up; the light's directions are ``(x, y, z)_pbrt = (z, −x, y)_world`` — pbrt +X is
  world +Z (back), pbrt +Y world −X, pbrt +Z world +Y (up). That is the frame in which pbrt's own lat-long convention
  (``imgtool makeequiarea``: u = φ/2π with φ = atan2(y, x), v = θ/π from +Z) puts every pixel where lightprobe's
  lat-long has it, so ``imgtool makeequiarea`` of a lightprobe lat-long gives this layout's image. The centre is +Y
  (up), the four corners −Y, the middle of the right edge world +Z, of the bottom edge world −X. Every pixel covers
  exactly 4π/N².

No maintained Python library maps octahedral environment images with per-pixel solid angles (pyquaternion, healpy and
spherical-harmonics packages map other grids), so the formulas are written here from the two engines' definitions.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .layout_base import Layout

# pbrt's light frame from the world frame: (x, y, z)_pbrt = PBRT_FROM_WORLD @ (x, y, z)_world. Its determinant is −1:
# pbrt's coordinates are left-handed, lightprobe's right-handed, so the same physical direction changes handedness.
PBRT_FROM_WORLD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_CLIP_BAND = 1 << 16  # pixels per block while the plain map's exact solid angles are computed (bounds the temporaries)


def folded(u, v) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates past the square's edges brought back inside by the octahedral fold.

    Crossing the left or right edge mirrors the point top to bottom (u → −u or 2 − u, v → 1 − v); crossing the top or
    bottom edge mirrors it left to right. It is Godot's ``oct_to_vec3_with_border`` and pbrt's
    ``WrapEqualAreaSquare``; points inside the square are returned as they are.

    Parameters
    ----------
    u : numpy.ndarray
        Horizontal image coordinate, [0, 1] across the square (anything within one square of it).
    v : numpy.ndarray
        Vertical image coordinate, [0, 1] down the square.

    Returns
    -------
    u : numpy.ndarray
        float64 horizontal coordinate in [0, 1].
    v : numpy.ndarray
        float64 vertical coordinate in [0, 1].
    """
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    past = (u < 0) | (u > 1)
    u = np.where(u < 0, -u, np.where(u > 1, 2 - u, u))
    v = np.where(past, 1 - v, v)
    past = (v < 0) | (v > 1)
    v = np.where(v < 0, -v, np.where(v > 1, 2 - v, v))
    u = np.where(past, 1 - u, u)
    return u, v


class _OctahedralLayout(Layout):
    """One N × N square holding the whole sphere; every pixel covers part of it. Subclasses give the square ↔
    local-frame pair (s, t ∈ [−1, 1], s right, t down) and the local frame's place in the world."""

    aspect = (1, 1)
    valid_fraction = 1.0
    local_from_world: np.ndarray  # (3, 3): local = local_from_world @ world

    def _local_direction(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _square_of(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def uv_to_dir(self, face, u, v):
        """(u, v) → the world direction there; past the square's edges, the folded point's (:func:`folded`).

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the square is one face.
        u : numpy.ndarray
            Horizontal image coordinate, 0 at the left edge, 1 at the right.
        v : numpy.ndarray
            Vertical image coordinate, 0 at the top edge (row 0), 1 at the bottom.

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors (+Y up, front −Z, right +X), shape ``u.shape + (3,)``.
        """
        u, v = folded(u, v)
        return self._local_direction(2 * u - 1, 2 * v - 1) @ self.local_from_world

    def dir_to_uv(self, d):
        """World directions → (0, u, v) in the square.

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors (+Y up, front −Z, right +X), shape (..., 3).

        Returns
        -------
        face : numpy.ndarray
            int64 zeros, shape ``d.shape[:-1]``.
        u : numpy.ndarray
            float64 horizontal image coordinate in [0, 1].
        v : numpy.ndarray
            float64 vertical image coordinate in [0, 1], 0 at the top.
        """
        d = np.asarray(d, dtype=np.float64)
        s, t = self._square_of(d @ self.local_from_world.T)
        return np.zeros(d.shape[:-1], dtype=np.int64), (s + 1) / 2, (t + 1) / 2

    def _solid_angle_table(self, n: int) -> np.ndarray:
        raise NotImplementedError

    def solid_angles(self, grid):
        """Exact solid angle of every pixel: 4π/N² each for the equal-area map; for the plain map each pixel's
        spherical polygon (its edges are great-circle arcs), cut where the folds cross it.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the square.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape (N, N), a new array; they sum to 4π.

        Raises
        ------
        LayoutError
            When ``grid`` is not square.
        """
        self.check_grid(grid)
        return np.array(self._solid_angle_table(grid[0]))

    def valid_mask(self, grid):
        """All true: every pixel of the square covers part of the sphere.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the square.

        Returns
        -------
        numpy.ndarray
            bool ones of shape ``grid``, a new array.

        Raises
        ------
        LayoutError
            When ``grid`` is not square.
        """
        self.check_grid(grid)
        return np.ones(grid, dtype=bool)


class Octahedral(_OctahedralLayout):
    """The plain octahedral map as Godot stores its radiance maps: the sphere projected onto the octahedron
    |x| + |y| + |z| = 1 and unfolded; centre +Z, bottom edge's middle +Y, corners −Z (module docstring)."""

    name = "octahedral"
    local_from_world = np.eye(3)

    @staticmethod
    def _octahedron_point(s, t) -> np.ndarray:
        """The point of the octahedron |x| + |y| + |z| = 1 at square point (s, t): (s, t, 1 − |s| − |t|) inside the
        diamond, folded across its edge outside it (GLSL's sign(0) = 0, as Godot's ``oct_to_vec3``)."""
        s, t = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64))
        z = 1 - np.abs(s) - np.abs(t)
        lower = z < 0
        x = np.where(lower, (1 - np.abs(t)) * np.sign(s), s)
        y = np.where(lower, (1 - np.abs(s)) * np.sign(t), t)
        return np.stack([x, y, z], axis=-1)

    def _local_direction(self, s, t):
        p = self._octahedron_point(s, t)
        return p / np.linalg.norm(p, axis=-1, keepdims=True)

    def _square_of(self, local):
        n = local / np.abs(local).sum(axis=-1, keepdims=True)
        x, y, z = n[..., 0], n[..., 1], n[..., 2]
        sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)  # Godot's oct_wrap: 0 counts as +
        lower = z < 0
        return np.where(lower, (1 - np.abs(y)) * sx, x), np.where(lower, (1 - np.abs(x)) * sy, y)

    def uv_density(self, face, u, v):
        """dω / (du dv) = 4 / |p|³, p the octahedron's point there (|p| from 1/√3 at a face's centre to 1 at a
        vertex): each of the eight triangles is a face of the octahedron seen from the centre.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the square is one face.
        u : numpy.ndarray
            Horizontal image coordinate.
        v : numpy.ndarray
            Vertical image coordinate.

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area, the broadcast shape of ``u`` and ``v``; it integrates to 4π.
        """
        u, v = folded(u, v)
        p = self._octahedron_point(2 * u - 1, 2 * v - 1)
        return 4 / np.linalg.norm(p, axis=-1) ** 3

    def _solid_angle_table(self, n: int) -> np.ndarray:
        """Exact: each pixel's parts in the octahedron's eight faces are spherical polygons. Within one face of the
        octahedron the square maps affinely onto the face and the face radially onto the sphere, so straight lines
        become great circles: a pixel inside one triangle of the square is a spherical quadrilateral, and a pixel the
        folds cut (the diamond's edges, and the axes for odd N) is cut there into convex polygons, each measured by
        Van Oosterom and Strackee's triangle formula. Cached per size, read-only."""
        return _octahedral_solid_angles(n)


class OctahedralEqualArea(_OctahedralLayout):
    """Clarberg's equal-area octahedral map as pbrt-v4 stores environment maps, in pbrt's light frame
    (x, y, z)_pbrt = (z, −x, y)_world; centre +Y (up), corners −Y (module docstring)."""

    name = "octahedral-ea"
    local_from_world = PBRT_FROM_WORLD

    def _local_direction(self, s, t):
        s, t = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64))
        signed_distance = 1 - (np.abs(s) + np.abs(t))  # from the diamond's edge: + inside (pbrt's upper, +Z)
        r = 1 - np.abs(signed_distance)
        phi = np.where(r == 0, 1.0, (np.abs(t) - np.abs(s)) / np.where(r == 0, 1.0, r) + 1) * np.pi / 4
        z = np.copysign(1 - r * r, signed_distance)
        ring = r * np.sqrt(np.clip(2 - r * r, 0.0, None))
        return np.stack([np.copysign(np.cos(phi), s) * ring, np.copysign(np.sin(phi), t) * ring, z], axis=-1)

    def _square_of(self, local):
        local = local / np.linalg.norm(local, axis=-1, keepdims=True)
        x, y, z = local[..., 0], local[..., 1], local[..., 2]
        # r = √(1 − |z|), written as √(x² + y²)/√(1 + |z|) so it keeps its digits next to the poles
        r = np.hypot(x, y) / np.sqrt(1 + np.abs(z))
        b = r * np.arctan2(np.abs(y), np.abs(x)) * (2 / np.pi)  # |t| in the upper hemisphere
        a = r - b
        lower = z < 0
        a, b = np.where(lower, 1 - b, a), np.where(lower, 1 - a, b)
        return np.copysign(a, x), np.copysign(b, y)

    def uv_density(self, face, u, v):
        """dω / (du dv) = 4π everywhere: the map is equal-area.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the square is one face.
        u : numpy.ndarray
            Horizontal image coordinate (sets the result's shape).
        v : numpy.ndarray
            Vertical image coordinate.

        Returns
        -------
        numpy.ndarray
            float64 4π, the broadcast shape of ``u`` and ``v``.
        """
        return np.full(np.broadcast(np.asarray(u), np.asarray(v)).shape, 4 * np.pi)

    def _solid_angle_table(self, n: int) -> np.ndarray:
        return np.full((n, n), 4 * np.pi / (n * n))  # equal-area: every pixel the same

    def solid_angles_of(self, grid, flat):
        """4π/N² for the pixels at ``flat`` indices, with no table.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the square.
        flat : numpy.ndarray
            Row-major integer pixel indices, any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat``.
        """
        return np.full(np.shape(flat), 4 * np.pi / (grid[0] * grid[1]))


# ---- the plain map's exact solid angles ------------------------------------------------------------------------------

def _triangle_solid_angle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Signed solid angle of the spherical triangle of unit vectors a, b, c (..., 3): Van Oosterom and Strackee,
    tan(Ω/2) = a·(b × c) / (1 + a·b + b·c + c·a); positive for anticlockwise vertices seen from outside."""
    triple = np.einsum("...i,...i->...", a, np.cross(b, c))
    denominator = 1 + np.einsum("...i,...i->...", a, b) + np.einsum("...i,...i->...", b, c) \
        + np.einsum("...i,...i->...", c, a)
    return 2 * np.arctan2(triple, denominator)


def _sphere_points(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    p = Octahedral._octahedron_point(s, t)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def _clip(points: np.ndarray, count: np.ndarray, normal: np.ndarray, offset: np.ndarray):
    """Convex polygons (M, K, 2) with ``count`` vertices each (the rest padding) cut to the half-plane
    normal·p ≤ offset (normal (M, 2), offset (M,)): Sutherland–Hodgman for all at once. Returns (points, count) of
    the cut polygons, at most K + 1 vertices each."""
    m, k = points.shape[:2]
    index = np.arange(k)
    following = np.where(index[None, :] + 1 < count[:, None], index[None, :] + 1, 0)
    after = np.take_along_axis(points, following[..., None], axis=1)
    dist = np.einsum("mkj,mj->mk", points, normal) - offset[:, None]
    dist_after = np.take_along_axis(dist, following, axis=1)
    real = index[None, :] < count[:, None]
    keep = real & (dist <= 0)
    crosses = real & (dist * dist_after < 0)
    share = np.where(crosses, dist / np.where(crosses, dist - dist_after, 1.0), 0.0)
    crossing = points + share[..., None] * (after - points)
    candidates = np.stack([points, crossing], axis=2).reshape(m, 2 * k, 2)  # each vertex, then its edge's crossing
    wanted = np.stack([keep, crosses], axis=2).reshape(m, 2 * k)
    order = np.argsort(~wanted, axis=1, kind="stable")[:, :k + 1]
    return np.take_along_axis(candidates, order[..., None], axis=1), wanted.sum(axis=1)


def _polygon_solid_angles(points: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Solid angles of convex polygons of the square (M, K, 2), ``count`` vertices each, all inside one triangle of
    the map (so their edges are great circles): a fan of spherical triangles from the first vertex."""
    d = _sphere_points(points[..., 0], points[..., 1])
    total = np.zeros(len(points))
    for i in range(1, points.shape[1] - 1):
        part = np.abs(_triangle_solid_angle(d[:, 0], d[:, i], d[:, i + 1]))
        total += np.where(i + 1 < count, part, 0.0)
    return total


def _cut_pixel_solid_angles(n: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Solid angles of pixels (rows, cols) of an N × N plain octahedral map that a fold cuts: each pixel's square
    clipped to each of the eight triangles (a quadrant, then inside or outside the diamond), the parts summed."""
    total = np.zeros(len(rows))
    m = len(rows)
    s0, s1 = (2 * cols - n) / n, (2 * cols + 2 - n) / n
    t0, t1 = (2 * rows - n) / n, (2 * rows + 2 - n) / n
    square = np.stack([np.stack([s0, t0], -1), np.stack([s1, t0], -1), np.stack([s1, t1], -1),
                       np.stack([s0, t1], -1)], axis=1)
    for sign_s in (-1.0, 1.0):
        for sign_t in (-1.0, 1.0):
            for inside in (True, False):
                points, count = square, np.full(m, 4)
                for normal, offset in (((-sign_s, 0.0), 0.0), ((0.0, -sign_t), 0.0),
                                       ((sign_s, sign_t) if inside else (-sign_s, -sign_t), 1.0 if inside else -1.0)):
                    points, count = _clip(points, count, np.broadcast_to(np.array(normal), (m, 2)),
                                          np.full(m, offset))
                total += _polygon_solid_angles(points, count)
    return total


@lru_cache(maxsize=8)
def _octahedral_solid_angles(n: int) -> np.ndarray:
    """Exact solid angles of an N × N plain octahedral map (read-only, cached). The map is symmetric under s → −s
    and t → −t, so the quadrant s, t ≥ 0 (with the middle row and column for odd N) is measured and mirrored: its
    pixels as two spherical triangles between their corners' directions, then the pixels a fold cuts again by
    :func:`_cut_pixel_solid_angles`. Which pixels are cut is decided in integers (corner i of the edges is
    s = (2i − N)/N), so none is misjudged by rounding."""
    half = n // 2
    edges = np.arange(half, n + 1)  # corner indices of the quadrant's pixels
    quadrant = np.empty((n - half, n - half))
    band = max(1, _CLIP_BAND // (n - half + 1))
    for top in range(0, n - half, band):  # bands of rows: no (N/2)² × 3 float64 corner grid at once
        rows = edges[top:top + band + 1]
        d = _sphere_points((2 * edges[None, :] - n) / n, (2 * rows[:, None] - n) / n)
        quadrant[top:top + band] = (np.abs(_triangle_solid_angle(d[:-1, :-1], d[:-1, 1:], d[1:, 1:]))
                                    + np.abs(_triangle_solid_angle(d[:-1, :-1], d[1:, 1:], d[1:, :-1])))
    rows, cols = np.divmod(np.arange((n - half) ** 2), n - half)
    rows, cols = rows + half, cols + half
    lo_s, hi_s, lo_t, hi_t = 2 * cols - n, 2 * cols + 2 - n, 2 * rows - n, 2 * rows + 2 - n  # the edges × N
    across_axis = (lo_s < 0) | (lo_t < 0)  # the middle column or row of an odd N
    near = np.maximum(lo_s, 0) + np.maximum(lo_t, 0)
    cut = np.flatnonzero(across_axis | ((near < n) & (hi_s + hi_t > n)))
    quadrant.reshape(-1)[cut] = _cut_pixel_solid_angles(n, rows[cut], cols[cut])
    out = np.empty((n, n))
    out[half:, half:] = quadrant
    out[half:, :half] = out[half:, n - 1:n - 1 - half:-1]  # mirrored: s → −s
    out[:half] = out[n - 1:n - 1 - half:-1]  # t → −t
    out.setflags(write=False)
    return out


OCTAHEDRAL = Octahedral()
OCTAHEDRAL_EA = OctahedralEqualArea()

