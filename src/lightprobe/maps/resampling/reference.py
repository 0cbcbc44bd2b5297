"""The numpy formulation of a conversion: the reference the compiled kernel is tested against.

:func:`reference_resample` sums what :func:`lightprobe.maps.resampling.fused.resample_into` sums — each target pixel's
k×k lookups of the source's cubic B-spline, weighted by the target layout's dω/(du dv), the kernel's cells in a
lat-long target's pole rows and its edge terms on a cube's — with whole arrays of lookups, a chunk of pixels at a
time. It is also the path of :func:`lightprobe.maps.resampling.resampler.resample` for layouts the kernel does not
know.
"""

from __future__ import annotations

import numpy as np

from ...util.progress import track
from ..envmap import EnvMap, owned
from ..layouts import CUBE, LATLONG, Cross, Layout
from . import balance, fused

_CHUNK_SAMPLES = 1 << 18  # direction lookups per chunk of a resampling pass (bounds memory to ~100 MB)


def reference_resample(source: EnvMap, target: Layout, grid: tuple[int, ...], k: int,
                       rotation: np.ndarray | None) -> EnvMap:
    """The numpy formulation of :func:`~lightprobe.maps.resampling.resampler.resample`: the kernel's reference.

    k×k lookups per target pixel, in chunks; a lat-long target's pole rows in the kernel's cells, a cube target's edge
    terms as the kernel's. It is also the path for layouts the kernel does not know. Its lookups are the layout's
    plain B-spline: near a lat-long source's poles it lacks the kernel's rational row weights (the tests compare the
    two on sources under :data:`lightprobe.maps.resampling.pole_rows.MIN_HEIGHT` rows, where the kernel has none
    either).

    Parameters
    ----------
    source : EnvMap
        The map to convert, as the conversion reads it (no box reduction is made here).
    target : Layout
        The target layout, an instance.
    grid : tuple of int
        The target's grid (``target.grid_shape(size)``).
    k : int
        Lookups per side of a target pixel.
    rotation : numpy.ndarray or None
        3×3 rotation matrix R in the world frame (the target at direction d shows the source at Rᵀd), or None.

    Returns
    -------
    EnvMap
        The converted map in ``target`` of ``grid`` (float32 radiance; 0 on pixels off the sphere).
    """
    if isinstance(target, Cross):  # filled as cube faces and rearranged, as the kernel does (edge terms are a face's)
        faces = reference_resample(source, CUBE, CUBE.grid_shape(target.size_of(grid)), k, rotation)
        return EnvMap(owned(target.from_cube(faces.data)), target)
    lookup = source.layout.sampler(source.data, "bspline", balance.prefilter_for(source.layout))
    sub = (np.arange(k) + 0.5) / k
    h, w = grid[-2:]
    index = [a.ravel() for a in np.indices(grid)]
    flat_face, flat_row, flat_col = index if target.faces > 1 else [np.zeros_like(index[0]), *index]
    valid = target.valid_mask(grid).ravel()
    out = np.zeros((flat_row.size, 3), dtype=np.float32)
    step = max(1, _CHUNK_SAMPLES // (k * k))
    chunks = range(0, flat_row.size, step)
    for start in track(chunks, f"resampling to {target.name}", total=len(chunks)):
        sl = slice(start, start + step)
        f, u, v = np.broadcast_arrays(
            flat_face[sl, None, None],
            (flat_col[sl, None, None] + sub[None, None, :]) / w,
            (flat_row[sl, None, None] + sub[None, :, None]) / h,
        )
        weight = target.uv_density(f, u, v)
        if target.name == "latlong":  # the kernel's cells in its pole rows (fused.POLE)
            v, weight = _pole_cells(flat_row[sl], sub, h, u, v, weight)
        d = np.where(weight[..., None] > 0, target.uv_to_dir(f, u, v), _ANY_DIRECTION)
        if rotation is not None:
            d = d @ rotation  # row vectors: d @ R = (Rᵀ d)ᵀ
        values = lookup(d)
        wsum = weight.sum(axis=(1, 2))
        total = np.einsum("pij,pijc->pc", weight, values)
        if target.name == "cube":  # the kernel's edge terms (fused._cube_edge_terms)
            _add_cube_edge_terms(lookup, flat_face[sl], flat_row[sl], flat_col[sl], h, w, rotation, total, wsum)
        out[sl] = total / np.where(wsum > 0, wsum, 1.0)[:, None]
        # a disc's rim pixel can have all its subsamples off the disc: it shows its centre's (rim) direction
        missed = np.nonzero((wsum == 0) & valid[sl])[0]
        if missed.size:
            f0, u0, v0 = flat_face[sl][missed], (flat_col[sl][missed] + 0.5) / w, (flat_row[sl][missed] + 0.5) / h
            d0 = np.nan_to_num(target.uv_to_dir(f0, u0, v0), nan=0.0)
            out[start + missed] = lookup(d0 if rotation is None else d0 @ rotation)
    out[~valid] = 0.0
    return EnvMap(owned(out.reshape(grid + (3,))), target)


def _add_cube_edge_terms(lookup, face: np.ndarray, row: np.ndarray, col: np.ndarray, h: int, w: int, rotation,
                         total: np.ndarray, wsum: np.ndarray) -> None:
    """Add to cube pixels' weighted sums ``total`` (p, 3) and weight sums ``wsum`` (p,), at k × k plain cells, the
    kernel's edge terms (:func:`lightprobe.maps.resampling.fused._cube_edge_terms`): for each side of a pixel on its
    face's side, lookups at the side's ends weighted ± t·(dω/(du dv))/48."""
    for side in range(4):
        across = float(side % 2)
        on = (col == (0 if side == 0 else w - 1)) if side < 2 else (row == (0 if side == 2 else h - 1))
        at = np.nonzero(on)[0]
        for end in (0, 1):
            if side < 2:
                u, v = np.full(at.size, across), (row[at] + end) / h
                t = 2 * v - 1
            else:
                u, v = (col[at] + end) / w, np.full(at.size, across)
                t = 2 * u - 1
            weight = (-1.0 if end else 1.0) * t * CUBE.uv_density(face[at], u, v) / 48.0
            d = CUBE.uv_to_dir(face[at], u, v)
            total[at] += weight[:, None] * lookup(d if rotation is None else d @ rotation)
            wsum[at] += weight


def _pole_cells(rows: np.ndarray, sub: np.ndarray, h: int, u: np.ndarray, v: np.ndarray,
                weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v, weight) of a lat-long target's (p, k, k) subsamples (v along axis 1) of pixels in ``rows`` of ``h``,
    with the pole rows' cells warped as the kernel's (:data:`lightprobe.maps.resampling.fused.POLE`): v at the warped
    positions, the density there times the cell's width."""
    k = sub.size
    v, weight = v.copy(), weight.copy()
    for pole_row in (0, h - 1):
        before = fused.POLE if pole_row == 0 else k
        after = fused.POLE if pole_row == h - 1 else k
        fv, sv = fused._graded.py_func(sub, k, before, after)
        at = rows == pole_row
        v[at] = (pole_row + fv[None, :, None]) / h
        weight[at] = LATLONG.uv_density(None, u[at], v[at]) * sv[None, :, None]
    return v, weight


_ANY_DIRECTION = np.array([0.0, 0.0, -1.0])  # stands in for subsamples off the valid region (their weight is 0)
