"""Disc layouts: Debevec's angular map and the mirror ball, with exact pixel ∩ disc solid angles and the rim's
pixels integrated finely (conventions in :mod:`lightprobe.maps.layouts`)."""

from __future__ import annotations

from functools import lru_cache


import numpy as np

from ..util.errors import LayoutError
from .layout_base import _GL_W, _GL_X, _RIM_SUBSAMPLES, PAD, Layout


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
