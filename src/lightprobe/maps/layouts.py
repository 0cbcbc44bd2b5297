"""Environment-map layouts: pixels ↔ directions, exact per-pixel solid angles, validity masks (docs/spec.md §2).

Conventions shared by every layout:

* Directions are unit vectors in the **world frame** (:mod:`lightprobe.maps.frames`: +Y up, front −Z, right +X).
* Pixels are stored in an array of shape ``grid + (3,)``: ``grid`` is ``(H, W)`` for the flat layouts and
  ``(6, N, N)`` for ``cube`` (faces +X, −X, +Y, −Y, +Z, −Z). Row 0 is the top row as displayed.
* Continuous coordinates are ``(face, u, v)`` with ``u, v ∈ [0, 1]`` across the face (the whole image for flat
  layouts, ``face`` = 0). Pixel (row, col) has its centre at ``u = (col + ½)/W``, ``v = (row + ½)/H``.
* Each layout is a pure forward/inverse pair — :meth:`Layout.uv_to_dir` and :meth:`Layout.dir_to_uv` — plus the
  solid-angle density ``dω / (du dv)`` and exact per-pixel solid angles summing to 4π.

``size`` (used by ``lightprobe convert --size``) is the image height for ``latlong``, ``angular`` and ``sphere``
and the face edge N for ``cube``, ``cross`` (3N × 4N) and ``hcross`` (4N × 3N).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from functools import lru_cache

import math

import numpy as np

from ..util.errors import LayoutError

Grid = tuple[int, ...]
PAD = 2  # border texels of padded images: enough for a cubic B-spline's 4×4 taps

# Gauss–Legendre nodes on [0, 1] for integrating the smooth interior of disc layouts.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)
_GL_X, _GL_W = (_GL_X + 1) / 2, _GL_W / 2
_RIM_SUBSAMPLES = 24  # midpoint subsamples per axis for pixels the disc's rim cuts through


class Layout(ABC):
    """A mapping between the pixels of an image (or six faces) and directions on the sphere."""

    name: str
    faces: int = 1
    aspect: tuple[int, int] = (1, 1)  # (width, height) units of a flat layout's image
    valid_fraction: float = 1.0  # share of the image's pixels that cover the sphere (π/4 for discs, ½ for crosses)

    # ---- shapes -------------------------------------------------------------------------------------------------
    def grid_shape(self, size: int) -> Grid:
        """The pixel grid for ``size`` (see the module docstring for what ``size`` means).

        Parameters
        ----------
        size : int
            Image height for ``latlong``, ``angular`` and ``sphere``, face edge N for ``cube``, ``cross`` and
            ``hcross``; at least 1.

        Returns
        -------
        tuple of int
            ``(size × aspect height, size × aspect width)``: (H, W) of a flat layout's image.

        Raises
        ------
        LayoutError
            When ``size`` is under 1.
        """
        if size < 1:
            raise LayoutError(f"{self.name}: size must be at least 1, got {size}")
        return (size * self.aspect[1], size * self.aspect[0])

    def size_of(self, grid: Grid) -> int:
        """Inverse of :meth:`grid_shape`.

        Parameters
        ----------
        grid : tuple of int
            A pixel grid of this layout, (H, W).

        Returns
        -------
        int
            The layout's size: H divided by the aspect's height (H for the 1:1 and 2:1 layouts, N for a cross).
        """
        return grid[0] // self.aspect[1]

    def check_grid(self, grid: Grid) -> None:
        """Raise :class:`LayoutError` if an image of pixel grid ``grid`` cannot be in this layout.

        Parameters
        ----------
        grid : tuple of int
            The pixel grid to check: a flat layout needs (H, W), both at least 1, in the layout's width:height
            aspect and whole multiples of it.

        Raises
        ------
        LayoutError
            When the grid is not (H, W), is empty, or does not have the layout's aspect.
        """
        if len(grid) != 2 or grid[0] < 1 or grid[1] < 1:
            raise LayoutError(f"{self.name} needs a flat H×W image, got grid {grid}")
        h, w = grid
        aw, ah = self.aspect
        if w * ah != h * aw or h % ah or w % aw:
            raise LayoutError(f"a {w}×{h} image does not fit the {self.name} layout (needs width:height = {aw}:{ah})")

    # ---- the forward/inverse pair -------------------------------------------------------------------------------
    @abstractmethod
    def uv_to_dir(self, face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Continuous coordinates → unit world directions (..., 3). Undefined (NaN) outside the valid region.

        Parameters
        ----------
        face : numpy.ndarray
            Face index (0 for flat layouts; 0–5 in the order +X, −X, +Y, −Y, +Z, −Z for ``cube``).
        u : numpy.ndarray
            Horizontal coordinate across the face, 0 at the left edge, 1 at the right.
        v : numpy.ndarray
            Vertical coordinate across the face, 0 at the top edge, 1 at the bottom.

        Returns
        -------
        numpy.ndarray
            float64 unit vectors in the world frame (+Y up, front −Z, right +X), shape ``u.shape + (3,)``.
        """

    @abstractmethod
    def dir_to_uv(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit world directions (..., 3) → (face, u, v). Total: every direction has a place.

        Parameters
        ----------
        d : numpy.ndarray
            Unit vectors in the world frame (+Y up, front −Z, right +X), shape (..., 3).

        Returns
        -------
        face : numpy.ndarray
            int64 face index, shape ``d.shape[:-1]`` (0 for flat layouts).
        u : numpy.ndarray
            float64 horizontal coordinate in [0, 1] across the face.
        v : numpy.ndarray
            float64 vertical coordinate in [0, 1] across the face, 0 at the top.
        """

    @abstractmethod
    def uv_density(self, face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Solid angle per unit (u, v) area, ``dω / (du dv)``; 0 outside the valid region.

        Parameters
        ----------
        face : numpy.ndarray
            Face index, as :meth:`uv_to_dir` takes it.
        u : numpy.ndarray
            Horizontal coordinate across the face.
        v : numpy.ndarray
            Vertical coordinate across the face.

        Returns
        -------
        numpy.ndarray
            float64 steradians per unit of (u, v) area, the broadcast shape of the coordinates; its integral over
            all faces is 4π.
        """

    # ---- per-pixel quantities -----------------------------------------------------------------------------------
    def pixel_centres(self, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(face, u, v) of every pixel centre, each of shape ``grid``.

        Pixel (row, col) has its centre at ``u = (col + ½)/W``, ``v = (row + ½)/H``.

        Parameters
        ----------
        grid : tuple of int
            A pixel grid of this layout: (H, W), or (6, N, N) for ``cube``.

        Returns
        -------
        face : numpy.ndarray
            int64 face index of every pixel (zeros for flat layouts; for ``cube`` a read-only broadcast).
        u : numpy.ndarray
            float64 horizontal coordinate of every pixel centre.
        v : numpy.ndarray
            float64 vertical coordinate of every pixel centre.
        """
        h, w = grid[-2:]
        v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
        if self.faces == 1:
            return np.zeros(grid, dtype=np.int64), u, v
        face = np.broadcast_to(np.arange(self.faces)[:, None, None], grid)
        return face, np.broadcast_to(u, grid), np.broadcast_to(v, grid)

    def directions(self, grid: Grid) -> np.ndarray:
        """World direction of every pixel centre, shape ``grid + (3,)``; zero for invalid pixels.

        Parameters
        ----------
        grid : tuple of int
            The pixel grid whose centres are turned into directions.

        Returns
        -------
        numpy.ndarray
            float64 unit vectors in the world frame (+Y up, front −Z), shape ``grid + (3,)``; (0, 0, 0) for pixels
            that cover no part of the sphere.
        """
        d = self.uv_to_dir(*self.pixel_centres(grid))
        return np.where(self.valid_mask(grid)[..., None], np.nan_to_num(d), 0.0)

    @abstractmethod
    def solid_angles(self, grid: Grid) -> np.ndarray:
        """Exact solid angle (steradians) of every pixel, shape ``grid``; they sum to 4π. 0 for invalid pixels.

        Parameters
        ----------
        grid : tuple of int
            The pixel grid to measure; checked to fit the layout.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape ``grid``.

        Raises
        ------
        LayoutError
            When ``grid`` does not fit the layout.
        """

    def solid_angles_of(self, grid: Grid, flat: np.ndarray) -> np.ndarray:
        """:meth:`solid_angles` of the pixels at ``flat`` indices of ``grid`` alone (the same values).

        For work that needs a few of a large grid's pixels (a 4k disc's exact table takes seconds).

        Parameters
        ----------
        grid : tuple of int
            The pixel grid that ``flat`` indexes.
        flat : numpy.ndarray
            Integer indices into the flattened grid (row-major; face-major for ``cube``), any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat``.
        """
        return self.solid_angles(grid).reshape(-1)[np.asarray(flat)]

    def valid_mask(self, grid: Grid) -> np.ndarray:
        """True for pixels that cover part of the sphere.

        Parameters
        ----------
        grid : tuple of int
            The pixel grid to classify.

        Returns
        -------
        numpy.ndarray
            bool, shape ``grid``: true where the pixel's solid angle is positive; a new array the caller may change.
        """
        return self.solid_angles(grid) > 0

    def shared_valid_mask(self, grid: Grid) -> np.ndarray:
        """:meth:`valid_mask`, read-only, and for a disc the layout's cached table itself rather than a copy.

        For code that only reads it (a 4k disc's mask is 10 MiB; a conversion into one held a copy beside the cache).

        Parameters
        ----------
        grid : tuple of int
            The pixel grid (a disc's table is cached per size).

        Returns
        -------
        numpy.ndarray
            Read-only bool, shape ``grid``: true for pixels that cover part of the sphere.
        """
        mask = self.valid_mask(grid)
        mask.setflags(write=False)
        return mask

    def rim_direction(self) -> np.ndarray | None:
        """The one direction a disc layout spreads over its rim (a ring of pixels), or None for other layouts.

        Returns
        -------
        numpy.ndarray or None
            A float64 unit vector (3,) in the world frame for ``angular`` and ``sphere``; None here.
        """
        return None

    def pixel_coords(self, d: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Directions → (face, x, y) continuous pixel coordinates (pixel centre of column c is x = c).

        Parameters
        ----------
        d : numpy.ndarray
            Unit vectors in the world frame (+Y up, front −Z), shape (..., 3).
        grid : tuple of int
            The pixel grid the coordinates are in.

        Returns
        -------
        face : numpy.ndarray
            int64 face index, shape ``d.shape[:-1]``.
        x : numpy.ndarray
            float64 column coordinate ``u·W − ½``, in texels.
        y : numpy.ndarray
            float64 row coordinate ``v·H − ½`` (pixel centre of row r is y = r), in texels.
        """
        face, u, v = self.dir_to_uv(d)
        h, w = grid[-2:]
        return face, u * w - 0.5, v * h - 0.5

    # ---- lookup -------------------------------------------------------------------------------------------------
    def padded(self, data: np.ndarray, pad: int = PAD, prefilter=None) -> tuple[np.ndarray, np.ndarray]:
        """``data`` with a border of ``pad`` texels taken from across its seams and poles, and a validity mask.

        Returns ``(img, valid)`` of shapes (F, H+2p, W+2p, C) and (F, H+2p, W+2p), float32. The border texel at
        extended coordinates (u, v) holds the pixel nearest to the direction ``uv_to_dir(u, v)``: this works for any
        layout whose formulas extend past the face edge (latlong: past a pole is the ring at azimuth + π; cube: the
        next face), so bilinear and cubic lookups are seamless without knowing the layout. ``prefilter(faces)``, if
        given, rewrites the (F, H, W, C) interior in place before the border copies it (a cube's texel balance).

        Parameters
        ----------
        data : numpy.ndarray
            Pixel values of this layout, shape ``grid + (C,)`` (C channels, e.g. RGB radiance).
        pad : int, default 2
            Border width in texels (:data:`PAD`: enough for a cubic B-spline's 4×4 taps).
        prefilter : callable or None, default None
            ``prefilter(faces)`` rewrites the float32 (F, H, W, C) interior in place before the border is copied;
            None leaves the pixels as they are.

        Returns
        -------
        img : numpy.ndarray
            float32 (F, H+2p, W+2p, C): the pixels (F = 1 for flat layouts, 6 for ``cube``) with their border.
        valid : numpy.ndarray
            float32 (F, H+2p, W+2p): 1 where the texel covers part of the sphere, 0 where it does not.
        """
        grid = data.shape[:-1]
        faces = data.reshape((self.faces,) + grid[-2:] + data.shape[-1:])
        h, w = grid[-2:]
        img = np.empty((self.faces, h + 2 * pad, w + 2 * pad, data.shape[-1]), dtype=np.float32)
        interior = img[:, pad:pad + h, pad:pad + w]
        interior[...] = faces  # interior texels are themselves, exactly (unless prefiltered)
        if prefilter is not None:
            prefilter(interior)
        valid = np.empty(img.shape[:-1], dtype=np.float32)
        valid[:, pad:pad + h, pad:pad + w] = self.valid_mask(grid).reshape((self.faces, h, w))
        border, (face, row, col) = _padding_index(self, grid, pad)
        img[border] = interior[face, row, col]
        valid[border] = self.valid_mask(grid).reshape((self.faces, h, w))[face, row, col]
        return img, valid

    def sampler(self, data: np.ndarray, kernel: str = "bilinear", prefilter=None):
        """A function ``d (..., 3) → values (..., C)``: lookup of ``data`` at world directions, seam- and pole-correct.

        ``data`` has shape ``grid + (C,)``. ``kernel``: ``bilinear``, or ``bspline`` (cubic B-spline, for
        resampling); ``prefilter``: as :meth:`padded`'s.

        The padded image is made once, so one sampler serves many lookups of the same data.

        Parameters
        ----------
        data : numpy.ndarray
            Pixel values of this layout, shape ``grid + (C,)``.
        kernel : str, default "bilinear"
            ``"bilinear"`` (2×2 taps), or ``"bspline"`` (cubic B-spline, 4×4 taps, for resampling); the taps are
            weighted by their validity and renormalised.
        prefilter : callable or None, default None
            As :meth:`padded` takes it.

        Returns
        -------
        callable
            ``lookup(d)``: world directions ``d`` (..., 3) → float32 values (..., C).
        """
        from .lookups import gather  # numba is imported when a lookup is first built, not with the package

        grid = data.shape[:-1]
        img, valid = self.padded(data, PAD, prefilter)

        def lookup(d: np.ndarray) -> np.ndarray:
            face, x, y = self.pixel_coords(d, grid)
            return gather(img, valid, face, x + PAD, y + PAD, kernel)

        return lookup

    def sample(self, data: np.ndarray, d: np.ndarray, kernel: str = "bilinear") -> np.ndarray:
        """Lookup of ``data`` at directions ``d`` (one-off; see :meth:`sampler`).

        Parameters
        ----------
        data : numpy.ndarray
            Pixel values of this layout, shape ``grid + (C,)``.
        d : numpy.ndarray
            Unit vectors in the world frame (+Y up, front −Z), shape (..., 3).
        kernel : str, default "bilinear"
            ``"bilinear"`` or ``"bspline"``, as :meth:`sampler` takes it.

        Returns
        -------
        numpy.ndarray
            float32 values at the directions, shape (..., C).
        """
        return self.sampler(data, kernel)(d)

    def default_size(self, valid_pixels: int) -> int:
        """A size whose valid pixel count is close to ``valid_pixels`` (keeps the angular resolution).

        Parameters
        ----------
        valid_pixels : int
            How many pixels cover the sphere in the map being converted.

        Returns
        -------
        int
            The size (as :meth:`grid_shape` takes it), at least 1: √(valid_pixels / valid pixels per size²),
            rounded.
        """
        per_size2 = self.valid_fraction * self.aspect[0] * self.aspect[1] * self.faces
        return max(1, int(round(np.sqrt(valid_pixels / per_size2))))

    def __repr__(self) -> str:
        return f"<layout {self.name}>"


@lru_cache(maxsize=16)
def _padding_index(lay: Layout, grid: Grid, pad: int):
    """The border of :meth:`Layout.padded`'s image — a boolean mask of shape (F, H+2p, W+2p) — and, for its texels
    in mask order, the (face, row, col) of the pixel each holds (cached per grid; only the border is computed)."""
    h, w = grid[-2:]
    border = np.ones((lay.faces, h + 2 * pad, w + 2 * pad), dtype=bool)
    border[:, pad:pad + h, pad:pad + w] = False
    face, prow, pcol = np.nonzero(border)
    u, v = (pcol - pad + 0.5) / w, (prow - pad + 0.5) / h
    f, uu, vv = lay.dir_to_uv(lay.uv_to_dir(face, u, v))
    row = np.clip(np.floor(vv * h), 0, h - 1).astype(np.int64)
    col = np.clip(np.floor(uu * w), 0, w - 1).astype(np.int64)
    if lay.name == "cube" and min(h, w) >= 2 * pad:
        _cube_corner_blocks(lay, h, pad, border, f, row, col)
    border.setflags(write=False)
    return border, (f, row, col)


def _cube_corner_blocks(lay: Layout, n: int, pad: int, border: np.ndarray, f, row, col) -> None:
    """The pad × pad block of a cube face's padding beyond each of its corners, refilled in place: the face next
    round the vertex, anticlockwise, gives its own corner block, each of its texels once.

    Three faces meet at a cube's vertex, where a flat grid has four quadrants: the fourth, beyond a face's corner,
    is nobody's. The nearest texel there is one of the two other faces' corner texels — sometimes the same one
    for two slots, and for two faces — so a sun in a corner texel was read again through the others' diagonal
    padding and came out up to 4.6 % too bright at any cube size (a sun in the corner texel of the next face less).
    A texel i, j texels from the two edges at the vertex has m(i)·m(j) of its B-spline beyond both (m: the spline's
    mass past an edge), the same as the diagonal slot i, j (or j, i) texels out: given once to one slot of one
    face, each corner texel gets back the quadrant the vertex lacks, as the texels along an edge do."""
    index = {key: i for i, key in enumerate(zip(*np.nonzero(border)))}
    last = n - 1

    def texel_direction(face: int, r: float, c: float) -> np.ndarray:  # (r, c) unpadded, may lie outside the face
        return lay.uv_to_dir(np.array([face]), np.array([(c + 0.5) / n]), np.array([(r + 0.5) / n]))[0]

    vertices: dict[tuple, list] = {}
    for face in range(6):
        for r, c in ((0, 0), (0, last), (last, 0), (last, last)):
            corner = texel_direction(face, -0.5 if r == 0 else last + 0.5, -0.5 if c == 0 else last + 0.5)
            vertices.setdefault(tuple(np.sign(np.round(corner, 9)).astype(int)), []).append((face, r, c))
    for vertex, members in vertices.items():
        axis = np.array(vertex, np.float64) / math.sqrt(3.0)
        e1 = np.cross(axis, (0.0, 0.0, 1.0) if abs(axis[2]) < 0.9 else (1.0, 0.0, 0.0))
        e2 = np.cross(axis, e1)
        centres = [texel_direction(face, last / 2, last / 2) for face, _, _ in members]
        order = np.argsort([math.atan2(d @ e2, d @ e1) for d in centres])
        ring = [members[i] for i in order]
        for place, (face, r, c) in enumerate(ring):
            donor, dr, dc = ring[(place + 1) % 3]
            out_r, out_c = (-1 if r == 0 else 1), (-1 if c == 0 else 1)  # this corner's outward steps
            in_r, in_c = (1 if dr == 0 else -1), (1 if dc == 0 else -1)  # the donor's inward steps
            for a in range(pad):
                for b in range(a, pad):  # slots (a, b) and (b, a) take texels (a, b) and (b, a), as fits best
                    # slot (a, b): a texels out in columns, b in rows; texel (a, b): a texels in in rows, b in columns
                    slots = [(r + out_r * (b + 1), c + out_c * (a + 1)), (r + out_r * (a + 1), c + out_c * (b + 1))]
                    texels = [(dr + in_r * a, dc + in_c * b), (dr + in_r * b, dc + in_c * a)]
                    here = [texel_direction(face, *q) for q in slots]
                    there = [texel_direction(donor, *t) for t in texels]
                    swapped = there[1] @ here[0] + there[0] @ here[1] >= there[0] @ here[0] + there[1] @ here[1]
                    for (pr, pc), texel in zip(slots, texels[::-1] if swapped else texels):
                        j = index[(face, pr + pad, pc + pad)]
                        f[j], (row[j], col[j]) = donor, texel


# ============================================================================================================ latlong
class LatLong(Layout):
    """Equirectangular, W = 2H: θ = πv from +Y, φ = 2π(u − ½); centre column → −Z, u = ¾ → +X."""

    name = "latlong"
    aspect = (2, 1)

    def uv_to_dir(self, face, u, v):
        """(u, v) → (sin θ sin φ, cos θ, −sin θ cos φ) with θ = πv from +Y and φ = 2π(u − ½).

        The formulas hold past the image's edges (past a pole is the ring at azimuth + π), which the padding uses.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: a lat-long is one face.
        u : numpy.ndarray
            Azimuth coordinate: 0 and 1 at the back (+Z), ¼ at −X, ½ at the front (−Z), ¾ at +X.
        v : numpy.ndarray
            Polar coordinate, the shape of ``u``: 0 at +Y (top row's edge), ½ at the horizon, 1 at −Y.

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors, shape ``u.shape + (3,)``; past the edges, the continued formulas'.
        """
        theta, phi = np.pi * np.asarray(v), 2 * np.pi * (np.asarray(u) - 0.5)
        st = np.sin(theta)
        return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], axis=-1)

    def dir_to_uv(self, d):
        """Directions → (0, φ/2π + ½, θ/π) with θ = arccos y from +Y and φ = atan2(x, −z) from the front.

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors (+Y up, front −Z), shape (..., 3): y gives the row, (x, −z) the column.

        Returns
        -------
        face : numpy.ndarray
            int64 zeros, shape ``d.shape[:-1]``.
        u : numpy.ndarray
            float64 azimuth coordinate in [0, 1], ½ at the front (−Z).
        v : numpy.ndarray
            float64 polar coordinate in [0, 1], 0 at +Y.
        """
        d = np.asarray(d, dtype=np.float64)
        theta = np.arccos(np.clip(d[..., 1], -1.0, 1.0))
        phi = np.arctan2(d[..., 0], -d[..., 2])
        return np.zeros(d.shape[:-1], dtype=np.int64), phi / (2 * np.pi) + 0.5, theta / np.pi

    def uv_density(self, face, u, v):
        """dω / (du dv) = 2π² sin(πv): the rows shrink toward the poles.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: a lat-long has one face.
        u : numpy.ndarray
            Azimuth coordinate (the density does not depend on it; it sets the result's shape).
        v : numpy.ndarray
            Polar coordinate in [0, 1].

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area, the broadcast shape of ``u`` and ``v``; 0 at the poles.
        """
        return 2 * np.pi**2 * np.sin(np.pi * np.asarray(v)) + 0 * np.asarray(u)

    def solid_angles(self, grid):
        """Each row's exact solid angle (:meth:`row_solid_angles`) repeated along the row.

        Parameters
        ----------
        grid : tuple of int
            (H, 2H).

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape (H, 2H), a new array; they sum to 4π.

        Raises
        ------
        LayoutError
            When ``grid`` is not a 2:1 (H, W) grid.
        """
        self.check_grid(grid)
        return np.broadcast_to(self.row_solid_angles(grid)[:, None], grid).copy()

    def solid_angles_of(self, grid, flat):
        """The solid angles of the rows of the pixels at ``flat`` indices, with no per-pixel table.

        Parameters
        ----------
        grid : tuple of int
            (H, W) of the lat-long.
        flat : numpy.ndarray
            Row-major integer pixel indices (row × W + column), any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat``: each pixel's row's solid angle.
        """
        return self.row_solid_angles(grid)[np.asarray(flat) // grid[1]]

    def row_solid_angles(self, grid) -> np.ndarray:
        """Solid angle of one pixel of each row (all pixels of a row are equal): (2π/W)(cos θ_top − cos θ_bottom).

        Parameters
        ----------
        grid : tuple of int
            (H, W) of the lat-long; θ of row r's edges are πr/H and π(r + 1)/H.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape (H,).
        """
        h, w = grid
        cos_edges = np.cos(np.pi * np.arange(h + 1) / h)
        return (2 * np.pi / w) * (cos_edges[:-1] - cos_edges[1:])

    def valid_mask(self, grid):
        """All true: every pixel of a lat-long covers part of the sphere.

        Parameters
        ----------
        grid : tuple of int
            (H, W) of the lat-long.

        Returns
        -------
        numpy.ndarray
            bool ones of shape ``grid``, a new array.
        """
        return np.ones(grid, dtype=bool)


# ============================================================================================================ discs
class _DiscLayout(Layout):
    """A square image whose valid region is the inscribed disc; rim pixels count with the part of them inside it."""

    valid_fraction = np.pi / 4

    def _disc_radius(self, u, v):
        return np.hypot(2 * np.asarray(u) - 1, 1 - 2 * np.asarray(v))

    def solid_angles(self, grid):
        """Integrated ``uv_density`` of every pixel, cached per disc size and returned as a copy.

        4×4 Gauss–Legendre inside the disc, a fine midpoint rule on the rim; 0 off the disc.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the disc image; checked square.

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
        return _disc_solid_angles(self, grid[0]).copy()

    def solid_angles_of(self, grid, flat):
        """The disc pixels' solid angles at ``flat`` indices, integrated for those pixels alone.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the disc image.
        flat : numpy.ndarray
            Row-major integer pixel indices, any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat``; 0 for pixels off the disc.
        """
        n = grid[0]
        rows, cols = np.divmod(np.asarray(flat), n)
        inner, cut = _disc_pixel_classes_of(n, rows, cols)
        out = np.zeros(rows.shape)
        out[inner] = _interior_solid_angles(self, n, rows[inner], cols[inner])
        out[cut] = self._rim_pixel_solid_angles(n, rows[cut], cols[cut])
        return out

    def valid_mask(self, grid):
        """``solid_angles(grid) > 0`` without integrating the interior.

        Every pixel wholly inside the disc is valid; of the rim pixels, those whose share of the disc is not 0 (a 1/n²
        part of the work).

        Parameters
        ----------
        grid : tuple of int
            (N, N): the disc size whose table is copied.

        Returns
        -------
        numpy.ndarray
            bool (N, N), a writable copy of the cached table.
        """
        return self.shared_valid_mask(grid).copy()

    def shared_valid_mask(self, grid):
        """The cached validity table of this disc size itself, read-only: no copy.

        Parameters
        ----------
        grid : tuple of int
            (N, N): the disc size whose cached table is returned.

        Returns
        -------
        numpy.ndarray
            Read-only bool (N, N), shared by every caller.
        """
        self.check_grid(grid)
        return _disc_valid_mask(self, grid[0])  # read-only

    def _rim_pixel_solid_angles(self, n: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Solid angles of the rim pixels (rows, cols) of an n×n image, without integrating the interior."""
        return _rim_solid_angles(self, n, rows, cols)

    def _clamped_ab(self, u, v):
        """Disc coordinates (a right, b up), pulled onto the rim where they fall outside it.

        The whole rim of a disc layout is one direction, so a pixel the rim cuts through is given that direction
        even when its centre lies just outside the disc."""
        a, b = 2 * np.asarray(u) - 1, 1 - 2 * np.asarray(v)
        r = np.hypot(a, b)
        shrink = np.where(r > 1.0, 1.0 / np.maximum(r, 1e-300), 1.0)
        return a * shrink, b * shrink

    def padded(self, data, pad=PAD, prefilter=None):
        """A zero border with zero validity (nothing lies beyond a disc's rim), and each pixel's certainty.

        Parameters
        ----------
        data : numpy.ndarray
            Pixel values of the disc image, (N, N, C).
        pad : int, default 2
            Border width in texels.
        prefilter : callable or None, default None
            Rewrites the float32 (1, N, N, C) interior in place, as for :meth:`Layout.padded`.

        Returns
        -------
        img : numpy.ndarray
            float32 (1, N+2p, N+2p, C), zeros in the border.
        valid : numpy.ndarray
            float32 (1, N+2p, N+2p): 1 inside the disc, 0 off it and in the border, and for a pixel the rim cuts its
            share of a whole pixel's solid angle (lookups renormalise by it).
        """
        # nothing lies beyond a disc's rim: zero border with zero validity; rim pixels count by their share
        img = np.pad(data.astype(np.float32), ((pad, pad), (pad, pad), (0, 0)))[None]
        if prefilter is not None:
            prefilter(img[:, pad:-pad, pad:-pad])
        valid = np.pad(_disc_certainty(self, data.shape[0]), pad)[None]
        return img, valid


@lru_cache(maxsize=8)
def _disc_certainty(layout: _DiscLayout, n: int) -> np.ndarray:
    """How much each pixel of an n×n disc image counts in a lookup that renormalises its taps (float32): 1 inside
    the disc, 0 off it, and for a pixel the rim cuts its solid angle over that of a whole pixel where it lies (the
    density at its centre, or half a pixel inside the rim if its centre is further out). A lookup is then a
    normalised convolution whose certainties are the pixels' shares of the sphere. Counted whole (the validity mask),
    a rim sliver with 0.1 % of a pixel's area was read as much as a whole pixel beside it, and a sun in it came out
    with up to ~1000 times its energy (mirror ball 256 → cube 64: +94 000 %, angular 256 → cube 64: +125 000 %).
    By area alone, an angular map's slivers (its density falls to 0 at the rim) still came out up to 14×."""
    interior, rim = _disc_pixel_classes(n)
    rows, cols = np.nonzero(rim)
    a, b = (2 * cols + 1) / n - 1, 1 - (2 * rows + 1) / n  # the rim pixels' centres
    inward = np.minimum(1.0, (1 - 1 / n) / np.hypot(a, b))
    whole = layout.uv_density(0, (a * inward + 1) / 2, (1 - b * inward) / 2) / n**2
    out = interior.astype(np.float32)
    out[rows, cols] = np.clip(layout._rim_pixel_solid_angles(n, rows, cols) / whole, 0.0, 1.0)
    out.setflags(write=False)
    return out


def _quarter_disc_area(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Signed area of the rectangle between (0, 0) and (a, b) inside the unit disc (exact).

    Inclusion–exclusion of this over a pixel's corners gives the pixel's exact area inside the disc."""
    sign = np.sign(a) * np.sign(b)
    a, b = np.minimum(np.abs(a), 1.0), np.minimum(np.abs(b), 1.0)
    x_star = np.sqrt(np.clip(1 - b * b, 0.0, None))  # where the circle crosses height b
    lo = np.minimum(a, x_star)

    def circle_integral(x):  # ∫ √(1 − x²) dx
        return (x * np.sqrt(np.clip(1 - x * x, 0.0, None)) + np.arcsin(x)) / 2

    return sign * (b * lo + circle_integral(a) - circle_integral(lo))


def _disc_extents(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per column (or row) of an n×n disc image: the pixel's farthest and nearest |coordinate| from the centre."""
    edges = np.arange(n + 1) / n
    a = np.abs(2 * edges - 1)
    far_a = np.maximum(a[:-1], a[1:])
    near_a = np.where((edges[:-1] < 0.5) & (edges[1:] > 0.5), 0.0, np.minimum(a[:-1], a[1:]))
    return far_a, near_a


def _disc_pixel_classes_of(n: int, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_disc_pixel_classes` of the pixels at ``rows``, ``cols`` alone (the same values)."""
    far_a, near_a = _disc_extents(n)
    far, near = np.hypot(far_a[cols], far_a[rows]), np.hypot(near_a[cols], near_a[rows])
    return far <= 1.0, (near < 1.0) & (far > 1.0)


def _disc_pixel_classes(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(interior, rim) masks of an n×n disc image: pixels wholly inside the disc, and pixels the rim cuts."""
    far_a, near_a = _disc_extents(n)  # per column (or row): the pixel's farthest and nearest |coordinate|
    interior, rim = np.empty((n, n), dtype=bool), np.empty((n, n), dtype=bool)
    band = max(1, (1 << 18) // n)
    for top in range(0, n, band):  # bands of rows: no n×n float64 temporaries
        far = np.hypot(far_a[None, :], far_a[top:top + band, None])
        near = np.hypot(near_a[None, :], near_a[top:top + band, None])
        interior[top:top + band], rim[top:top + band] = far <= 1.0, (near < 1.0) & (far > 1.0)
    return interior, rim


@lru_cache(maxsize=8)
def _disc_valid_mask(layout: _DiscLayout, n: int) -> np.ndarray:
    mask, rim = _disc_pixel_classes(n)  # the interior, and the rim pixels whose share of the disc is not 0
    rows, cols = np.nonzero(rim)
    del rim
    mask[rows, cols] = layout._rim_pixel_solid_angles(n, rows, cols) > 0
    mask.setflags(write=False)
    return mask


def _rim_solid_angles(layout: _DiscLayout, n: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Solid angles of rim pixels (a fine midpoint rule: the density jumps to 0 at the rim), in chunks."""
    sub = (np.arange(_RIM_SUBSAMPLES) + 0.5) / _RIM_SUBSAMPLES
    out = np.empty(len(rows))
    for start in range(0, len(rows), 2048):
        r, c = rows[start:start + 2048], cols[start:start + 2048]
        u = (c[:, None, None] + sub[None, None, :]) / n
        v = (r[:, None, None] + sub[None, :, None]) / n
        out[start:start + 2048] = layout.uv_density(0, u, v).mean(axis=(1, 2)) / n**2
    return out


def _interior_solid_angles(layout: _DiscLayout, n: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Solid angles of pixels wholly inside the disc: 4×4 Gauss–Legendre (the density is smooth there)."""
    u = (cols[:, None, None] + _GL_X[None, None, :]) / n
    v = (rows[:, None, None] + _GL_X[None, :, None]) / n
    wts = _GL_W[None, :, None] * _GL_W[None, None, :]
    return (layout.uv_density(0, u, v) * wts).sum(axis=(1, 2)) / n**2


@lru_cache(maxsize=8)
def _disc_solid_angles(layout: _DiscLayout, n: int) -> np.ndarray:
    """Integrate ``uv_density`` over every pixel of an n×n disc image.

    Pixels wholly inside the disc: 4×4 Gauss–Legendre (the density is smooth there). Pixels the rim cuts through:
    a fine midpoint rule, because the density jumps to 0 at the rim.
    """
    interior, rim = _disc_pixel_classes(n)
    omega = np.zeros((n, n))
    band = max(1, (1 << 16) // n)
    for top in range(0, n, band):  # bands of rows: the point grids stay ~10 MB
        rows, cols = np.nonzero(interior[top:top + band])
        rows = rows + top
        omega[rows, cols] = _interior_solid_angles(layout, n, rows, cols)
    rows, cols = np.nonzero(rim)
    omega[rows, cols] = layout._rim_pixel_solid_angles(n, rows, cols)
    omega.setflags(write=False)
    return omega


class Angular(_DiscLayout):
    """Debevec angular map: radius r ∝ angle from the front (−Z); centre → −Z, rim → +Z (docs/spec.md §2)."""

    name = "angular"

    def rim_direction(self):
        """+Z, straight behind: the whole rim of an angular map.

        Returns
        -------
        numpy.ndarray
            float64 (0, 0, 1).
        """
        return np.array([0.0, 0.0, 1.0])

    def uv_to_dir(self, face, u, v):
        """Disc point (a, b) = (2u − 1, 1 − 2v) at radius r → (a, b)·sin(πr)/r in x, y and −cos(πr) in z.

        r is the angle from the front (−Z) over π: the centre is −Z, r = ½ the horizon ring of ±X, ±Y, the rim +Z.
        Points off the disc are pulled onto the rim, so they give +Z rather than NaN.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the disc is one face.
        u : numpy.ndarray
            Horizontal image coordinate, ½ at the centre, increasing to the right (+X).
        v : numpy.ndarray
            Vertical image coordinate, ½ at the centre, increasing downward (−Y).

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors, shape ``u.shape + (3,)``; +Z off the disc.
        """
        a, b = self._clamped_ab(u, v)
        r = np.hypot(a, b)
        s = np.pi * np.sinc(r)  # sin(πr)/r, finite at r = 0
        return np.stack([a * s, b * s, -np.cos(np.pi * r)], axis=-1)

    def dir_to_uv(self, d):
        """Directions → disc point at radius r = (angle from −Z)/π in the direction of (x, y).

        Straight behind (+Z), the whole rim, maps to its right-hand point (u, v) = (1, ½).

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors, shape (..., 3): the angle from −Z gives the radius, (x, y) the way out from the centre.

        Returns
        -------
        face : numpy.ndarray
            int64 zeros, shape ``d.shape[:-1]``.
        u : numpy.ndarray
            float64 ``(a + 1)/2`` in [0, 1].
        v : numpy.ndarray
            float64 ``(1 − b)/2`` in [0, 1].
        """
        d = np.asarray(d, dtype=np.float64)
        r = np.arccos(np.clip(-d[..., 2], -1.0, 1.0)) / np.pi
        rho = np.hypot(d[..., 0], d[..., 1])
        off_axis = rho > 1e-150  # closer to ±Z than that, r/ρ overflows (and the pixel is the same)
        scale = np.where(off_axis, r / np.where(off_axis, rho, 1.0), 0.0)
        # straight behind (+Z) is the whole rim: take its right-hand point
        a = np.where(off_axis, d[..., 0] * scale, r)
        b = d[..., 1] * scale
        return np.zeros(d.shape[:-1], dtype=np.int64), (a + 1) / 2, (1 - b) / 2

    def uv_density(self, face, u, v):
        """dω / (du dv) = 4π² sinc(r) = 4π sin(πr)/r inside the disc (r ≤ 1), 0 outside; it falls to 0 at the rim.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the disc has one face.
        u : numpy.ndarray
            Horizontal image coordinate; with ``v``, the radius r from the centre.
        v : numpy.ndarray
            Vertical image coordinate.

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area, the broadcast shape of ``u`` and ``v``; 0 off the disc.
        """
        r = self._disc_radius(u, v)
        return np.where(r <= 1.0, 4 * np.pi**2 * np.sinc(r), 0.0)


class Sphere(_DiscLayout):
    """Mirror ball / OpenGL sphere map seen by a camera with axes T = [right, up, back] (default: looking along −Z).

    The centre of the image reflects the direction straight back toward the camera (T·+z); the rim is the single
    direction the camera looks along (T·−z).

    Parameters
    ----------
    camera_axes : numpy.ndarray or None, default None
        T, a 3×3 rotation matrix whose columns are the camera's right, up and back axes in the world frame; None:
        the identity (right +X, up +Y, looking along −Z).

    Raises
    ------
    LayoutError
        When ``camera_axes`` is not a rotation matrix (3×3, orthogonal, determinant +1).
    """

    name = "sphere"

    def __init__(self, camera_axes: np.ndarray | None = None):
        t = np.eye(3) if camera_axes is None else np.asarray(camera_axes, dtype=np.float64)
        if t.shape != (3, 3) or not np.allclose(t @ t.T, np.eye(3), atol=1e-9) or np.linalg.det(t) < 0:
            raise LayoutError("sphere layout: camera_axes must be a rotation matrix [right, up, back]")
        self.camera_axes = t

    def __eq__(self, other):
        return isinstance(other, Sphere) and np.array_equal(self.camera_axes, other.camera_axes)

    def __hash__(self):
        return hash((self.name, self.camera_axes.tobytes()))

    def rim_direction(self):
        """T·−z, the direction the camera looks along: the whole rim of the ball.

        Returns
        -------
        numpy.ndarray
            float64 world unit vector (3,): −Z for the default camera.
        """
        return self.camera_axes @ np.array([0.0, 0.0, -1.0])

    def uv_to_dir(self, face, u, v):
        """Ball normal (x, y, z) at (x, y) = (2u − 1, 1 − 2v) → the view ray reflected there, T·(2xz, 2yz, 2z² − 1).

        The centre reflects T·+z (back toward the camera), the rim T·−z. Points off the disc are pulled onto the rim,
        so they give T·−z rather than NaN.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the ball is one face.
        u : numpy.ndarray
            Horizontal image coordinate, increasing along the camera's right.
        v : numpy.ndarray
            Vertical image coordinate, increasing along the camera's down.

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors, shape ``u.shape + (3,)``; T·−z off the disc.
        """
        x, y = self._clamped_ab(u, v)
        z = np.sqrt(np.clip(1 - x * x - y * y, 0.0, None))
        local = np.stack([2 * x * z, 2 * y * z, 2 * z * z - 1], axis=-1)
        return local @ self.camera_axes.T

    def solid_angles(self, grid):
        """In closed form: 4 sr per unit of disc area (a constant density) times each pixel's exact area in the disc.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the ball image.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape (N, N); exactly 0 off the disc; they sum to 4π.

        Raises
        ------
        LayoutError
            When ``grid`` is not a square (N, N) image.
        """
        # constant density: the exact area of each pixel inside the disc, times 4 sr per unit of (a, b) area
        self.check_grid(grid)
        n = grid[0]
        e = np.linspace(-1.0, 1.0, n + 1)
        g = _quarter_disc_area(e[:, None], e[None, :])
        area = g[1:, 1:] - g[:-1, 1:] - g[1:, :-1] + g[:-1, :-1]
        interior, rim = _disc_pixel_classes(n)
        return np.where(interior | rim, 4 * np.maximum(area, 0.0), 0.0)  # exact 0 off the disc

    def solid_angles_of(self, grid, flat):
        """The closed form of :meth:`solid_angles` for the pixels at ``flat`` indices alone.

        Parameters
        ----------
        grid : tuple of int
            (N, N) of the ball image.
        flat : numpy.ndarray
            Row-major integer indices (row × N + column), any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat``; 0 off the disc.
        """
        n = grid[0]
        rows, cols = np.divmod(np.asarray(flat), n)
        inner, cut = _disc_pixel_classes_of(n, rows, cols)  # the closed form holds inside the disc too
        return np.where(inner | cut, self._rim_pixel_solid_angles(n, rows, cols), 0.0)

    def valid_mask(self, grid):
        """``solid_angles(grid) > 0``, with the exact areas of the rim pixels only.

        Parameters
        ----------
        grid : tuple of int
            (N, N): the ball image whose rim pixels are measured.

        Returns
        -------
        numpy.ndarray
            bool (N, N), a new array.
        """
        self.check_grid(grid)
        n = grid[0]
        interior, rim = _disc_pixel_classes(n)
        rows, cols = np.nonzero(rim)
        interior[rows, cols] = self._rim_pixel_solid_angles(n, rows, cols) > 0
        return interior

    def _rim_pixel_solid_angles(self, n, rows, cols):
        # constant density: 4 sr per unit of disc area, each pixel's area in the disc exact
        e = np.linspace(-1.0, 1.0, n + 1)
        area = (_quarter_disc_area(e[rows + 1], e[cols + 1]) - _quarter_disc_area(e[rows], e[cols + 1])
                - _quarter_disc_area(e[rows + 1], e[cols]) + _quarter_disc_area(e[rows], e[cols]))
        return 4 * np.maximum(area, 0.0)

    def dir_to_uv(self, d):
        """Directions → the ball point whose normal halves the angle between the camera's back axis and d.

        In camera axes (Tᵀd), the normal is Tᵀd + (0, 0, 1) normalised; its (x, y) is the disc point. The direction
        the camera looks along, the whole rim, maps to its right-hand point (u, v) = (1, ½).

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors, shape (..., 3), taken into camera axes by Tᵀ.

        Returns
        -------
        face : numpy.ndarray
            int64 zeros, shape ``d.shape[:-1]``.
        u : numpy.ndarray
            float64 ``(x + 1)/2`` in [0, 1].
        v : numpy.ndarray
            float64 ``(1 − y)/2`` in [0, 1].
        """
        local = np.asarray(d, dtype=np.float64) @ self.camera_axes
        n = local + np.array([0.0, 0.0, 1.0])
        norm = np.hypot(np.hypot(n[..., 0], n[..., 1]), n[..., 2])
        # the direction the camera looks along has no unique normal: any rim point; take the right-hand one. Within
        # 1e-150 of it the components of n are (near-)denormal and lose digits (hypothesis found 5.6e-158 and
        # 2.2e-313 moving the point 1e-5 off the rim): those directions are the rim point too, to any precision.
        on_axis = norm <= 1e-150
        x = np.where(on_axis, 1.0, n[..., 0] / np.where(on_axis, 1.0, norm))
        y = np.where(on_axis, 0.0, n[..., 1] / np.where(on_axis, 1.0, norm))
        return np.zeros(local.shape[:-1], dtype=np.int64), (x + 1) / 2, (1 - y) / 2

    def uv_density(self, face, u, v):
        """dω / (du dv) = 16 inside the disc, 0 outside: a mirror ball's density is constant.

        That is 4 sr per unit area of the disc's (x, y), which spans four times the (u, v) area.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the ball has one face.
        u : numpy.ndarray
            Horizontal image coordinate (only whether (u, v) lies on the disc matters).
        v : numpy.ndarray
            Vertical image coordinate.

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area, 16.0 or 0.0, the broadcast shape of ``u`` and ``v``.
        """
        return np.where(self._disc_radius(u, v) <= 1.0, 16.0, 0.0)


# ============================================================================================================ cubes
# Each cube face is a signed permutation matrix A with  direction ∝ A · (s, t, 1),  s, t ∈ [−1, 1]  (s right, t down).
# Its third column is the face's axis. Inverse: (s, t) = (Aᵀd)[:2] / (Aᵀd)[2]. Tables from docs/spec.md §2, verbatim.
def _face(*rows) -> np.ndarray:
    return np.array(rows, dtype=np.float64)


CUBE_FACES = {  # OpenGL / KTX / glTF orientation, order +X, −X, +Y, −Y, +Z, −Z
    "+X": _face((0, 0, 1), (0, -1, 0), (-1, 0, 0)),  # (1, −t, −s)
    "-X": _face((0, 0, -1), (0, -1, 0), (1, 0, 0)),  # (−1, −t, s)
    "+Y": _face((1, 0, 0), (0, 0, 1), (0, 1, 0)),  # (s, 1, t)
    "-Y": _face((1, 0, 0), (0, 0, -1), (0, -1, 0)),  # (s, −1, −t)
    "+Z": _face((1, 0, 0), (0, -1, 0), (0, 0, 1)),  # (s, −t, 1)
    "-Z": _face((-1, 0, 0), (0, -1, 0), (0, 0, -1)),  # (−s, −t, −1)
}
CUBE_FACE_ORDER = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")

VCROSS_TILES = {  # Debevec vertical cross, (tile row, tile col) → matrix; a right, b down inside the tile
    (1, 1): _face((1, 0, 0), (0, -1, 0), (0, 0, -1)),  # front −Z: (a, −b, −1)
    (0, 1): _face((1, 0, 0), (0, 0, 1), (0, -1, 0)),  # +Y: (a, 1, −b)
    (1, 0): _face((0, 0, -1), (0, -1, 0), (-1, 0, 0)),  # −X: (−1, −b, −a)
    (1, 2): _face((0, 0, 1), (0, -1, 0), (1, 0, 0)),  # +X: (1, −b, a)
    (2, 1): _face((1, 0, 0), (0, 0, -1), (0, 1, 0)),  # −Y: (a, −1, b)
    (3, 1): _face((1, 0, 0), (0, 1, 0), (0, 0, 1)),  # back +Z, upside down: (a, b, 1)
}
HCROSS_TILES = {  # horizontal cross: the middle row runs −X, front, +X, back, all upright
    (1, 1): VCROSS_TILES[(1, 1)],
    (0, 1): VCROSS_TILES[(0, 1)],
    (1, 0): VCROSS_TILES[(1, 0)],
    (1, 2): VCROSS_TILES[(1, 2)],
    (2, 1): VCROSS_TILES[(2, 1)],
    (1, 3): _face((-1, 0, 0), (0, -1, 0), (0, 0, 1)),  # back +Z: (−a, −b, 1)
}


def _faces_dir_to_st(mats: np.ndarray, d: np.ndarray):
    """Pick, for each direction, the face whose axis it is closest to; return (face index, s, t)."""
    d = np.asarray(d, dtype=np.float64)
    axes = mats[:, :, 2]  # (F, 3): each face's outward axis
    face = np.argmax(d @ axes.T, axis=-1)
    local = np.einsum("...ji,...j->...i", mats[face], d)  # Aᵀ d per direction
    return face, local[..., 0] / local[..., 2], local[..., 1] / local[..., 2]


def _faces_st_to_dir(mats: np.ndarray, face, s, t) -> np.ndarray:
    st1 = np.stack(np.broadcast_arrays(s, t, np.ones_like(s, dtype=np.float64)), axis=-1)
    d = np.einsum("...ij,...j->...i", mats[np.asarray(face)], st1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _cube_texel_solid_angles(n: int, rows: np.ndarray | None = None, cols: np.ndarray | None = None) -> np.ndarray:
    """Exact solid angle of the texels of one N×N cube face: signed sum of atan2(xy, √(x²+y²+1)) at the corners;
    of the texels at ``rows``, ``cols`` alone if given (the same values)."""
    e = np.linspace(-1.0, 1.0, n + 1)
    if rows is None:
        x, y = np.meshgrid(e, e, indexing="xy")
        f = np.arctan2(x * y, np.sqrt(x * x + y * y + 1))
        return f[1:, 1:] - f[:-1, 1:] - f[1:, :-1] + f[:-1, :-1]

    def corner(r, c):
        x, y = e[c], e[r]
        return np.arctan2(x * y, np.sqrt(x * x + y * y + 1))

    return corner(rows + 1, cols + 1) - corner(rows, cols + 1) - corner(rows + 1, cols) + corner(rows, cols)


def _st_density(s, t):
    """dω / (ds dt) on a cube face."""
    return (1 + s * s + t * t) ** -1.5


class Cube(Layout):
    """Six N×N faces in the order +X, −X, +Y, −Y, +Z, −Z with OpenGL orientation; grid (6, N, N).

    As an image file a cube is a horizontal strip 6N × N of the faces in that order.
    """

    name = "cube"
    faces = 6
    aspect = (1, 1)
    _mats = np.stack([CUBE_FACES[k] for k in CUBE_FACE_ORDER])

    def grid_shape(self, size):
        """(6, N, N) for face edge N = ``size``.

        Parameters
        ----------
        size : int
            Face edge N in texels, at least 1.

        Returns
        -------
        tuple of int
            (6, size, size).

        Raises
        ------
        LayoutError
            When the face edge ``size`` is under 1.
        """
        if size < 1:
            raise LayoutError(f"cube: size must be at least 1, got {size}")
        return (6, size, size)

    def size_of(self, grid):
        """The face edge N of a (6, N, N) grid.

        Parameters
        ----------
        grid : tuple of int
            A cube grid (6, N, N).

        Returns
        -------
        int
            N.
        """
        return grid[-1]

    def check_grid(self, grid):
        """Refuse anything but six square faces.

        Parameters
        ----------
        grid : tuple of int
            The grid to check: (6, N, N) with N ≥ 1.

        Raises
        ------
        LayoutError
            When it is not (6, N, N).
        """
        if len(grid) != 3 or grid[0] != 6 or grid[1] != grid[2] or grid[1] < 1:
            raise LayoutError(f"cube needs six square faces (6, N, N), got grid {grid}")

    def uv_to_dir(self, face, u, v):
        """(face, u, v) → A_face·(s, t, 1) normalised, with s = 2u − 1 (right) and t = 2v − 1 (down).

        A_face is the face's signed permutation matrix (:data:`CUBE_FACES`, OpenGL orientation). Past the face's
        edge the same plane continues, toward the next face's directions.

        Parameters
        ----------
        face : numpy.ndarray
            Integer face index 0–5: +X, −X, +Y, −Y, +Z, −Z.
        u : numpy.ndarray
            Horizontal coordinate across the face.
        v : numpy.ndarray
            Vertical coordinate across the face, 0 at the top.

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors, the broadcast shape of the coordinates ``+ (3,)``.
        """
        return _faces_st_to_dir(self._mats, face, 2 * np.asarray(u) - 1, 2 * np.asarray(v) - 1)

    def dir_to_uv(self, d):
        """Directions → the face whose axis is nearest, and (s, t) = (Aᵀd)[:2] / (Aᵀd)[2] on it.

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors, shape (..., 3): the face whose axis has the largest dot product takes each.

        Returns
        -------
        face : numpy.ndarray
            int64 face index 0–5 (+X, −X, +Y, −Y, +Z, −Z), shape ``d.shape[:-1]``.
        u : numpy.ndarray
            float64 ``(s + 1)/2`` in [0, 1].
        v : numpy.ndarray
            float64 ``(t + 1)/2`` in [0, 1], 0 at the face's top.
        """
        face, s, t = _faces_dir_to_st(self._mats, d)
        return face, (s + 1) / 2, (t + 1) / 2

    def uv_density(self, face, u, v):
        """dω / (du dv) = 4 (1 + s² + t²)^(−3/2), the same on every face: highest at a face's centre.

        Parameters
        ----------
        face : numpy.ndarray
            Face index (the density does not depend on it; it takes part in the result's shape).
        u : numpy.ndarray
            s = 2u − 1, rightward across the face.
        v : numpy.ndarray
            t = 2v − 1, downward across the face.

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area, the broadcast shape of ``face``, ``u`` and ``v``.
        """
        return 4 * _st_density(2 * np.asarray(u) - 1, 2 * np.asarray(v) - 1) + 0 * np.asarray(face)

    def solid_angles(self, grid):
        """Exact texel solid angles (signed sums of atan2(xy, √(x² + y² + 1)) at the corners), alike on all faces.

        Parameters
        ----------
        grid : tuple of int
            (6, N, N); checked.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape (6, N, N), a new array; they sum to 4π.

        Raises
        ------
        LayoutError
            When ``grid`` is not (6, N, N).
        """
        self.check_grid(grid)
        return np.broadcast_to(_cube_texel_solid_angles(grid[-1]), grid).copy()

    def solid_angles_of(self, grid, flat):
        """The exact texel solid angles at ``flat`` indices, from their corners alone.

        Parameters
        ----------
        grid : tuple of int
            (6, N, N): N sets the texel edges.
        flat : numpy.ndarray
            Integer indices into the flattened (6, N, N) grid (face × N² + row × N + column), any shape.

        Returns
        -------
        numpy.ndarray
            float64 steradians, the shape of ``flat`` (a texel's place in its face decides it).
        """
        rows, cols = np.divmod(np.asarray(flat) % (grid[-1] * grid[-2]), grid[-1])
        return _cube_texel_solid_angles(grid[-1], rows, cols)

    def valid_mask(self, grid):
        """All true: the six faces cover the sphere.

        Parameters
        ----------
        grid : tuple of int
            (6, N, N): the mask's shape.

        Returns
        -------
        numpy.ndarray
            bool ones of shape (6, N, N), a new array.
        """
        return np.ones(grid, dtype=bool)


class Cross(Layout):
    """A cube unfolded into one image of tiles (N×N each); tiles not in the table are invalid (black).

    Parameters
    ----------
    name : str
        The layout's name: ``cross`` (:data:`VCROSS_TILES`) or ``hcross`` (:data:`HCROSS_TILES`).
    tiles : dict
        (tile row, tile column) → the tile's 3×3 signed permutation matrix A, direction ∝ A·(a, b, 1) with a right
        and b down inside the tile, in [−1, 1]; its order numbers this layout's faces.
    aspect : tuple of int
        (width, height) of the image in tiles: (3, 4) for the vertical cross, (4, 3) for the horizontal one.
    """

    def __init__(self, name: str, tiles: dict, aspect: tuple[int, int]):
        self.name, self.aspect = name, aspect
        self._tiles = list(tiles)  # (row, col) per face index of this layout
        self._mats = np.stack([tiles[k] for k in self._tiles])
        self.valid_fraction = 6 / (aspect[0] * aspect[1])

    def _tile_of(self, u, v):
        cols, rows = self.aspect
        tc, tr = np.floor(np.asarray(u) * cols), np.floor(np.asarray(v) * rows)
        tile = np.full(np.shape(tc), -1, dtype=np.int64)
        for k, (r, c) in enumerate(self._tiles):
            tile[(tr == r) & (tc == c)] = k
        a = 2 * (np.asarray(u) * cols - tc) - 1
        b = 2 * (np.asarray(v) * rows - tr) - 1
        return tile, a, b

    def uv_to_dir(self, face, u, v):
        """(u, v) over the whole image → its tile's A·(a, b, 1) normalised; NaN on the empty tiles.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: the tile comes from (u, v).
        u : numpy.ndarray
            Horizontal coordinate across the whole cross image.
        v : numpy.ndarray
            Vertical coordinate across the whole cross image, 0 at the top.

        Returns
        -------
        numpy.ndarray
            float64 world unit vectors, shape ``u.shape + (3,)``; NaN off the six tiles.
        """
        tile, a, b = self._tile_of(u, v)
        d = _faces_st_to_dir(self._mats, np.maximum(tile, 0), a, b)
        return np.where((tile >= 0)[..., None], d, np.nan)

    def dir_to_uv(self, d):
        """Directions → the nearest face's tile and the place in it, as coordinates across the whole image.

        A face's edges are kept inside its tile (by 1e-12), so an outer edge does not round onto an empty tile.

        Parameters
        ----------
        d : numpy.ndarray
            World unit vectors, shape (..., 3): each goes to its cube face's tile.

        Returns
        -------
        face : numpy.ndarray
            int64 zeros, shape ``d.shape[:-1]`` (the image is one face).
        u : numpy.ndarray
            float64 horizontal coordinate in [0, 1] across the image.
        v : numpy.ndarray
            float64 vertical coordinate in [0, 1] across the image.
        """
        k, a, b = _faces_dir_to_st(self._mats, d)
        # keep face edges inside their tile: an outer edge must not round onto the empty neighbouring tile
        a, b = np.clip(a, -1 + 1e-12, 1 - 1e-12), np.clip(b, -1 + 1e-12, 1 - 1e-12)
        tiles = np.array(self._tiles)
        cols, rows = self.aspect
        u = (tiles[k, 1] + (a + 1) / 2) / cols
        v = (tiles[k, 0] + (b + 1) / 2) / rows
        return np.zeros(np.shape(k), dtype=np.int64), u, v

    def uv_density(self, face, u, v):
        """dω / (du dv) = 4·columns·rows·(1 + a² + b²)^(−3/2) on the six tiles, 0 on the empty ones.

        Parameters
        ----------
        face : numpy.ndarray
            Not used: (u, v) pick the tile.
        u : numpy.ndarray
            Horizontal coordinate across the whole cross image.
        v : numpy.ndarray
            Vertical coordinate across the whole cross image.

        Returns
        -------
        numpy.ndarray
            float64 sr per unit (u, v) area of the image, the broadcast shape of ``u`` and ``v``.
        """
        tile, a, b = self._tile_of(u, v)
        cols, rows = self.aspect
        return np.where(tile >= 0, 4 * cols * rows * _st_density(a, b), 0.0)

    def solid_angles(self, grid):
        """A cube face's exact texel solid angles in each of the six tiles, 0 elsewhere.

        Parameters
        ----------
        grid : tuple of int
            (H, W) of the cross image, in the layout's aspect.

        Returns
        -------
        numpy.ndarray
            float64 steradians, shape ``grid``; they sum to 4π.

        Raises
        ------
        LayoutError
            When ``grid`` does not have the layout's aspect.
        """
        self.check_grid(grid)
        n = grid[0] // self.aspect[1]
        omega = np.zeros(grid)
        texels = _cube_texel_solid_angles(n)  # symmetric under the flips and swaps that orient the tiles
        for r, c in self._tiles:
            omega[r * n : (r + 1) * n, c * n : (c + 1) * n] = texels
        return omega

    def valid_mask(self, grid):
        """The six tiles (a bool per pixel: no solid angles at float64, 134 MB for a 4k map's cross).

        Parameters
        ----------
        grid : tuple of int
            (H, W) of the cross image.

        Returns
        -------
        numpy.ndarray
            bool, shape ``grid``, a new array: true on the six tiles.

        Raises
        ------
        LayoutError
            When ``grid`` is not (H, W) in the layout's aspect.
        """
        self.check_grid(grid)
        n = grid[0] // self.aspect[1]
        mask = np.zeros(grid, dtype=bool)
        for r, c in self._tiles:
            mask[r * n:(r + 1) * n, c * n:(c + 1) * n] = True
        return mask

    def to_cube(self, data: np.ndarray) -> np.ndarray:
        """Rearrange a cross image into cube faces (6, N, N, C). Exact: both hold the same texel centres.

        Parameters
        ----------
        data : numpy.ndarray
            The cross image, shape (H, W, …) in the layout's aspect (tiles N × N).

        Returns
        -------
        numpy.ndarray
            A new array (6, N, N, …) of ``data``'s dtype: the faces in the cube's order +X, −X, +Y, −Y, +Z, −Z
            and orientation.
        """
        n = data.shape[0] // self.aspect[1]
        out = np.empty((6, n, n) + data.shape[2:], dtype=data.dtype)
        for face, (row, col, turn) in enumerate(_tile_turns(self)):
            out[face] = _unturned(data[row * n:(row + 1) * n, col * n:(col + 1) * n], *turn)
        return out

    def tile_turns(self) -> tuple[tuple[int, int, tuple[bool, bool, bool]], ...]:
        """Per cube face: its tile and the symmetry of the square that turns the face's texels into the tile.

        The tile is given by (row, column), the symmetry by (transpose, flip rows, flip columns) (see
        :meth:`from_cube`).

        Returns
        -------
        tuple
            Six ``(tile row, tile column, (transpose, flip rows, flip columns))``, in the cube's face order; the
            face is transposed first, then flipped.
        """
        return _tile_turns(self)

    def rows_are_face_rows(self) -> bool:
        """Whether every tile is its face flipped, not transposed: each image row is then rows of faces.

        A streamed writer then computes them row by row.

        Returns
        -------
        bool
            True when no tile is a transposed face.
        """
        return not any(turn[0] for _, _, turn in _tile_turns(self))

    def from_cube(self, faces: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_cube`; tiles outside the cross are 0.

        Parameters
        ----------
        faces : numpy.ndarray
            Cube faces (6, N, N, …) in the order +X, −X, +Y, −Y, +Z, −Z.

        Returns
        -------
        numpy.ndarray
            The cross image (N × aspect height, N × aspect width, …), a new array of ``faces``' dtype.
        """
        n = faces.shape[1]
        out = np.zeros((n * self.aspect[1], n * self.aspect[0]) + faces.shape[3:], dtype=faces.dtype)
        for face, (row, col, turn) in enumerate(_tile_turns(self)):
            out[row * n:(row + 1) * n, col * n:(col + 1) * n] = _turned(faces[face], *turn)
        return out

    def sampler(self, data, kernel="bilinear", prefilter=None):
        """:meth:`Layout.sampler` of the cross's cube faces (:meth:`to_cube`).

        Parameters
        ----------
        data : numpy.ndarray
            The cross image, (H, W, C).
        kernel : str, default "bilinear"
            ``"bilinear"`` or ``"bspline"``.
        prefilter : callable or None, default None
            Applied to the (6, N, N, C) cube faces, as the cube's :meth:`Layout.padded` takes it.

        Returns
        -------
        callable
            ``lookup(d)``: world directions (..., 3) → float32 values (..., C).
        """
        # looked up through its cube faces: the rearrangement is exact and the cube's padding is seamless
        return CUBE.sampler(self.to_cube(data), kernel, prefilter)


@lru_cache(maxsize=4)
def _tile_turns(layout: Cross) -> tuple[tuple[int, int, tuple[bool, bool, bool]], ...]:
    """Per cube face, (tile row, tile column, (transpose, flip rows, flip columns)): the symmetry of the square that
    turns the face's texels into its tile of the cross (:func:`_turned`). A tile holds the same texel centres as its
    face, so it is one of the square's eight symmetries at every size: found once, from the directions of a
    3-texel cube (:func:`_cross_to_cube_index`), instead of a direction per texel at the map's size (a 4k map's
    cube of 1182 had 1.2 GB of float64 directions and indices for a cross target)."""
    n = 3
    rows, cols = _cross_to_cube_index(layout, n)
    texels = np.arange(n * n).reshape(n, n)
    turns = []
    for face in range(6):
        row, col = int(rows[face].min()) // n, int(cols[face].min()) // n
        tile = np.empty((n, n), np.int64)
        tile[rows[face] - row * n, cols[face] - col * n] = texels
        turn = next(t for t in np.ndindex(2, 2, 2) if np.array_equal(_turned(texels, *map(bool, t)), tile))
        turns.append((row, col, tuple(map(bool, turn))))
    return tuple(turns)


def _turned(face: np.ndarray, transpose: bool, flip_rows: bool, flip_columns: bool) -> np.ndarray:
    """A face's texels (N, N, …) as its tile shows them: transposed, then flipped (a view)."""
    out = face.swapaxes(0, 1) if transpose else face
    return out[::-1 if flip_rows else 1, ::-1 if flip_columns else 1]


def _unturned(tile: np.ndarray, transpose: bool, flip_rows: bool, flip_columns: bool) -> np.ndarray:
    """The inverse of :func:`_turned` (a view): unflipped, then transposed back."""
    out = tile[::-1 if flip_rows else 1, ::-1 if flip_columns else 1]
    return out.swapaxes(0, 1) if transpose else out


@lru_cache(maxsize=4)
def _cross_to_cube_index(layout: Cross, n: int):
    """For every cube texel (6, N, N), the cross pixel (row, col) that holds the same direction."""
    grid = CUBE.grid_shape(n)
    d = CUBE.uv_to_dir(*CUBE.pixel_centres(grid))
    _, x, y = layout.pixel_coords(d, layout.grid_shape(n))
    return np.rint(y).astype(np.int64), np.rint(x).astype(np.int64)


LATLONG = LatLong()
ANGULAR = Angular()
SPHERE = Sphere()
CUBE = Cube()
CROSS = Cross("cross", VCROSS_TILES, (3, 4))
HCROSS = Cross("hcross", HCROSS_TILES, (4, 3))

LAYOUTS: dict[str, Layout] = {lay.name: lay for lay in (LATLONG, ANGULAR, SPHERE, CUBE, CROSS, HCROSS)}


def layout(name: str | Layout) -> Layout:
    """Look a layout up by name; a :class:`Layout` passes through.

    Parameters
    ----------
    name : str or Layout
        ``latlong``, ``angular``, ``sphere``, ``cube``, ``cross`` or ``hcross``, or a :class:`Layout`.

    Returns
    -------
    Layout
        The shared instance of that name (``sphere``: the default camera, looking along −Z), or ``name`` itself.

    Raises
    ------
    LayoutError
        When no layout has that name.
    """
    if isinstance(name, Layout):
        return name
    try:
        return LAYOUTS[name]
    except KeyError:
        raise LayoutError(f"unknown layout {name!r}; known layouts: {', '.join(LAYOUTS)}") from None


def detect_layout(width: int, height: int) -> Layout:
    """Guess a flat image's layout from its aspect ratio.

    2:1 latlong, 1:1 angular, 3:4 cross, 4:3 hcross, 6:1 cube strip. A mirror ball (also 1:1) must be stated
    explicitly.

    Parameters
    ----------
    width : int
        Image width in pixels.
    height : int
        Image height in pixels.

    Returns
    -------
    Layout
        The layout of that aspect ratio (1:1 is ``angular``).

    Raises
    ------
    LayoutError
        When the aspect ratio is none of those; the message says to state the layout with ``--layout``.
    """
    ratios = {(2, 1): LATLONG, (1, 1): ANGULAR, (3, 4): CROSS, (4, 3): HCROSS, (6, 1): CUBE}
    for (aw, ah), lay in ratios.items():
        if width * ah == height * aw:
            return lay
    raise LayoutError(
        f"cannot tell the layout of a {width}×{height} image from its aspect ratio "
        "(2:1 latlong, 1:1 angular, 3:4 cross, 4:3 hcross, 6:1 cube); state it with --layout"
    )
