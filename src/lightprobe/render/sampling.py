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


@njit(cache=True, inline="always")
def _enters_box(o0, o1, o2, i0, i1, i2, boxes, b):  # pragma: no cover - compiled
    """Whether the ray o + t·w, t ≥ 0, meets box ``b`` of ``boxes`` (B, 2, 3): the slab test, with i = 1/w per
    axis (±inf where w is 0: the slab's bounds then give ±inf, or NaN for an origin on a face, which max/min
    below skip, so the ray counts as inside that slab — conservative)."""
    near, far = 0.0, math.inf
    for j, o, inv in ((0, o0, i0), (1, o1, i1), (2, o2, i2)):
        t1, t2 = (boxes[b, 0, j] - o) * inv, (boxes[b, 1, j] - o) * inv
        if t1 > t2:
            t1, t2 = t2, t1
        if t1 > near:
            near = t1
        if t2 < far:
            far = t2
        if near > far:
            return False
    return True


@njit(cache=True, inline="always")
def may_hit(o0, o1, o2, w0, w1, w2, planes, roots, ranges, leaves):  # pragma: no cover - compiled
    """False only if the ray from o along w can hit no mesh of the scene (bounds of
    :func:`lightprobe.render.raycast._ray_bounds`): a flat mesh only by a ray heading into its plane; another mesh
    only by a ray entering its box and one of its triangle groups' boxes (a ray from inside its box always may)."""
    for i in range(planes.shape[0]):
        side = o0 * planes[i, 0] + o1 * planes[i, 1] + o2 * planes[i, 2] - planes[i, 3]
        toward = w0 * planes[i, 0] + w1 * planes[i, 1] + w2 * planes[i, 2]
        if not ((side > 0 and toward >= 0) or (side < 0 and toward <= 0)):
            return True
    i0 = 1.0 / w0 if w0 != 0.0 else math.copysign(math.inf, w0)
    i1 = 1.0 / w1 if w1 != 0.0 else math.copysign(math.inf, w1)
    i2 = 1.0 / w2 if w2 != 0.0 else math.copysign(math.inf, w2)
    for i in range(roots.shape[0]):
        if (roots[i, 0, 0] <= o0 <= roots[i, 1, 0] and roots[i, 0, 1] <= o1 <= roots[i, 1, 1]
                and roots[i, 0, 2] <= o2 <= roots[i, 1, 2]):
            return True
        if _enters_box(o0, o1, o2, i0, i1, i2, roots, i):
            for k in range(ranges[i, 0], ranges[i, 1]):
                if _enters_box(o0, o1, o2, i0, i1, i2, leaves, k):
                    return True
    return False


@njit(cache=True, inline="always")
def _queued(o0, o1, o2, w0, w1, w2, value, planes, roots, ranges, leaves, i, ray_orig, ray_dir,
            values):  # pragma: no cover - compiled
    """Write the ray (o, w) and its value to row i if :func:`may_hit` says it may be blocked; whether it did."""
    if not may_hit(o0, o1, o2, w0, w1, w2, planes, roots, ranges, leaves):
        return False
    ray_dir[i, 0], ray_dir[i, 1], ray_dir[i, 2] = w0, w1, w2
    ray_orig[i, 0], ray_orig[i, 1], ray_orig[i, 2] = o0, o1, o2
    values[i] = value
    return True


@njit(cache=True, parallel=True)
def _rays_may_hit(o, w, planes, roots, ranges, leaves, out):  # pragma: no cover - compiled
    for i in prange(o.shape[0]):
        out[i] = may_hit(o[i, 0], o[i, 1], o[i, 2], w[i, 0], w[i, 1], w[i, 2], planes, roots, ranges, leaves)


def rays_may_hit(origins: np.ndarray, directions: np.ndarray, bounds) -> np.ndarray:
    """:func:`may_hit` for each ray (N, 3 each) against a tracer's ``ray_bounds``: False where no mesh can be hit."""
    out = np.empty(len(origins), dtype=np.bool_)
    _rays_may_hit(np.ascontiguousarray(origins, np.float64), np.ascontiguousarray(directions, np.float64), *bounds,
                  out)
    return out


@njit(cache=True, parallel=True)
def cap_rays(normals, origins, axis, t, s, cos_r, uni, planes, roots, ranges, leaves, ray_orig, ray_dir, cosine,
             traced, free):  # pragma: no cover - compiled
    """The n samples of each point p over the cap (``axis``, frame t, s; cos of its radius ``cos_r``), uniform in
    solid angle — cos θ = 1 − u (1 − cos r), φ = 2πv — sorted three ways: below the point's shading horizon
    (n·ω ≤ 0: no light, no ray), free (:func:`may_hit` says nothing can block them: n·ω added to ``free[p]``), or
    to trace: the first ``traced[p]`` rows of the point's n rows p·n… of ray_orig, ray_dir, with n·ω in
    ``cosine`` (:func:`compact` gathers them)."""
    points, n = uni.shape[0], uni.shape[1]
    for p in prange(points):
        order = np.empty(n, np.int64)
        _shuffle(uni, p, n, order)
        o0, o1, o2 = origins[p, 0], origins[p, 1], origins[p, 2]
        count, free_sum = 0, 0.0
        for k in range(n):
            u, v = _latin(uni, p, n, k, order)
            ct = 1.0 - u * (1.0 - cos_r)
            st = math.sqrt(max(0.0, 1.0 - ct * ct))
            cp, sp = st * math.cos(2 * math.pi * v), st * math.sin(2 * math.pi * v)
            w0 = cp * t[0] + sp * s[0] + ct * axis[0]
            w1 = cp * t[1] + sp * s[1] + ct * axis[1]
            w2 = cp * t[2] + sp * s[2] + ct * axis[2]
            c = normals[p, 0] * w0 + normals[p, 1] * w1 + normals[p, 2] * w2
            if c <= 0.0:
                continue
            if _queued(o0, o1, o2, w0, w1, w2, c, planes, roots, ranges, leaves, p * n + count, ray_orig, ray_dir,
                       cosine):
                count += 1
            else:
                free_sum += c
        traced[p], free[p] = count, free_sum


@njit(cache=True, parallel=True)
def compact(n, offsets, ray_orig, ray_dir, cosine, out_orig, out_dir, out_cosine):  # pragma: no cover - compiled
    """Rows p·n … p·n + (offsets[p+1] − offsets[p]) − 1 of each point's block to rows offsets[p]… of the outputs."""
    for p in prange(offsets.shape[0] - 1):
        for j in range(offsets[p + 1] - offsets[p]):
            src, dst = p * n + j, offsets[p] + j
            for c in range(3):
                out_orig[dst, c] = ray_orig[src, c]
                out_dir[dst, c] = ray_dir[src, c]
            out_cosine[dst] = cosine[src]


@njit(cache=True, parallel=True)
def cosine_rays(normals, tangents, bitangents, origins, uni, table, planes, roots, ranges, leaves, ray_orig,
                ray_dir, weight, traced, free, total):  # pragma: no cover - compiled
    """Cosine-weighted directions about each point's normal (Malley: the stratified disc point lifted to the
    hemisphere), n per point, each weighted by the bilinear lookup of ``table`` (a lat-long, rows from +Y, column
    0 at azimuth −π from the front −Z) in its direction. ``total[p]`` gets the sum of point p's weights, ``free[p]``
    the sum over the rays :func:`may_hit` rules out; the others, ``traced[p]`` of them, fill the first rows of the
    point's n rows p·n… of ray_orig, ray_dir, with their weights (:func:`compact` gathers them)."""
    points, n = uni.shape[0], uni.shape[1]
    h, w = table.shape
    for p in prange(points):
        order = np.empty(n, np.int64)
        _shuffle(uni, p, n, order)
        o0, o1, o2 = origins[p, 0], origins[p, 1], origins[p, 2]
        count, free_sum, sum_all = 0, 0.0, 0.0
        for k in range(n):
            u, v = _latin(uni, p, n, k, order)
            r = math.sqrt(u)
            up = math.sqrt(max(0.0, 1.0 - u))
            a, b = r * math.cos(2 * math.pi * v), r * math.sin(2 * math.pi * v)
            w0 = a * tangents[p, 0] + b * bitangents[p, 0] + up * normals[p, 0]
            w1 = a * tangents[p, 1] + b * bitangents[p, 1] + up * normals[p, 1]
            w2 = a * tangents[p, 2] + b * bitangents[p, 2] + up * normals[p, 2]
            theta = math.acos(min(1.0, max(-1.0, w1)))
            phi = math.atan2(w0, -w2)
            y = theta / math.pi * h - 0.5
            x = (phi / (2 * math.pi) + 0.5) * w - 0.5
            y0, x0 = math.floor(y), math.floor(x)
            fy, fx = y - y0, x - x0
            r0, r1 = min(max(int(y0), 0), h - 1), min(max(int(y0) + 1, 0), h - 1)
            c0, c1 = int(x0) % w, (int(x0) + 1) % w
            value = ((1 - fy) * ((1 - fx) * table[r0, c0] + fx * table[r0, c1])
                     + fy * ((1 - fx) * table[r1, c0] + fx * table[r1, c1]))
            sum_all += value
            if _queued(o0, o1, o2, w0, w1, w2, value, planes, roots, ranges, leaves, p * n + count, ray_orig,
                       ray_dir, weight):
                count += 1
            else:
                free_sum += value
        traced[p], free[p], total[p] = count, free_sum, sum_all
