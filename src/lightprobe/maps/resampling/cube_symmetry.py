"""Lat-long → cube faces through the cube's symmetries: one footprint computed, up to eight target pixels read.

An unturned lat-long source and a cube target share symmetries that the general kernel
(:func:`lightprobe.maps.resampling.fused.resample_into`) recomputes for every pixel:

- a quarter turn of yaw carries the −Z face onto −X, +Z and +X, and moves a lat-long by W/4 columns — exactly, when
  W is a multiple of 4: the four side faces' footprints are one footprint whose columns are shifted;
- the mirror x → −x carries column c of the −Z, +Y and −Y faces onto column N − 1 − c of the same face, and a
  lat-long column c onto W − 1 − c (in a row reduced to W/2^ℓ columns, onto W/2^ℓ − 1 − c; a row reached across
  the pole stays across it, since a half turn is its own mirror).

So for each pixel of the left half of a row of −Z, +Y and −Y the subsamples' directions, footprint weights and
tile of taps (the geometry: most of the general kernel's time) are computed once, and the tile is read at its
transformed columns for each image of the pixel: 8 target pixels for the side faces, 2 for the top and bottom.
On −Z a subsample's direction is (−s, −t, −1), so its source column depends on s alone: tabulated once a call
(:func:`_back_columns`), leaving one atan2 per subsample.
A footprint the tile cannot hold, or a polar tile whose shift is not whole in a reduced row, takes the general
path for that pixel. The result equals the general kernel's to float32 rounding (the sums are regrouped and the
subsamples' positions rounded differently): ``tests/test_resample.py``.
"""

from __future__ import annotations

import numpy as np

from ...util.jit import njit
from .fused import CUBE, KERNEL_FASTMATH, LATLONG, TILE, _cube_edge_terms, _polar_tile, _row_frame, _subsamples, _sum_into_tile, _tile_bounds, atan2, _wrapped_column, pixel_into, slots

# The side faces as images of −Z (face 5) under quarter turns of yaw: (face, turns); a turn is +W/4 columns.
SIDE_FACES = np.array([[5, 0], [0, 1], [4, 2], [1, 3]], dtype=np.int64)
TOP, BOTTOM, BACK = 2, 3, 5  # +Y, −Y, −Z: the faces whose left halves are computed
NO_TILE, PLAIN, POLAR = 0, 1, 2


def applies(source_width: int, rotation) -> bool:
    """Whether a lat-long of this width, turned by ``rotation``, can be converted to a cube this way."""
    return source_width % 4 == 0 and (rotation is None or np.array_equal(np.asarray(rotation), np.eye(3)))


@njit(cache=True, inline="always", error_model="numpy")
def _modulo(c, width):  # pragma: no cover - compiled
    """c brought into [0, width) (for the rare taps whose run of columns crosses the seam)."""
    while c < 0:
        c += width
    while c >= width:
        c -= width
    return c


@njit(cache=True, inline="always", error_model="numpy")
def _base_tile(levels, caps, h, w, pxs, pys, pws, n, scratch, tile):  # pragma: no cover - compiled
    """The footprint tile of n subsamples, as :func:`lightprobe.maps.resampling.fused._footprint` builds it:
    (kind, first column, first row, columns, rows) — kind NO_TILE when it cannot hold them."""
    c0, r0, tw, th = _tile_bounds(pxs, pys, n, 0)
    if th > TILE:
        return NO_TILE, 0, 0, 0, 0
    if r0 < caps[0] or r0 + th > h - caps[1]:  # reaches the reduced polar rows: per-row frames, each row's width
        r0, th = _polar_tile(levels, h, w, pxs, pys, pws, n, 1.0, scratch, tile)
        return (POLAR if th > 0 else NO_TILE), 0, r0, 0, th
    if tw > TILE:
        return NO_TILE, 0, 0, 0, 0
    _sum_into_tile(tile, pxs, pys, pws, n, 1.0, c0, r0, tw, th, 0)
    return PLAIN, c0, r0, tw, th


@njit(cache=True, inline="always", error_model="numpy")
def _read_plain(src, h, w, c0, r0, tw, th, tile, shift, mirror, acc):  # pragma: no cover - compiled
    """acc = Σ tile · source over a plain tile whose columns are mirrored (c → W − 1 − c) if ``mirror``, then
    shifted by ``shift`` columns. A row past a pole is its reflection half a turn round (added after the mirror:
    a half turn is its own mirror)."""
    r, g, b = 0.0, 0.0, 0.0
    for ty in range(th):
        row, turn = r0 + ty, 0
        if row < 0:
            row, turn = -1 - row, w // 2
        elif row >= h:
            row, turn = 2 * h - 1 - row, w // 2
        row = min(max(row, 0), h - 1)
        if mirror:
            start, step = w - 1 - c0 + turn + shift, -1
            lo = start - (tw - 1)
        else:
            start, step = c0 + turn + shift, 1
            lo = start
        if lo >= 0 and lo + tw <= w:
            for tx in range(tw):
                k, col = tile[ty, tx], start + step * tx
                r += k * src[0, row, col, 0]
                g += k * src[0, row, col, 1]
                b += k * src[0, row, col, 2]
        else:
            for tx in range(tw):
                k, col = tile[ty, tx], _modulo(start + step * tx, w)
                r += k * src[0, row, col, 0]
                g += k * src[0, row, col, 1]
                b += k * src[0, row, col, 2]
    acc[0], acc[1], acc[2] = r, g, b


@njit(cache=True, inline="always", error_model="numpy")
def _read_polar(src, levels, reduced, row_offsets, h, w, r0, th, tile, scratch, shift, mirror,
                acc):  # pragma: no cover - compiled
    """:func:`_read_plain` for a tile of per-row frames (:func:`lightprobe.maps.resampling.fused._polar_tile`); False,
    touching nothing, if ``shift`` is not a whole number of a reduced row's columns."""
    for ty in range(th):
        width = _row_frame(levels, h, w, r0 + ty)[2]
        if (shift * width) % w != 0:  # not whole reduced columns (2^ℓ source columns each, or w / width)
            return False
    c0s, tws = scratch[0], scratch[1]
    r, g, b = 0.0, 0.0, 0.0
    for ty in range(th):
        row, level, width, _ = _row_frame(levels, h, w, r0 + ty)
        moved = shift * width // w
        for tx in range(tws[ty]):
            col = _wrapped_column(c0s[ty] + tx, width)
            if mirror:
                col = width - 1 - col
            col += moved
            if col >= width:
                col -= width
            k = tile[ty, tx]
            if level == 0:
                r += k * src[0, row, col, 0]
                g += k * src[0, row, col, 1]
                b += k * src[0, row, col, 2]
            else:
                i = row_offsets[row] + col
                r += k * reduced[i, 0]
                g += k * reduced[i, 1]
                b += k * reduced[i, 2]
    acc[0], acc[1], acc[2] = r, g, b
    return True


@njit(cache=True, error_model="numpy")
def _scratch(k):  # pragma: no cover - compiled
    """Per-call scratch: subsamples (faces, columns, rows, weights), the tile and its per-row frames, lookups, and
    the identity turn and all-valid table the general path takes (made once a call, not once a pixel)."""
    m = slots(k)
    return ((np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m)),
            np.empty((TILE, TILE)), (np.empty(TILE, np.int64), np.empty(TILE, np.int64), np.empty((m, 4, 2))),
            (np.empty(4), np.empty(4), np.empty(3), np.empty(3)), (np.eye(3), np.ones((1, 1, 1), np.float32)))


@njit(cache=True, error_model="numpy")
def _back_columns(n, k, w):  # pragma: no cover - compiled
    """What the −Z face's subsamples share along a column: for subsample column i of pixel column c (index c·k + i,
    left half), its source column (the lat-long azimuth depends on s alone: the direction is (−s, −t, −1)),
    √(s² + 1) and s²."""
    cols = (n + 1) // 2
    table = np.empty((3, cols * k))
    for c in range(cols):
        for i in range(k):
            s = 2.0 * ((c + (i + 0.5) / k) / n) - 1.0
            table[0, c * k + i] = (atan2(-s, 1.0) / (2.0 * np.pi) + 0.5) * w - 0.5
            table[1, c * k + i] = np.sqrt(s * s + 1.0)
            table[2, c * k + i] = s * s
    return table


@njit(cache=True, inline="always", error_model="numpy")
def _back_subsamples(row, col, n, k, h, w, columns, eye, latlong, pfs, pxs, pys, pws):  # pragma: no cover - compiled
    """:func:`lightprobe.maps.resampling.fused._subsamples` for a pixel of the −Z face into an unturned lat-long, the
    azimuths from :func:`_back_columns`: one atan2 a subsample instead of two, the same values and order (the
    edge terms too, :func:`lightprobe.maps.resampling.fused._cube_edge_terms`)."""
    m, wsum = 0, 0.0
    for j in range(k):
        t = 2.0 * ((row + (j + 0.5) / k) / n) - 1.0
        for i in range(k):
            q = col * k + i
            pfs[m], pxs[m] = 0, columns[0, q]
            pys[m] = atan2(columns[1, q], -t) / np.pi * h - 0.5
            r = 1.0 + columns[2, q] + t * t
            pws[m] = 4.0 / (r * np.sqrt(r))
            wsum += pws[m]
            m += 1
    return _cube_edge_terms(eye, np.int64(BACK), row, col, n, n, (k, k, k, k, k, k), eye, latlong, eye, h, w, pfs, pxs, pys,
                            pws, np.int64(m), wsum)


# Compiled apart, not inlined, as fused._subsamples is and for the same reason (compile time); the kernels pass its
# arguments that could be constants as np.int64, so it compiles once.
@njit(cache=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def _orbit(src, levels, reduced, row_offsets, caps, n, k, kinds, base, row, col, images, count, out, top,
           work, columns):  # pragma: no cover - compiled
    """Target pixel (base, row, col)'s footprint, computed once, read for each of its ``count`` images:
    ``images[i]`` = (face, row, column, source column shift, mirrored), stored at out[face, row − top, column]."""
    h, w = src.shape[1], src.shape[2]
    (pfs, pxs, pys, pws), tile, scratch, (wx, wy, acc, value), (eye, valid) = work  # valid: every tap (lat-long)
    latlong, cube = kinds[0], kinds[1]
    if base == BACK:
        taps, wsum = _back_subsamples(row, col, n, k, h, w, columns, eye, latlong, pfs, pxs, pys, pws)
    else:
        taps, wsum = _subsamples(cube, eye, base, row, col, n, n, (k, k, k, k, k, k), eye, latlong, eye, h, w, pfs,
                                 pxs, pys, pws, np.int64(0))
    kind, c0, r0, tw, th = _base_tile(levels, caps, h, w, pxs, pys, pws, taps, scratch, tile)
    for i in range(count):
        face, r, c, shift, mirror = images[i, 0], images[i, 1], images[i, 2], images[i, 3], images[i, 4] == 1
        done = kind != NO_TILE
        if kind == PLAIN:
            _read_plain(src, h, w, c0, r0, tw, th, tile, shift, mirror, acc)
        elif kind == POLAR:
            done = _read_polar(src, levels, reduced, row_offsets, h, w, r0, th, tile, scratch, shift, mirror, acc)
        if done:
            for ch in range(3):
                out[face, r - top, c, ch] = acc[ch] / wsum
            continue
        pixel_into(latlong, src, valid, levels, reduced, row_offsets, caps, eye, h, w, cube, eye, face, r, c, n, n, k,
                   eye, pfs, pxs, pys, pws, wx, wy, value, tile, scratch, acc)  # the general path, this pixel alone
        for ch in range(3):
            out[face, r - top, c, ch] = acc[ch]
        if kind != NO_TILE:  # the general path used the scratch: the tile is rebuilt for the other images
            taps, wsum = _subsamples(cube, eye, base, row, col, n, n, (k, k, k, k, k, k), eye, latlong, eye, h, w, pfs,
                                 pxs, pys, pws, np.int64(0))
            kind, c0, r0, tw, th = _base_tile(levels, caps, h, w, pxs, pys, pws, taps, scratch, tile)


@njit(cache=True, inline="always", error_model="numpy")
def _image(images, i, face, row, col, shift, mirror):  # pragma: no cover - compiled
    images[i, 0], images[i, 1], images[i, 2], images[i, 3], images[i, 4] = face, row, col, shift, mirror
    return i + 1


# The layout codes as run-time values, not the module's constants: numba specialises a callee on literal arguments,
# and with LATLONG and CUBE as literals it compiled pixel_into to another value near a pole with reduced rows (4.89
# for 4.73, where its Python source and its int64-typed build agree) — found by the test of this module.
def _kinds() -> np.ndarray:
    return np.array([LATLONG, CUBE], np.int64)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def cube_rows_into(src, levels, reduced, row_offsets, caps, n, k, kinds, poles, out, top, first,
                   last):  # pragma: no cover - compiled
    """Fill rows ``first`` … ``last − 1`` of ``out`` (6, R, n, 3) float32 — image rows ``top + first`` … of the
    faces of an n-texel cube (+X, −X, +Y, −Y, +Z, −Z): the side faces, and +Y and −Y if ``poles`` — from the
    unpadded lat-long ``src`` (1, H, W, 3), W a multiple of 4, unturned, at k × k subsamples; ``levels`` …
    ``caps`` are its polar reductions as for :func:`lightprobe.maps.resampling.fused.resample_into`, whose values these are
    (to float32 rounding); ``kinds`` is :func:`_kinds`. A side pixel has 8 images (4 faces × the mirror), a pixel
    of +Y or −Y 2 (the mirror) within a row.

    Serial and without the GIL: the caller runs bands of rows on threads."""
    w = src.shape[2]
    work, images = _scratch(k), np.empty((8, 5), np.int64)
    columns = _back_columns(n, k, w)  # the −Z face's azimuths, once a call
    for r in range(first, last):
        row = top + r
        for col in range((n + 1) // 2):
            mirrors = 2 if 2 * col + 1 != n else 1
            count = 0
            for i in range(4):
                for m in range(mirrors):
                    count = _image(images, count, SIDE_FACES[i, 0], row, n - 1 - col if m else col,
                                   SIDE_FACES[i, 1] * (w // 4), m)
            _orbit(src, levels, reduced, row_offsets, caps, n, k, kinds, np.int64(BACK), row, col, images,
                   np.int64(count), out, top, work, columns)
            if not poles:
                continue
            for base in (TOP, BOTTOM):
                count = _image(images, 0, base, row, col, 0, 0)
                if mirrors == 2:
                    count = _image(images, count, base, row, n - 1 - col, 0, 1)
                _orbit(src, levels, reduced, row_offsets, caps, n, k, kinds, base, row, col, images, np.int64(count),
                       out, top, work, columns)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=KERNEL_FASTMATH)
def polar_faces_into(src, levels, reduced, row_offsets, caps, n, k, kinds, out, first, last):  # pragma: no cover
    """Fill faces +Y and −Y of ``out`` (6, n, n, 3) whole, through their eight symmetries (quarter turns about the
    pole — a turn is (row, column) → (column, n − 1 − row) on +Y, (n − 1 − column, row) on −Y, and W/4 source
    columns — and the mirror): a pixel (r, c) with r ≤ c ≤ (n − 1)/2 is computed for rows r = ``first`` …
    ``last − 1`` of that triangle, and read for its 8 images. Arguments as for :func:`cube_rows_into`."""
    w = src.shape[2]
    work, images = _scratch(k), np.empty((8, 5), np.int64)
    columns = np.empty((3, 0))  # no −Z pixel here
    for r0 in range(first, last):
        for c0 in range(r0, (n - 1) // 2 + 1):
            for base in (TOP, BOTTOM):
                count, r, c = 0, r0, c0
                for turn in range(4):
                    count = _image(images, count, base, r, c, turn * (w // 4), 0)
                    count = _image(images, count, base, r, n - 1 - c, (4 - turn) % 4 * (w // 4), 1)
                    r, c = (c, n - 1 - r) if base == TOP else (n - 1 - c, r)
                _orbit(src, levels, reduced, row_offsets, caps, n, k, kinds, base, r0, c0, images, np.int64(count), out,
                       np.int64(0), work, columns)
