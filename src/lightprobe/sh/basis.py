"""Real spherical harmonics in Ramamoorthi & Hanrahan's convention (docs/spec.md §3), any order.

Convention (stated once, used everywhere):

* Y_lm(θ, φ) = N_lm P_l^|m|(cos θ) az_m(φ), az_0 = 1, az_{+m} = √2 cos mφ, az_{−m} = √2 sin |m|φ, with P_l^m the
  associated Legendre functions **without** the Condon–Shortley phase (−1)^m. So Y1−1 = +0.488603 y,
  Y10 = +0.488603 z, Y11 = +0.488603 x (the dissertation's eq. 4.5; the SIGGRAPH text's ordering is a misprint).
* θ, φ are the polar angles of a direction about the +z axis of the **frame in which coefficients are stated**
  (:class:`SHCoeffs.frame`); for the world frame that is world +Z (backwards), not +Y (up).
* Flat index i = l(l+1) + m: L00, L1−1, L10, L11, L2−2, L2−1, L20, L21, L22, …
* Quantities: ``radiance`` coefficients L_lm of the environment, or ``irradiance`` coefficients E_lm = Â_l L_lm
  (E(n) = Σ E_lm Y_lm(n), irradiance at a surface with normal n; **not** divided by π). Engine pre-scaled forms
  live in :mod:`lightprobe.exports.sh`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from math import comb, factorial, pi, sqrt

import numpy as np

from ..util.jit import njit, prange, read_only, worth_compiling
from ..maps import EnvMap
from ..util.errors import UsageError
from ..maps.frames import WORLD, Frame, frame as frame_named
from ..maps.layouts import LatLong
from ..util.names import WINDOWS  # the names users type: numpy-free, for the command line
from .row_sums import row_sums

QUANTITIES = ("radiance", "irradiance")


# ---- indexing -----------------------------------------------------------------------------------------------------
def n_coeffs(l_max: int) -> int:
    """(l_max + 1)², the number of coefficients up to band l_max.

    Parameters
    ----------
    l_max : int
        The highest band (order), ≥ 0.

    Returns
    -------
    int
        The number of coefficients of bands 0..l_max.
    """
    return (l_max + 1) ** 2


def index(l: int, m: int) -> int:
    """Flat index l(l+1) + m.

    Parameters
    ----------
    l : int
        The band, ≥ 0.
    m : int
        The order, −l ≤ m ≤ l (not checked).

    Returns
    -------
    int
        The coefficient's position in flat order: L00, L1−1, L10, L11, L2−2, …
    """
    return l * (l + 1) + m


def degree_order(i: int) -> tuple[int, int]:
    """(l, m) of flat index i.

    Parameters
    ----------
    i : int
        A flat index l(l+1) + m, ≥ 0.

    Returns
    -------
    tuple of (int, int)
        The band l and order m, −l ≤ m ≤ l.
    """
    l = int(np.floor(np.sqrt(i)))
    return l, i - l * (l + 1)


def name(i: int) -> str:
    """Coefficient name as in the paper: L00, L1-1, L10, …

    Parameters
    ----------
    i : int
        The coefficient's flat index, ≥ 0 (0 → L00, 1 → L1-1, …).

    Returns
    -------
    str
        ``L`` followed by l and m, with an ASCII minus (``L2-2``).
    """
    l, m = degree_order(i)
    return f"L{l}{m}"


def l_max_of(n: int) -> int:
    """The highest band of ``n`` coefficients: l_max with (l_max + 1)² = n.

    Parameters
    ----------
    n : int
        A number of coefficients; it must be a square.

    Returns
    -------
    int
        l_max = √n − 1.

    Raises
    ------
    UsageError
        ``n`` is not a square.
    """
    l = int(round(np.sqrt(n))) - 1
    if (l + 1) ** 2 != n:
        raise UsageError(f"{n} is not a number of SH coefficients (a square)")
    return l


def band_of_each(l_max: int) -> np.ndarray:
    """The band l of every flat index up to l_max.

    Parameters
    ----------
    l_max : int
        The last band listed, ≥ 0.

    Returns
    -------
    numpy.ndarray
        ((l_max+1)²,) integers: 0, 1, 1, 1, 2, 2, 2, 2, 2, …
    """
    return np.concatenate([np.full(2 * l + 1, l) for l in range(l_max + 1)])


# ---- the basis ----------------------------------------------------------------------------------------------------
def basis(l_max: int, d: np.ndarray) -> np.ndarray:
    """Y_lm(d) for all l ≤ l_max, shape d.shape[:-1] + ((l_max+1)²,); d are unit vectors in the coefficients' frame.

    Evaluated with the fully normalised associated-Legendre recurrences on P_l^m / sin^m θ and the exact
    polynomials Re/Im (x + iy)^m, so there is no sqrt, no atan2 and no loss at the poles. The basis is the module's:
    real SH without the Condon–Shortley phase, θ and φ about the frame's +z.

    Parameters
    ----------
    l_max : int
        The highest band, ≥ 0.
    d : numpy.ndarray
        (..., 3) unit vectors, in the frame the coefficients are stated in (for the world frame: +Y up, front −Z,
        polar axis +Z); converted to float64.

    Returns
    -------
    numpy.ndarray
        d.shape[:-1] + ((l_max+1)²,) float64: Y_lm(d) in flat order l(l+1) + m.
    """
    d = np.asarray(d, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.empty(d.shape[:-1] + (n_coeffs(l_max),))
    cos_m, sin_m = np.ones_like(x), np.zeros_like(x)  # Re, Im of (x + iy)^m
    p_mm = np.full_like(x, 1 / sqrt(4 * pi))  # normalised P_m^m / sin^m θ
    for m in range(l_max + 1):
        if m > 0:
            p_mm = p_mm * sqrt((2 * m + 1) / (2 * m))
            cos_m, sin_m = cos_m * x - sin_m * y, sin_m * x + cos_m * y
        p_prev, p_cur = np.zeros_like(x), p_mm
        for l in range(m, l_max + 1):
            if l == m + 1:
                p_prev, p_cur = p_cur, z * sqrt(2 * m + 3) * p_cur
            elif l > m + 1:
                a = sqrt((4 * l * l - 1) / (l * l - m * m))
                b = sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
                p_prev, p_cur = p_cur, a * (z * p_cur - b * p_prev)
            if m == 0:
                out[..., index(l, 0)] = p_cur
            else:
                out[..., index(l, m)] = sqrt(2) * p_cur * cos_m
                out[..., index(l, -m)] = sqrt(2) * p_cur * sin_m
    return out


@njit(cache=True, inline="always")
def _basis_at(x, y, z, a, b, pmm_step, out):  # pragma: no cover - compiled
    """Y_lm(x, y, z) for every l ≤ l_max (= len(pmm_step) − 1) into ``out``: :func:`basis`'s recurrences for one
    direction, constants from :func:`_recurrence_tables`."""
    l_max = pmm_step.shape[0] - 1
    cos_m, sin_m, p_mm = 1.0, 0.0, pmm_step[0]
    for m in range(l_max + 1):
        if m > 0:
            p_mm *= pmm_step[m]
            cos_m, sin_m = cos_m * x - sin_m * y, sin_m * x + cos_m * y
        p_prev, p_cur = 0.0, p_mm
        for l in range(m, l_max + 1):
            if l == m + 1:
                p_prev, p_cur = p_cur, z * math.sqrt(2.0 * m + 3.0) * p_cur
            elif l > m + 1:
                p_prev, p_cur = p_cur, a[l, m] * (z * p_cur - b[l, m] * p_prev)
            if m == 0:
                out[l * (l + 1)] = p_cur
            else:
                out[l * (l + 1) + m] = 1.4142135623730951 * p_cur * cos_m
                out[l * (l + 1) - m] = 1.4142135623730951 * p_cur * sin_m


@njit(cache=True, parallel=True, fastmath=False)
def _series(d, coeffs, a, b, pmm_step, out):  # pragma: no cover - compiled
    """out[p] = Σ_lm coeffs[lm] Y_lm(d[p]) per point, without the (points × coefficients) basis matrix (which
    costs more to fill and read than the sums themselves)."""
    for p in prange(d.shape[0]):
        y_lm = np.empty(coeffs.shape[0])
        _basis_at(d[p, 0], d[p, 1], d[p, 2], a, b, pmm_step, y_lm)
        for c in range(coeffs.shape[1]):
            total = 0.0
            for k in range(coeffs.shape[0]):
                total += y_lm[k] * coeffs[k, c]
            out[p, c] = total


def series(l_max: int, d: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Σ_lm coeffs[lm] Y_lm(d), shape d.shape[:-1] + coeffs.shape[1:]: ``basis(l_max, d) @ coeffs``.

    Computed by a compiled kernel above order 2 where that is worth loading numba for
    (:func:`lightprobe.util.jit.worth_compiling`; 6× faster than numpy's basis matrix and product at order 12, 47k
    points: 21 against 132 ms), else by numpy. The two agree to float64 rounding, not bit for bit.

    Parameters
    ----------
    l_max : int
        The highest band of ``coeffs``, ≥ 0.
    d : numpy.ndarray
        (..., 3) unit vectors in the coefficients' frame; converted to float64.
    coeffs : numpy.ndarray
        ((l_max+1)², ...) coefficients in flat order, e.g. ((l_max+1)², 3) RGB; converted to float64.

    Returns
    -------
    numpy.ndarray
        d.shape[:-1] + coeffs.shape[1:] float64: the function's value at each direction (per channel).
    """
    d = np.asarray(d, dtype=np.float64)
    coeffs = np.asarray(coeffs, dtype=np.float64)
    points = math.prod(d.shape[:-1])
    if l_max <= 2 or not worth_compiling(points * coeffs.shape[0] * 16):  # numpy: ~16 ns per point and coefficient
        return basis(l_max, d) @ coeffs
    flat = np.ascontiguousarray(coeffs.reshape(coeffs.shape[0], -1))
    out = np.empty((points, flat.shape[1]))
    _series(read_only(d.reshape(-1, 3)), read_only(flat), *_recurrence_tables(l_max), out)
    return out.reshape(d.shape[:-1] + coeffs.shape[1:])


def normalisation(l: int, m: int) -> float:
    """N_lm = √((2l+1)/(4π) · (l−|m|)!/(l+|m|)!) (docs/spec.md §3).

    Parameters
    ----------
    l : int
        The band, ≥ 0.
    m : int
        The order, |m| ≤ l; only |m| matters.

    Returns
    -------
    float
        N_lm (without the √2 of the m ≠ 0 functions).
    """
    m = abs(m)
    return sqrt((2 * l + 1) / (4 * pi) * factorial(l - m) / factorial(l + m))


def a_hat(l: int) -> float:
    """Â_l, the SH coefficients of the clamped cosine (paper eqs. 8–9): π, 2π/3, π/4, 0, −π/24, 0, π/64, …

    For even l ≥ 2, Â_l = 2π (−1)^(l/2−1) / ((l+2)(l−1)) · l! / (2^l (l/2)!²), and l! / (l/2)!² = C(l, l/2). The
    binomial and 2^l are formed as exact Python integers and divided once (correctly rounded), so the value is
    right at any order; numpy's int64 (the old ``2**l`` on a numpy integer) overflows from l = 63 and silently
    gave Â_24 = 1522.9 instead of −0.0017 through the float factorials.

    Parameters
    ----------
    l : int
        The band, ≥ 0 (a numpy integer is converted to a Python one).

    Returns
    -------
    float
        Â_l: E_lm = Â_l L_lm gives irradiance (not divided by π); 0 for odd l ≥ 3.

    Raises
    ------
    UsageError
        ``l`` is negative.
    """
    l = int(l)
    if l < 0:
        raise UsageError(f"Â_l needs l ≥ 0, got {l}")
    if l == 0:
        return pi
    if l == 1:
        return 2 * pi / 3
    if l % 2:
        return 0.0
    h = l // 2
    return 2 * pi * (-1) ** (h - 1) / ((l + 2) * (l - 1)) * (comb(l, h) / (1 << l))


def a_hat_per_coefficient(l_max: int) -> np.ndarray:
    """Â_l of every flat index up to l_max: what multiplies each radiance coefficient to give irradiance.

    Parameters
    ----------
    l_max : int
        The last band whose Â_l is given, ≥ 0.

    Returns
    -------
    numpy.ndarray
        ((l_max+1)²,) float64: Â_l of each coefficient's band (:func:`a_hat`), in flat order.
    """
    return np.array([a_hat(l) for l in band_of_each(l_max)])


# ---- frame changes and rotations ------------------------------------------------------------------------------------
def _sample_directions(n: int) -> np.ndarray:
    """n well-spread directions (Fibonacci sphere), deterministic."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def transform_matrix(l_max: int, q: np.ndarray) -> np.ndarray:
    """Matrix T with b = T a, where a are the coefficients of f and b those of f'(d) = f(Qᵀ d), for orthogonal Q.

    Q may be any orthogonal matrix: a rotation, or a mirror such as the world → rh2001 frame change. T is
    block-diagonal by band.

    Each band block is solved exactly from Y_l(Qᵀ d) = D_l Y_l(d) at well-spread directions: band l is closed under
    O(3), so the system is consistent and least squares returns the exact matrix (to ~1e-13); this is the
    "equivalent exact method" docs/spec.md §1 allows in place of the Ivanic–Ruedenberg recurrence, and it needs no
    sign bookkeeping for mirrors.

    Parameters
    ----------
    l_max : int
        The highest band, ≥ 0.
    q : numpy.ndarray
        (3, 3) orthogonal matrix (not checked), acting on column vectors of the frame the coefficients are stated
        in; converted to float64.

    Returns
    -------
    numpy.ndarray
        ((l_max+1)², (l_max+1)²) float64, read-only: the matrix is cached and shared by later calls with the same
        ``l_max`` and ``q``.
    """
    q = np.asarray(q, dtype=np.float64)
    return _transform_matrix(l_max, q.tobytes())


@lru_cache(maxsize=64)
def _transform_matrix(l_max: int, q_bytes: bytes) -> np.ndarray:
    q = np.frombuffer(q_bytes).reshape(3, 3)
    d = _sample_directions(4 * (2 * l_max + 1) + 8)
    y, yq = basis(l_max, d), basis(l_max, d @ q)  # rows: Y(d_k), Y(Qᵀ d_k)  (row-vector d @ Q = (Qᵀ d)ᵀ)
    t = np.zeros((n_coeffs(l_max), n_coeffs(l_max)))
    for l in range(l_max + 1):
        s = slice(l * l, (l + 1) ** 2)
        t[s, s] = np.linalg.lstsq(y[:, s], yq[:, s], rcond=None)[0]  # solves Y·Dᵀ = Y_q: T = Dᵀ
    t.setflags(write=False)
    return t


# ---- windows --------------------------------------------------------------------------------------------------------


def window_weights(kind: str, l_max: int, width: float | None = None) -> np.ndarray:
    """Per-band weights w_l (l = 0..l_max) of a de-ringing window of ``width`` (default l_max + 1).

    ``hanning``: w_l = (1 + cos(πl/W))/2; ``lanczos``: w_l = sinc(l/W); both 0 for l ≥ W. ``none``: 1.

    Parameters
    ----------
    kind : str
        ``none``, ``hanning`` or ``lanczos``. (``auto`` is a search, not a fixed window: :meth:`SHCoeffs.windowed`
        handles it through :func:`auto_window`; here it is refused.)
    l_max : int
        The highest band, ≥ 0.
    width : float, optional
        The window's width W in bands (default l_max + 1); ignored by ``none``.

    Returns
    -------
    numpy.ndarray
        (l_max + 1,) float64: w_l for each band (index it with :func:`band_of_each` for one weight a coefficient).

    Raises
    ------
    UsageError
        ``kind`` is not one of the windows above.
    """
    l = np.arange(l_max + 1, dtype=np.float64)
    w = float(width if width is not None else l_max + 1)
    if kind == "none":
        return np.ones(l_max + 1)
    if kind == "hanning":
        return np.where(l < w, 0.5 * (1 + np.cos(np.pi * l / w)), 0.0)
    if kind == "lanczos":
        return np.where(l < w, np.sinc(l / w), 0.0)
    raise UsageError(f"unknown window {kind!r}; choose one of {', '.join(WINDOWS)}")


# ---- the coefficient type -------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SHCoeffs:
    """SH coefficients of an RGB function on the sphere.

    ``coeffs``: ((l_max+1)², 3) float64 in flat order; ``frame``: the frame whose +z the basis is built about;
    ``quantity``: ``radiance`` (L_lm) or ``irradiance`` (E_lm = Â_l L_lm); ``window``: the de-ringing window
    applied, if any (e.g. ``lanczos(3.7)``).
    """

    coeffs: np.ndarray
    frame: Frame = WORLD
    quantity: str = "radiance"
    window: str = "none"

    def __post_init__(self) -> None:
        c = np.array(self.coeffs, dtype=np.float64)
        if c.ndim == 1:
            c = c[:, None]
        l_max_of(c.shape[0])
        if self.quantity not in QUANTITIES:
            raise UsageError(f"unknown quantity {self.quantity!r}; one of {QUANTITIES}")
        if not np.isfinite(c).all():
            raise UsageError("SH coefficients must be finite numbers (found NaN or infinity)")
        c.setflags(write=False)
        object.__setattr__(self, "coeffs", c)

    @property
    def l_max(self) -> int:
        """The highest band l of the coefficients (there are (l_max+1)² of them)."""
        return l_max_of(self.coeffs.shape[0])

    def __getitem__(self, lm: tuple[int, int]) -> np.ndarray:
        return self.coeffs[index(*lm)]

    def evaluate(self, d_world: np.ndarray) -> np.ndarray:
        """The function at world directions (..., 3): radiance for ``radiance``, E(n) for ``irradiance``.

        Parameters
        ----------
        d_world : numpy.ndarray
            (..., 3) unit vectors in the world frame (+Y up, front −Z), whatever :attr:`frame` the coefficients
            are stated in: directions for radiance, surface normals for irradiance.

        Returns
        -------
        numpy.ndarray
            (..., 3) float64 (one value per channel of :attr:`coeffs`): radiance L(d), or irradiance E(n) not
            divided by π.
        """
        d = self.frame.from_world(np.asarray(d_world, dtype=np.float64))
        return series(self.l_max, d, self.coeffs)

    def to_irradiance(self) -> SHCoeffs:
        """E_lm = Â_l L_lm (paper eq. 7). Refuses coefficients that already are irradiance.

        Returns
        -------
        SHCoeffs
            Irradiance coefficients (E not divided by π) in the same frame, order and window.

        Raises
        ------
        UsageError
            The coefficients already are irradiance (convolving twice is an error).
        """
        if self.quantity != "radiance":
            raise UsageError(f"these coefficients are already {self.quantity}; convolving twice is an error")
        return replace(self, coeffs=self.coeffs * a_hat_per_coefficient(self.l_max)[:, None], quantity="irradiance")

    def to_frame(self, target: str | Frame) -> SHCoeffs:
        """The same function stated in another frame (docs/spec.md §1: world → rh2001 negates L10, L2−1, L21, …).

        Frames with the same axes (world and three.js-axes, say) only change the label: exact, with no
        least-squares round-off; any other change goes through :func:`transform_matrix`.

        Parameters
        ----------
        target : str or Frame
            A frame name of :data:`lightprobe.maps.frames.FRAMES` (``world``, ``rh2001``, ``threejs``, …) or a
            :class:`~lightprobe.maps.frames.Frame`.

        Returns
        -------
        SHCoeffs
            The coefficients stated in ``target``; quantity and window unchanged.

        Raises
        ------
        UsageError
            ``target`` is not a known frame name.
        """
        target = frame_named(target)
        q = target.to_frame @ self.frame.to_frame.T  # this frame → target frame
        if np.array_equal(q, np.eye(3)):  # the same axes (world and Filament, say): exact, no least-squares round-off
            return replace(self, frame=target)
        return replace(self, coeffs=transform_matrix(self.l_max, q) @ self.coeffs, frame=target)

    def rotated(self, rotation: np.ndarray) -> SHCoeffs:
        """The lighting turned by a world rotation R (light from d moves to R·d), exactly, in the same frame.

        Parameters
        ----------
        rotation : numpy.ndarray
            (3, 3) rotation matrix R acting on world-frame column vectors (+Y up, front −Z), e.g. from
            :func:`lightprobe.maps.frames.rotation_from_ypr` (yaw, pitch, roll in degrees). It is not checked here.

        Returns
        -------
        SHCoeffs
            The turned lighting, stated in the same frame, with the same quantity and window.
        """
        r = np.asarray(rotation, dtype=np.float64)
        q = self.frame.to_frame @ r @ self.frame.to_frame.T  # R expressed in this frame
        return replace(self, coeffs=transform_matrix(self.l_max, q) @ self.coeffs)

    def truncated(self, l_max: int) -> SHCoeffs:
        """The coefficients of bands ≤ ``l_max`` only.

        Parameters
        ----------
        l_max : int
            The highest band to keep, ≥ 0; at or above the coefficients' own order, they are returned whole.

        Returns
        -------
        SHCoeffs
            The first (l_max+1)² coefficients, same frame, quantity and window.
        """
        return replace(self, coeffs=self.coeffs[: n_coeffs(l_max)])

    def windowed(self, kind: str, width: float | None = None) -> SHCoeffs:
        """Coefficients times a de-ringing window (see :func:`window_weights`; ``auto``: :func:`auto_window`).

        Parameters
        ----------
        kind : str
            ``none``, ``hanning``, ``lanczos`` or ``auto`` (:data:`lightprobe.util.names.WINDOWS`).
        width : float, optional
            The window's width W in bands (default l_max + 1); ignored by ``none`` and ``auto``.

        Returns
        -------
        SHCoeffs
            The windowed coefficients (same frame and quantity) whose ``window`` names what was applied: ``none``,
            e.g. ``lanczos(3.7)``, or for ``auto`` the label :func:`auto_window` gives.

        Raises
        ------
        UsageError
            ``kind`` is not a known window, or ``auto`` is asked of irradiance coefficients.
        """
        if kind == "auto":
            return auto_window(self)
        w = window_weights(kind, self.l_max, width)[band_of_each(self.l_max)]
        label = "none" if kind == "none" else f"{kind}({width if width is not None else self.l_max + 1:g})"
        return replace(self, coeffs=self.coeffs * w[:, None], window=label)

    def scaled_band(self, l: int, factor: float) -> SHCoeffs:
        """Lighting design: multiply band l by ``factor``.

        Parameters
        ----------
        l : int
            The band, 0 ≤ l ≤ :attr:`l_max` (a band above it changes nothing).
        factor : float
            The factor, applied to every coefficient of the band and every channel.

        Returns
        -------
        SHCoeffs
            Band l times ``factor``, the other bands as they were; frame, quantity and window kept.

        Raises
        ------
        UsageError
            ``factor`` is NaN or makes a coefficient infinite.
        """
        c = self.coeffs.copy()
        c[l * l : (l + 1) ** 2] *= factor
        return replace(self, coeffs=c)

    def with_coefficient(self, lm: tuple[int, int], rgb) -> SHCoeffs:
        """Lighting design: set one coefficient (all channels to one value, or an RGB triple).

        Parameters
        ----------
        lm : tuple of (int, int)
            The coefficient's (l, m), |m| ≤ l ≤ :attr:`l_max`.
        rgb : float or sequence of 3 floats
            The new value, in the coefficients' quantity and frame: one number for every channel, or R, G, B.

        Returns
        -------
        SHCoeffs
            A copy with L_lm replaced by ``rgb`` (every other coefficient, the frame, quantity and window kept).

        Raises
        ------
        UsageError
            ``rgb`` holds NaN or an infinity.
        """
        c = self.coeffs.copy()
        c[index(*lm)] = np.broadcast_to(np.asarray(rgb, dtype=np.float64), (3,))
        return replace(self, coeffs=c)

    def as_list(self) -> list[list[float]]:
        """The coefficients as plain Python floats, for JSON.

        Returns
        -------
        list of list of float
            One row per coefficient in flat order, one value per channel ([R, G, B]).
        """
        return [[float(v) for v in row] for row in self.coeffs]


def auto_window(sh: SHCoeffs, samples: int = 16384) -> SHCoeffs:
    """The widest Lanczos window (least blurring) whose reconstructed irradiance is ≥ 0 everywhere, per channel.

    Like Filament cmgen's ``--sh-window auto``: ringing around a bright sun makes the irradiance on the far side
    negative; a window that just removes the negative lobes keeps as much detail as possible. The minimum over
    ``samples`` well-spread normals is not monotone in the width W, so W is scanned from wide to narrow (steps of
    3 %) and the first width that works is refined by bisection against the last one that failed.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, any order and frame.
    samples : int, default 16384
        How many well-spread normals (a Fibonacci lattice) the irradiance is checked at.

    Returns
    -------
    SHCoeffs
        Radiance coefficients with the widest working Lanczos window applied, labelled ``auto:lanczos(W)``; or
        the coefficients unchanged, labelled ``auto(none needed)``, when the irradiance is non-negative without a
        window.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, not radiance, coefficients.
    """
    if sh.quantity != "radiance":
        raise UsageError("the auto window needs radiance coefficients")
    y = basis(sh.l_max, sh.frame.from_world(_sample_directions(samples)))  # evaluated once for the whole search
    bands = band_of_each(sh.l_max)
    convolved = sh.coeffs * a_hat_per_coefficient(sh.l_max)[:, None]

    # Between the samples the minimum can dip a little lower (≈ 2e-5 of the maximum at 16k samples): require a
    # margin of 1e-4 of the mean irradiance on the samples so the result is non-negative everywhere.
    margin = 1e-4 * max(float(convolved[0].max()) * basis(0, np.array([0.0, 0.0, 1.0]))[0], 0.0)

    def non_negative(width: float) -> bool:
        w = window_weights("lanczos", sh.l_max, width)[bands]
        return float((y @ (convolved * w[:, None])).min()) >= margin

    if non_negative(np.inf):
        return replace(sh, window="auto(none needed)")
    failed = 8.0 * (sh.l_max + 1)
    width = failed
    while width > 1.0 and not non_negative(width):
        failed, width = width, width * 0.97
    if width <= 1.0:
        width = 1.0  # only band 0 survives: never negative for a non-negative map
    for _ in range(20):  # the widest working width between `width` (works) and `failed` (does not)
        mid = 0.5 * (width + failed)
        width, failed = (mid, failed) if non_negative(mid) else (width, mid)
    out = sh.windowed("lanczos", width)
    return replace(out, window=f"auto:lanczos({width:.4g})")


# ---- projection -----------------------------------------------------------------------------------------------------
# A lat-long row is a ring of constant θ about +Y. In the frame P below, the SH polar axis is +Y and P's (θ, φ) are
# exactly the lat-long's, so the projection separates into row sums against cos/sin tables (sh/row_sums.py) and a
# per-row Legendre weighting. P is x' = −Z, y' = +X, z' = +Y (a mirror of the world frame; transform_matrix handles
# mirrors).
_LATLONG_POLAR = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _project_latlong(env: EnvMap, l_max: int, compiled: bool) -> np.ndarray:
    h, w = env.grid
    sums = row_sums(np.ascontiguousarray(env.data), l_max, compiled)
    weights, which = _latlong_row_weights(h, w, l_max)
    coeffs = np.empty((len(which), sums.shape[2]))
    for k, of_sum in enumerate(_coefficients_of_each_sum(l_max)):  # one product per row sum: the einsum over
        coeffs[of_sum] = weights[of_sum] @ sums[:, k, :]  # sums[:, which] took 5–7× as long (0.56 ms at order 8)
    # coefficients of L in frame P; L(d_world) = g(P d) ⇒ world coefficients are g's transformed by Q = Pᵀ
    return transform_matrix(l_max, _LATLONG_POLAR.T) @ coeffs


@lru_cache(maxsize=8)
def _coefficients_of_each_sum(l_max: int) -> tuple[np.ndarray, ...]:
    """For each row sum (order 0, then cos and sin of each m ≥ 1), the coefficients it weights (see
    :func:`_latlong_row_weights`: ``which``)."""
    which = _latlong_row_weights(2, 4, l_max)[1]  # the same for every grid
    return tuple(np.flatnonzero(which == k) for k in range(2 * l_max + 1))


@lru_cache(maxsize=8)
def _latlong_row_weights(h: int, w: int, l_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Per coefficient (frame P), its weight for each row — the row's solid angle times Y_lm at the row's φ = 0
    point (= √2 N_lm P_l^m(cos θ) for m > 0) — and which row sum it weights: order 0, cos mφ for +m, sin mφ for −m."""
    theta = np.pi * (np.arange(h) + 0.5) / h
    ring = np.stack([np.sin(theta), np.zeros(h), np.cos(theta)], axis=-1)  # φ = 0 point of each row, frame P
    legendre = basis(l_max, ring)  # at φ = 0: Y_l,+m = √2 N P cos 0, Y_l,−m = 0
    omega = LatLong().row_solid_angles((h, w))  # every pixel of a row has the same solid angle
    weights, which = np.zeros((n_coeffs(l_max), h)), np.zeros(n_coeffs(l_max), dtype=np.int64)
    for l in range(l_max + 1):
        for m in range(-l, l + 1):
            weights[index(l, m)] = omega * legendre[:, index(l, abs(m))]
            which[index(l, m)] = 0 if m == 0 else 2 * m - 1 if m > 0 else 2 * -m
    weights.setflags(write=False)
    return weights, which


def _recurrence_tables(l_max: int):
    """Constants of the normalised Legendre recurrences used by :func:`basis`, for the compiled kernel."""
    a = np.zeros((l_max + 1, l_max + 1))
    b = np.zeros((l_max + 1, l_max + 1))
    for m in range(l_max + 1):
        for l in range(m + 2, l_max + 1):
            a[l, m] = sqrt((4 * l * l - 1) / (l * l - m * m))
            b[l, m] = sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
    pmm = np.array([1 / sqrt(4 * pi)] + [sqrt((2 * m + 1) / (2 * m)) for m in range(1, l_max + 1)])
    return a, b, pmm


@njit(cache=True, parallel=True, fastmath=False)
def _project_points(d, radiance, omega, l_max, a, b, pmm_step, blocks, out):  # pragma: no cover - compiled
    """out[k] = Σ over block k of Y(d_p) L_p Δω_p — the same recurrences as :func:`basis`, per pixel; pixels
    with no solid angle or no light are skipped."""
    n_points = d.shape[0]
    n = (l_max + 1) * (l_max + 1)
    size = (n_points + blocks - 1) // blocks
    for k in prange(blocks):
        y = np.empty(n)
        acc = np.zeros((n, 3))
        for p in range(k * size, min(n_points, (k + 1) * size)):
            w0 = radiance[p, 0] * omega[p]
            w1 = radiance[p, 1] * omega[p]
            w2 = radiance[p, 2] * omega[p]
            if w0 == 0.0 and w1 == 0.0 and w2 == 0.0:
                continue
            _basis_at(d[p, 0], d[p, 1], d[p, 2], a, b, pmm_step, y)
            for i in range(n):
                acc[i, 0] += y[i] * w0
                acc[i, 1] += y[i] * w1
                acc[i, 2] += y[i] * w2
        out[k] = acc


def _project_generic(env: EnvMap, l_max: int) -> np.ndarray:
    blocks = 64
    out = np.empty((blocks, n_coeffs(l_max), 3))
    _project_points(env.directions().reshape(-1, 3), env.data.reshape(-1, 3), env.solid_angles().reshape(-1),
                    l_max, *_recurrence_tables(l_max), blocks, out)
    return out.sum(axis=0)


def project(env: EnvMap, l_max: int = 2, frame: str | Frame = WORLD, fast: bool = True,
            compiled: bool | None = None) -> SHCoeffs:
    """Radiance SH coefficients L_lm = Σ_pixels L(d_p) Y_lm(d_p) Δω_p (exact per-pixel solid angles), in ``frame``.

    Lat-long maps are separable: per-row azimuthal sums, then per-row Legendre weights (one pass over the pixels,
    O(S·l_max) work). The row sums come from compiled kernels (above order 2 they need W divisible by 4) or, with
    ``compiled`` False, from numpy matrix products; ``compiled`` None takes the kernels when numba is already
    loaded or the map is big enough to repay loading it (:func:`lightprobe.util.jit.worth_compiling`). Every other
    map evaluates the basis at its pixel directions. All compute the same sum (to float64 rounding).

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance in any layout (directions in the world frame).
    l_max : int, default 2
        The highest band, a whole number ≥ 0 (2: the paper's nine coefficients).
    frame : str or Frame, default WORLD
        The frame to state the coefficients in: a name of :data:`lightprobe.maps.frames.FRAMES` or a
        :class:`~lightprobe.maps.frames.Frame`.
    fast : bool, default True
        Take the separable lat-long path for a lat-long map (when its kernels can: always with ``compiled`` False
        or l_max ≤ 2, else when W is divisible by 4); False always evaluates the basis per pixel.
    compiled : bool, optional
        For the lat-long row sums: True or False forces the compiled kernels or numpy's matrix products; None
        (default) decides by the work, as above. The per-pixel path always runs a compiled kernel.

    Returns
    -------
    SHCoeffs
        Radiance coefficients L_lm ((l_max+1)², 3) in ``frame``, no window.

    Raises
    ------
    UsageError
        ``l_max`` is not a whole number ≥ 0, or ``frame`` is not a known frame name.
    """
    if not isinstance(l_max, (int, np.integer)) or l_max < 0:
        raise UsageError(f"the SH order l_max must be a whole number ≥ 0, got {l_max!r}")
    if compiled is None:
        compiled = worth_compiling(math.prod(env.grid) * (1 + l_max))
    if fast and isinstance(env.layout, LatLong) and (not compiled or l_max <= 2 or env.grid[1] % 4 == 0):
        coeffs = _project_latlong(env, l_max, compiled)
    else:
        coeffs = _project_generic(env, l_max)
    return SHCoeffs(coeffs).to_frame(frame)


def delta_light(direction, power_rgb, l_max: int = 2) -> SHCoeffs:
    """Radiance coefficients of a distant point light: L_lm = Φ Y_lm(s) (world frame), for analytic checks.

    Parameters
    ----------
    direction : array_like
        (3,) the direction s the light comes from, world frame (+Y up, front −Z); any non-zero length (it is
        normalised).
    power_rgb : array_like
        (3,) the light's RGB power Φ (radiance × sr, ∫L dω).
    l_max : int, default 2
        The highest band, ≥ 0.

    Returns
    -------
    SHCoeffs
        Radiance coefficients ((l_max+1)², 3) in the world frame, no window.
    """
    s = np.asarray(direction, dtype=np.float64)
    s = s / np.linalg.norm(s)
    return SHCoeffs(basis(l_max, s)[:, None] * np.asarray(power_rgb, dtype=np.float64)[None, :])
