"""Bad pixels: counting NaN, infinite and negative values, and repairing them (replaced by 0, with one warning)."""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import LightprobeWarning
from ..kernels import bad_pixel_scan


def bad_pixel_counts(data: np.ndarray) -> dict[str, int]:
    """Number of pixels with any NaN, any ±inf, or any negative (finite) channel (one compiled pass)."""
    px = np.ascontiguousarray(np.asarray(data, dtype=np.float32).reshape(-1, 3))
    nan, inf, neg = bad_pixel_scan(px)
    return {"nan": int(nan), "inf": int(inf), "negative": int(neg)}


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
