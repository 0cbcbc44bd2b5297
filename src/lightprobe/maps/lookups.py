"""Numba kernels for image lookups (compiled once, cached on disk).

All kernels read a *padded* image ``img`` of shape (F, H + 2p, W + 2p, C) and its validity ``valid`` (same without
C): the border of p texels holds the neighbouring pixels across seams and poles (see
:meth:`lightprobe.maps.layouts.Layout.padded`), so the kernels need no knowledge of layouts. Sample coordinates ``x, y``
are in padded pixel units (the centre of padded column c is x = c). Taps with ``valid == 0`` carry no weight and the
remaining weights are renormalised, so a disc's black corners never bleed into it.
"""

from __future__ import annotations

import numpy as np

from ..util.jit import import_numba, use_threads

numba = import_numba()
njit, prange = numba.njit, numba.prange
use_threads()  # LIGHTPROBE_THREADS, as for the kernels compiled through lightprobe.util.jit


@njit(cache=True, parallel=True, fastmath=False)
def gather_bilinear(img, valid, face, x, y, out):  # pragma: no cover - compiled
    nf, hp, wp, nc = img.shape
    for i in prange(x.shape[0]):
        fx, fy = np.floor(x[i]), np.floor(y[i])
        tx, ty = x[i] - fx, y[i] - fy
        x0 = min(max(int(fx), 0), wp - 2)
        y0 = min(max(int(fy), 0), hp - 2)
        f = face[i]
        wsum = 0.0
        acc = np.zeros(nc)
        for dy in range(2):
            wy = ty if dy else 1.0 - ty
            for dx in range(2):
                w = wy * (tx if dx else 1.0 - tx) * valid[f, y0 + dy, x0 + dx]
                if w > 0.0:
                    wsum += w
                    for c in range(nc):
                        acc[c] += w * img[f, y0 + dy, x0 + dx, c]
        for c in range(nc):
            out[i, c] = acc[c] / wsum if wsum > 0.0 else 0.0


@njit(cache=True, inline="always")
def _bspline3(t, k):  # pragma: no cover - compiled
    """Weight of tap k (0..3, at offsets −1..2) of the uniform cubic B-spline at fraction t ∈ [0, 1)."""
    if k == 0:
        return (1.0 - t) ** 3 / 6.0
    if k == 1:
        return (3.0 * t**3 - 6.0 * t**2 + 4.0) / 6.0
    if k == 2:
        return (-3.0 * t**3 + 3.0 * t**2 + 3.0 * t + 1.0) / 6.0
    return t**3 / 6.0


@njit(cache=True, parallel=True, fastmath=False)
def gather_bspline(img, valid, face, x, y, out):  # pragma: no cover - compiled
    """Cubic B-spline (approximating, σ ≈ 0.58 px) lookup: its spectrum falls as sinc⁴, so sums of lookups
    on any lattice finer than half a pixel integrate the image (even a one-pixel sun) to about 0.1 %."""
    nf, hp, wp, nc = img.shape
    for i in prange(x.shape[0]):
        fx, fy = np.floor(x[i]), np.floor(y[i])
        tx, ty = x[i] - fx, y[i] - fy
        x0 = min(max(int(fx) - 1, 0), wp - 4)
        y0 = min(max(int(fy) - 1, 0), hp - 4)
        f = face[i]
        wsum = 0.0
        acc = np.zeros(nc)
        for dy in range(4):
            wy = _bspline3(ty, dy)
            for dx in range(4):
                w = wy * _bspline3(tx, dx) * valid[f, y0 + dy, x0 + dx]
                if w > 0.0:
                    wsum += w
                    for c in range(nc):
                        acc[c] += w * img[f, y0 + dy, x0 + dx, c]
        for c in range(nc):
            out[i, c] = acc[c] / wsum if wsum > 0.0 else 0.0


def gather(img: np.ndarray, valid: np.ndarray, face, x, y, kernel: str = "bilinear") -> np.ndarray:
    """Look up ``img`` at padded pixel coordinates; any leading shape of ``face, x, y``; returns (..., C) float32."""
    shape = np.shape(x)
    face = np.ascontiguousarray(np.broadcast_to(face, shape), dtype=np.int64).ravel()
    xs = np.ascontiguousarray(x, dtype=np.float64).ravel()
    ys = np.ascontiguousarray(y, dtype=np.float64).ravel()
    out = np.empty((xs.size, img.shape[-1]), dtype=np.float32)
    fn = gather_bspline if kernel == "bspline" else gather_bilinear
    fn(img, valid, face, xs, ys, out)
    return out.reshape(shape + (img.shape[-1],))


@njit(cache=True, parallel=True, fastmath=True)
def clamped_cosine_sums(normals, dirs_t, weights_t, out):  # pragma: no cover - compiled
    """out[t] = Σ_s max(n_t · d_s, 0) w_s for every normal t: the brute-force irradiance sum, O(T·S).

    ``dirs_t`` and ``weights_t`` are (3, S) float32 (structure of arrays, so the inner loop vectorises). Products
    are float32; each block of 4096 terms is added into a float64 total, which keeps ~1e-7 relative accuracy."""
    n_normals = normals.shape[0]
    n_dirs = dirs_t.shape[1]
    dx, dy, dz = dirs_t[0], dirs_t[1], dirs_t[2]
    w0, w1, w2 = weights_t[0], weights_t[1], weights_t[2]
    for t in prange(n_normals):
        nx = np.float32(normals[t, 0])
        ny = np.float32(normals[t, 1])
        nz = np.float32(normals[t, 2])
        total0 = 0.0
        total1 = 0.0
        total2 = 0.0
        for start in range(0, n_dirs, 4096):
            a0 = np.float32(0.0)
            a1 = np.float32(0.0)
            a2 = np.float32(0.0)
            for s in range(start, min(start + 4096, n_dirs)):
                c = max(nx * dx[s] + ny * dy[s] + nz * dz[s], np.float32(0.0))
                a0 += c * w0[s]
                a1 += c * w1[s]
                a2 += c * w2[s]
            total0 += a0
            total1 += a1
            total2 += a2
        out[t, 0] = total0
        out[t, 1] = total1
        out[t, 2] = total2


@njit(cache=True, parallel=True, fastmath=True)
def ggx_lobe_sums(r, dirs_t, omega, values_t, alpha, below, out):  # pragma: no cover - compiled
    """out[t] = (Σ_s k_t(s) v_s, Σ_s k_t(s)) with k_t(s) = D_α(h) (r_t·d_s)⁺ ω_s, h halfway between r_t and d_s,
    summed over the s with r_t·d_s < ``below``: the GGX prefilter's direct sum (n = v = r), O(T·S).

    ``dirs_t`` (3, S) and ``values_t`` (3, S) float32, ``omega`` (S,) float32 (structure of arrays); ``out`` (T, 4)
    float64, the sums kept in float64. cos²θ_h = (1 + r·d)/2, D = α²/(π (cos²θ_h (α² − 1) + 1)²)."""
    scale = alpha * alpha / np.pi
    am1 = alpha * alpha - 1.0
    for t in prange(r.shape[0]):
        sums = np.zeros(4)
        for s in range(dirs_t.shape[1]):
            c = r[t, 0] * dirs_t[0, s] + r[t, 1] * dirs_t[1, s] + r[t, 2] * dirs_t[2, s]
            if 0.0 < c < below:
                q = (1.0 + c) * 0.5 * am1 + 1.0
                w = scale / (q * q) * c * omega[s]
                for k in range(3):
                    sums[k] += w * values_t[k, s]
                sums[3] += w
        out[t, :] = sums

