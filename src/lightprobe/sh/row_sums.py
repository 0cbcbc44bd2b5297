"""The azimuthal sums of a lat-long map's rows: the part of its SH projection that reads the pixels.

A lat-long row is a ring of constant θ, so its pixels enter every coefficient of order m only through
Σ_col L·cos(mφ_col) and Σ_col L·sin(mφ_col) (:func:`lightprobe.sh.basis.project` weights those per row). Conventions:

* ``img`` is the map's (H, W, 3) pixels, float32 or float64, C-contiguous; column ``col`` sits at azimuth
  φ_col = 2π((col + ½)/W − ½), the lat-long's own (its columns are the rings' azimuths about +Y);
* the sums of a row come in the order 0, then cos and sin of each m ≥ 1: (H, 2 l_max + 1, 3) float64, per channel;
* compiled kernels fold a row by the symmetries of its azimuths first (half a turn, then a mirror: W even for
  orders ≤ 2, divisible by 4 above); numpy's matrix products need neither and no numba.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..util.jit import njit, prange


def row_sums(img: np.ndarray, l_max: int, compiled: bool) -> np.ndarray:
    """Σ_col L cos(mφ_col) and Σ_col L sin(mφ_col) of every row, for the orders m ≤ ``l_max``.

    Parameters
    ----------
    img : numpy.ndarray
        (H, W, 3) C-contiguous radiance of a lat-long map; W even, and divisible by 4 when ``compiled`` and
        ``l_max`` > 2.
    l_max : int
        The highest order m summed, ≥ 0.
    compiled : bool
        True: the compiled kernels (one sweep over half of each row up to order 2, a row folded to a quarter
        above); False: numpy's matrix products.

    Returns
    -------
    numpy.ndarray
        (H, 2 l_max + 1, 3) float64: per row, order 0, then the cos and sin sums of each m ≥ 1, per channel.
    """
    h, w, _ = img.shape
    if not compiled:
        return _blas_row_sums(img, l_max)
    if l_max <= 2:  # SH9 and below: one sweep over half of each row (W = 2H is always even)
        full = np.empty((h, 5, 3))
        _latlong_row_sums_sh9(img, *_sh9_tables(w), full)
        return full[:, : 2 * l_max + 1]
    return _folded_row_sums(img, l_max)  # higher orders: fold each row to a quarter first (W divisible by 4)


@njit(cache=True, parallel=True, fastmath=True)
def _latlong_row_sums_folded(img, cos_even, sin_even, cos_odd, sin_odd, out):  # pragma: no cover - compiled
    """Per row r, the azimuthal sums Σ_col img·cos(mφ_col) and Σ img·sin(mφ_col) for every order m, from a quarter
    of the row, for W divisible by 4.

    The columns c, W−1−c, c+W/2 and W/2−1−c sit at azimuths φ, −φ, φ+π and π−φ, whose cos mφ and sin mφ differ
    only in sign: with pixels a, b, c, d there, Σ v cos mφ = (a + b ± (c + d)) cos mφ and
    Σ v sin mφ = (a − b ± (c − d)) sin mφ, the sign + for even m and − for odd m. The row is folded in two passes
    that each read whole runs of memory, so both vectorise: half a turn (e = a + c, o = a − c over the first W/2
    columns, into a plane per channel), then the mirror about φ = π/2 (e at c and W/2−1−c give a + b + c + d and
    a − b + c − d; o gives the odd orders' two). Each order's sum is then a dot product over the quarter's W/4
    columns against its row of the tables (n × W/4: cos/sin of the even orders 0, 2, … and of the odd orders
    1, 3, …). Folding a group of four pixels at a time, the orders innermost, took 2.3× this at order 8 (its
    short order loops and the pixels' interleaved channels kept it scalar). ``out`` (H, 4, 3, n): even-cos,
    even-sin, odd-cos, odd-sin sums per channel (slots past an order's count are left as they are)."""
    h, w, _ = img.shape
    q = w // 4
    half = w // 2
    for r in prange(h):
        even, odd = np.empty((3, half)), np.empty((3, half))
        for col in range(half):
            for ch in range(3):
                a = np.float64(img[r, col, ch])
                c = np.float64(img[r, col + half, ch])
                even[ch, col] = a + c
                odd[ch, col] = a - c
        folded = np.empty((4, 3, q))
        for ch in range(3):
            for col in range(q):
                near, far = even[ch, col], even[ch, half - 1 - col]
                folded[0, ch, col] = near + far  # a + b + c + d
                folded[1, ch, col] = near - far  # a − b + c − d
                near, far = odd[ch, col], odd[ch, half - 1 - col]
                folded[2, ch, col] = near - far  # a + b − c − d
                folded[3, ch, col] = near + far  # a − b − c + d
        for ch in range(3):
            _dot_rows(folded[0, ch], cos_even, out[r, 0, ch])
            _dot_rows(folded[1, ch], sin_even, out[r, 1, ch])
            _dot_rows(folded[2, ch], cos_odd, out[r, 2, ch])
            _dot_rows(folded[3, ch], sin_odd, out[r, 3, ch])


@njit(cache=True, inline="always", fastmath=True)
def _dot_rows(values, table, out):  # pragma: no cover - compiled
    """out[j] = Σ_col values[col] · table[j, col] for each row j of ``table`` (a loop the compiler vectorises)."""
    for j in range(table.shape[0]):
        total = 0.0
        for col in range(values.shape[0]):
            total += values[col] * table[j, col]
        out[j] = total


@lru_cache(maxsize=8)
def _folded_tables(w: int, l_max: int):
    """The folded kernel's tables for W columns (see :func:`_latlong_row_sums_folded`), and where each row sum
    (order 0, then cos and sin of each m ≥ 1) lies in its output: (kind, order slot) per sum."""
    phi = 2 * np.pi * ((np.arange(w // 4) + 0.5) / w - 0.5)
    even, odd = np.arange(0, l_max + 1, 2), np.arange(1, max(l_max, 1) + 1, 2)
    tables = [np.ascontiguousarray(fn(np.outer(m, phi))) for m in (even, odd) for fn in (np.cos, np.sin)]
    for t in tables:
        t.setflags(write=False)  # cached: shared by every later call
    kind, slot = [0], [0]
    for m in range(1, l_max + 1):
        kind += [0, 1] if m % 2 == 0 else [2, 3]
        slot += [m // 2] * 2
    return tables, max(len(even), len(odd)), np.array(kind), np.array(slot)


@lru_cache(maxsize=8)
def _sh9_tables(w: int) -> tuple[np.ndarray, np.ndarray]:
    """cos mφ and sin mφ, m = 0..2, of the first W/2 columns (the SH9 kernel's tables)."""
    phi = 2 * np.pi * ((np.arange(w // 2) + 0.5) / w - 0.5)
    m = np.arange(3)[:, None]
    tables = np.cos(m * phi), np.sin(m * phi)
    for t in tables:
        t.setflags(write=False)  # cached: shared by every later call
    return tables


def _folded_row_sums(img: np.ndarray, l_max: int) -> np.ndarray:
    """(H, 2 l_max + 1, 3) row sums (order 0, then cos and sin of each m ≥ 1) through the folded kernel."""
    (cos_even, sin_even, cos_odd, sin_odd), n, kind, slot = _folded_tables(img.shape[1], l_max)
    raw = np.empty((img.shape[0], 4, 3, n))
    _latlong_row_sums_folded(img, cos_even, sin_even, cos_odd, sin_odd, raw)
    return raw[:, kind, :, slot].transpose(1, 0, 2)  # (H, sums, 3)


def _blas_row_sums(img: np.ndarray, l_max: int) -> np.ndarray:
    """The same row sums as matrix products in numpy (float64, blocks of rows): no compiled kernel, for a process
    in which numba has not been loaded (its import costs more than this whole projection of a 2k map)."""
    h, w, _ = img.shape
    phi = 2 * np.pi * ((np.arange(w) + 0.5) / w - 0.5)
    m = np.arange(1, l_max + 1)[:, None]
    table = np.empty((2 * l_max + 1, w))
    table[0], table[1::2], table[2::2] = 1.0, np.cos(m * phi), np.sin(m * phi)
    sums = np.empty((h, 2 * l_max + 1, 3))
    rows = max(1, (1 << 20) // (3 * w))  # 8 MB of float64 a block
    for top in range(0, h, rows):
        sums[top:top + rows] = np.matmul(table[None], img[top:top + rows].astype(np.float64))
    return sums


@njit(cache=True, parallel=True, fastmath=True)
def _latlong_row_sums_sh9(img, cos_table, sin_table, out):  # pragma: no cover - compiled
    """Orders m ≤ 2 (SH9) for even W in one sweep over half of each row: columns c and c + W/2 sit at φ and φ + π,
    so with s = a + c and t = a − c the sums are Σ s, Σ t cos φ, Σ t sin φ, Σ s cos 2φ, Σ s sin 2φ over the first
    half. Fifteen scalar accumulators and no buffers; tables hold the first W/2 columns, orders 0..2."""
    h, w, _ = img.shape
    half = w // 2
    for r in prange(h):
        s0 = s1 = s2 = 0.0
        c10 = c11 = c12 = 0.0
        n10 = n11 = n12 = 0.0
        c20 = c21 = c22 = 0.0
        n20 = n21 = n22 = 0.0
        for col in range(half):
            cos1 = cos_table[1, col]
            sin1 = sin_table[1, col]
            cos2 = cos_table[2, col]
            sin2 = sin_table[2, col]
            a0 = np.float64(img[r, col, 0])
            a1 = np.float64(img[r, col, 1])
            a2 = np.float64(img[r, col, 2])
            b0 = np.float64(img[r, col + half, 0])
            b1 = np.float64(img[r, col + half, 1])
            b2 = np.float64(img[r, col + half, 2])
            e0 = a0 + b0
            e1 = a1 + b1
            e2 = a2 + b2
            d0 = a0 - b0
            d1 = a1 - b1
            d2 = a2 - b2
            s0 += e0
            s1 += e1
            s2 += e2
            c10 += d0 * cos1
            c11 += d1 * cos1
            c12 += d2 * cos1
            n10 += d0 * sin1
            n11 += d1 * sin1
            n12 += d2 * sin1
            c20 += e0 * cos2
            c21 += e1 * cos2
            c22 += e2 * cos2
            n20 += e0 * sin2
            n21 += e1 * sin2
            n22 += e2 * sin2
        out[r, 0, 0] = s0
        out[r, 0, 1] = s1
        out[r, 0, 2] = s2
        out[r, 1, 0] = c10
        out[r, 1, 1] = c11
        out[r, 1, 2] = c12
        out[r, 2, 0] = n10
        out[r, 2, 1] = n11
        out[r, 2, 2] = n12
        out[r, 3, 0] = c20
        out[r, 3, 1] = c21
        out[r, 3, 2] = c22
        out[r, 4, 0] = n20
        out[r, 4, 1] = n21
        out[r, 4, 2] = n22
