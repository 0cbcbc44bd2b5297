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



import numpy as np

from ..util.errors import LayoutError
from .cube_layouts import CUBE, CUBE_FACE_ORDER, CUBE_FACES, HCROSS_TILES, VCROSS_TILES, Cross, Cube
from .disc_layouts import Angular, Sphere
from .layout_base import PAD, Grid, Layout

__all__ = ["Layout", "LatLong", "Angular", "Sphere", "Cube", "Cross", "LATLONG", "ANGULAR", "SPHERE",
           "CUBE", "CROSS", "HCROSS", "LAYOUTS", "layout", "detect_layout", "PAD", "Grid", "CUBE_FACES",
           "CUBE_FACE_ORDER", "VCROSS_TILES", "HCROSS_TILES"]


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


LATLONG = LatLong()
ANGULAR = Angular()
SPHERE = Sphere()

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
