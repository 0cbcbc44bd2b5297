"""A cube source's texel balance: the pre-filter after which each texel's B-spline carries exactly its solid angle.

The resampler reads a cube map through a cubic B-spline on each face, the face's 2-texel padding filled from its
neighbours (:meth:`lightprobe.maps.layouts.Layout.padded`). What a texel j gives to ∫L dω of the reconstruction is the
integral over the sphere of its basis — its spline on its own face plus its copies in the neighbours' padding —
I_j. For a conversion to keep the energy of a one-texel sun, I_j must be the texel's solid angle Ω_j. It is not
quite, and the error is the source's, whatever the target:

* along an edge, the density dω/(ds dt) = (1 + s² + t²)^(−3/2) falls toward the edge from both faces — a kink — and
  the part of a texel's spline past the edge meets the rising density of the next face, not the falling one its
  own face would continue with: edge texels carry +0.47…0.79 % too much at 64 texels a side, ∝ 1/N;
* a padding texel holds the next face's texel nearest to its direction, and the next face's grid seen from this
  one is compressed along the edge, so here and there a texel is copied twice or not at all: up to ±0.26 % at
  any size (the second row, a third of the way along an edge, at 256 and 1024 alike);
* inside a face, the spline's variance (1/3 texel²) against a box's (1/12) over the density's curvature: −0.07 %
  at the face centre at 64, ∝ 1/N².

Both are exact numbers of the geometry (:func:`face_texel_integrals`, Gauss–Legendre on each half texel, where the
splines are polynomials). The balance moves the surplus I_j − Ω_j by blending each texel's value with its row and
column neighbours, c'_j = c_j + a_j (c_next − c_j) + b_j (c_prev − c_j) (a_j, b_j ≥ 0): a texel's basis then
serves part of its neighbour's value. One pass along each row takes every row's surplus to the same amount per
texel, one along each column then to zero — a texel's effective integral is Ω_j to float rounding. The blends are
convex, so a uniform map stays exactly uniform and a positive one positive; their weights are at most 10 % at 4–8
texels a side, 3.3 % at 16 and 2.2 % from 32 to 1024 (the padding's rounding does not shrink with N): a sun stays
where it was, and what a conversion still loses is its target's quadrature. All six faces have the same
weights (the cube's symmetry; a test checks the integrals against brute force)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ...util.jit import njit, read_only
from ..layout_base import _padding_index
from ..layouts import CUBE, PAD, Cross, Layout
from ..envmap import pixel_solid_angles
from .pole_rows import bspline

MIN_SIZE = 2 * PAD  # smaller cubes have no padding corner blocks (layouts._cube_corner_blocks): left as they are
_NODES = 3  # Gauss–Legendre nodes per half texel: the spline is cubic there, the density smooth (exact to ~1e-12)
_ROW_BLOCK = 64  # padded texel rows whose nodes' densities are held at a time (bounds memory for large faces)


def face_integrals(n: int) -> np.ndarray:
    """(n + 2·PAD)² float64: ∫ over one face of the tensor B-spline centred on each texel of the padded face grid,
    β(x − τx) β(y − τy) dω, x, y in texels (texel centres at integers, the face spanning −½ … n − ½).

    The splines' knots are at the integers, so Gauss–Legendre nodes on each half texel integrate them exactly
    against the smooth density; every padded texel's spline is the same pattern of node values shifted by two
    half texels, so the sums are banded (8 half texels a spline) and the node grid is formed a block at a time."""
    nodes, weights = np.polynomial.legendre.leggauss(_NODES)
    x = ((np.arange(2 * n) * 0.5 - 0.25)[:, None] + 0.25 * nodes).ravel()  # half texels [k/2 − ½, k/2]
    w = np.tile(0.25 * weights, 2 * n)
    s = 2.0 * (x + 0.5) / n - 1.0  # face coordinate −1 … 1
    padded = n + 2 * PAD
    half = (padded + 1) // 2  # the face is symmetric under s → −s in each axis: one quadrant, then mirrored
    columns = np.empty((half, x.size))  # each padded texel row's spline summed over the node rows
    for first in range(0, half, _ROW_BLOCK):
        rows = np.arange(first, min(first + _ROW_BLOCK, half))
        lo, hi = max(0, _first_node(rows[0])), min(x.size, _first_node(rows[-1]) + _PER_SPLINE)
        q = 1.0 + s[lo:hi, None] ** 2 + s ** 2
        density = (2.0 / n) ** 2 * (w[lo:hi, None] * w) / (q * np.sqrt(q))
        columns[rows] = _spline_sums(density, rows, lo)
    quadrant = _spline_sums(columns.T, np.arange(half), 0).T
    mirror = np.minimum(np.arange(padded), padded - 1 - np.arange(padded))
    return quadrant[np.ix_(mirror, mirror)]


_PER_SPLINE = 8 * _NODES  # nodes under one spline (support ±2 texels: 8 half texels)
_PATTERN = bspline((np.arange(-3, 5) * 0.5 - 0.25)[:, None]
                   + 0.25 * np.polynomial.legendre.leggauss(_NODES)[0]).ravel()  # the spline of τ = 0 at its nodes


def _first_node(padded_texel):
    """Index of the first node under the spline of padded texel p (τ = p − PAD): half texel 2τ − 3."""
    return (2 * (padded_texel - PAD) - 3) * _NODES


def _spline_sums(values: np.ndarray, padded_texels: np.ndarray, offset: int) -> np.ndarray:
    """Σ_a pattern[a] · values[node(p) + a − offset] for consecutive padded texels p (rows of ``values`` are nodes
    from ``offset``; nodes off the face or outside ``values`` count zero): strided slices, one per spline node."""
    first, count, stride = _first_node(padded_texels[0]) - offset, padded_texels.size, 2 * _NODES
    lead = max(0, -first)
    span = first + lead + stride * (count - 1) + _PER_SPLINE
    ext = np.zeros((max(span, lead + values.shape[0]),) + values.shape[1:])
    ext[lead:lead + values.shape[0]] = values
    out = np.zeros((count,) + values.shape[1:])
    for a in range(_PER_SPLINE):
        start = first + lead + a
        out += _PATTERN[a] * ext[start:start + stride * (count - 1) + 1:stride]
    return out


def face_texel_integrals(n: int) -> np.ndarray:
    """(n, n) float64: I_j for the texels of one face — the integral over the sphere of texel j's reconstruction
    basis: its spline on its own face plus every copy of it in the faces' padding (:meth:`Layout.padded`; all six
    faces alike, by the cube's symmetry). Only the padding's index is formed, not an image of the cube."""
    per_slot = face_integrals(n)
    out = per_slot[PAD:PAD + n, PAD:PAD + n].copy()  # each texel's spline on its own face
    border, (face, row, col) = _padding_index(CUBE, (6, n, n), PAD)
    _, slot_row, slot_col = np.nonzero(border)  # the border's slots, in the index's order
    mine = face == 0  # the copies of face 0's texels, on whichever face's border they sit
    np.add.at(out, (row[mine], col[mine]), per_slot[slot_row[mine], slot_col[mine]])
    return out


def _moving(integrals: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(up, down), float32 like ``integrals``: the blends along the last axis, c'_j = c_j + up_j (c_{j+1} − c_j) +
    down_j (c_{j−1} − c_j), that turn effective integrals ``integrals`` into ``goal`` (equal sums along the axis).
    The surplus carried across the boundary after texel j is F_j = Σ_{i≤j} (I_i − goal_i): texel j's basis serves
    F_j of texel j+1's value when F_j > 0, texel j+1's serves −F_j of texel j's when it is negative."""
    carried = np.cumsum(integrals - goal, axis=-1)[..., :-1]
    up, down = np.zeros(integrals.shape, np.float32), np.zeros(integrals.shape, np.float32)
    up[..., :-1] = np.maximum(carried, 0.0) / integrals[..., :-1]
    down[..., 1:] = np.maximum(-carried, 0.0) / integrals[..., 1:]
    return up, down


def _integrals_after(integrals: np.ndarray, up: np.ndarray, down: np.ndarray) -> np.ndarray:
    """Each texel's effective integral once its neighbours' bases (along the last axis) serve part of its value:
    Σ_j A_ij I_j (float64)."""
    out = integrals * (1.0 - up.astype(np.float64) - down)
    out[..., 1:] += up[..., :-1] * integrals[..., :-1]
    out[..., :-1] += down[..., 1:] * integrals[..., 1:]
    return out


@dataclass(frozen=True)
class Balance:
    """A cube size's texel balance (:func:`balance_of`): blends along each face's rows (neighbours left and
    right), then along its columns (above and below), as they act on the integrals; values take them in the other
    order (the pre-filter is P_rows · P_columns, and its transpose acts on I). Four (n, n) float32 weights,
    indexed [row, column]: 16 bytes a face texel, the same for all six faces."""

    row_up: np.ndarray  # weight of the texel to the right
    row_down: np.ndarray  # of the texel to the left
    column_up: np.ndarray  # of the texel below (the next row)
    column_down: np.ndarray  # of the texel above

    def apply(self, faces: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Balanced values of cube faces (6, n, n, C) float32 (radiance in, radiance out; the frame and layout
        untouched), into ``out`` (may be ``faces`` itself): per face the column blends into a scratch face, then
        the row blends from it (:func:`_blend_pass`; numba is loaded already wherever a cube is resampled)."""
        out = np.empty_like(faces) if out is None else out
        scratch = np.empty(faces.shape[1:], np.float32)
        for f in range(faces.shape[0]):
            _blend_pass(read_only(faces[f]), self.column_up, self.column_down, 1, 0, scratch)
            strided = not out[f].flags.c_contiguous  # the pass is compiled for C-ordered faces alone (read_only)
            face = np.empty_like(scratch) if strided else out[f]
            _blend_pass(read_only(scratch), self.row_up, self.row_down, 0, 1, face)
            if strided:
                out[f] = face
        return out

    def delivered(self, per_texel: np.ndarray) -> np.ndarray:
        """What a linear measure of the balanced values gives each source texel, from what it gives each texel of
        the values it reads (6, n, n): Pᵀ — e.g. a conversion's Σ_t Ω_t W_tj, so a sun's energy is its own."""
        after_rows = _integrals_after(per_texel, self.row_up, self.row_down)
        return _integrals_after(after_rows.transpose(0, 2, 1), self.column_up.T,
                                self.column_down.T).transpose(0, 2, 1)


@njit(cache=True, nogil=True, error_model="numpy")
def _blend_pass(face, up, down, dr, dc, out):  # pragma: no cover - compiled
    """One pass over a face (n, n, C) float32 into ``out`` (not ``face``): each texel blended with its neighbours a
    step (dr, dc) on and back, c + up (c_next − c) − down (c − c_prev), weights indexed [row, column] — written on
    the differences of neighbours, so equal values stay exactly equal (a uniform map uniform to the bit)."""
    n, channels = face.shape[0], face.shape[2]
    for r in range(n):
        for c in range(n):
            ahead = r + dr < n and c + dc < n
            behind = r - dr >= 0 and c - dc >= 0
            for k in range(channels):
                v = face[r, c, k]
                x = v
                if ahead:
                    x += up[r, c] * (face[r + dr, c + dc, k] - v)
                if behind:
                    x -= down[r, c] * (v - face[r - dr, c - dc, k])
                out[r, c, k] = x


@lru_cache(maxsize=4)
def balance_of(n: int) -> Balance | None:
    """The balance of a cube of ``n`` texels a side (None under :data:`MIN_SIZE`, left as is): 0.04 s at 256,
    ~0.7 s at 1024, once per process and size."""
    if n < MIN_SIZE:
        return None
    integrals = face_texel_integrals(n)
    omega = pixel_solid_angles(CUBE, (6, n, n))[0]
    surplus = (integrals - omega).sum(axis=-1, keepdims=True)  # per row; the rows of a face sum to 0
    row_up, row_down = _moving(integrals, omega + surplus / n)  # every texel of a row the same surplus
    after = _integrals_after(integrals, row_up, row_down)
    column_up, column_down = _moving(after.T, omega.T)  # each column's surplus sums to 0: to Ω exactly
    return Balance(row_up, row_down, np.ascontiguousarray(column_up.T), np.ascontiguousarray(column_down.T))


def balanced_faces(faces: np.ndarray) -> np.ndarray:
    """Cube faces (6, n, n, C) float32 balanced, a new array (the same array for cubes under :data:`MIN_SIZE`)."""
    balance = balance_of(faces.shape[-2])
    return faces if balance is None else balance.apply(faces)


def delivered_to_texels(per_texel: np.ndarray) -> np.ndarray:
    """:meth:`Balance.delivered` for a cube of any size: what a linear measure (6, n, n) of a cube's balanced
    values gives each of its own texels (unchanged under :data:`MIN_SIZE`)."""
    balance = balance_of(per_texel.shape[-1])
    return per_texel if balance is None else balance.delivered(per_texel)


def balance_in_place(faces: np.ndarray) -> None:
    """:func:`balanced_faces` into ``faces`` itself (a padded image's interior: :meth:`Layout.padded`'s prefilter)."""
    balance = balance_of(faces.shape[-2])
    if balance is not None:
        balance.apply(faces, out=faces)


def prefilter_for(layout: Layout) -> Callable[[np.ndarray], None] | None:
    """What a B-spline resampling reads a source of ``layout`` through: the texel balance for a cube (or a cross,
    read as its cube), nothing for the others."""
    return balance_in_place if layout is CUBE or isinstance(layout, Cross) else None
