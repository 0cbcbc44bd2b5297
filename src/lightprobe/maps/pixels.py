"""Bad pixels: counting NaN, infinite and negative values, and repairing them (replaced by 0, with one warning)."""

from __future__ import annotations

import warnings

import numpy as np

from ..util.errors import LightprobeWarning


def bad_pixel_counts(data: np.ndarray) -> dict[str, int]:
    """Number of pixels with any NaN, any ±inf, or any negative (finite) channel.

    A clean map (nearly every file) is recognised by its minimum and maximum alone — two reductions without
    temporaries, NaN propagating into both — so reading is not slowed by the check and needs no compiled kernel
    (which would cost every command numba's import); only a map that fails them is counted in full.

    Parameters
    ----------
    data : numpy.ndarray
        Linear RGB pixels, shape ``(..., 3)`` (an ``(H, W, 3)`` image, a cube's ``(6, N, N, 3)`` faces or ``(N, 3)``
        pixels): read as ``(N, 3)`` rows of R, G, B, in any float dtype. Not modified.

    Returns
    -------
    dict[str, int]
        Pixel counts under the keys ``"nan"``, ``"inf"`` and ``"negative"``: a pixel counts once under each kind of
        bad channel it has (a pixel with a NaN and a negative channel counts under both). All 0 for a clean or empty
        array.
    """
    px = np.asarray(data).reshape(-1, 3)
    if px.size == 0 or (px.min() >= 0 and px.max() < np.inf):
        return {"nan": 0, "inf": 0, "negative": 0}
    nan = np.isnan(px).any(axis=1)
    inf = np.isinf(px).any(axis=1)
    neg = ((px < 0) & np.isfinite(px)).any(axis=1)
    return {"nan": int(nan.sum()), "inf": int(inf.sum()), "negative": int(neg.sum())}


def repair(data: np.ndarray, source: str = "image") -> np.ndarray:
    """Replace NaN, infinite and negative values by 0, warning once with how many pixels were touched.

    Parameters
    ----------
    data : numpy.ndarray
        Linear RGB radiance, shape ``(..., 3)`` (as :func:`bad_pixel_counts` reads it). Not modified.
    source : str, default "image"
        What the pixels came from (a file's path), the first words of the warning.

    Returns
    -------
    numpy.ndarray
        ``data`` itself when no value is bad; otherwise a new float32 array of the same shape with every NaN, ±inf
        and negative channel value set to 0 (the other channels of a pixel are kept), after one
        :class:`~lightprobe.util.errors.LightprobeWarning` giving the NaN, infinite and negative pixel counts.
    """
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
