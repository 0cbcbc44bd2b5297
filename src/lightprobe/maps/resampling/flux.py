"""A conversion's flux correction: the pre-filter after which a sun in any source pixel keeps its energy exactly.

A resampling is linear: a sun wholly in source pixel j reaches the target as column j of the weights, and its energy
there is D_j = Σ_t Ω_t W_tj (:func:`lightprobe.maps.resampling.taps.delivered`). It should be the pixel's solid angle Ω_j.
What is left between the two after the texel balance (:mod:`lightprobe.maps.resampling.balance`) is the target's quadrature:
k×k subsamples per target pixel sum a spline that is not constant over the pixel — a cube's corner texels seen from
a lat-long of 32 rows (2.4 %), a disc target's coarse pixels (1.8 %), the rings where the per-pixel rate steps
(0.2–0.4 %), a lat-long's pixels read by the 20–40° rim rings of a 16–32-pixel disc (0.26–0.74 %). It depends on
the pair of grids, so it is measured for the pair, and the source is pre-filtered so that every pixel's effective
delivery is Ω_j (which conversions are: :func:`_flux_corrects`):

    x'_p = x_p + Σ_q w_pq (x_q − x_p),   w_pq ≥ 0 on the grid's edges (and a cube's seams), Σ_q w_pq < 1.

Pixel p then serves part of its neighbour q's value: q's delivery gains D_p w_pq and p's loses as much — a flow of
delivery along the edge p → q. A flow whose net inflow at every pixel is Ω_j − D_j makes every delivery exact, and
in this difference form a uniform map stays exactly uniform (every difference is 0) and a positive map positive.

The flow is built top-down on a quadtree of each face (:func:`_face_flows`): at each block, the flows between its
four children that leave each child's total demand at zero, spread along their shared boundary in proportion to each
pair's capacity min(D_p, D_q); a block's children are then blocks of the next level, down to single pixels. Every
edge belongs to one level, the work is a few passes over the pixels, and the result is exact to float rounding. A
cube's faces first exchange their totals over their seams (a 6-node Laplacian). Every pixel is corrected, a disc
source's to its rim direction (one direction spread over rings of pixels, which the conversion reads round that
direction: :data:`lightprobe.maps.resampling.fused.SOURCE_RIM_MARK`; an angular source's pixels within 20° of it were once left
alone, up to 3000 % off, as read they were too uneven for the flow). Weights stay small: 0.5–4 % at
the worst pixel at the sizes maps are converted at (benchmarks/bench_energy.py --part flux), up to 30 % for 20-pixel
mirror balls; over 50 % only for a few dozen pixels by a rim direction (up to 95 % in a mirror ball's outer
rings); a pixel's total is capped at :data:`MAX_WEIGHT`, so the blend stays convex whatever the input.

A conversion's correction is measured from the kernel's adjoint (its deliveries) when the conversion is first made and
kept for the last pairs of grids (:func:`_flux_stencil`)."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from ..envmap import pixel_solid_angles
from ..layout_base import _padding_index
from ..layouts import CUBE, Layout
from . import pole_rows
from .taps import DISCS, _face_layout, _raw_pixel_delivery

MAX_WEIGHT = 0.95  # a pixel's weights are scaled down to this total where a flow through it would exceed it. Only
#                   pixels by a rim direction need over 0.5 (a few dozen, within 18° of it): the source pixels a
#                   disc target's rim reads up to 0.6 (lat-long 128 → mirror ball 64; 13 % off at 0.5), a disc
#                   source's ring round its rim direction up to 0.82 (mirror ball 1024 → cube 128; 0.69 angular
#                   1024 → cube 256). A mirror ball's rings needed 0.95 before they were read round that direction


@dataclass(frozen=True)
class Stencil:
    """Non-negative weights of the pre-filter x'_p = x_p + Σ_q w_pq (x_q − x_p) on a (F, H, W) source grid:
    ``right`` (F, H, W−1): pixel (r, c) reads (r, c+1); ``left``: (r, c+1) reads (r, c); ``down`` (F, H−1, W): (r, c)
    reads (r+1, c); ``up``: (r+1, c) reads (r, c); ``seams`` (reader, read, weight) over flat pixel indices for a
    cube's pairs across its edges. float32, as the pixels they blend."""

    right: np.ndarray
    left: np.ndarray
    down: np.ndarray
    up: np.ndarray
    seams: tuple[np.ndarray, np.ndarray, np.ndarray]
    residual: float  # the largest |Ω_j − effective delivery| / Ω_j left among the corrected pixels (float rounding)

    def apply(self, pixels: np.ndarray) -> np.ndarray:
        """The pre-filtered pixels, float32, from ``pixels`` of the source's grid and C channels ((F,) H, W, C)."""
        x = np.asarray(pixels, dtype=np.float32)
        shape = x.shape
        x = x.reshape((-1,) + shape[-3:])
        out = x.copy()
        for f in range(x.shape[0]):  # a face at a time: the differences are the pass's only temporaries
            dx = x[f, :, 1:] - x[f, :, :-1]
            out[f, :, :-1] += self.right[f, ..., None] * dx
            out[f, :, 1:] -= self.left[f, ..., None] * dx
            del dx
            dy = x[f, 1:] - x[f, :-1]
            out[f, :-1] += self.down[f, ..., None] * dy
            out[f, 1:] -= self.up[f, ..., None] * dy
        reader, read, weight = self.seams
        if reader.size:
            flat, src = out.reshape(-1, x.shape[-1]), x.reshape(-1, x.shape[-1])
            np.add.at(flat, reader, weight[:, None] * (src[read] - src[reader]))
        return out.reshape(shape)

    def delivered(self, per_pixel: np.ndarray) -> np.ndarray:
        """Each source pixel's delivery through the pre-filter, from the delivery ``per_pixel`` ((F,) H, W) of the
        pixels the conversion reads: the transpose of :meth:`apply` (pixel p's weight w_pq moves D_p w_pq to q)."""
        shape = np.shape(per_pixel)
        d = np.asarray(per_pixel, dtype=np.float64).reshape((-1,) + shape[-2:])
        out = d.copy()
        for weights, reader, read in ((self.right, (slice(None), slice(None), slice(None, -1)),
                                       (slice(None), slice(None), slice(1, None))),
                                      (self.left, (slice(None), slice(None), slice(1, None)),
                                       (slice(None), slice(None), slice(None, -1))),
                                      (self.down, (slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                                      (self.up, (slice(None), slice(1, None)), (slice(None), slice(None, -1)))):
            moved = weights * d[reader]
            out[read] += moved
            out[reader] -= moved
        p, q, w = self.seams
        if p.size:
            flat, moved = out.reshape(-1), w * d.reshape(-1)[p]
            np.add.at(flat, q, moved)
            np.add.at(flat, p, -moved)
        return out.reshape(shape)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.right, self.left, self.down, self.up, *self.seams))

    @property
    def largest_weight(self) -> float:
        """The largest total weight a pixel gives its neighbours (how far the pre-filter is from the identity)."""
        return float(self.totals().max(initial=0.0))

    def totals(self) -> np.ndarray:
        """Each pixel's total weight (F, H, W): 1 minus what its own value keeps."""
        total = np.zeros(self.right.shape[:2] + (self.right.shape[2] + 1,))
        total[:, :, :-1] += self.right
        total[:, :, 1:] += self.left
        total[:, :-1] += self.down
        total[:, 1:] += self.up
        reader, _, weight = self.seams
        np.add.at(total.reshape(-1), reader, weight)
        return total


def stencil_for(layout: Layout, delivery: np.ndarray, omega: np.ndarray) -> Stencil:
    """The pre-filter that makes every pixel's delivery its solid angle, for a source of ``layout`` whose pixels'
    deliveries are ``delivery`` and solid angles ``omega`` (both (F, H, W) float64, the grid the conversion reads;
    0 where a pixel covers no sphere). The total delivery must equal the total solid angle (so it does for any
    conversion that keeps a uniform map uniform)."""
    delivery = np.where(omega > 0, delivery, 0.0)
    demand = np.where(delivery > 0, omega - delivery, 0.0)  # the inflow each pixel needs
    demand = demand - demand.sum() * delivery / delivery.sum()  # float rounding of the totals, spread
    faces, h, w = delivery.shape
    flow_h, flow_v = np.zeros((faces, h, w - 1)), np.zeros((faces, h - 1, w))
    seams = _no_seams()
    if faces == 6 and layout.name == "cube":
        seams = _cube_seams(delivery, demand, h)
    _face_flows(delivery, demand, flow_h, flow_v)
    del demand
    stencil = _convex(_stencil(delivery, flow_h, flow_v, seams))
    del flow_h, flow_v
    effective = stencil.delivered(delivery)
    corrected = omega > 0
    error = np.abs(effective - omega)[corrected] / omega[corrected]
    return Stencil(stencil.right, stencil.left, stencil.down, stencil.up, stencil.seams,
                   float(error.max(initial=0.0)))


def _no_seams():
    return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)


def _cube_seams(delivery: np.ndarray, demand: np.ndarray, n: int):
    """The faces' totals evened out over the cube's seams: flows between adjacent faces (a weighted Laplacian of the
    six faces, its capacities the seams' Σ min(D_p, D_q)), each spread along its seam's pixel pairs. ``demand`` is
    updated in place; returns the seams' (from, to, flow) over flat pixel indices (flow from → to)."""
    a, b = _seam_pairs(n)
    flat_d = delivery.reshape(-1)
    capacity = np.minimum(flat_d[a], flat_d[b])
    fa, fb = a // (n * n), b // (n * n)
    c = np.zeros((6, 6))
    np.add.at(c, (fa, fb), capacity)
    np.add.at(c, (fb, fa), capacity)
    laplacian = np.diag(c.sum(axis=1)) - c
    totals = demand.reshape(6, -1).sum(axis=1)
    potential = np.linalg.lstsq(laplacian, totals, rcond=None)[0]  # inflow_f = Σ_g c_fg (φ_f − φ_g) = total_f
    face_flow = c[fa, fb] * (potential[fb] - potential[fa])  # flow a → b across the pair's two faces, in total
    pair_flow = np.where(c[fa, fb] > 0, face_flow * capacity / np.where(c[fa, fb] > 0, c[fa, fb], 1.0), 0.0)
    flat = demand.reshape(-1)
    np.add.at(flat, a, pair_flow)  # a sends: it needs as much more
    np.add.at(flat, b, -pair_flow)
    return a, b, pair_flow


def _seam_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Unordered pairs (a, b) of flat cube pixel indices that neighbour across a seam (each edge pixel with the
    pixel its one-texel padding copies from the next face), each pair once."""
    border, (face, row, col) = _padding_index(CUBE, (6, n, n), 1)
    f_idx, r_idx, c_idx = np.nonzero(border)  # padded positions (f, r, c) in the (6, n+2, n+2) grid
    inner_r, inner_c = np.clip(r_idx - 1, 0, n - 1), np.clip(c_idx - 1, 0, n - 1)
    edge_only = ((r_idx == 0) | (r_idx == n + 1)) ^ ((c_idx == 0) | (c_idx == n + 1))  # not the padding's corners
    own = (f_idx * n + inner_r) * n + inner_c
    other = (face * n + row) * n + col
    own, other = own[edge_only], other[edge_only]
    pairs = np.unique(np.sort(np.stack([own, other], axis=1), axis=1), axis=0)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    return pairs[:, 0], pairs[:, 1]


def _face_flows(delivery: np.ndarray, demand: np.ndarray, flow_h: np.ndarray, flow_v: np.ndarray) -> None:
    """Fill ``flow_h`` (F, H, W−1; flow (r, c) → (r, c+1)) and ``flow_v`` (F, H−1, W; flow (r, c) → (r+1, c)) so that
    every pixel's net inflow is its ``demand`` (each face's total must be 0; ``demand`` is used up in place): the
    quadtree of the face, padded with empty pixels to a power of two, top-down (see the module's text). Below
    :data:`_TILE` pixels a side the blocks are independent, and are done a tile at a time (the finest levels' many
    children are what would cost memory). Demands and flows are float64 (each pair's flow is what both of its
    pixels' demands are updated with), capacities float32 (they only share a flow out)."""
    faces, h, w = delivery.shape
    size = 1 << max(1, math.ceil(math.log2(max(h, w))))
    tile = min(size, _TILE)
    for face in range(faces):
        d = np.zeros((1, size, size), np.float32)
        d[0, :h, :w] = delivery[face]
        s = np.zeros((1, size, size))
        s[0, :h, :w] = demand[face]
        fh, fv = np.zeros((1, size, size - 1)), np.zeros((1, size - 1, size))
        block = size
        while block > tile:
            _split_blocks(d, s, fh, fv, block, block // 2)
            block //= 2
        for y in range(0, size, tile):
            for x in range(0, size, tile):
                part = (slice(None), slice(y, y + tile), slice(x, x + tile))
                rows, columns = slice(y, y + tile - 1), slice(x, x + tile - 1)
                sub_d, sub_s = d[part], s[part]
                sub_h, sub_v = fh[:, part[1], columns], fv[:, rows, part[2]]
                for level in _levels_below(tile):
                    _split_blocks(sub_d, sub_s, sub_h, sub_v, level, level // 2)
        flow_h[face] = fh[0, :h, :w - 1]
        flow_v[face] = fv[0, :h - 1, :w]
        demand[face] = s[0, :h, :w]


_TILE = 256


def _levels_below(tile: int):
    block = tile
    while block >= 2:
        yield block
        block //= 2


def _split_blocks(d, s, fh, fv, block: int, half: int) -> None:
    """One level of the quadtree: in every block of ``block`` pixels a side, the flows between its four children
    (``half`` a side) that zero each child's total demand, given that the block's total is zero."""
    faces, size = d.shape[0], d.shape[1]
    n = size // half  # children per side
    totals = s.reshape(faces, n, half, n, half).sum(axis=(2, 4))
    sa, sb, sc = totals[:, 0::2, 0::2], totals[:, 0::2, 1::2], totals[:, 1::2, 0::2]  # d's follows: Σ = 0
    top = np.arange(half - 1, size - 1, block)  # the row above each block's middle line; the column left of it
    cap_v = np.minimum(d[:, top], d[:, top + 1]).reshape(faces, n // 2, n, half)  # per column pair
    cap_h = np.minimum(d[:, :, top], d[:, :, top + 1]).transpose(0, 2, 1).reshape(faces, n // 2, n, half)
    seg_v, seg_h = cap_v.sum(axis=3, dtype=np.float64), cap_h.sum(axis=3, dtype=np.float64)  # per child's stretch
    left_v, right_v = seg_v[:, :, 0::2], seg_v[:, :, 1::2]  # bottom-left → top-left, bottom-right → top-right
    upward = sa + sb  # what the top children need from the bottom ones
    both = left_v + right_v
    up_left = np.where(both > 0, upward * left_v / np.where(both > 0, both, 1.0), 0.0)
    up_right = upward - up_left
    to_a = sa - up_left  # b → a
    to_c = sc + up_left  # d → c
    _spread_v(d, s, fv, top, cap_v, seg_v, np.stack([up_left, up_right], axis=-1).reshape(faces, n // 2, n))
    leftward = np.stack([to_a, to_c], axis=-1).transpose(0, 2, 1, 3).reshape(faces, n // 2, n)  # [block col, row]
    _spread_h(d, s, fh, top, cap_h, seg_h, leftward)


def _spread_v(d, s, fv, top, cap, seg, upward) -> None:
    """Flows ``upward`` (F, blocks, children) across each block's middle row, from the lower child to the upper one,
    spread over its column pairs in proportion to their capacities."""
    share = np.where(seg > 0, upward / np.where(seg > 0, seg, 1.0), 0.0)
    per_pair = (cap * share[..., None]).reshape(d.shape[0], len(top), -1)  # (F, blocks, columns)
    fv[:, top] = -per_pair  # flow_v is downward
    s[:, top] -= per_pair  # the upper pixel received
    s[:, top + 1] += per_pair


def _spread_h(d, s, fh, left, cap, seg, leftward) -> None:
    """Flows ``leftward`` (F, blocks, children) across each block's middle column, from the right child to the left
    one, spread over its row pairs in proportion to their capacities."""
    share = np.where(seg > 0, leftward / np.where(seg > 0, seg, 1.0), 0.0)
    per_pair = (cap * share[..., None]).reshape(d.shape[0], len(left), -1).transpose(0, 2, 1)  # (F, rows, blocks)
    fh[:, :, left] = -per_pair  # flow_h is rightward
    s[:, :, left] -= per_pair
    s[:, :, left + 1] += per_pair


def _convex(stencil: Stencil) -> Stencil:
    """The stencil with each pixel's weights scaled down to :data:`MAX_WEIGHT` in total where they exceed it (a
    flow squeezed through a thin link by a disc's rim): the pre-filter stays a convex blend, so a positive map
    stays positive; what it costs in exactness shows in :attr:`Stencil.residual`."""
    total = stencil.totals()
    reader, read, weight = stencil.seams
    if total.max(initial=0.0) <= MAX_WEIGHT:
        return stencil
    scale = np.minimum(1.0, MAX_WEIGHT / np.maximum(total, 1e-300)).astype(np.float32)
    return Stencil(stencil.right * scale[:, :, :-1], stencil.left * scale[:, :, 1:], stencil.down * scale[:, :-1],
                   stencil.up * scale[:, 1:], (reader, read, weight * scale.reshape(-1)[reader]), stencil.residual)


def _stencil(delivery, flow_h, flow_v, seams) -> Stencil:
    """Weights from flows: a flow p → q of F is p reading q with weight F / D_p."""
    def reading(flow, reader_d):
        return np.where(flow > 0, flow / np.where(reader_d > 0, reader_d, 1.0), 0.0).astype(np.float32)

    right = reading(flow_h, delivery[:, :, :-1])
    left = reading(-flow_h, delivery[:, :, 1:])
    down = reading(flow_v, delivery[:, :-1])
    up = reading(-flow_v, delivery[:, 1:])
    a, b, f = seams
    flat = delivery.reshape(-1)
    reader = np.where(f > 0, a, b)
    read = np.where(f > 0, b, a)
    weight = np.abs(f) / np.where(flat[reader] > 0, flat[reader], 1.0)
    keep = weight > 0
    return Stencil(right, left, down, up, (reader[keep], read[keep], weight[keep].astype(np.float32)), 0.0)


# ---- which conversions are corrected, and the corrections kept ----------------------------------------------------
# While lightprobe.maps.resampling.resampler.link_kernels runs its small map: .small (whose memory the resampler does
# not check), and .uncorrected where the map it stands for is not corrected (read by _corrected).
_LINKING = threading.local()


# Lat-long sources are flux-corrected into discs up to this many pixels (as the conversion reads them, after any box
# reduction): 2048×1024. A 16–32-pixel disc's outer rings span 20–40° each, and a one-pixel sun read by them came out
# 0.26–0.74 % off (no rate fixes a pixel that straddles the rim). Larger discs hold most of the 0.2 % by their rates
# (LATLONG_SPHERE_MAX_SAMPLES, fused.LATLONG_ANGULAR_SPACING) and, to the rim direction, by their rim pixels' rows
# round it (fused._rim_subsamples), but not all of it: where a ball's rim-row pixel meets a plain one (lat-long
# 2048×1024 → mirror ball 512, 0.22 % 10–25° from its rim direction; 1536×768 → 384, 0.25 %), where the rates step
# mid-ball (1024×512 → 817, the default size, 0.33 %), at an angular map's rim direction (2048×1024 → 1634, 0.34 %):
# corrected, each is exact. It costs 2.4× the conversion the first time (2048×1024 → mirror ball 512–1024, 1.1–1.5 s
# → 2.7–3.6 s; then the weights are cached) and ~130 B a source pixel while it is made (+270 MB at 2048×1024). A 4k
# lat-long's correction would hold more than convert may (tests/test_limits.py: 3× the map): there it is not made.
# Its rows alone hold the bar into a mirror ball since lookups are 0.35 source pixels apart there
# (fused.LATLONG_SPHERE_SPACING), a side may take more than k_max where the other needs fewer (fused._within_budget)
# and the ball's long ring pixels are read round its rim direction (fused._rim_polar): 4096×2048 → mirror ball 1024
# 0.16 % (was 0.41 %), → 3268, its default size, 0.12 % (0.30 %). Into an angular map, since the pixels by its rim
# direction take lookups closer there (fused.ANGULAR_RIM_SPACING): → angular 3268 0.15 % (0.26 %; 0.12 % at the rim
# direction).
LATLONG_FLUX_MAX_PIXELS = 1 << 21


def _flux_corrects(source_layout: Layout, source_pixels: int, target: Layout) -> bool:
    """Whether a conversion from ``source_layout`` (``source_pixels`` as read) into ``target`` is flux-corrected (with
    its rate left automatic): every source but a lat-long; a lat-long into a disc up to :data:`LATLONG_FLUX_MAX_PIXELS`,
    and into anything when it has fewer rows than the rational pole rows need
    (:data:`lightprobe.maps.resampling.pole_rows.MIN_HEIGHT`: its first rows keep the plain spline, a sun there
    +22–25 %). Into a lat-long or a cube a larger lat-long keeps a sun's energy by its own construction — the polar
    rows' reductions and rational weights, measured in tests/test_resample.py."""
    if source_layout.name != "latlong":
        return True
    if math.isqrt(source_pixels // 2) < pole_rows.MIN_HEIGHT:  # a lat-long of H rows has 2H² pixels
        return True
    return target.name in DISCS and source_pixels <= LATLONG_FLUX_MAX_PIXELS


def _corrected(source_layout: Layout, source_grid: tuple[int, ...], target: Layout, samples: int | None) -> bool:
    """Whether this conversion gets a flux correction: :func:`_flux_corrects`, with the rate left automatic (and not
    while :func:`lightprobe.maps.resampling.resampler.link_kernels` runs a small map for a large one that is not
    corrected)."""
    if getattr(_LINKING, "uncorrected", False):
        return False
    return samples is None and _flux_corrects(source_layout, math.prod(source_grid), _face_layout(target))


_FLUX_CACHE: dict = {}
_FLUX_LOCK = threading.Lock()
_FLUX_CACHE_BYTES = 256 << 20  # the corrections a process keeps (a batch converts one pair of grids many times)


def _flux_stencil(source_layout: Layout, source_grid: tuple[int, ...], target: Layout, filled_grid, rotation,
                  samples: int | None, rates: tuple[int, int], delivery_of) -> Stencil | None:
    """The flux correction of this conversion, or None where none is made (see
    :func:`_flux_corrects`; nor where the rate is given by hand, ``samples``: the kernel compared as it is).
    ``rates`` (k, k_max) are the conversion's; ``delivery_of(omega_t)`` gives each source pixel's delivery, flat,
    as the kernel reads them. Kept for the last pairs of grids, up to :data:`_FLUX_CACHE_BYTES` of weights, keyed by
    the layouts themselves (a turned mirror ball is named "sphere" too)."""
    if not _corrected(source_layout, source_grid, target, samples):
        return None
    target = _face_layout(target)  # a cross target is filled as cube faces
    key = (source_layout, source_grid, target, tuple(filled_grid), rates,
           None if rotation is None else np.asarray(rotation, np.float64).tobytes())
    with _FLUX_LOCK:
        if key in _FLUX_CACHE:
            return _FLUX_CACHE[key]
    omega_t = pixel_solid_angles(target, tuple(filled_grid)).reshape(-1)
    per_pixel = _raw_pixel_delivery(delivery_of(omega_t), source_layout, source_grid)
    omega_s = pixel_solid_angles(source_layout, source_grid)
    face_shape = (-1,) + tuple(source_grid[-2:])
    stencil = stencil_for(source_layout, per_pixel.reshape(face_shape), omega_s.reshape(face_shape))
    with _FLUX_LOCK:  # threads converting at once (a Dask worker's) share the cache
        while _FLUX_CACHE and sum(kept.nbytes for kept in _FLUX_CACHE.values()) + stencil.nbytes > _FLUX_CACHE_BYTES:
            _FLUX_CACHE.pop(next(iter(_FLUX_CACHE)))  # the oldest first
        _FLUX_CACHE[key] = stencil
    return stencil
