"""Exact overlaps of two partitions of one interval: the weights of a box reduction by any factor, not only 2.

A cell of the new partition takes each old cell's value in proportion to the length they share, so each old cell's
content is shared out whole (a sun keeps its energy) and a constant stays constant. Used where a lat-long's size
is not a power of two times what a reduction needs: an odd height halved (:func:`lightprobe.maps.resampling.resampler.
_odd_box_reduce`), a polar row of W = 2 × odd columns reduced to W / 2^ℓ rounded (:mod:`lightprobe.maps.resampling.polar`).
"""

from __future__ import annotations

import functools

import numpy as np


def interval_overlaps(old_edges: np.ndarray, new_edges: np.ndarray):
    """Sparse (new, old) CSR: the lengths of the intersections of two partitions of one interval, from their
    increasing edges (each new cell's few old cells only: a dense table of a 4k map's columns was 2 GB)."""
    from scipy import sparse

    n_old = len(old_edges) - 1
    first = np.clip(np.searchsorted(old_edges, new_edges[:-1], side="right") - 1, 0, n_old - 1)
    last = np.searchsorted(old_edges, new_edges[1:], side="left")  # one past the last old cell each new one meets
    old = first[:, None] + np.arange(int((last - first).max()))[None, :]
    inside = old < n_old
    old = np.minimum(old, n_old - 1)
    length = np.minimum(new_edges[1:, None], old_edges[old + 1]) - np.maximum(new_edges[:-1, None], old_edges[old])
    length = np.where(inside, np.maximum(length, 0.0), 0.0)
    new = np.repeat(np.arange(len(new_edges) - 1), old.shape[1])
    return sparse.csr_matrix((length.ravel(), (new, old.ravel())), shape=(len(new_edges) - 1, n_old))


@functools.lru_cache(maxsize=32)
def column_means(width: int, cells: int):
    """Sparse (cells, width) CSR (kept for the last few widths: every row of a level, and every map of a batch,
    shares it; read-only by use): row j holds the weights that make reduced cell j of a periodic row of ``width``
    columns, reduced to ``cells`` equal cells, the mean of the columns it overlaps (each weight the share of the
    column it covers over the cell's width in columns; every column's weights sum to cells / width)."""
    overlaps = interval_overlaps(np.arange(width + 1, dtype=np.float64), np.arange(cells + 1) * (width / cells))
    return (overlaps * (cells / width)).tocsr()
