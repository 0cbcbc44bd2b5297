"""Shadow-ray samples for the lighting methods, built by compiled kernels from numpy's seeded uniforms.

The random numbers come from a ``numpy.random.Generator`` (so a render is reproducible bit for bit from its seed,
whatever the thread count); the kernels only turn them into directions, in one sequential pass per batch (a few ms
per million rays and core: numpy's temporaries cost ~10× that, more than Embree spends tracing them).

Stratification: each point's n samples form a Latin hypercube — the first coordinate in n strata in order, the
second in n strata in a random order (a Fisher–Yates shuffle drawn from the point's own uniforms), both jittered.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, prange


def uniforms(rng: np.random.Generator, points: int, n: int) -> np.ndarray:
    """The (points, n, 3) float32 uniforms in [0, 1) one batch of :func:`cap_rays` or :func:`cosine_rays`
    consumes."""
    return rng.random((points, n, 3), dtype=np.float32)


@njit(cache=True, inline="always")
def _latin(uni, p, n, k, order):  # pragma: no cover - compiled
    """(u, v) of sample k of point p: u in stratum k, v in stratum order[k] (a shuffled 0..n-1)."""
    return (k + uni[p, k, 0]) / n, (order[k] + uni[p, k, 1]) / n


@njit(cache=True, inline="always")
def _shuffle(uni, p, n, order):  # pragma: no cover - compiled
    for k in range(n):
        order[k] = k
    for k in range(n - 1, 0, -1):
        j = min(k, int(uni[p, k, 2] * (k + 1)))
        order[k], order[j] = order[j], order[k]


@njit(cache=True, parallel=True)
def cap_rays(normals, origins, axis, t, s, cos_r, uni, ray_orig, ray_dir, cosine):  # pragma: no cover
    """Directions uniform in solid angle over the cap (``axis``, frame t, s; cos of its radius ``cos_r``) for every
    point, sample k of point p in row p·n + k: cos θ = 1 − u (1 − cos r), φ = 2πv. ``cosine`` gets n·ω, ≤ 0 for the
    samples below the point's shading horizon (which need no ray)."""
    points, n = uni.shape[0], uni.shape[1]
    for p in prange(points):
        order = np.empty(n, np.int64)
        _shuffle(uni, p, n, order)
        for k in range(n):
            u, v = _latin(uni, p, n, k, order)
            ct = 1.0 - u * (1.0 - cos_r)
            st = math.sqrt(max(0.0, 1.0 - ct * ct))
            cp, sp = math.cos(2 * math.pi * v), math.sin(2 * math.pi * v)
            i = p * n + k
            c = 0.0
            for j in range(3):
                w = st * cp * t[j] + st * sp * s[j] + ct * axis[j]
                ray_dir[i, j] = w
                ray_orig[i, j] = origins[p, j]
                c += normals[p, j] * w
            cosine[i] = c


@njit(cache=True, parallel=True)
def cosine_rays(normals, tangents, bitangents, origins, uni, table, ray_orig, ray_dir, weight):  # pragma: no cover
    """Cosine-weighted directions about each point's normal (Malley: the stratified disc point lifted to the
    hemisphere), n per point in order, each with the bilinear lookup of ``table`` (a lat-long, rows from +Y, column
    0 at azimuth −π from the front −Z) in its direction as its weight."""
    points, n = uni.shape[0], uni.shape[1]
    h, w = table.shape
    for p in prange(points):
        order = np.empty(n, np.int64)
        _shuffle(uni, p, n, order)
        for k in range(n):
            u, v = _latin(uni, p, n, k, order)
            r = math.sqrt(u)
            up = math.sqrt(max(0.0, 1.0 - u))
            a, b = r * math.cos(2 * math.pi * v), r * math.sin(2 * math.pi * v)
            i = p * n + k
            for j in range(3):
                ray_dir[i, j] = a * tangents[p, j] + b * bitangents[p, j] + up * normals[p, j]
                ray_orig[i, j] = origins[p, j]
            theta = math.acos(min(1.0, max(-1.0, ray_dir[i, 1])))
            phi = math.atan2(ray_dir[i, 0], -ray_dir[i, 2])
            y = theta / math.pi * h - 0.5
            x = (phi / (2 * math.pi) + 0.5) * w - 0.5
            y0, x0 = math.floor(y), math.floor(x)
            fy, fx = y - y0, x - x0
            r0, r1 = min(max(int(y0), 0), h - 1), min(max(int(y0) + 1, 0), h - 1)
            c0, c1 = int(x0) % w, (int(x0) + 1) % w
            weight[i] = ((1 - fy) * ((1 - fx) * table[r0, c0] + fx * table[r0, c1])
                         + fy * ((1 - fx) * table[r1, c0] + fx * table[r1, c1]))
