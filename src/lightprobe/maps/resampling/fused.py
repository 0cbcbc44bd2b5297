"""The resampler's compiled kernel: every target pixel's k×k footprint lookups in one pass, no whole-grid temporaries.

:func:`resample_into` does what the numpy formulation in :mod:`lightprobe.maps.resampling.reference` describes — per target
pixel, k×k stratified subsamples, each weighted by the target's ``dω/(du dv)`` and looked up in the source with a
cubic B-spline, the weighted mean stored — but it computes each subsample's direction, weight and source
coordinates in registers instead of as float64 grids, so its memory is the output alone and its time is linear in
the target's pixels. The per-layout formulas below are the same as :mod:`lightprobe.maps.layouts`' forward/inverse pairs,
written for one direction at a time (``tests/test_resample.py`` checks them against those pairs and the whole kernel
against the numpy path, to float32 rounding).

Layout codes: 0 latlong, 1 cube (faces +X, −X, +Y, −Y, +Z, −Z, OpenGL), 2 angular, 3 sphere (camera axes ``axes``).
A latlong source is read unpadded (columns wrap; a row past a pole is the row at the other side of it, half a turn
round); other sources are read from their padded image (:meth:`lightprobe.maps.layouts.Layout.padded`).
"""

from __future__ import annotations

import math

import numpy as np

from ...util.jit import njit
from .pole_rows import FACTORS as POLE_FACTORS, TIER_HEIGHTS as POLE_TIER_HEIGHTS, TIER_REACH as POLE_REACH

# The kernels' floating-point licences, one set for all: fused multiply-adds, reciprocals, no signed zeros and
# reassociation, enough for sums and weights to vectorise. Not "nnan"/"ninf", with which LLVM may assume that no NaN or
# infinity ever occurs and fold away what depends on one. Helpers that must decide alike in every kernel (which row,
# which pixel a point falls in) take fastmath=False.
KERNEL_FASTMATH = {"contract", "arcp", "nsz", "reassoc"}

# COMPILED_APART: numba inlines an ``inline="always"`` helper by copying its IR, its own inlined callees included,
# into every call site, so a helper that reaches the layouts' formulas (target_direction, source_position: ~170
# lines with their atan2s) costs their compile once per copy. Helpers run once per subsample or lookup stay inlined
# (compiled apart they cost a call each and lose the caller's fastmath: a cube → lat-long convert took 2.5× as long
# with none inlined); helpers run once per pixel, row or rim pixel — the rates' steps, the cube's edge terms and vertex
# distance, the rim's arcs and areas, the source rim's frame and pixel tests — are compiled once, apart, with their
# fastmath stated (a helper that sets none takes its first caller's, and numba's cache keeps whichever came first):
# False for those that decide which rate, ring or pixel (as their strict callers do), the kernels' for the rest.
# Their callers pass np.int64(…) where an argument could be a constant: numba compiles a callee once for each
# literal value it is called with.

LATLONG, CUBE, ANGULAR, SPHERE = 0, 1, 2, 3
CODES = {"latlong": LATLONG, "cube": CUBE, "angular": ANGULAR, "sphere": SPHERE}

# Cube faces as signed permutations: direction ∝ A·(s, t, 1); rows of A for +X, −X, +Y, −Y, +Z, −Z (layouts.CUBE_FACES)
FACE_MATRICES = np.array([
    [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],
    [[0, 0, -1], [0, -1, 0], [1, 0, 0]],
    [[1, 0, 0], [0, 0, 1], [0, 1, 0]],
    [[1, 0, 0], [0, 0, -1], [0, -1, 0]],
    [[1, 0, 0], [0, -1, 0], [0, 0, 1]],
    [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],
], dtype=np.float64)


_TAN_PI_12 = 2.0 - math.sqrt(3.0)  # tan(π/12)
_SQRT3 = math.sqrt(3.0)


@njit(cache=True, inline="always", error_model="numpy")
def _atan_series(t2):  # pragma: no cover - compiled
    """1 − t²/3 + t⁴/5 − … + t¹⁴/15 (Horner in t²), for t² ≤ tan²(π/12)."""
    p = -1.0 / 15.0
    p = p * t2 + 1.0 / 13.0
    p = p * t2 - 1.0 / 11.0
    p = p * t2 + 1.0 / 9.0
    p = p * t2 - 1.0 / 7.0
    p = p * t2 + 1.0 / 5.0
    p = p * t2 - 1.0 / 3.0
    return p * t2 + 1.0


@njit(cache=True, inline="always", error_model="numpy")
def atan2(y, x):  # pragma: no cover - compiled
    """math.atan2 for finite arguments to ~1e-11 rad (0 at the origin), one division instead of libm's cost (most
    of a lookup's): with t = min/max of |x|, |y| ≤ 1, past tan(π/12) atan(t) = π/6 + atan((√3t − 1)/(t + √3)) brings t
    within tan(π/12) = 0.268, where the odd Taylor series to t¹⁵ is exact to 0.268¹⁷/17 ≈ 1e-11 (3e-9 of a pixel
    of a 2048-wide map)."""
    ax, ay = abs(x), abs(y)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    swap = ay > ax
    lo, hi = (ax, ay) if swap else (ay, ax)
    if lo > _TAN_PI_12 * hi:
        t, shift = (_SQRT3 * lo - hi) / (lo + _SQRT3 * hi), math.pi / 6.0
    else:
        t, shift = lo / hi, 0.0
    a = shift + t * _atan_series(t * t)
    if swap:
        a = math.pi / 2.0 - a
    if x < 0.0:
        a = math.pi - a
    return math.copysign(a, y)


@njit(cache=True, inline="always", error_model="numpy")
def _sinc(r):  # pragma: no cover - compiled
    """sin(πr)/(πr), 1 at 0 (numpy's sinc)."""
    if r == 0.0:
        return 1.0
    return math.sin(math.pi * r) / (math.pi * r)


@njit(cache=True, inline="always", error_model="numpy")
def _rim_clamped(u, v):  # pragma: no cover - compiled
    """Disc coordinates (a right, b up), pulled onto the rim where they fall outside it (layouts._clamped_ab)."""
    a, b = 2.0 * u - 1.0, 1.0 - 2.0 * v
    r = math.hypot(a, b)
    if r > 1.0:
        return a / r, b / r
    return a, b


@njit(cache=True, inline="always", error_model="numpy")
def target_direction(kind, axes, face, u, v):  # pragma: no cover - compiled
    """(x, y, z, dω/(du dv)) at continuous target coordinates; the direction is not normalised for cube faces."""
    if kind == LATLONG:
        theta, phi = math.pi * v, 2.0 * math.pi * (u - 0.5)
        st = math.sin(theta)
        return st * math.sin(phi), math.cos(theta), -st * math.cos(phi), 2.0 * math.pi * math.pi * st
    if kind == CUBE:
        s, t = 2.0 * u - 1.0, 2.0 * v - 1.0
        m = FACE_MATRICES[face]
        x = m[0, 0] * s + m[0, 1] * t + m[0, 2]
        y = m[1, 0] * s + m[1, 1] * t + m[1, 2]
        z = m[2, 0] * s + m[2, 1] * t + m[2, 2]
        q = 1.0 + s * s + t * t
        return x, y, z, 4.0 / (q * math.sqrt(q))
    inside = math.hypot(2.0 * u - 1.0, 1.0 - 2.0 * v) <= 1.0
    a, b = _rim_clamped(u, v)
    if kind == ANGULAR:
        r = math.hypot(a, b)
        s = math.pi * _sinc(r)
        return a * s, b * s, -math.cos(math.pi * r), 4.0 * math.pi * math.pi * _sinc(r) if inside else 0.0
    z = math.sqrt(max(1.0 - a * a - b * b, 0.0))  # sphere: mirror-ball normal (a, b, z), reflected back-direction
    lx, ly, lz = 2.0 * a * z, 2.0 * b * z, 2.0 * z * z - 1.0
    return (axes[0, 0] * lx + axes[0, 1] * ly + axes[0, 2] * lz,
            axes[1, 0] * lx + axes[1, 1] * ly + axes[1, 2] * lz,
            axes[2, 0] * lx + axes[2, 1] * ly + axes[2, 2] * lz, 16.0 if inside else 0.0)


@njit(cache=True, inline="always", error_model="numpy")
def _on_face_plane(face, x, y, z, h, w):  # pragma: no cover - compiled
    """(depth along the face's axis, column, row) of direction (x, y, z) on cube face ``face``'s plane — past the
    face's edge too, for a direction off the face (meaningful while the depth is positive)."""
    m = FACE_MATRICES[face]
    ls = m[0, 0] * x + m[1, 0] * y + m[2, 0] * z  # Aᵀ d
    lt = m[0, 1] * x + m[1, 1] * y + m[2, 1] * z
    lz = m[0, 2] * x + m[1, 2] * y + m[2, 2] * z
    return lz, (ls / lz + 1.0) / 2.0 * w - 0.5, (lt / lz + 1.0) / 2.0 * h - 0.5


@njit(cache=True, inline="always", error_model="numpy")
def _turned(x, y, z, rotation):  # pragma: no cover - compiled
    """d @ R: the source direction a target direction shows (the target at d shows the source at Rᵀd)."""
    return (x * rotation[0, 0] + y * rotation[1, 0] + z * rotation[2, 0],
            x * rotation[0, 1] + y * rotation[1, 1] + z * rotation[2, 1],
            x * rotation[0, 2] + y * rotation[1, 2] + z * rotation[2, 2])


@njit(cache=True, inline="always", error_model="numpy")
def source_position(kind, axes, x, y, z, h, w):  # pragma: no cover - compiled
    """(face, column, row) continuous pixel coordinates (centre of column c is c) of direction (x, y, z), which
    need not be unit length. Total, like :meth:`lightprobe.maps.layouts.Layout.dir_to_uv`."""
    if kind == LATLONG:
        u = atan2(x, -z) / (2.0 * math.pi) + 0.5
        v = atan2(math.sqrt(x * x + z * z), y) / math.pi
        return 0, u * w - 0.5, v * h - 0.5
    if kind == CUBE:
        ax, ay, az = abs(x), abs(y), abs(z)
        if ax >= ay and ax >= az:  # first maximum in face order, as numpy's argmax picks it
            face = 0 if x >= 0.0 else 1
        elif ay >= az:
            face = 2 if y >= 0.0 else 3
        else:
            face = 4 if z >= 0.0 else 5
        if x == y == z == 0.0:
            face = 0
        _, px, py = _on_face_plane(face, x, y, z, h, w)
        return face, px, py
    norm = math.sqrt(x * x + y * y + z * z)
    x, y, z = x / norm, y / norm, z / norm
    if kind == ANGULAR:
        r = math.acos(min(max(-z, -1.0), 1.0)) / math.pi
        rho = math.hypot(x, y)
        if rho > 1e-150:
            a, b = x * r / rho, y * r / rho
        else:  # straight behind (+Z) is the whole rim: its right-hand point
            a, b = r, 0.0
        return 0, (a + 1.0) / 2.0 * w - 0.5, (1.0 - b) / 2.0 * h - 0.5
    lx = x * axes[0, 0] + y * axes[1, 0] + z * axes[2, 0]  # d · T: the camera's frame
    ly = x * axes[0, 1] + y * axes[1, 1] + z * axes[2, 1]
    lz = x * axes[0, 2] + y * axes[1, 2] + z * axes[2, 2] + 1.0
    n = math.sqrt(lx * lx + ly * ly + lz * lz)
    a, b = (1.0, 0.0) if n <= 1e-150 else (lx / n, ly / n)
    return 0, (a + 1.0) / 2.0 * w - 0.5, (1.0 - b) / 2.0 * h - 0.5


@njit(cache=True, inline="always", error_model="numpy")
def _bspline_weights(t, out):  # pragma: no cover - compiled
    """The uniform cubic B-spline's four tap weights (offsets −1..2) at fraction t ∈ [0, 1)."""
    t2 = t * t
    t3 = t2 * t
    r = 1.0 - t
    out[0] = r * r * r / 6.0
    out[1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0
    out[2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0
    out[3] = t3 / 6.0


@njit(cache=True, inline="always", error_model="numpy")
def _bspline4(t):  # pragma: no cover - compiled
    """The same four weights as scalars (they sum to 1: the third is what the others leave)."""
    r = 1.0 - t
    w0, w3 = r * r * r / 6.0, t * t * t / 6.0
    w1 = 0.5 * t * t * t - t * t + 2.0 / 3.0
    return w0, w1, 1.0 - w0 - w1 - w3, w3


@njit(cache=True, error_model="numpy")
def _reflected_row(row, h):  # pragma: no cover - compiled
    """A latlong row that may lie past a pole → (the row that holds it, whether it is half a turn round)."""
    if row < 0:  # past the north pole: row −1 − row, half a turn round
        return min(-1 - row, h - 1), True
    if row >= h:
        return max(2 * h - 1 - row, 0), True
    return row, False


@njit(cache=True, inline="always", error_model="numpy")
def _pole_tier(h):  # pragma: no cover - compiled
    """The tier of :data:`lightprobe.maps.resampling.pole_rows.TIERS` a latlong of h rows takes (−1: plain B-spline)."""
    for t in range(POLE_TIER_HEIGHTS.size):
        if h >= POLE_TIER_HEIGHTS[t]:
            return t
    return -1


@njit(cache=True, inline="always", error_model="numpy")
def _pole_factor(row, h, tier):  # pragma: no cover - compiled
    """The rational weight factor a_j of a latlong tap row (past a pole or not): j rows from its pole."""
    src, _ = _reflected_row(row, h)
    j = min(src, h - 1 - src)
    return POLE_FACTORS[tier, j] if j < POLE_REACH[tier] else 1.0


@njit(cache=True, inline="always", error_model="numpy")
def _pole_rows4(r0, h, b0, b1, b2, b3):  # pragma: no cover - compiled
    """The y weights of latlong tap rows r0 … r0 + 3, made rational where a row is near a pole (a_j B_j / Σ a_m
    B_m, :mod:`lightprobe.maps.resampling.pole_rows`: each row keeps its ∫ dω; the plain B-spline over-counts the first
    row by 25 %), unchanged elsewhere and in maps under pole_rows.MIN_HEIGHT rows."""
    tier = _pole_tier(h)
    if tier < 0:
        return b0, b1, b2, b3
    reach = POLE_REACH[tier]
    if r0 >= reach and r0 + 3 < h - reach:
        return b0, b1, b2, b3
    c0, c1 = b0 * _pole_factor(r0, h, tier), b1 * _pole_factor(r0 + 1, h, tier)
    c2, c3 = b2 * _pole_factor(r0 + 2, h, tier), b3 * _pole_factor(r0 + 3, h, tier)
    s = c0 + c1 + c2 + c3
    return c0 / s, c1 / s, c2 / s, c3 / s


@njit(cache=True, error_model="numpy")
def _lookup_latlong(src, levels, reduced, offsets, x, y, wx, wy, acc):  # pragma: no cover - compiled
    """B-spline lookup of an unpadded latlong image (1, H, W, 3) at pixel coordinates (x, y), added to ``acc``.

    Row r of level ``levels[r]`` = ℓ > 0 is read from its azimuthal box reduction (``reduced[offsets[r]:]``,
    W / 2^ℓ pixels of 2^ℓ columns each; see :func:`lightprobe.maps.resampling.polar.reduced_rows`), at its own column
    coordinate (x + ½) / 2^ℓ − ½: each row is interpolated on its own grid, with the rows' weights in y as ever."""
    h, w = src.shape[1], src.shape[2]
    fy = math.floor(y)
    _bspline_weights(y - fy, wy)
    r0 = int(fy) - 1
    wy[0], wy[1], wy[2], wy[3] = _pole_rows4(r0, h, wy[0], wy[1], wy[2], wy[3])
    for dy in range(4):
        row, level, width, shift = _row_frame(levels, h, w, r0 + dy)
        xr = _in_frame(x, level, width, w, shift)
        fx = math.floor(xr)
        _bspline_weights(xr - fx, wx)
        c0 = int(fx) - 1
        r, g, b = 0.0, 0.0, 0.0
        for dx in range(4):
            col = _wrapped_column(c0 + dx, width)
            if level == 0:
                r += wx[dx] * src[0, row, col, 0]
                g += wx[dx] * src[0, row, col, 1]
                b += wx[dx] * src[0, row, col, 2]
            else:
                i = offsets[row] + col
                r += wx[dx] * reduced[i, 0]
                g += wx[dx] * reduced[i, 1]
                b += wx[dx] * reduced[i, 2]
        acc[0] += wy[dy] * r
        acc[1] += wy[dy] * g
        acc[2] += wy[dy] * b


@njit(cache=True, error_model="numpy")
def _lookup_padded(img, valid, face, x, y, wx, wy, acc):  # pragma: no cover - compiled
    """B-spline lookup of a padded image (kernels.gather_bspline for one point): taps of zero validity carry no
    weight and the rest are renormalised; the result (RGB) is added to ``acc``. A ``valid`` of shape (1, 1, 1)
    means every tap is valid (a cube's padding), without a table the size of the image."""
    hp, wp = img.shape[1], img.shape[2]
    x, y = x + 2.0, y + 2.0  # padded coordinates (PAD = 2)
    fx, fy = math.floor(x), math.floor(y)
    _bspline_weights(x - fx, wx)
    _bspline_weights(y - fy, wy)
    x0 = min(max(int(fx) - 1, 0), wp - 4)
    y0 = min(max(int(fy) - 1, 0), hp - 4)
    wsum, r, g, b = 0.0, 0.0, 0.0, 0.0
    for dy in range(4):
        for dx in range(4):
            k = wy[dy] * wx[dx] * (1.0 if valid.shape[1] == 1 else valid[face, y0 + dy, x0 + dx])
            if k > 0.0:
                wsum += k
                r += k * img[face, y0 + dy, x0 + dx, 0]
                g += k * img[face, y0 + dy, x0 + dx, 1]
                b += k * img[face, y0 + dy, x0 + dx, 2]
    if wsum > 0.0:
        acc[0] += r / wsum
        acc[1] += g / wsum
        acc[2] += b / wsum


TILE = 10  # footprint tiles up to TILE × TILE source taps; larger footprints (near the poles) are looked up directly


@njit(cache=True, inline="always", error_model="numpy")
def _source_row_col(row, col, h, w):  # pragma: no cover - compiled
    """A latlong tap (row, col) that may lie past a pole or the seam → the pixel that holds it."""
    if row < 0:  # past the north pole: row −1 − row, half a turn round
        row, col = -1 - row, col + w // 2
    elif row >= h:
        row, col = 2 * h - 1 - row, col + w // 2
    col = col % w
    return min(max(row, 0), h - 1), col


@njit(cache=True, inline="always", error_model="numpy")
def _tile_bounds(pxs, pys, n, pad):  # pragma: no cover - compiled
    """(first column, first row, width, height) of the taps of n subsamples, in an image padded by ``pad``."""
    x0, y0 = math.floor(pxs[0]), math.floor(pys[0])
    x1, y1 = x0, y0
    for s in range(1, n):
        x0, x1 = min(x0, math.floor(pxs[s])), max(x1, math.floor(pxs[s]))
        y0, y1 = min(y0, math.floor(pys[s])), max(y1, math.floor(pys[s]))
    return int(x0) - 1 + pad, int(y0) - 1 + pad, int(x1 - x0) + 4, int(y1 - y0) + 4


@njit(cache=True, inline="always", error_model="numpy")
def _sum_into_tile(tile, pxs, pys, pws, n, scale, c0, r0, tw, th, pad):  # pragma: no cover - compiled
    """tile[:th, :tw] = Σ_s scale·pws[s] · (subsample s's 4×4 B-spline taps), the tile's corner at (c0, r0)."""
    for ty in range(th):
        for tx in range(tw):
            tile[ty, tx] = 0.0
    for s in range(n):  # the weights as scalars, not arrays: this loop is half the kernel's time
        fx, fy = math.floor(pxs[s]), math.floor(pys[s])
        ox, oy = int(fx) - 1 + pad - c0, int(fy) - 1 + pad - r0
        a0, a1, a2, a3 = _bspline4(pxs[s] - fx)
        b0, b1, b2, b3 = _bspline4(pys[s] - fy)
        p = scale * pws[s]
        for dy in range(4):
            wrow = p * (b0 if dy == 0 else b1 if dy == 1 else b2 if dy == 2 else b3)
            tile[oy + dy, ox] += wrow * a0
            tile[oy + dy, ox + 1] += wrow * a1
            tile[oy + dy, ox + 2] += wrow * a2
            tile[oy + dy, ox + 3] += wrow * a3


@njit(cache=True, inline="always", error_model="numpy")
def _in_frame(x, level, width, w, shift):  # pragma: no cover - compiled
    """Source column coordinate x (column c's centre at c) in a row's frame: its reduction level, to ``width``
    columns of the source's ``w`` (a frame column is w / width source columns: 2^ℓ, the same bits as before
    where that is whole, or not, :func:`lightprobe.maps.resampling.polar.reduced_width`), and half-turn shift."""
    if level == 0:
        return x + shift
    return (x + 0.5) * (width / w) - 0.5 + shift


@njit(cache=True, inline="always", error_model="numpy")
def _reduced_width(w, level):  # pragma: no cover - compiled
    """:func:`lightprobe.maps.resampling.polar.reduced_width`, compiled: W / 2^ℓ, rounded where it is not whole."""
    return (w + ((1 << level) >> 1)) >> level


@njit(cache=True, inline="always", error_model="numpy")
def _row_frame(levels, h, w, row):  # pragma: no cover - compiled
    """Tile row ``row`` of a latlong (past a pole or not) → (source row, its level, its width, column shift: half
    its width when the row is reached across the pole — a half column where the width is odd)."""
    src_row, turned = _reflected_row(row, h)
    level = levels[src_row]
    width = _reduced_width(w, level)
    return src_row, level, width, 0.5 * width if turned else 0.0


@njit(cache=True, error_model="numpy")
def _row_tile(levels, h, w, pxs, pys, pws, n, scale, r0, th, tile, c0s, tws, taps):  # pragma: no cover - compiled
    """:func:`_sum_into_tile` for latlong tiles whose rows may each have their own column frame — a reduction
    level (its columns are 2^ℓ source columns) or a half-turn shift (a row reached across the pole): tile row ty
    holds its row's taps from column c0s[ty] of that row's frame, tws[ty] of them. ``taps`` (n, 4, 2) is scratch:
    each subsample's first column and fraction in each of its four rows' frames. False if a row's taps span over
    TILE columns."""
    for ty in range(th):
        c0s[ty], tws[ty] = 1 << 62, -(1 << 62)  # lowest and highest first column, until the end
    for s in range(n):
        fy = int(math.floor(pys[s]))
        last_level, last_shift, q = -1, -1.0, 0.0
        for dy in range(4):
            ty = fy - 1 + dy - r0
            _, level, width, shift = _row_frame(levels, h, w, fy - 1 + dy)
            if level != last_level or shift != last_shift:  # most rows share their neighbour's frame
                q = _in_frame(pxs[s], level, width, w, shift)
                last_level, last_shift = level, shift
            fx = math.floor(q)
            taps[s, dy, 0], taps[s, dy, 1] = fx, q - fx
            c0s[ty], tws[ty] = min(c0s[ty], int(fx)), max(tws[ty], int(fx))
    for ty in range(th):
        if tws[ty] < c0s[ty]:  # a row no subsample reaches (cannot happen: each row is some subsample's)
            c0s[ty], tws[ty] = 0, 0
            continue
        width = tws[ty] - c0s[ty] + 4
        if width > TILE:
            return False
        c0s[ty], tws[ty] = c0s[ty] - 1, width
        for tx in range(width):
            tile[ty, tx] = 0.0
    for s in range(n):
        fy = math.floor(pys[s])
        b0, b1, b2, b3 = _bspline4(pys[s] - fy)
        b0, b1, b2, b3 = _pole_rows4(int(fy) - 1, h, b0, b1, b2, b3)
        p = scale * pws[s]
        for dy in range(4):
            ty = int(fy) - 1 + dy - r0
            a0, a1, a2, a3 = _bspline4(taps[s, dy, 1])
            ox = int(taps[s, dy, 0]) - 1 - c0s[ty]
            wrow = p * (b0 if dy == 0 else b1 if dy == 1 else b2 if dy == 2 else b3)
            tile[ty, ox] += wrow * a0
            tile[ty, ox + 1] += wrow * a1
            tile[ty, ox + 2] += wrow * a2
            tile[ty, ox + 3] += wrow * a3
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _wrapped_column(col, width):  # pragma: no cover - compiled
    """A column at most one turn out of [0, width) brought into it (an integer modulo costs more)."""
    if col < 0:
        col += width
    elif col >= width:
        col -= width
    return min(max(col, 0), width - 1)


@njit(cache=True, error_model="numpy")
def _polar_scratch(k):  # pragma: no cover - compiled
    """Scratch arrays for :func:`_row_tile`: each tile row's first column and width, each subsample's taps."""
    return np.empty(TILE, np.int64), np.empty(TILE, np.int64), np.empty((slots(k), 4, 2))


@njit(cache=True, error_model="numpy")
def _polar_tile(levels, h, w, pxs, pys, pws, n, scale, scratch, tile):  # pragma: no cover - compiled
    """The tile of a latlong footprint near the poles, row by row in each row's frame (:func:`_row_tile`):
    (first row, rows), rows 0 if it outgrows TILE. Each tile row's first column and width are left in
    ``scratch``."""
    fy0, fy1 = math.floor(pys[0]), math.floor(pys[0])
    for s in range(1, n):
        fy0, fy1 = min(fy0, math.floor(pys[s])), max(fy1, math.floor(pys[s]))
    r0, th = int(fy0) - 1, int(fy1 - fy0) + 4
    c0s, tws, taps = scratch
    if th > TILE or not _row_tile(levels, h, w, pxs, pys, pws, n, scale, r0, th, tile, c0s, tws, taps):
        return r0, 0
    return r0, th


@njit(cache=True, error_model="numpy")  # compiled apart: the kernels compile in half the time
def _polar_footprint(src, levels, reduced, row_offsets, pxs, pys, pws, n, scratch, tile, acc):  # pragma: no cover
    """:func:`_footprint` for a latlong footprint that reaches the reduced polar rows (or past a pole): one tile
    of per-row frames (:func:`_row_tile`), read from each row's own pixels."""
    h, w = src.shape[1], src.shape[2]
    r0, th = _polar_tile(levels, h, w, pxs, pys, pws, n, 1.0, scratch, tile)
    if th == 0:
        return False
    c0s, tws = scratch[0], scratch[1]
    r, g, b = 0.0, 0.0, 0.0
    for ty in range(th):
        row, level, width, _ = _row_frame(levels, h, w, r0 + ty)
        for tx in range(tws[ty]):
            k = tile[ty, tx]
            col = _wrapped_column(c0s[ty] + tx, width)
            if level == 0:
                r += k * src[0, row, col, 0]
                g += k * src[0, row, col, 1]
                b += k * src[0, row, col, 2]
            else:
                i = row_offsets[row] + col
                r += k * reduced[i, 0]
                g += k * reduced[i, 1]
                b += k * reduced[i, 2]
    acc[0] += r
    acc[1] += g
    acc[2] += b
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _footprint(src, face, padded, levels, reduced, row_offsets, caps, pxs, pys, pws, n, scratch, tile,
               acc):  # pragma: no cover - compiled
    """Σ_s pws[s] · (B-spline lookup at (pxs[s], pys[s])) for one target pixel's n subsamples on source face
    ``face``, added to ``acc``. ``src`` is an unpadded latlong image (``padded`` False: taps past a pole or the seam
    are found by :func:`_source_row_col`) or a padded image whose validity is 1 everywhere (a cube's).

    The subsamples' 4×4 taps overlap: their weights are first summed into one tile of source taps, which is then
    read once (a k = 3 footprint reads ~25 taps instead of 144). Returns False, touching nothing, when the taps
    span more than TILE × TILE (near a latlong's seam) or leave the padded image, for the caller to look up
    directly. Footprints reaching a latlong's reduced polar rows (``caps``: how many rows at the north and south
    ends have a reduction) are summed in each row's own frame (:func:`_polar_footprint`), where a row's taps are
    counted in its reduced columns: a footprint wider than TILE source columns near a pole fits there."""
    pad = 2 if padded else 0
    c0, r0, tw, th = _tile_bounds(pxs, pys, n, pad)
    if th > TILE:
        return False
    h, w = src.shape[1], src.shape[2]
    if not padded and (r0 < caps[0] or r0 + th > h - caps[1]):  # before the width test: its rows are narrower
        return _polar_footprint(src, levels, reduced, row_offsets, pxs, pys, pws, n, scratch, tile, acc)
    if tw > TILE:
        return False
    inside = r0 >= 0 and r0 + th <= h and c0 >= 0 and c0 + tw <= w
    if padded and not inside:
        return False
    _sum_into_tile(tile, pxs, pys, pws, n, 1.0, c0, r0, tw, th, pad)
    r, g, b = 0.0, 0.0, 0.0
    if inside:
        for ty in range(th):
            for tx in range(tw):
                k = tile[ty, tx]
                r += k * src[face, r0 + ty, c0 + tx, 0]
                g += k * src[face, r0 + ty, c0 + tx, 1]
                b += k * src[face, r0 + ty, c0 + tx, 2]
    else:
        for ty in range(th):
            for tx in range(tw):
                row, col = _source_row_col(r0 + ty, c0 + tx, h, w)
                k = tile[ty, tx]
                r += k * src[0, row, col, 0]
                g += k * src[0, row, col, 1]
                b += k * src[0, row, col, 2]
    acc[0] += r
    acc[1] += g
    acc[2] += b
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _same_face(pfs, n):  # pragma: no cover - compiled
    for s in range(1, n):
        if pfs[s] != pfs[0]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def _lookup(src_kind, src, valid, levels, reduced, row_offsets, face, px, py, wx, wy,
            acc):  # pragma: no cover - compiled
    if src_kind == LATLONG:
        _lookup_latlong(src, levels, reduced, row_offsets, px, py, wx, wy, acc)
    else:
        _lookup_padded(src, valid, face, px, py, wx, wy, acc)


# A lat-long target's rows next to a pole are rings: there the midpoint rule in θ over-counts the pole by the
# Euler–Maclaurin end term, 1/(12 kv²) of the row — a sun at the pole came out +0.9–1.4 % from cube, angular and
# mirror-ball sources at kv = k. A pole row takes k_max subsample rows, and each row away POLE_RAMP fewer down to its
# own rate: a gentle ramp, as a sudden change of spacing between two rows costs the same end term at their seam.
# The pole rows' cells now vanish at the pole (POLE), which takes that term away whatever kv is; the ramp was kept
# (not measured without it since).
POLE_RAMP = 2
ADAPTIVE_SPACING = 0.5  # source pixels between neighbouring lookups, at most, where the rate adapts (polar.MAX_SPACING)
# From a lat-long into an angular map the midpoint rule at 0.5 left a ring of moiré (the two grids beating, ~40° from
# the map's centre) where a one-pixel sun came out up to 0.28 % off, at every size (lat-long 128 → angular 32 to
# 2048 → 1024); lookups 0.4 source pixels apart hold it to 0.12 %, for 1.1–1.25× the conversion's time (lat-long
# 2048 → angular 256–1024).
LATLONG_ANGULAR_SPACING = 0.4
# An angular map's plain pixels just inside the ring the rim crosses lie 1–3 source pixels from its rim direction,
# where the solid angle per image area (∝ sin ρ) changes by its own size across a pixel: the midpoint rule's error
# goes as spacing²/ρ there, and at 0.4 a one-pixel sun by the rim direction came out 0.26 % over (lat-long 4096×2048
# → angular 3268, the default size, which is not flux-corrected; 0.43 % for 512×256 → 600 before its correction) —
# a ring of pixels over-weighting the sun's near side. Lookups there at most ANGULAR_RIM_SPACING·√ρ apart (ρ in
# source pixels, up to k_max a side: _by_angular_rim): 0.12 % (0.06 %), for a few rings' more lookups (+3–7 % of
# the 4k conversion's time). Where a target pixel spans two source pixels the rim direction's sun goes from 0.10 to
# 0.12 % (lat-long 512×256 → angular 128): the rows of the pixels the rim crosses, no longer offset by their
# neighbours' error.
ANGULAR_RIM_SPACING = 0.075
# From a lat-long into a mirror ball, the rings where the rate steps mid-ball (60–90° from its rim direction) held a
# one-pixel sun to 0.30–0.33 % at 0.5 (lat-long 512 → 817, 2048 → 3268: the balls' default sizes); at 0.35, 0.12 %.
# Flux-corrected below LATLONG_FLUX_MAX_PIXELS, this is what a larger lat-long keeps.
LATLONG_SPHERE_SPACING = 0.35


@njit(cache=True, inline="always", error_model="numpy")
def _pair_spacing(src_kind, tgt_kind):  # pragma: no cover - compiled
    """Source pixels between neighbouring lookups, at most, where the rate adapts, for this pair of layouts."""
    if src_kind == LATLONG and tgt_kind == ANGULAR:
        return LATLONG_ANGULAR_SPACING
    if src_kind == LATLONG and tgt_kind == SPHERE:
        return LATLONG_SPHERE_SPACING
    return ADAPTIVE_SPACING


@njit(cache=True, inline="always", error_model="numpy")
def _source_point(tgt_kind, tgt_axes, face, u, v, rotation, src_kind, src_axes, src_h,
                  src_w):  # pragma: no cover - compiled
    """(source face, column, row, and the turned direction rx, ry, rz) that target point (u, v) of ``face`` shows."""
    x, y, z, _ = target_direction(tgt_kind, tgt_axes, face, u, v)
    rx, ry, rz = _turned(x, y, z, rotation)
    f, px, py = source_position(src_kind, src_axes, rx, ry, rz, src_h, src_w)
    return f, px, py, rx, ry, rz


@njit(cache=True, inline="always", error_model="numpy")
def _on_disc(u, v):  # pragma: no cover - compiled
    """Whether point (u, v) of a disc layout's image lies on its disc (as :func:`target_direction` decides)."""
    return math.hypot(2.0 * u - 1.0, 1.0 - 2.0 * v) <= 1.0


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _source_step(tgt_kind, tgt_axes, face, u0, v0, u1, v1, rotation, src_kind, src_axes, src_h,
                 src_w):  # pragma: no cover - compiled
    """How far apart, in source pixels, the source positions of target points (u0, v0) and (u1, v1) land. On a
    cube the second is placed on the first one's face plane, extended past its edge if need be (a step across an
    edge is still a step). A lat-long's columns count at their width, sin θ of a column: nearer a pole the polar
    reductions (:mod:`lightprobe.maps.resampling.polar`) serve, not more lookups. No step (0) when either point lies off a
    disc target: both would show its rim direction, rim-clamped, and a disc source places that direction anywhere
    on its own rim as rounding falls — a mirror ball into a mirror ball gave such points steps of 0 to 30 pixels,
    whose rates then graded their valid neighbours' cells (:func:`_pixel_rates`) differently from kernel to kernel,
    and the cached taps and the direct pass differed by up to 10 % on rim pixels."""
    if tgt_kind != LATLONG and tgt_kind != CUBE and not (_on_disc(u0, v0) and _on_disc(u1, v1)):
        return 0.0
    f0, x0, y0, _, _, _ = _source_point(tgt_kind, tgt_axes, face, u0, v0, rotation, src_kind, src_axes, src_h, src_w)
    f1, x1, y1, rx, ry, rz = _source_point(tgt_kind, tgt_axes, face, u1, v1, rotation, src_kind, src_axes, src_h,
                                           src_w)
    if f0 != f1:
        depth, x1, y1 = _on_face_plane(f0, rx, ry, rz, src_h, src_w)
        if depth <= 0.0:
            return 0.0
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    if src_kind == LATLONG:
        dx = min(dx, src_w - dx) * math.sin(math.pi * min(max((y0 + y1 + 1.0) / (2.0 * src_h), 0.0), 1.0))
    return math.hypot(dx, dy)


# A cube's texel at a vertex is read through the padding of all three faces there, the 2 × 2 block beyond a face's
# corner standing in for a fourth quadrant that does not exist: its weight jumps between faces, and the midpoint rule
# over a jump is off by the order of its spacing — a sun in a corner texel came out 2.7 % off into a lat-long at
# k = 4 (cube 256 → lat-long 512), 0.5 % at 8, 0.3 % at 16. Target pixels whose footprint reaches within
# CUBE_VERTEX_REACH texels of a vertex (the B-spline's two, and half a texel) take k_max, and the rate falls from
# there by CUBE_VERTEX_RAMP each target pixel further away: eight small spots.
CUBE_VERTEX_REACH = 2.5
CUBE_VERTEX_RAMP = 1.25


@njit(cache=True, inline="always", error_model="numpy")
def _aligned_cubes(tgt_kind, rotation):  # pragma: no cover - compiled
    """Whether the target is a cube unturned from the source cube: each source face's edges then lie between
    target pixels, the jump at a vertex with them, and a raised rate there only adds a seam (cube 256 → cube 256:
    0.21 % without, 0.36 % with)."""
    return tgt_kind == CUBE and rotation[0, 0] == 1.0 and rotation[1, 1] == 1.0 and rotation[2, 2] == 1.0


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)  # apart: see COMPILED_APART
def _from_cube_vertex(tgt_kind, tgt_axes, face, u, v, rotation, src_axes, src_h, src_w):  # pragma: no cover
    """How far, in texels, target point (u, v) lands from the nearest vertex of its cube source face (the larger
    of its distances to the two nearest edges)."""
    _, px, py, _, _, _ = _source_point(tgt_kind, tgt_axes, face, u, v, rotation, CUBE, src_axes, src_h, src_w)
    return max(min(px + 0.5, src_w - 0.5 - px), min(py + 0.5, src_h - 0.5 - py))


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)  # apart: see COMPILED_APART
def _rates(tgt_kind, tgt_axes, face, row, col, h, w, k, k_max, rotation, src_kind, src_axes, src_h,
           src_w):  # pragma: no cover - compiled
    """(ku, kv): one target pixel's subsamples across and down — k each, raised up to ``k_max`` until neighbouring
    lookups land at most :data:`ADAPTIVE_SPACING` source pixels apart (:func:`_pair_spacing`). The steps are
    measured over the pixel's middle half (it stays inside its face and its disc). Where a disc's rim stretches one
    direction over a ring, a pixel's footprint in the other layout is many pixels long one way, and a cube's corner
    texels are a fifth of its centre's: with one rate for the whole map, a sun in such a pixel was hit or missed —
    ±15 % from an angular map into a lat-long, 74 % from a mirror ball into an angular map (pixels 90–155° from the
    camera's axis), 7 % from a cube's corner texel into a lat-long (``Resampler.energy_gains``, every pixel). Where
    the rate changes between neighbouring pixels, :func:`_graded` warps the cells so the spacing does not jump. A
    lat-long target's rows ramp up to k_max at its poles (:data:`POLE_RAMP`), and the pixels round a cube source's
    vertices up to k_max (:data:`CUBE_VERTEX_REACH`)."""
    uc, vc = (col + 0.5) / w, (row + 0.5) / h
    across = 2.0 * _source_step(tgt_kind, tgt_axes, face, (col + 0.25) / w, vc, (col + 0.75) / w, vc, rotation,
                                src_kind, src_axes, src_h, src_w)
    down = 2.0 * _source_step(tgt_kind, tgt_axes, face, uc, (row + 0.25) / h, uc, (row + 0.75) / h, rotation,
                              src_kind, src_axes, src_h, src_w)
    spacing = _pair_spacing(src_kind, tgt_kind)
    need = max(across, down) / spacing
    short = need > SOURCE_RIM_SHORT * k_max  # the cells fall far short of the spacing (see SOURCE_RIM_MARK)
    ku = max(k, int(math.ceil(across / spacing - 1e-9)))
    kv = max(k, int(math.ceil(down / spacing - 1e-9)))
    if tgt_kind != SPHERE:
        ku, kv = min(ku, k_max), min(kv, k_max)
    if src_kind == CUBE and not _aligned_cubes(tgt_kind, rotation):
        away = _from_cube_vertex(tgt_kind, tgt_axes, face, uc, vc, rotation, src_axes, src_h, src_w)
        pixels = max(0.0, away - CUBE_VERTEX_REACH - 0.5 * max(across, down)) / max(across, down, 1e-9)
        near = int(math.ceil(k_max * CUBE_VERTEX_RAMP ** -pixels - 1e-9))
        ku, kv = max(ku, near), max(kv, near)
    if tgt_kind == LATLONG:
        from_pole = min(row, h - 1 - row)
        kv = max(kv, k_max - POLE_RAMP * from_pole)
    if tgt_kind == ANGULAR:
        ku, kv = _by_angular_rim(row, col, h, w, across, down, spacing, ku, kv, k_max)
    ku, kv = _within_budget(ku, kv, k_max)
    return ku, kv, short


@njit(cache=True, inline="always", error_model="numpy")
def _by_angular_rim(row, col, h, w, across, down, spacing, ku, kv, k_max):  # pragma: no cover - compiled
    """(ku, kv) of an angular map's pixel, raised near its rim direction: lookups at most
    :data:`ANGULAR_RIM_SPACING` · √ρ source pixels apart, up to ``k_max``, ρ the pixel's least distance from the
    rim direction in source pixels (its radial span, 2π/h radians, is about max(``across``, ``down``) of them). The
    pixels the rim crosses (ρ from 0) are sampled round the rim direction instead (:func:`_rim_subsamples`)."""
    rho_lo, rho_hi = _rim_span(ANGULAR, row, col, h, w)
    if not 0.0 < rho_lo < rho_hi:
        return ku, kv
    most = ANGULAR_RIM_SPACING * math.sqrt(rho_lo * max(across, down) * h / (2.0 * math.pi))
    if most >= spacing:
        return ku, kv
    ku = min(k_max, max(ku, int(math.ceil(across / most - 1e-9))))
    kv = min(k_max, max(kv, int(math.ceil(down / most - 1e-9))))
    return ku, kv


@njit(cache=True, inline="always", error_model="numpy")
def _within_budget(ku, kv, k_max):  # pragma: no cover - compiled
    """(ku, kv) held to the scratch's k_max² subsamples: a side may take more than k_max where the other needs
    fewer (a mirror ball's ring pixels are long one way and a sliver the other: from a 4k lat-long, ball 1024's
    pixels 10–25° from its rim direction span 11–22 rows radially, where 32 lookups left a one-pixel sun 0.25 %
    off); where both want more, each is cut to k_max and the other given what is left. Mirror-ball targets only
    (:func:`_rates`), where it was measured to be needed; elsewhere each side keeps to k_max."""
    budget = k_max * k_max
    if ku * kv <= budget:
        return ku, kv
    if ku >= kv:
        kv = min(kv, k_max)
        return min(ku, budget // kv), kv
    ku = min(ku, k_max)
    return ku, min(kv, budget // ku)


# A lat-long target's pole rows meet at the pole, where dω = sin θ dθ dφ: along θ a row's integrand g = B sin θ starts
# at 0 with slope B(pole), and the midpoint rule over it is off by the Euler–Maclaurin end term h²/24 · B(pole) per
# unit of φ — a one-pixel sun on a turned lat-long's pole came out +0.48 % (lat-long 805 rows → 246, k_max = 16),
# 1/k² in the rate. With the cells warped so their width vanishes at the pole (φ(t) = 2t² − t³ from that end),
# the sum is the midpoint rule of G(t) = g(φ(t)) φ'(t), whose slope at the pole is 0: the end term goes, the next is
# O(h⁴). In _graded's neighbour rates, POLE stands for that end.
POLE = 0


@njit(cache=True, inline="always", error_model="numpy")
def _graded(t, k, k_before, k_after):  # pragma: no cover - compiled
    """(position in the pixel, cell width × k) of the subsample at t = (i + ½)/k of a pixel with k cells a side whose
    neighbours before and after have ``k_before`` and ``k_after``: the cells are warped by the cubic Hermite φ with
    φ(0) = 0, φ(1) = 1 whose end cells are 2/(k + k_neighbour) wide — the width the neighbour's end cell has too —
    so the spacing of the lookups changes smoothly across a pixel edge where the rate steps. φ is the identity
    between equal rates, and monotone (its end slopes lie in (0, 2)). With plain cells the spacing jumped there and
    the lookups' sum over a sun's spline lost its balance: rings of pixels off by up to ~1 % (cube 256 → lat-long
    512: 4.5 % of the pixels over 0.2 %; 0.4 % graded). A neighbour of :data:`POLE` cells (a lat-long target's
    pole) makes the end cell there vanish: φ'(0) = 0 (see POLE)."""
    m0 = 0.0 if k_before == POLE else 2.0 * k / (k + k_before)
    m1 = 0.0 if k_after == POLE else 2.0 * k / (k + k_after)
    t2, t3 = t * t, t * t * t
    phi = m0 * (t3 - 2.0 * t2 + t) + (3.0 * t2 - 2.0 * t3) + m1 * (t3 - t2)
    slope = m0 * (3.0 * t2 - 4.0 * t + 1.0) + 6.0 * (t - t2) + m1 * (3.0 * t2 - 2.0 * t)
    return phi, slope


@njit(cache=True, inline="always", error_model="numpy")
def _rate_rows(tgt_kind, tgt_axes, face, row, h, w, k, k_max, rotation, src_kind, src_axes, src_h, src_w, fresh,
               rates):  # pragma: no cover - compiled
    """Keep ``rates`` — (3, 2, W) int64, the (ku, kv) of :func:`_rates` for face rows row − 1, row and row + 1, row r
    at index r % 3 — current for ``row``: all three when ``fresh`` (a band's first line, a face's first row), else
    row + 1 alone (the two others are the previous line's). Each pixel's rates are computed once; at a fixed rate
    (``k_max`` = k) none are."""
    if k_max == k:
        return
    for r in range(max(row - 1 if fresh else row + 1, 0), min(row + 2, h)):
        for col in range(w):
            # A disc source's rim direction first, a disc target's rim next (its rows serve its own rim direction,
            # not the ring a disc source spreads another over), then the cells' own rates
            polar = _rim_polar(tgt_kind, tgt_axes, r, col, h, w, rotation, src_kind, src_axes, src_h, src_w,
                               k_max)
            disc_source = src_kind == ANGULAR or src_kind == SPHERE
            ku, kv, short = RIM_MARK, RIM_MARK, False
            if disc_source or not polar:
                ku, kv, short = _rates(tgt_kind, tgt_axes, face, r, col, h, w, k, k_max, rotation, src_kind,
                                       src_axes, src_h, src_w)
            if disc_source and (_by_source_rim(tgt_kind, tgt_axes, face, r, col, h, w, rotation, src_kind, src_axes)
                                or _source_rim_wanted(tgt_kind, tgt_axes, face, r, col, h, w, rotation, src_kind,
                                                      src_axes, short)):
                ku, kv = SOURCE_RIM_MARK, SOURCE_RIM_MARK
            elif polar:
                ku, kv = RIM_MARK, RIM_MARK
            rates[r % 3, 0, col], rates[r % 3, 1, col] = ku, kv


@njit(cache=True, inline="always", error_model="numpy")
def _source_rim_marked(rates, row, col, k, k_max):  # pragma: no cover - compiled
    """Whether :func:`_rate_rows` marked pixel (row, col) to be sampled round a disc source's rim direction."""
    return k_max > k and rates[row % 3, 0, col] == SOURCE_RIM_MARK


@njit(cache=True, inline="always", error_model="numpy")
def _pixel_rates(rates, src_kind, tgt_kind, row, col, h, w, k, k_max):  # pragma: no cover - compiled
    """(ku, kv, ku left, ku right, kv above, kv below) of pixel (row, col) from :func:`_rate_rows`' buffer: its
    rates and its four neighbours' on its face (a lat-long's columns wrap); past a face's edge, its own. At a
    fixed rate, k six times."""
    if k_max == k:
        return k, k, k, k, k, k
    here = row % 3
    ku, kv = rates[here, 0, col], rates[here, 1, col]
    if ku == RIM_MARK:  # sampled round the rim direction: its rates serve only if that finds nothing
        return k, k, k, k, k, k
    if ku == SOURCE_RIM_MARK:  # sampled round the source's rim direction: likewise, at the most it may take
        return k_max, k_max, k_max, k_max, k_max, k_max
    left, right, above, below = ku, ku, kv, kv
    if col > 0 or tgt_kind == LATLONG:
        left = rates[here, 0, (col - 1) % w]
    if col < w - 1 or tgt_kind == LATLONG:
        right = rates[here, 0, (col + 1) % w]
    if row > 0:
        above = rates[(row - 1) % 3, 1, col]
    if row < h - 1:
        below = rates[(row + 1) % 3, 1, col]
    # A neighbour sampled round the rim direction has its rows _rim_spacing apart, a fraction of the cells' spacing
    # here: the end cells at that edge are graded to that width (towards edge × k: 3k for cells 0.5 apart and rows
    # 0.25), so that the two pixels' midpoint rules, each off by a term in its spacing² at the edge, still cancel
    # there (a one-pixel sun 0.9 % off where they did not).
    edge = 2.0 * _pair_spacing(src_kind, tgt_kind) / _rim_spacing(tgt_kind) - 1.0
    left = int(edge * ku + 0.5) if left == RIM_MARK else k_max if left == SOURCE_RIM_MARK else left
    right = int(edge * ku + 0.5) if right == RIM_MARK else k_max if right == SOURCE_RIM_MARK else right
    above = int(edge * kv + 0.5) if above == RIM_MARK else k_max if above == SOURCE_RIM_MARK else above
    below = int(edge * kv + 0.5) if below == RIM_MARK else k_max if below == SOURCE_RIM_MARK else below
    return ku, kv, left, right, above, below


# A mirror ball's outer pixels squeeze its back cap into one ring: a pixel touching the rim reads from its rim direction
# (ρ = 0) out to ~(8/R)^½ rad, and its image radius r = cos(ρ/2) is flat in ρ there, so subsamples evenly spaced in
# the image bunch at the pixel's inner edge and land rows of source pixels apart by the rim direction: a one-pixel
# sun there came out up to 33 % off (lat-long 256 → mirror ball 128), 48 % (512 → 256), wherever no flux correction
# mends it. Where a pixel's ρ spans more than RIM_POLAR_SPAN× its least ρ, its subsamples are laid out in (ρ, α) round
# the rim direction instead (:func:`_rim_subsamples`).
RIM_POLAR_SPAN = 2.0
RIM_MARK = -1  # in the rates buffer: a pixel sampled round the rim direction
RIM_R = 1.0 - 1e-12  # the image radius of the rim direction as sampled: a hair inside the disc
RIM_SPLIT = 8  # sub-rows of a ring band that the pixel's edge cuts along its length
RIM_SPACING = 0.25  # source pixels between a rim pixel's rows and its subsamples along a row (at 0.5: 0.36 % by the
#                     ring's inner edge, lat-long 512 → mirror ball 256; the rows' error at the rim direction itself
#                     is taken off in _rim_subsamples)
# A mirror ball's: its rings inside RIM_SHORT_REACH are sampled so too where they are long (_rim_polar), and there
# rows 0.25 apart, beside a plain pixel, left a sun 0.28 % off (lat-long 2048 → mirror ball 840, 17° from the rim
# direction; 0.14 % at 0.125). An angular map keeps 0.25: at 0.125 its rim direction's sun went from 0.26 to 0.53 %
# (lat-long 2048 → angular 3268), when most of that 0.26 % was its plain pixels just inside (ANGULAR_RIM_SPACING).
SPHERE_RIM_SPACING = 0.125


@njit(cache=True, inline="always", error_model="numpy")
def _rim_spacing(tgt_kind):  # pragma: no cover - compiled
    """Source pixels between a disc target's rim rows and between their subsamples (:func:`_rim_subsamples`)."""
    return SPHERE_RIM_SPACING if tgt_kind == SPHERE else RIM_SPACING


@njit(cache=True, inline="always", error_model="numpy")
def _rim_radius(tgt_kind, rho):  # pragma: no cover - compiled
    """Image radius (disc coordinates) of the circle ``rho`` radians from a disc's rim direction: cos(ρ/2) on a
    mirror ball, 1 − ρ/π on an angular map."""
    return math.cos(0.5 * rho) if tgt_kind == SPHERE else 1.0 - rho / math.pi


@njit(cache=True, inline="always", error_model="numpy")
def _rim_rho(tgt_kind, r):  # pragma: no cover - compiled
    """ρ from the rim direction of the circle of image radius ``r`` ≤ 1 (the inverse of :func:`_rim_radius`)."""
    return 2.0 * math.acos(r) if tgt_kind == SPHERE else math.pi * (1.0 - r)


@njit(cache=True, inline="always", error_model="numpy")
def _ring_density(tgt_kind, rho_a, rho_b):  # pragma: no cover - compiled
    """Solid angle per image area (disc coordinates) of the ring between ``rho_a`` < ``rho_b`` from the rim
    direction, in the rim rows' weight unit: 1 on a mirror ball (its image area is ¼ of its solid angle
    everywhere: weights are areas); on an angular map the ring's solid angle 2π(cos ρ_a − cos ρ_b) over its image
    area π(r_a² − r_b²), exact for a whole ring, which a band of the pixel stands for."""
    if tgt_kind == SPHERE:
        return 1.0
    r_a, r_b = _rim_radius(tgt_kind, rho_a), _rim_radius(tgt_kind, rho_b)
    if r_a <= r_b:
        return 0.0
    return 2.0 * (math.cos(rho_a) - math.cos(rho_b)) / ((r_a - r_b) * (r_a + r_b))


@njit(cache=True, inline="always", error_model="numpy")
def _rim_point(tgt_kind, rho, alpha):  # pragma: no cover - compiled
    """Image coordinates (u, v) of the point of a disc ``rho`` radians from its rim direction, at angle ``alpha``
    round the image centre (from image right, counter-clockwise); kept a hair inside the disc."""
    r = min(_rim_radius(tgt_kind, rho), RIM_R)
    return 0.5 * (1.0 + r * math.cos(alpha)), 0.5 * (1.0 - r * math.sin(alpha))


@njit(cache=True, inline="always", error_model="numpy")
def _wrapped_angle(a):  # pragma: no cover - compiled
    """``a`` wrapped into [−π, π)."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _arc_cuts(r, a0, a1, b0, b1, centre, lo, hi, cuts):  # pragma: no cover - compiled
    """Sorted angles (relative to ``centre``, within (lo, hi)) where the circle of radius ``r`` crosses the lines of
    square [a0, a1] × [b0, b1], with ``lo`` and ``hi`` themselves, into ``cuts``; returns how many."""
    n = 0
    cuts[n] = lo
    n += 1
    for i in range(4):
        c = a0 if i == 0 else a1 if i == 1 else b0 if i == 2 else b1
        if abs(c) > r:
            continue
        for j in range(2):
            if i < 2:
                base = math.acos(c / r)
                a = base if j == 0 else -base
            else:
                base = math.asin(c / r)
                a = base if j == 0 else math.pi - base
            d = _wrapped_angle(a - centre)
            if lo < d < hi:
                cuts[n] = d
                n += 1
    cuts[n] = hi
    n += 1
    for i in range(1, n):  # insertion sort: ten at most
        x, j = cuts[i], i - 1
        while j >= 0 and cuts[j] > x:
            cuts[j + 1] = cuts[j]
            j -= 1
        cuts[j + 1] = x
    return n


@njit(cache=True, inline="always", error_model="numpy")
def _quadrant_area(x, y, r):  # pragma: no cover - compiled
    """Signed area of the rectangle between (0, 0) and (x, y) inside the disc of radius ``r`` round the origin: r² ×
    :func:`lightprobe.maps.disc_layouts._quarter_disc_area` at (x/r, y/r), written again for one point in compiled code."""
    a, b = min(abs(x) / r, 1.0), min(abs(y) / r, 1.0)
    x_star = math.sqrt(max(1.0 - b * b, 0.0))  # where the unit circle crosses height b
    lo = min(a, x_star)
    area = b * lo + 0.5 * (a * math.sqrt(max(1.0 - a * a, 0.0)) + math.asin(a)
                           - lo * math.sqrt(max(1.0 - lo * lo, 0.0)) - math.asin(lo))
    return r * r * (area if (x >= 0.0) == (y >= 0.0) else -area)


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _disc_in_square(r, a0, a1, b0, b1):  # pragma: no cover - compiled
    """Area of the disc of radius ``r`` round the origin within the square [a0, a1] × [b0, b1]."""
    return (_quadrant_area(a1, b1, r) - _quadrant_area(a0, b1, r) - _quadrant_area(a1, b0, r)
            + _quadrant_area(a0, b0, r))


@njit(cache=True, inline="always", error_model="numpy")
def _disc_square(row, col, h, w):  # pragma: no cover - compiled
    """Pixel (row, col) of an h × w disc image as (a0, a1, b0, b1) in disc coordinates (a right, b up)."""
    return 2.0 * col / w - 1.0, 2.0 * (col + 1) / w - 1.0, 1.0 - 2.0 * (row + 1) / h, 1.0 - 2.0 * row / h


@njit(cache=True, inline="always", error_model="numpy")
def _rim_span(tgt_kind, row, col, h, w):  # pragma: no cover - compiled
    """(least, greatest) ρ from the rim direction over disc pixel (row, col) of h × w (a mirror ball's or an angular
    map's: ``tgt_kind``); (1, 0) for a pixel off the disc or holding its centre."""
    a0, a1, b0, b1 = _disc_square(row, col, h, w)
    near = math.hypot(min(max(0.0, a0), a1), min(max(0.0, b0), b1))
    far = math.sqrt(max(a0 * a0, a1 * a1) + max(b0 * b0, b1 * b1))
    if near >= 1.0 or near <= 0.0:
        return 1.0, 0.0
    return _rim_rho(tgt_kind, min(far, 1.0)), _rim_rho(tgt_kind, near)


@njit(cache=True, inline="always", error_model="numpy")
def _rim_sampled(tgt_kind, rho_lo, rho_hi):  # pragma: no cover - compiled
    """Whether a disc pixel spanning ``rho_lo`` … ``rho_hi`` from the rim direction is sampled round it for its
    shape alone: on a mirror ball where its ρ spans :data:`RIM_POLAR_SPAN`× its least (r = cos(ρ/2) is flat
    there); on an angular map (r = 1 − ρ/π: even cells stay even in ρ) only the pixels the rim crosses, whose rim
    direction is the one the plain cells miss — sampled so out to twice their least ρ, a 16-pixel map's second ring
    took a lat-long's sun up to 23 % off before its flux correction (0.26 % with its plain cells)."""
    if tgt_kind == ANGULAR:
        return rho_lo == 0.0
    return rho_hi >= RIM_POLAR_SPAN * rho_lo


# A mirror ball's rings just inside those are each a few source rows deep radially and a sliver across: from a 4k
# lat-long, ball 1024's second ring (7–10° from its rim direction) spans 33 rows, where k_max = 32 cells a side left
# the lookups a row apart and a one-pixel sun 0.41 % off (ball 1536: 0.24 %). A ring pixel whose radial span needs
# more than k_max lookups at the pair's spacing is sampled round the rim direction too, where the rows follow ρ.
RIM_SHORT = 2.0
RIM_SHORT_REACH = 0.5 * math.pi  # ... within this of the rim direction (the ball's back half)


@njit(cache=True, error_model="numpy", fastmath=False)  # apart for compile time (see _subsamples); as its callers
def _rim_radial(tgt_kind, tgt_axes, rho_lo, rho_hi, centre, rotation, src_kind, src_axes, src_h,
                src_w):  # pragma: no cover - compiled
    """Source pixels a disc pixel spanning ``rho_lo`` … ``rho_hi`` covers radially, along angle ``centre``
    (twice the step across the middle half of its span)."""
    span = rho_hi - rho_lo
    u0, v0 = _rim_point(tgt_kind, rho_lo + 0.25 * span, centre)
    u1, v1 = _rim_point(tgt_kind, rho_lo + 0.75 * span, centre)
    return 2.0 * _source_step(tgt_kind, tgt_axes, np.int64(0), u0, v0, u1, v1, rotation, src_kind, src_axes, src_h,
                              src_w)


@njit(cache=True, inline="always", error_model="numpy")
def _disc_angle(a0, a1, b0, b1):  # pragma: no cover - compiled
    """The angle round a disc image's centre of the middle of square [a0, a1] × [b0, b1]."""
    return math.atan2(0.5 * (b0 + b1), 0.5 * (a0 + a1))


@njit(cache=True, error_model="numpy", fastmath=False)  # as _rim_subsamples: every kernel decides alike
def _rim_polar(tgt_kind, tgt_axes, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w,
               k_max):  # pragma: no cover - compiled
    """Whether target pixel (row, col) is sampled round the rim direction (:func:`_rim_subsamples`): for its shape
    (:func:`_rim_sampled`) or, on a mirror ball within :data:`RIM_SHORT_REACH` of its rim direction, where its
    radial span needs more than ``k_max`` lookups at the pair's spacing (:func:`_pair_spacing`)."""
    if tgt_kind != SPHERE and tgt_kind != ANGULAR:
        return False
    rho_lo, rho_hi = _rim_span(tgt_kind, row, col, h, w)
    if _rim_sampled(tgt_kind, rho_lo, rho_hi):
        return True
    if tgt_kind != SPHERE or not rho_lo < rho_hi <= RIM_SHORT_REACH:
        return False
    a0, a1, b0, b1 = _disc_square(row, col, h, w)
    radial = _rim_radial(tgt_kind, tgt_axes, rho_lo, rho_hi, _disc_angle(a0, a1, b0, b1), rotation, src_kind,
                         src_axes, src_h, src_w)
    return radial > RIM_SHORT * k_max * _pair_spacing(src_kind, tgt_kind)


# Compiled apart and without the kernels' fastmath (numba passes a caller's fastmath on to a callee that does not
# set its own): the band areas are differences of nearly equal areas, and the rows' places differences of nearly
# equal terms, which the fast-math rewrites spoiled (the weights summed 3 % over the pixel's area).
@njit(cache=True, error_model="numpy", fastmath=False)
def _rim_subsamples(tgt_kind, tgt_axes, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w, k_max, pfs, pxs,
                    pys, pws):  # pragma: no cover - compiled
    """A disc's pixel by its rim (a mirror ball's or an angular map's: ``tgt_kind``) as subsamples in (ρ, α) — ρ
    from the rim direction, α round the image centre — or (0, 0.0) where :func:`_rim_polar` leaves it to the
    plain cells. Rows at the middles of even steps of ρ; each row
    weighs the pixel's exact share of its ring's image area times the ring's solid angle per area
    (:func:`_ring_density`), spread evenly over the row's arc inside the pixel, cut exactly at the pixel's edges;
    rows and subsamples :func:`_rim_spacing` source pixels apart, thinned to fit the scratch (``pfs``) held."""
    if not _rim_polar(tgt_kind, tgt_axes, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w, k_max):
        return 0, 0.0
    rho_lo, rho_hi = _rim_span(tgt_kind, row, col, h, w)
    a0, a1, b0, b1 = _disc_square(row, col, h, w)
    centre = _disc_angle(a0, a1, b0, b1)
    lo, hi = 0.0, 0.0
    for i in range(4):
        d = _wrapped_angle(math.atan2(b0 if i < 2 else b1, a0 if i % 2 == 0 else a1) - centre)
        lo, hi = min(lo, d), max(hi, d)
    span = rho_hi - rho_lo
    radial = _rim_radial(tgt_kind, tgt_axes, rho_lo, rho_hi, centre, rotation, src_kind, src_axes, src_h, src_w)
    u0, v0 = _rim_point(tgt_kind, rho_hi, centre + 0.25 * (hi - lo) + lo)  # and round its widest arc
    u1, v1 = _rim_point(tgt_kind, rho_hi, centre + 0.75 * (hi - lo) + lo)
    round_ = 2.0 * _source_step(tgt_kind, tgt_axes, np.int64(0), u0, v0, u1, v1, rotation, src_kind, src_axes, src_h,
                                src_w)
    budget = pfs.shape[0] - 1  # a row's arc may fall in pieces, each rounded up: a subsample more each
    rows_budget = 3 * budget // 4  # the rest for split bands
    spacing = _rim_spacing(tgt_kind)
    while True:  # wider apart both ways where the scratch is short (a ball of 512's rim pixels from a 1024 lat-long:
        #          rows thinned alone left one subsample a row, 0.26 % off by the ring's inner edge; this, 0.18 %)
        rows = max(2, int(math.ceil(radial / spacing)))
        per_row = max(2, int(math.ceil(round_ / spacing)))
        if rows * (per_row + 1) <= rows_budget or rows == 2 and per_row == 2:
            break
        spacing *= 1.1
    cuts = np.empty(10)
    n, wsum, d_rho = 0, 0.0, span / rows
    r_out = _rim_radius(tgt_kind, rho_lo)
    outer = _disc_in_square(r_out, a0, a1, b0, b1)
    for i in range(rows):
        r_in = _rim_radius(tgt_kind, rho_lo + (i + 1) * d_rho)
        inner = _disc_in_square(r_in, a0, a1, b0, b1)
        band = outer - inner  # the pixel's share of the ring between this row's edges, exactly
        rho = rho_lo + (i + 0.5) * d_rho
        r_mid = _rim_radius(tgt_kind, rho)
        m = _arc_cuts(r_mid, a0, a1, b0, b1, centre, lo, hi, cuts)
        inside = _arc_inside(r_mid, a0, a1, b0, b1, centre, cuts, m)
        # Where the pixel's edge runs along the rings (by the disc's top, bottom and sides) the band is only partly
        # in the pixel and its middle arc stands for it badly (a one-pixel sun there 2 % off): split in RIM_SPLIT.
        split = 1
        if abs(inside * r_mid * (r_out - r_in) - band) > 0.01 * band \
                and n + (RIM_SPLIT + rows - i) * (per_row + 1) <= budget:
            split = RIM_SPLIT
        sub_out = outer
        for j in range(split):
            sub_r = _rim_radius(tgt_kind, rho_lo + (i + (j + 1.0) / split) * d_rho)
            sub_in = inner if j == split - 1 else _disc_in_square(sub_r, a0, a1, b0, b1)
            sub_rho = rho_lo + (i + (j + 0.5) / split) * d_rho
            count = per_row
            if split > 1:  # this sub-row's own arc
                count = max(1, int(math.ceil(per_row * (sub_out - sub_in) / band)))
                sub_mid = _rim_radius(tgt_kind, sub_rho)
                m = _arc_cuts(sub_mid, a0, a1, b0, b1, centre, lo, hi, cuts)
                inside = _arc_inside(sub_mid, a0, a1, b0, b1, centre, cuts, m)
            density = _ring_density(tgt_kind, rho_lo + (i + j / split) * d_rho,
                                    rho_lo + (i + (j + 1.0) / split) * d_rho)
            n, wsum = _arc_samples(tgt_kind, sub_rho, (sub_out - sub_in) * density, count, a0, a1, b0, b1, centre,
                                   cuts, m, inside, tgt_axes, rotation, src_kind, src_axes, src_h, src_w, pfs, pxs,
                                   pys, pws, n, wsum)
            sub_out = sub_in
        outer, r_out = inner, r_in
    if rho_lo == 0.0 and tgt_kind == SPHERE and n < pfs.shape[0]:
        # The rows are the midpoint rule in ρ of g(ρ) = ∫ L dA, which vanishes at the rim direction with slope
        # g'(0) = ¼ L(0) Δα (dA = ¼ sin ρ dρ dα): the rule is off by −Δρ²/24 · g'(0) there (Euler–Maclaurin), a
        # one-pixel sun at the rim direction 0.37 % over. One subsample at the rim direction with that weight,
        # negative, takes it off; counted in the weights' sum too, so a uniform map stays uniform. On an angular
        # map the rows alone leave that sun 0.04 % over (lat-long 256 → angular 128), and the same term in its unit
        # (Δρ²Δα/24 of solid angle) took it to −0.19 %: measured, so it is left out there. (Its plain pixels just
        # inside were over-weighting that sun, +0.40 % at lat-long 512×256 → angular 408, where the pixels the rim
        # crosses took −0.13 %, by brute-force integrals of each target pixel: ANGULAR_RIM_SPACING.)
        m = _arc_cuts(RIM_R, a0, a1, b0, b1, centre, lo, hi, cuts)
        weight = -d_rho * d_rho * _arc_inside(RIM_R, a0, a1, b0, b1, centre, cuts, m) / 96.0
        if weight < 0.0:
            _store_rim_subsample(tgt_kind, 0.0, centre, weight, tgt_axes, rotation, src_kind, src_axes, src_h,
                                 src_w, pfs, pxs, pys, pws, np.int64(n))
            wsum += weight
            n += 1
    return n, wsum


@njit(cache=True, error_model="numpy", fastmath=False)  # apart for compile time (see _subsamples); as its callers
def _store_rim_subsample(tgt_kind, rho, alpha, weight, tgt_axes, rotation, src_kind, src_axes, src_h, src_w, pfs,
                         pxs, pys, pws, n):  # pragma: no cover - compiled
    """Store subsample ``n``: the disc's point (``rho``, ``alpha``) (:func:`_rim_point`) as a source position,
    with ``weight``."""
    u, v = _rim_point(tgt_kind, rho, alpha)
    x, y, z, _ = target_direction(tgt_kind, tgt_axes, 0, u, v)
    rx, ry, rz = _turned(x, y, z, rotation)
    pfs[n], pxs[n], pys[n] = source_position(src_kind, src_axes, rx, ry, rz, src_h, src_w)
    pws[n] = weight


@njit(cache=True, inline="always", error_model="numpy")
def _arc_inside(r, a0, a1, b0, b1, centre, cuts, m):  # pragma: no cover - compiled
    """Length (in angle) of the circle of radius ``r`` inside square [a0, a1] × [b0, b1], from its ``m`` cuts."""
    inside = 0.0
    for j in range(m - 1):
        mid = centre + 0.5 * (cuts[j] + cuts[j + 1])
        a, b = r * math.cos(mid), r * math.sin(mid)
        if a0 <= a <= a1 and b0 <= b <= b1:
            inside += cuts[j + 1] - cuts[j]
    return inside


@njit(cache=True, inline="always", error_model="numpy")
def _arc_samples(tgt_kind, rho, area, per_row, a0, a1, b0, b1, centre, cuts, m, inside, tgt_axes, rotation,
                 src_kind, src_axes, src_h, src_w, pfs, pxs, pys, pws, n, wsum):  # pragma: no cover - compiled
    """Subsamples along the circle ``rho`` from a disc's rim direction where it crosses the square (its ``m`` cuts,
    :func:`_arc_cuts`, and its length ``inside``, :func:`_arc_inside`), about ``per_row`` spread evenly over its
    pieces inside, weighing ``area`` in all, stored from ``n``; (n, wsum) after."""
    r = _rim_radius(tgt_kind, rho)
    if inside <= 0.0 or area <= 0.0:
        return n, wsum
    for j in range(m - 1):
        mid = centre + 0.5 * (cuts[j] + cuts[j + 1])
        a, b = r * math.cos(mid), r * math.sin(mid)
        length = cuts[j + 1] - cuts[j]
        if not (a0 <= a <= a1 and b0 <= b <= b1) or length <= 0.0:
            continue
        count = min(max(1, int(round(per_row * length / inside))), pfs.shape[0] - n)  # the budget bounds it
        if count <= 0:
            break
        weight = area * length / (inside * count)
        for q in range(count):
            _store_rim_subsample(tgt_kind, rho, centre + cuts[j] + (q + 0.5) * length / count, weight, tgt_axes,
                                 rotation, src_kind, src_axes, src_h, src_w, pfs, pxs, pys, pws, np.int64(n))
            wsum += weight
            n += 1
    return n, wsum


@njit(cache=True, inline="always", error_model="numpy")
def slots(k):  # pragma: no cover - compiled
    """Subsamples a pixel of k × k cells may list: its cells, and a cube pixel's edge terms, two lookups for each
    side on its face's side (:func:`_cube_edge_terms`; a disc's rim pixel with no cell on the disc lists one, its
    centre)."""
    return k * k + 8


# A cube target's edges: two faces' grids of subsamples meet there at an angle. The midpoint rule's end terms,
# −(h²/24)·∂(JB)/∂n along each face's side (J = dω/(ds dt) = (1 + s² + t²)^(−3/2), h the spacing across the edge),
# cancel between the two faces only up to the lines' kink: the two faces' outward steps do not add to 0 but to
# −t·∂d/∂t, t ∈ [−1, 1] along the edge, leaving (h²/24)·∫ t J ∂B/∂t dt per edge, half from each face's side. For
# a uniform map that integral is 0, but its parts by parts are not: (h²/24)·([t J B] at the vertices − ∫ B ∂(tJ)/∂t),
# and at a vertex the three edges add (h²/8)·J·B — a one-pixel sun on the vertex came out +0.285 % (lat-long 505
# rows → cube 134, k = 5), 1/k² in the rate, where nothing else near it or along the edges was over 0.09 %. Each
# pixel on a face's side takes its share back in the same by-parts form, as lookups at its side's two ends weighted
# ±(h²/48)·t·J (:func:`_cube_edge_terms`), in its weight sum too: their weights sum to −(h²/48)·Δ(tJ) along the
# side, what the line integral takes from a map of the pixel's own value, so a uniform map stays exactly uniform.
@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)  # apart: see COMPILED_APART
def _cube_edge_terms(tgt_axes, face, row, col, h, w, rates, rotation, src_kind, src_axes, src_h, src_w, pfs, pxs,
                     pys, pws, n, wsum):  # pragma: no cover - compiled
    """Append to subsamples 0 … n − 1 of cube pixel (face, row, col) of an h × w face, with ``rates`` as
    :func:`_subsamples`', the edge terms of each side of it that lies on its face's side: lookups at that side's two
    ends, weighted +(first end) / −(second end) × (h²/48)·t·J in the cells' weight units (dω/(du dv) × cell area,
    1 for a plain cell); returns (n, wsum) with them added."""
    ku, kv, left, right, above, below = rates
    for side in range(4):  # the pixel's sides u = 0, u = 1 (along v), v = 0, v = 1 (along u)
        across = float(side % 2)  # where the side lies, in the pixel's (u or v) across it
        if side < 2:
            if col != (0 if side == 0 else w - 1):
                continue
            _, s_end = _graded(across, ku, left, right)  # the end cells' width × ku there
            scale = s_end * s_end / 48.0 * kv / ku  # h² in cell units: a cell is 1/(w ku) × 1/(h kv) of (u, v)
        else:
            if row != (0 if side == 2 else h - 1):
                continue
            _, s_end = _graded(across, kv, above, below)
            scale = s_end * s_end / 48.0 * ku / kv
        for end in range(2):  # the side's two ends, along it
            if side < 2:
                u, v = across, (row + end) / h
                t = 2.0 * v - 1.0
            else:
                u, v = (col + end) / w, across
                t = 2.0 * u - 1.0
            x, y, z, density = target_direction(CUBE, tgt_axes, face, u, v)
            weight = scale * t * density * (-1.0 if end == 1 else 1.0)
            rx, ry, rz = _turned(x, y, z, rotation)
            pfs[n], pxs[n], pys[n] = source_position(src_kind, src_axes, rx, ry, rz, src_h, src_w)
            pws[n] = weight
            wsum += weight
            n += 1
    return n, wsum


# Compiled apart, not inlined: numba inlines an ``inline="always"`` function by copying its IR, its own inlined
# callees included, into each call site, and this one (every layout's formulas, a cube's edge terms) sat in every
# kernel and twice in each cube orbit — most of the compile time (a first lat-long → cube convert compiled for
# ~5 min; 51 s with it and the orbit, the rim's radial step and its subsample store apart). One call per pixel
# costs 4–7 % of a 2048×1024 → 6×512² conversion, 1–2 % into a disc; the values are the same. Its callers pass
# np.int64(…) where an argument could be a constant: numba compiles a callee once for each literal value it is
# called with. It runs in every caller with the kernels' fastmath, as it did inlined.
@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _subsamples(tgt_kind, tgt_axes, face, row, col, h, w, rates, rotation, src_kind, src_axes, src_h, src_w, pfs, pxs,
                pys, pws, rim_k_max):  # pragma: no cover - compiled
    """One target pixel's subsamples — ku × kv, its cells graded towards its neighbours' rates (:func:`_graded`);
    ``rates`` = (ku, kv, ku left, ku right, kv above, kv below) (:func:`_pixel_rates`, or k six times): their
    source positions (pfs, pxs, pys) and weights ``dω/(du dv)`` × cell area (pws), those off a disc left out;
    returns (count, Σ weights). A disc's rim pixel with every subsample off the disc gets its centre's (rim)
    direction, weight 1. With ``rim_k_max`` (the rate automatic: its k_max, else 0), a mirror ball's or an angular
    map's pixels by its rim are sampled round its rim direction (:func:`_rim_subsamples`)."""
    if rim_k_max > 0 and (tgt_kind == SPHERE or tgt_kind == ANGULAR):
        n, wsum = _rim_subsamples(tgt_kind, tgt_axes, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w,
                                  rim_k_max, pfs, pxs, pys, pws)
        if n > 0:
            return n, wsum
    ku, kv, left, right, above, below = rates
    if tgt_kind == LATLONG:  # its pole rows' cells vanish at the pole (see POLE)
        above = POLE if row == 0 else above
        below = POLE if row == h - 1 else below
    n, wsum = 0, 0.0
    for i in range(ku * kv + 1):
        cell = 1.0
        if i < ku * kv:
            fu, su = _graded((i % ku + 0.5) / ku, ku, left, right)
            fv, sv = _graded((i // ku + 0.5) / kv, kv, above, below)
            u, v, cell = (col + fu) / w, (row + fv) / h, su * sv
        elif n == 0:
            u, v = (col + 0.5) / w, (row + 0.5) / h
        else:
            break
        x, y, z, weight = target_direction(tgt_kind, tgt_axes, face, u, v)
        if i == ku * kv:
            weight = 1.0
        if weight <= 0.0:
            continue
        weight *= cell
        rx, ry, rz = _turned(x, y, z, rotation)
        pfs[n], pxs[n], pys[n] = source_position(src_kind, src_axes, rx, ry, rz, src_h, src_w)
        pws[n] = weight
        wsum += weight
        n += 1
    if tgt_kind == CUBE:
        n, wsum = _cube_edge_terms(tgt_axes, face, row, col, h, w, (ku, kv, left, right, above, below), rotation,
                                   src_kind, src_axes, src_h, src_w, pfs, pxs, pys, pws, np.int64(n), wsum)
    return n, wsum


# ---- round a disc source's rim direction ------------------------------------------------------------------------------
# A disc source (an angular map, a mirror ball) spreads its rim direction over its outer ring: a target pixel ε from
# that direction reads an arc of the ring ~1/ε long, and the pixel holding it the whole ring — thousands of source
# pixels, where k_max × k_max lookups in the target's own cells read some pixels several times and miss others (a
# one-pixel sun there came out −100 % to +3000 %, angular 1024 → cube 256, more than the flux correction can mend). A
# target pixel whose footprint there needs far more than k_max lookups a side (SOURCE_RIM_SHORT) is sampled instead in
# (ρ, α) round the source's rim direction — rows of constant ρ are circles of the source image — rows and lookups
# SOURCE_RIM_SPACING source pixels apart, each lookup weighing its cell's exact solid angle (cos ρa − cos ρb)·Δα, kept
# where it falls in the pixel, the cells at its edge cut there (the pixel's region in (ρ, α) is not a simple shape for
# every target layout; the lookups that fall in it are its own, and every lookup falls in one pixel). What is left,
# within ±35 % of a pixel's solid angle, is the flux correction's (every pixel of a disc source is corrected).
SOURCE_RIM_MARK = -2  # in the rates buffer: a pixel sampled round a disc source's rim direction
SOURCE_RIM_SHORT = 4  # × k_max: the lookups a side a pixel's footprint would need before it is so sampled (at 1×,
#                       pixels 10–25° away, well served by their cells, came out 4–8 % off uncorrected, not 0.2–1.3 %)
SOURCE_RIM_REACH = 0.6  # rad (34°) from the source's rim direction: pixels further away keep their cells
SOURCE_RIM_CLOSE = 2.0  # pixel sides from the rim direction within which a pixel is so sampled whatever its cells
#                         (angular 96 → mirror ball 24 turned: the pixels whose corner touched it kept 16 a side, and
#                         a sun at the rim direction came out 279 % off before the correction, 76 % after)
SOURCE_RIM_EDGE_POINTS = 16  # points along each edge of a target pixel where its span in (ρ, α) is measured
SOURCE_RIM_MARGIN = 0.05  # of that span, added each way (an edge bulges between the points)
SOURCE_RIM_MAX_SAMPLES = 1 << 22  # lookups a pixel, at most: spaced wider past it
SOURCE_RIM_SPACING = 0.25  # source pixels between rows and lookups (at 0.5 the flows of mirror ball 1024 →
#                           angular 256 hit their cap: 6 % off at 10–25°; ~15 % faster)


@njit(cache=True, inline="always", error_model="numpy")
def _source_rim_frame(src_kind, src_axes):  # pragma: no cover - compiled
    """The source's rim direction D and the image's right and up axes e1, e2 ⊥ D, in the source's frame: α =
    atan2(s·e2, s·e1) is then the angle round the source image's centre."""
    if src_kind == ANGULAR:
        return 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0
    return (-src_axes[0, 2], -src_axes[1, 2], -src_axes[2, 2], src_axes[0, 0], src_axes[1, 0], src_axes[2, 0],
            src_axes[0, 1], src_axes[1, 1], src_axes[2, 1])


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _source_rim_polar(src_kind, src_axes, sx, sy, sz):  # pragma: no cover - compiled
    """(ρ, α) of source direction s (unit) round the source's rim direction."""
    dx, dy, dz, ax, ay, az, bx, by, bz = _source_rim_frame(src_kind, src_axes)
    c = min(max(sx * dx + sy * dy + sz * dz, -1.0), 1.0)
    return math.acos(c), math.atan2(sx * bx + sy * by + sz * bz, sx * ax + sy * ay + sz * az)


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _source_dir(tgt_kind, tgt_axes, face, u, v, rotation):  # pragma: no cover - compiled
    """The unit source direction that target point (u, v) of ``face`` shows."""
    x, y, z, _ = target_direction(tgt_kind, tgt_axes, face, u, v)
    sx, sy, sz = _turned(x, y, z, rotation)
    norm = math.sqrt(sx * sx + sy * sy + sz * sz)
    return sx / norm, sy / norm, sz / norm


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _target_pixel(tgt_kind, tgt_axes, rotation, sx, sy, sz, h, w):  # pragma: no cover - compiled
    """(face, row, col) of the target pixel that shows source direction s (d = R s)."""
    x = rotation[0, 0] * sx + rotation[0, 1] * sy + rotation[0, 2] * sz
    y = rotation[1, 0] * sx + rotation[1, 1] * sy + rotation[1, 2] * sz
    z = rotation[2, 0] * sx + rotation[2, 1] * sy + rotation[2, 2] * sz
    f, px, py = source_position(tgt_kind, tgt_axes, x, y, z, h, w)
    col, row = int(math.floor(px + 0.5)), min(max(int(math.floor(py + 0.5)), 0), h - 1)
    col = col % w if tgt_kind == LATLONG else min(max(col, 0), w - 1)
    return f, row, col


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _by_source_rim(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes):  # pragma: no cover
    """Whether target pixel (face, row, col) is the one that shows a disc source's rim direction or one of its eight
    neighbours on its face: sampled round that direction before anything else, a disc target's own rim rows
    included (angular 96 → mirror ball 32 turned so the source's rim direction fell in the ball's rim pixels, 25°
    from its own: read by the ball's rim rows, a sun there came out 177 % off after the correction)."""
    if src_kind != ANGULAR and src_kind != SPHERE:
        return False
    dx, dy, dz, _, _, _, _, _, _ = _source_rim_frame(src_kind, src_axes)
    f, r, c = _target_pixel(tgt_kind, tgt_axes, rotation, dx, dy, dz, h, w)
    across = abs(c - col)
    if tgt_kind == LATLONG:
        across = min(across, w - across)
    return f == face and abs(r - row) <= 1 and across <= 1


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _source_rim_wanted(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes,
                       short):  # pragma: no cover - compiled
    """Whether target pixel (face, row, col) is sampled round a disc source's rim direction: its centre lies within
    :data:`SOURCE_RIM_REACH` of it, and its cells fall ``short`` or its nearest point (of its corners, edge
    middles and centre) lies within :data:`SOURCE_RIM_CLOSE` × its size (√ of its solid angle) from it: its cells'
    spacing, measured over its middle half, misses the ring a corner of it touches, and a mirror ball target's rim
    pixels are long strips — one reaching the source's rim direction read its ring 130 % over. (Measured against
    the strips' length instead, every ball rim pixel within reach was so sampled, and its fan round the ball's own
    rim direction was read short: 54 % under 25° from the source's.)"""
    if src_kind != ANGULAR and src_kind != SPHERE:
        return False
    sx, sy, sz = _source_dir(tgt_kind, tgt_axes, face, (col + 0.5) / w, (row + 0.5) / h, rotation)
    rho, _ = _source_rim_polar(src_kind, src_axes, sx, sy, sz)
    if rho >= SOURCE_RIM_REACH:
        return False
    if short:
        return True
    _, _, _, density = target_direction(tgt_kind, tgt_axes, face, (col + 0.5) / w, (row + 0.5) / h)
    nearest = rho
    for q in range(8):
        u = 0.0 if q % 3 == 0 else 0.5 if q % 3 == 1 else 1.0
        v = 0.0 if q < 3 else 0.5 if q < 5 else 1.0
        if q == 3 or q == 4:  # the middles of the left and right edges
            u = 0.0 if q == 3 else 1.0
        px, py, pz = _source_dir(tgt_kind, tgt_axes, face, (col + u) / w, (row + v) / h, rotation)
        there, _ = _source_rim_polar(src_kind, src_axes, px, py, pz)
        nearest = min(nearest, there)
        _, _, _, here = target_direction(tgt_kind, tgt_axes, face, (col + u) / w, (row + v) / h)
        density = max(density, here)  # a disc's rim pixel may have its centre off the disc
    return nearest < SOURCE_RIM_CLOSE * math.sqrt(density / (w * h))


@njit(cache=True, error_model="numpy", fastmath=False)  # every kernel lays the rows out alike
def _source_rim_plan(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_w):  # pragma: no cover
    """(ρ_lo, ρ_hi, α centre, α_lo, α_hi, rows, spacing) of a target pixel sampled round the source's rim direction:
    its span in ρ and in α (relative to the centre's) measured along its edges and widened by
    :data:`SOURCE_RIM_MARGIN`; the whole circle from ρ = 0 for the pixel that holds the rim direction and those
    whose least ρ is under a quarter of their span; rows in ρ and the spacing of lookups along them in source pixels
    (:data:`SOURCE_RIM_SPACING`, wider where the pixel would take more than :data:`SOURCE_RIM_MAX_SAMPLES`)."""
    sx, sy, sz = _source_dir(tgt_kind, tgt_axes, face, (col + 0.5) / w, (row + 0.5) / h, rotation)
    _, centre = _source_rim_polar(src_kind, src_axes, sx, sy, sz)
    rho_lo, rho_hi, lo, hi = math.pi, 0.0, 0.0, 0.0
    for e in range(4):
        for j in range(SOURCE_RIM_EDGE_POINTS):
            t = j / SOURCE_RIM_EDGE_POINTS
            u = t if e == 0 else 1.0 if e == 1 else 1.0 - t if e == 2 else 0.0
            v = 0.0 if e == 0 else t if e == 1 else 1.0 if e == 2 else 1.0 - t
            sx, sy, sz = _source_dir(tgt_kind, tgt_axes, face, (col + u) / w, (row + v) / h, rotation)
            rho, alpha = _source_rim_polar(src_kind, src_axes, sx, sy, sz)
            a = _wrapped_angle(alpha - centre)
            rho_lo, rho_hi, lo, hi = min(rho_lo, rho), max(rho_hi, rho), min(lo, a), max(hi, a)
    span = rho_hi - rho_lo
    dx, dy, dz, _, _, _, _, _, _ = _source_rim_frame(src_kind, src_axes)
    f, r, c = _target_pixel(tgt_kind, tgt_axes, rotation, dx, dy, dz, h, w)
    holds = f == face and r == row and c == col
    if holds or rho_lo < 0.25 * span:
        rho_lo, centre, lo, hi = 0.0, 0.0, -math.pi, math.pi
    else:
        rho_lo = max(0.0, rho_lo - SOURCE_RIM_MARGIN * span)
        lo, hi = lo - SOURCE_RIM_MARGIN * (hi - lo), hi + SOURCE_RIM_MARGIN * (hi - lo)
    rho_hi = min(math.pi, rho_hi + SOURCE_RIM_MARGIN * span)
    radius = 0.5 * src_w  # source pixels per unit of image radius
    radial = radius / math.pi if src_kind == ANGULAR else 0.5 * radius * math.sin(0.5 * rho_hi)  # px per radian
    widest = (hi - lo) * radius * _rim_radius(src_kind, rho_lo)  # the longest row, in source pixels
    spacing = SOURCE_RIM_SPACING
    rows = max(2, int(math.ceil((rho_hi - rho_lo) * radial / spacing)))
    while rows * (widest / spacing + 1.0) > SOURCE_RIM_MAX_SAMPLES:
        spacing *= 1.25
        rows = max(2, int(math.ceil((rho_hi - rho_lo) * radial / spacing)))
    return rho_lo, rho_hi, centre, lo, hi, rows, spacing


@njit(cache=True, inline="always", error_model="numpy")
def _rim_frame_point(frame, rho, alpha):  # pragma: no cover - compiled
    """The source direction (ρ, α) round the rim direction of ``frame`` (:func:`_source_rim_frame`)."""
    dx, dy, dz, ax, ay, az, bx, by, bz = frame
    cr, sr, ca, sa = math.cos(rho), math.sin(rho), math.cos(alpha), math.sin(alpha)
    return (cr * dx + sr * (ca * ax + sa * bx), cr * dy + sr * (ca * ay + sa * by),
            cr * dz + sr * (ca * az + sa * bz))


@njit(cache=True, error_model="numpy", fastmath=False)  # apart: see COMPILED_APART
def _in_pixel(frame, rho, alpha, tgt_kind, tgt_axes, rotation, h, w, face, row, col):  # pragma: no cover - compiled
    """Whether source direction (ρ, α) round the rim direction shows in target pixel (face, row, col)."""
    sx, sy, sz = _rim_frame_point(frame, rho, alpha)
    f, r, c = _target_pixel(tgt_kind, tgt_axes, rotation, sx, sy, sz, h, w)
    return f == face and r == row and c == col


SOURCE_RIM_BISECTIONS = 12  # halvings that place a pixel's edge between a lookup inside it and one outside


@njit(cache=True, error_model="numpy", fastmath=False)
def _edge_between(frame, rho_in, alpha_in, rho_out, alpha_out, tgt_kind, tgt_axes, rotation, h, w, face, row,
                  col):  # pragma: no cover - compiled
    """Where, on the (ρ, α) segment from a point inside target pixel (face, row, col) to one outside, its edge
    lies: the fraction of the way, to 2^-:data:`SOURCE_RIM_BISECTIONS`."""
    t_in, t_out = 0.0, 1.0
    for _ in range(SOURCE_RIM_BISECTIONS):
        t = 0.5 * (t_in + t_out)
        if _in_pixel(frame, rho_in + t * (rho_out - rho_in), alpha_in + t * (alpha_out - alpha_in), tgt_kind,
                     tgt_axes, rotation, h, w, face, row, col):
            t_in = t
        else:
            t_out = t
    return 0.5 * (t_in + t_out)


@njit(cache=True, error_model="numpy", fastmath=False)
def _source_rim_chunk(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w,
                      start_row, start_at, pfs, pxs, pys, pws):  # pragma: no cover - compiled
    """The next lookups of a pixel sampled round the source's rim direction (``plan``: :func:`_source_rim_plan`),
    from row ``start_row``, lookup ``start_at`` of it, while ``pfs`` has room: their source positions and weights,
    those that fall outside the pixel left out; returns (count, Σ weights, row, lookup to resume from) — the row is
    ``plan``'s rows when it is done. Callers start at ``np.int64(0)``: with a plain 0 numba typed one caller's first
    call with literal arguments and compiled this a second time (it takes ~20 s of the set-up's warm-up)."""
    rho_lo, rho_hi, centre, lo, hi, rows, spacing = plan
    frame = _source_rim_frame(src_kind, src_axes)
    d_rho = (rho_hi - rho_lo) / rows
    radius = 0.5 * src_w
    n, wsum, i, j = 0, 0.0, start_row, start_at
    while i < rows:
        rho_a = rho_lo + i * d_rho
        rho = rho_a + 0.5 * d_rho
        per_row = max(2, int(math.ceil((hi - lo) * radius * _rim_radius(src_kind, rho) / spacing)))
        d_alpha = (hi - lo) / per_row
        # Along a row each lookup's place is found once: the one before it knows its left side (``seen``,
        # ``before``), and an inside one found its right neighbour's (``known``, ``here``).
        seen, before, known, here = False, False, False, False
        while j < per_row:
            if n == pfs.shape[0]:
                return n, wsum, i, j
            alpha = centre + lo + (j + 0.5) * d_alpha
            j += 1
            inside = here if known else _in_pixel(frame, rho, alpha, tgt_kind, tgt_axes, rotation, h, w, face, row,
                                                  col)
            left_known, left, known = seen, before, False
            seen, before = True, inside
            if not inside:
                continue
            # The lookup's cell [ρa, ρb] × [α ∓ Δα/2], its sides moved to the pixel's edge where a neighbouring
            # lookup falls outside: the cells then tile the pixel to its edges (counted whole or not at all, the
            # edge cells left the pixel's area ±10 % and a sun by the rim direction ±30 % before the correction).
            a0, a1, r0, r1 = alpha - 0.5 * d_alpha, alpha + 0.5 * d_alpha, rho_a, rho_a + d_rho
            if not (left if left_known else _in_pixel(frame, rho, alpha - d_alpha, tgt_kind, tgt_axes, rotation,
                                                      h, w, face, row, col)):
                a0 = alpha - d_alpha * _edge_between(frame, rho, alpha, rho, alpha - d_alpha, tgt_kind, tgt_axes,
                                                     rotation, h, w, face, row, col)
            known, here = True, _in_pixel(frame, rho, alpha + d_alpha, tgt_kind, tgt_axes, rotation, h, w, face,
                                          row, col)
            if not here:
                a1 = alpha + d_alpha * _edge_between(frame, rho, alpha, rho, alpha + d_alpha, tgt_kind, tgt_axes,
                                                     rotation, h, w, face, row, col)
            if not _in_pixel(frame, rho - d_rho, alpha, tgt_kind, tgt_axes, rotation, h, w, face, row, col):
                r0 = max(rho - d_rho * _edge_between(frame, rho, alpha, rho - d_rho, alpha, tgt_kind, tgt_axes,
                                                     rotation, h, w, face, row, col), 0.0)
            if not _in_pixel(frame, rho + d_rho, alpha, tgt_kind, tgt_axes, rotation, h, w, face, row, col):
                r1 = rho + d_rho * _edge_between(frame, rho, alpha, rho + d_rho, alpha, tgt_kind, tgt_axes, rotation,
                                                 h, w, face, row, col)
            weight = (math.cos(r0) - math.cos(r1)) * (a1 - a0)  # the cell's solid angle
            sx, sy, sz = _rim_frame_point(frame, rho, alpha)
            pfs[n], pxs[n], pys[n] = source_position(src_kind, src_axes, sx, sy, sz, src_h, src_w)
            pws[n] = weight
            wsum += weight
            n += 1
        i, j = i + 1, 0
    return n, wsum, rows, 0


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _source_rim_value(src_kind, src, valid, src_axes, src_h, src_w, tgt_kind, tgt_axes, face, row, col, h, w,
                      rotation, pfs, pxs, pys, pws, wx, wy, value, acc):  # pragma: no cover - compiled
    """``acc`` = target pixel (face, row, col) sampled round a disc source's rim direction (:func:`_source_rim_chunk`,
    a padded source as :func:`resample_into` reads it); False, ``acc`` untouched, where no lookup falls in it."""
    plan = _source_rim_plan(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_w)
    r, g, b, wsum, i, j = 0.0, 0.0, 0.0, 0.0, np.int64(0), np.int64(0)  # not literal 0s: see _source_rim_chunk
    while i < plan[5]:
        n, part, i, j = _source_rim_chunk(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind,
                                          src_axes, src_h, src_w, i, j, pfs, pxs, pys, pws)
        wsum += part
        for s in range(n):
            value[0], value[1], value[2] = 0.0, 0.0, 0.0
            _lookup_padded(src, valid, pfs[s], pxs[s], pys[s], wx, wy, value)
            r += pws[s] * value[0]
            g += pws[s] * value[1]
            b += pws[s] * value[2]
    if wsum <= 0.0:
        return False
    acc[0], acc[1], acc[2] = r / wsum, g / wsum, b / wsum
    return True


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _source_rim_weight(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_h, src_w,
                       pfs, pxs, pys, pws):  # pragma: no cover - compiled
    """Σ weights of a pixel's lookups round the source's rim direction (a first pass, for the taps' scale)."""
    wsum, i, j = 0.0, np.int64(0), np.int64(0)
    while i < plan[5]:
        _, part, i, j = _source_rim_chunk(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind,
                                          src_axes, src_h, src_w, i, j, pfs, pxs, pys, pws)
        wsum += part
    return wsum


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def resample_into(src_kind, src, valid, levels, reduced, row_offsets, caps, src_axes, src_h, src_w, tgt_kind,
                  tgt_axes, tgt_h, tgt_valid, all_valid, k, k_max, rotation, out, first):  # pragma: no cover - compiled
    """Fill ``out`` (n, W, 3) float32 with the target's lines ``first`` to ``first + n − 1`` (a line is one row of
    one face, face-major: line = face·H + row, H = ``tgt_h``), from ``src``: unpadded (1, H, W, 3) for a latlong
    source, else the padded (F, H+4, W+4, 3) image with its ``valid`` taps. A latlong source's polar rows may be
    read from their azimuthal reductions (``levels``, ``reduced``, ``row_offsets``, ``caps``: see
    :func:`_lookup_latlong` and :mod:`lightprobe.maps.resampling.polar`). Unless ``all_valid``, ``tgt_valid``
    (F, H, W) uint8 says which target pixels cover the sphere (the rest are 0). ``rotation`` R: the target at d
    shows the source at Rᵀd. k × k subsamples a pixel, or up to ``k_max`` × ``k_max`` where the pixel's footprint
    is long (:func:`_rates`). Lines are independent, so a caller can fill a map in bands or stream it in strips.

    Serial and without the GIL: the caller runs bands of lines on threads. (numba's ``parallel=True`` took 25 s
    to compile this kernel the first time, against 9 s serial, for the same speed per core.)"""
    h, w = tgt_h, out.shape[1]
    last = first + out.shape[0]
    wx, wy, acc, value = np.empty(4), np.empty(4), np.empty(3), np.empty(3)
    m = slots(k_max)
    pfs, pxs, pys, pws = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)
    tile, scratch = np.empty((TILE, TILE)), _polar_scratch(k_max)
    rates = np.empty((3, 2, w), np.int64)
    for line in range(first, last):
        face, row = line // h, line % h
        _rate_rows(tgt_kind, tgt_axes, face, row, h, w, k, k_max, rotation, src_kind, src_axes, src_h, src_w,
                   line == first or row == 0, rates)
        for col in range(w):
            if not all_valid and tgt_valid[face, row, col] == 0:
                for c in range(3):
                    out[line - first, col, c] = 0.0
                continue
            here = _pixel_rates(rates, src_kind, tgt_kind, row, col, h, w, k, k_max)
            if not (_source_rim_marked(rates, row, col, k, k_max)
                    and _source_rim_value(src_kind, src, valid, src_axes, src_h, src_w, tgt_kind, tgt_axes, face,
                                          row, col, h, w, rotation, pfs, pxs, pys, pws, wx, wy, value, acc)):
                _pixel(src_kind, src, valid, levels, reduced, row_offsets, caps, src_axes, src_h, src_w, tgt_kind,
                       tgt_axes, face, row, col, h, w, here, rotation, pfs, pxs, pys, pws, wx, wy, value, tile,
                       scratch, acc, k_max if k_max > k else 0)
            for c in range(3):
                out[line - first, col, c] = acc[c]


@njit(cache=True, inline="always", error_model="numpy")
def _pixel(src_kind, src, valid, levels, reduced, row_offsets, caps, src_axes, src_h, src_w, tgt_kind, tgt_axes,
           face, row, col, h, w, rates, rotation, pfs, pxs, pys, pws, wx, wy, value, tile, scratch,
           acc, rim_k_max):  # pragma: no cover - compiled
    """``acc`` = the value of target pixel (face, row, col) of an h × w face at ``rates``
    (:func:`_subsamples`, ``rim_k_max`` as there; :func:`resample_into`'s arguments; the rest is scratch)."""
    n, wsum = _subsamples(tgt_kind, tgt_axes, np.int64(face), row, col, h, w, rates, rotation, src_kind, src_axes,
                          src_h, src_w, pfs, pxs, pys, pws, np.int64(rim_k_max))
    acc[0], acc[1], acc[2] = 0.0, 0.0, 0.0
    tiled = src_kind == LATLONG or src_kind == CUBE  # sources whose taps are all valid (no renormalisation)
    if not (tiled and _same_face(pfs, n)
            and _footprint(src, pfs[0], src_kind != LATLONG, levels, reduced, row_offsets, caps, pxs, pys,
                           pws, n, scratch, tile, acc)):
        for s in range(n):  # looked up one by one (compiled apart: it is the rarer path for these sources)
            value[0], value[1], value[2] = 0.0, 0.0, 0.0
            _lookup(src_kind, src, valid, levels, reduced, row_offsets, pfs[s], pxs[s], pys[s], wx, wy, value)
            for c in range(3):
                acc[c] += pws[s] * value[c]
    for c in range(3):
        acc[c] /= wsum


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def pixel_into(src_kind, src, valid, levels, reduced, row_offsets, caps, src_axes, src_h, src_w, tgt_kind, tgt_axes,
               face, row, col, h, w, k, rotation, pfs, pxs, pys, pws, wx, wy, value, tile, scratch,
               acc):  # pragma: no cover - compiled
    """:func:`_pixel` compiled apart at a fixed rate k, for kernels that need the general path for a rare pixel."""
    _pixel(src_kind, src, valid, levels, reduced, row_offsets, caps, src_axes, src_h, src_w, tgt_kind, tgt_axes,
           face, row, col, h, w, (k, k, k, k, k, k), rotation, pfs, pxs, pys, pws, wx, wy, value, tile, scratch,
           acc, False)


# ---- cached footprint weights ---------------------------------------------------------------------------------------
# The resampled map is linear in the source: each target pixel is Σ_j w_j · source[i_j] over its footprint's taps.
# For many maps of one geometry (a batch), the taps are computed once (footprint_taps) and each map is then one
# gather (apply_taps): the direct kernel's geometry and B-spline weights are not recomputed per map.

@njit(cache=True, inline="always", error_model="numpy")
def _latlong_index(row, col, h, w):  # pragma: no cover - compiled
    """Flat pixel index of a latlong tap that may lie past a pole or the seam."""
    row, col = _source_row_col(row, col, h, w)
    return row * w + col


@njit(cache=True, inline="always", error_model="numpy")
def _latlong_taps(levels, row_offsets, h, w, x, r0, wy, q, wx, idx, wts, t):  # pragma: no cover - compiled
    """The 16 taps of one B-spline lookup in a latlong (rows r0 … r0 + 3, as :func:`_lookup_latlong` reads them),
    weight ``q`` each, stored from ``t``; returns the next free slot."""
    for dy in range(4):
        row, level, width, shift = _row_frame(levels, h, w, r0 + dy)
        xr = _in_frame(x, level, width, w, shift)
        fx = math.floor(xr)
        _bspline_weights(xr - fx, wx)
        for dx in range(4):
            col = _wrapped_column(int(fx) - 1 + dx, width)
            idx[t] = row * w + col if level == 0 else h * w + row_offsets[row] + col
            wts[t] = q * wy[dy] * wx[dx]
            t += 1
    return t


@njit(cache=True, error_model="numpy")  # compiled apart: the kernels compile in half the time
def _polar_taps(levels, row_offsets, h, w, pxs, pys, pws, n, scale, scratch, tile, idx, wts):  # pragma: no cover
    """:func:`_polar_footprint` as taps (a reduced row's at H·W + its place in the reduced rows); returns how
    many, 0 if the footprint outgrows the tile."""
    r0, th = _polar_tile(levels, h, w, pxs, pys, pws, n, scale, scratch, tile)
    if th == 0:
        return 0
    c0s, tws = scratch[0], scratch[1]
    t = 0
    for ty in range(th):
        row, level, width, _ = _row_frame(levels, h, w, r0 + ty)
        for tx in range(tws[ty]):
            if tile[ty, tx] != 0.0:
                col = _wrapped_column(c0s[ty] + tx, width)
                idx[t] = row * w + col if level == 0 else h * w + row_offsets[row] + col
                wts[t] = tile[ty, tx]
                t += 1
    return t


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def footprint_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h, src_w, tgt_kind,
                   tgt_axes, tgt_h, tgt_w, tgt_valid, all_valid, k, k_max, rotation, first, idx, wts,
                   counts):  # pragma: no cover - compiled
    """The taps of target lines ``first`` … (one row of ``idx``/``wts``, (n_pixels, max_taps), per target pixel of
    the lines, row-major): source pixel indices (flat over the unpadded source grid) and weights whose sum over a
    pixel's taps reproduces :func:`resample_into` for any source values. ``src_shape`` is the shape of the image
    resample_into reads (unpadded latlong, or padded); ``index_map`` gives, for a padded image, the flat source
    index of every padded texel. Taps of one footprint tile are merged; a pixel looked up subsample by subsample
    lists its 16 taps per subsample (the apply sums repeats). ``counts`` gets each pixel's number of taps. A tap
    of a latlong's reduced polar row (``levels`` …, as for :func:`resample_into`) has index H·W + its place in the
    reduced rows (:func:`apply_taps` reads it there)."""
    h, w = tgt_h, tgt_w
    n_lines = counts.shape[0] // w
    m = slots(k_max)
    pfs, pxs, pys, pws = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)
    tile, scratch = np.empty((TILE, TILE)), _polar_scratch(k_max)
    wx, wy = np.empty(4), np.empty(4)
    rates = np.empty((3, 2, w), np.int64)
    for line in range(first, first + n_lines):
        face, row = line // h, line % h
        _rate_rows(tgt_kind, tgt_axes, face, row, h, w, k, k_max, rotation, src_kind, src_axes, src_h, src_w,
                   line == first or row == 0, rates)
        for col in range(w):
            p = (line - first) * w + col
            counts[p] = 0
            if not all_valid and tgt_valid[face, row, col] == 0:
                continue  # off a disc target (its rim direction's pixels may be marked: they stay 0, as resample_into)
            if _source_rim_marked(rates, row, col, k, k_max):
                counts[p] = -1  # listed apart, their taps merged (source_rim_taps): they outnumber a row
            else:
                counts[p] = _pixel_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes,
                                        src_h, src_w, tgt_kind, tgt_axes, h, w, k, k_max, rotation, face, row, col,
                                        rates, pfs, pxs, pys, pws, tile, scratch, wx, wy, idx[p], wts[p])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def footprint_delivery(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h, src_w,
                       tgt_kind, tgt_axes, tgt_h, tgt_w, tgt_valid, all_valid, k, k_max, rotation, first, last,
                       omega_t, max_taps, total, base):  # pragma: no cover - compiled
    """Σ_t Ω_t W_ts over target lines ``first`` … ``last − 1``, added into ``total`` (float64, indexed as
    :func:`footprint_taps`'s taps less ``base``; taps outside it are left out): each target pixel's taps,
    weighted by its solid angle ``omega_t`` (flat over lines first …; a pixel whose weight is 0 is skipped)
    — the energy a sun in every source pixel at once takes there, without listing the taps. A ``base`` past the
    source's pixels and a short ``total`` keep a span of a latlong's reduced polar rows alone
    (:mod:`lightprobe.maps.resampling.polar_balance`); a disc source's rim taps ignore both (0 and all for those)."""
    h, w = tgt_h, tgt_w
    m = slots(k_max)
    pfs, pxs, pys, pws = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)
    tile, scratch = np.empty((TILE, TILE)), _polar_scratch(k_max)
    wx, wy = np.empty(4), np.empty(4)
    rates = np.empty((3, 2, w), np.int64)
    idx, wts = np.empty(max_taps, np.int32), np.empty(max_taps, np.float32)
    for line in range(first, last):
        face, row = line // h, line % h
        _rate_rows(tgt_kind, tgt_axes, face, row, h, w, k, k_max, rotation, src_kind, src_axes, src_h, src_w,
                   line == first or row == 0, rates)
        for col in range(w):
            if not all_valid and tgt_valid[face, row, col] == 0:
                continue
            o = omega_t[(line - first) * w + col]
            if o == 0.0:
                continue
            if _source_rim_marked(rates, row, col, k, k_max) and _source_rim_taps_into(
                    src_kind, src_shape, valid, index_map, src_axes, src_h, src_w, tgt_kind, tgt_axes, face, row,
                    col, h, w, rotation, o, pfs, pxs, pys, pws, wx, wy, idx, wts, total):
                continue
            t = _pixel_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h,
                            src_w, tgt_kind, tgt_axes, h, w, k, k_max, rotation, face, row, col, rates, pfs, pxs,
                            pys, pws, tile, scratch, wx, wy, idx, wts)
            for j in range(t):
                i = idx[j] - base
                if 0 <= i < total.shape[0]:
                    total[i] += o * wts[j]


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _source_rim_taps_into(src_kind, src_shape, valid, index_map, src_axes, src_h, src_w, tgt_kind, tgt_axes, face, row,
                          col, h, w, rotation, scale, pfs, pxs, pys, pws, wx, wy, idx, wts,
                          total):  # pragma: no cover - compiled
    """Add the taps of a pixel sampled round a disc source's rim direction, times ``scale``, into ``total`` (flat
    over the source); False, nothing added, where no lookup falls in the pixel. ``idx``/``wts`` hold a chunk's taps
    (16 per lookup of ``pfs``)."""
    plan = _source_rim_plan(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_w)
    wsum = _source_rim_weight(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_h,
                              src_w, pfs, pxs, pys, pws)
    if wsum <= 0.0:
        return False
    levels, row_offsets = np.zeros(1, np.int64), np.zeros(1, np.int64)  # a disc source has no polar rows
    i, j = np.int64(0), np.int64(0)
    while i < plan[5]:
        n, _, i, j = _source_rim_chunk(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes,
                                       src_h, src_w, i, j, pfs, pxs, pys, pws)
        t = 0
        for s in range(n):
            t = _lookup_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, src_h, src_w, pfs[s], pxs[s],
                             pys[s], pws[s] / wsum, wx, wy, idx, wts, t)
        for q in range(t):
            total[idx[q]] += scale * wts[q]
    return True


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def source_rim_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h, src_w, tgt_kind,
                    tgt_axes, tgt_h, tgt_w, tgt_valid, all_valid, k, k_max, rotation, line, col, merged,
                    touched):  # pragma: no cover - compiled
    """The merged taps of target pixel (line, col), one :func:`footprint_taps` listed apart (count −1): their
    weights added into ``merged`` (float64, zero, flat over the source) and their indices, each once, into
    ``touched``; returns how many. The caller reads them and zeroes ``merged`` there again."""
    h, w = tgt_h, tgt_w
    face, row = line // h, line % h
    m = slots(k_max)
    pfs, pxs, pys, pws = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)
    wx, wy = np.empty(4), np.empty(4)
    idx, wts = np.empty(16 * m, np.int32), np.empty(16 * m, np.float32)
    t = 0
    plan = _source_rim_plan(tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_w)
    wsum = _source_rim_weight(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes, src_h,
                              src_w, pfs, pxs, pys, pws)
    if wsum <= 0.0:  # no lookup fell in it: its cells, as resample_into falls back to
        tile, scratch = np.empty((TILE, TILE)), _polar_scratch(k_max)
        rates = np.full((3, 2, w), k_max, np.int64)
        n = _pixel_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h, src_w,
                        tgt_kind, tgt_axes, h, w, k_max, k_max, rotation, face, row, col, rates, pfs, pxs, pys,
                        pws, tile, scratch, wx, wy, idx, wts)
        return _merged_taps(idx, wts, n, merged, touched, t)
    i, j = np.int64(0), np.int64(0)
    while i < plan[5]:
        n, _, i, j = _source_rim_chunk(plan, tgt_kind, tgt_axes, face, row, col, h, w, rotation, src_kind, src_axes,
                                       src_h, src_w, i, j, pfs, pxs, pys, pws)
        for s in range(n):
            c = _lookup_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, src_h, src_w, pfs[s], pxs[s],
                             pys[s], pws[s] / wsum, wx, wy, idx, wts, 0)
            t = _merged_taps(idx, wts, c, merged, touched, t)
    return t


@njit(cache=True, inline="always", error_model="numpy")
def _merged_taps(idx, wts, n, merged, touched, t):  # pragma: no cover - compiled
    """Add ``n`` taps into ``merged``, listing each index the first time it gains weight in ``touched`` from ``t``;
    returns the next free place there."""
    for q in range(n):
        if wts[q] == 0.0:
            continue
        if merged[idx[q]] == 0.0:
            touched[t] = idx[q]
            t += 1
        merged[idx[q]] += wts[q]
    return t


@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _pixel_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, caps, src_axes, src_h, src_w, tgt_kind,
                tgt_axes, h, w, k, k_max, rotation, face, row, col, rates, pfs, pxs, pys, pws, tile, scratch, wx, wy,
                idx, wts):  # pragma: no cover - compiled
    """One target pixel's taps into ``idx``/``wts`` (its row of the rates already in ``rates``); returns how many."""
    here = _pixel_rates(rates, src_kind, tgt_kind, row, col, h, w, k, k_max)
    n, wsum = _subsamples(tgt_kind, tgt_axes, np.int64(face), row, col, h, w, here, rotation, src_kind, src_axes,
                          src_h, src_w, pfs, pxs, pys, pws, np.int64(k_max if k_max > k else 0))
    scale = 1.0 / wsum
    t = -1
    if (src_kind == LATLONG or src_kind == CUBE) and _same_face(pfs, n):
        t = _tile_taps(src_kind, src_shape, index_map, levels, row_offsets, caps, src_h, src_w, pfs, pxs,
                       pys, pws, n, scale, scratch, tile, idx, wts)
    if t < 0:
        t = 0
        for s in range(n):  # subsample by subsample, as _lookup does
            t = _lookup_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, src_h, src_w,
                             pfs[s], pxs[s], pys[s], pws[s] * scale, wx, wy, idx, wts, t)
    return t


@njit(cache=True, inline="always", error_model="numpy")
def _tile_taps(src_kind, src_shape, index_map, levels, row_offsets, caps, src_h, src_w, pfs, pxs, pys, pws, n, scale,
               scratch, tile, idx, wts):  # pragma: no cover - compiled
    """One pixel's subsamples on one face as merged footprint taps (:func:`_footprint`'s tile, or the per-row
    tile near a latlong's poles), weights times ``scale``; returns how many, or −1 where the footprint does not
    fit a tile (the caller lists the subsamples one by one)."""
    pad = 0 if src_kind == LATLONG else 2
    c0, r0, tw, th = _tile_bounds(pxs, pys, n, pad)
    ok = tw <= TILE and th <= TILE
    if ok and not pad and (r0 < caps[0] or r0 + th > src_h - caps[1]):
        t = _polar_taps(levels, row_offsets, src_h, src_w, pxs, pys, pws, n, scale, scratch, tile, idx, wts)
        return t if t > 0 else -1
    if ok and pad:
        ok = r0 >= 0 and r0 + th <= src_shape[1] and c0 >= 0 and c0 + tw <= src_shape[2]
    if not ok:
        return -1
    _sum_into_tile(tile, pxs, pys, pws, n, scale, c0, r0, tw, th, pad)
    t = 0
    for ty in range(th):
        for tx in range(tw):
            if tile[ty, tx] != 0.0:
                if pad:
                    idx[t] = index_map[pfs[0], r0 + ty, c0 + tx]
                else:
                    idx[t] = _latlong_index(r0 + ty, c0 + tx, src_h, src_w)
                wts[t] = tile[ty, tx]
                t += 1
    return t


@njit(cache=True, inline="always", error_model="numpy")
def _lookup_taps(src_kind, src_shape, valid, index_map, levels, row_offsets, src_h, src_w, f, x, y, q, wx, wy, idx,
                 wts, t):  # pragma: no cover - compiled
    """The taps of one B-spline lookup at source position (f, x, y), weight ``q`` in all (renormalised over a
    disc's valid taps, as :func:`_lookup_padded` reads them), stored from ``t``; returns the next free slot."""
    fx, fy = math.floor(x), math.floor(y)
    _bspline_weights(x - fx, wx)
    _bspline_weights(y - fy, wy)
    if src_kind == LATLONG:
        wy[0], wy[1], wy[2], wy[3] = _pole_rows4(int(fy) - 1, src_h, wy[0], wy[1], wy[2], wy[3])
        return _latlong_taps(levels, row_offsets, src_h, src_w, x, int(fy) - 1, wy, q, wx, idx, wts, t)
    x0 = min(max(int(fx) + 1, 0), src_shape[2] - 4)  # padded: + 2, − 1 for the first tap
    y0 = min(max(int(fy) + 1, 0), src_shape[1] - 4)
    total = 0.0
    for dy in range(4):
        for dx in range(4):
            total += wy[dy] * wx[dx] * (1.0 if valid.shape[1] == 1 else valid[f, y0 + dy, x0 + dx])
    for dy in range(4):
        for dx in range(4):
            kk = wy[dy] * wx[dx] * (1.0 if valid.shape[1] == 1 else valid[f, y0 + dy, x0 + dx])
            if kk > 0.0:
                idx[t] = index_map[f, y0 + dy, x0 + dx]
                wts[t] = q * kk / total
                t += 1
    return t


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def apply_taps(src, reduced, offsets, idx, wts, out, first):  # pragma: no cover - compiled
    """out[p − first] = Σ_j wts[j] · src[idx[j]] for pixels p = first … first + len(out) − 1 (CSR ``offsets``);
    ``src`` is the source flattened to (pixels, 3); an index past it reads ``reduced`` (a latlong's reduced polar
    rows) at index − pixels."""
    n_src = src.shape[0]
    for p in range(first, first + out.shape[0]):
        r, g, b = 0.0, 0.0, 0.0
        for j in range(offsets[p], offsets[p + 1]):
            q = wts[j]
            i = idx[j]
            if i < n_src:
                r += q * src[i, 0]
                g += q * src[i, 1]
                b += q * src[i, 2]
            else:
                r += q * reduced[i - n_src, 0]
                g += q * reduced[i - n_src, 1]
                b += q * reduced[i - n_src, 2]
        out[p - first, 0] = r
        out[p - first, 1] = g
        out[p - first, 2] = b
