"""The layout interface every environment-map layout implements, and what all share: padding with the
neighbours across seams, found by direction (see :mod:`lightprobe.maps.layouts` for the conventions)."""

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
