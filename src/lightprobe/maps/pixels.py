"""Bad pixels: counting NaN, infinite and negative values, and repairing them (replaced by 0, with one warning)."""

from __future__ import annotations

import warnings

import numpy as np

from ..util.errors import LightprobeWarning


def bad_pixel_counts(data: np.ndarray) -> dict[str, int]:
    """Number of pixels with any NaN, any ±inf, or any negative (finite) channel.

    A clean map (nearly every file) is recognised by its minimum and maximum alone — two reductions without
    temporaries, NaN propagating into both — so reading is not slowed by the check and needs no compiled kernel
    (which would cost every command numba's import); only a map that fails them is counted in full."""
    px = np.asarray(data).reshape(-1, 3)
    if px.size == 0 or (px.min() >= 0 and px.max() < np.inf):
        return {"nan": 0, "inf": 0, "negative": 0}
    nan = np.isnan(px).any(axis=1)
    inf = np.isinf(px).any(axis=1)
    neg = ((px < 0) & np.isfinite(px)).any(axis=1)
    return {"nan": int(nan.sum()), "inf": int(inf.sum()), "negative": int(neg.sum())}


def repair(data: np.ndarray, source: str = "image") -> np.ndarray:
    """Replace NaN, infinite and negative values by 0, warning once with how many pixels were touched."""
    counts = bad_pixel_counts(data)
    if not any(counts.values()):
        return data
    warnings.warn(
        f"{source}: replaced by 0 the bad values of {counts['nan']} NaN, {counts['inf']} infinite and "
        f"{counts['negative']} negative pixels",
        LightprobeWarning,
        stacklevel=3,
    )
    clean = np.nan_to_num(data, nan=0.0, posinf=0.0, neginf=0.0)
    return np.maximum(clean, 0.0).astype(np.float32)
