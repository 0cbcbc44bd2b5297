"""Cube layouts: the six-face strip and the vertical and horizontal crosses, in the OpenGL / KTX / glTF face
orientation, with exact texel solid angles (conventions in :mod:`lightprobe.maps.layouts`)."""

from __future__ import annotations

from functools import lru_cache


import numpy as np

from ..util.errors import LayoutError
from .layout_base import Layout


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




CUBE = Cube()  # the one cube layout (the crosses read through it)
