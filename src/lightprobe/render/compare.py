"""Image error against a reference: relative MSE, mean absolute relative error, HDR-FLIP, and a heat map.

Definitions (per pixel and channel, averaged; ``mask`` restricts to some pixels; ε makes them scale-invariant and
keeps black reference pixels from dividing by zero, ε = 1 % of the reference's mean):

* relative MSE  = mean((t − r)² / (r² + ε²))
* MARE          = mean(|t − r| / (|r| + ε))
* HDR-FLIP      = NVIDIA's FLIP in HDR mode (package ``flip-evaluator``): mean perceived difference in [0, 1].
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..util.errors import LayoutError
from ..maps.tonemap import heatmap, luminance


@dataclass(frozen=True)
class Metrics:
    """The three measures of one comparison (:func:`compare`), and how many pixels they cover.

    Parameters
    ----------
    relative_mse : float
        mean((t − r)² / (r² + ε²)) over the compared pixels and channels (:func:`relative_mse`).
    mare : float
        mean(|t − r| / (|r| + ε)) over the compared pixels and channels (:func:`mare`).
    flip : float
        Mean HDR-FLIP over the whole image, in [0, 1] (:func:`hdr_flip`).
    pixels : int
        Pixels compared: all of the image, or those of the mask.
    """
    relative_mse: float
    mare: float
    flip: float
    pixels: int

    def as_dict(self) -> dict:
        """The measures as a plain dict, for JSON.

        Returns
        -------
        dict
            ``relative_mse``, ``mare``, ``flip`` and ``pixels`` with their values.
        """
        return asdict(self)


def _epsilon(reference: np.ndarray) -> float:
    return 0.01 * max(float(np.mean(np.abs(reference))), 1e-12)


def relative_mse(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Relative MSE: mean((t − r)² / (r² + ε²)) over pixels and channels.

    ε is 1 % of the mean |r| of the values compared (at least 1e-14), so the measure is scale-invariant and black
    reference pixels do not divide by zero.

    Parameters
    ----------
    test : numpy.ndarray
        The image under test, linear RGB radiance, the shape of ``reference``.
    reference : numpy.ndarray
        The reference image, linear RGB radiance.
    mask : numpy.ndarray or None
        Boolean selection of the values compared (as ``reference[mask]`` indexes: the images' shape, or their leading
        dimensions); None (default): all.

    Returns
    -------
    float
        The relative MSE (dimensionless).
    """
    eps = _epsilon(reference if mask is None else reference[mask])
    e = (test - reference) ** 2 / (reference**2 + eps**2)
    return float(np.mean(e if mask is None else e[mask]))


def mare(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean absolute relative error: mean(|t − r| / (|r| + ε)) over pixels and channels.

    ε is 1 % of the mean |r| of the values compared (at least 1e-14).

    Parameters
    ----------
    test, reference : numpy.ndarray
        The image under test and the reference, linear RGB radiance of one shape, as for :func:`relative_mse`.
    mask : numpy.ndarray or None
        The values compared, selected as for :func:`relative_mse`; None (default): all.

    Returns
    -------
    float
        The MARE (dimensionless; 0.01 is 1 %).
    """
    eps = _epsilon(reference if mask is None else reference[mask])
    e = np.abs(test - reference) / (np.abs(reference) + eps)
    return float(np.mean(e if mask is None else e[mask]))


def hdr_flip(test: np.ndarray, reference: np.ndarray) -> tuple[float, np.ndarray]:
    """(mean HDR-FLIP, per-pixel FLIP map in [0, 1]).

    NVIDIA's FLIP in HDR mode (package ``flip-evaluator``). Both images have NaN set to 0 and negative values clamped
    to 0, and are evaluated in float32.

    Parameters
    ----------
    test : numpy.ndarray
        (H, W, 3) image under test, linear RGB radiance (NaN read as 0, negative values as 0).
    reference : numpy.ndarray
        (H, W, 3) reference image, likewise.

    Returns
    -------
    mean : float
        The mean perceived difference, in [0, 1].
    error_map : numpy.ndarray
        (H, W) float32 per-pixel FLIP, in [0, 1].
    """
    import flip_evaluator

    ref = np.ascontiguousarray(np.maximum(np.nan_to_num(reference), 0), dtype=np.float32)
    tst = np.ascontiguousarray(np.maximum(np.nan_to_num(test), 0), dtype=np.float32)
    error_map, mean, _ = flip_evaluator.evaluate(ref, tst, "HDR", applyMagma=False)
    return float(mean), np.asarray(error_map, dtype=np.float32).reshape(ref.shape[:2])


def compare(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> Metrics:
    """All three measures of ``test`` against ``reference`` (both linear RGB radiance of one size).

    Parameters
    ----------
    test : array_like
        (H, W, 3) image under test, linear RGB radiance (read as float64).
    reference : array_like
        (H, W, 3) reference image, linear RGB radiance.
    mask : array_like or None
        (H, W) booleans: the pixels (every channel of each) that relative MSE and MARE average over; HDR-FLIP is
        always of the whole image. None (default): every pixel.

    Returns
    -------
    Metrics
        Relative MSE, MARE, mean HDR-FLIP and the number of pixels compared.

    Raises
    ------
    LayoutError
        The images are not both H×W×3 of the same size.
    """
    test, reference = np.asarray(test, np.float64), np.asarray(reference, np.float64)
    if test.shape != reference.shape or test.ndim != 3 or test.shape[2] != 3:
        raise LayoutError(f"images to compare must be the same H×W×3 size, got {test.shape} and {reference.shape}")
    pixel_mask = None if mask is None else np.broadcast_to(np.asarray(mask, bool)[..., None], test.shape)
    flip, _ = hdr_flip(test, reference)
    return Metrics(relative_mse(test, reference, pixel_mask), mare(test, reference, pixel_mask), flip,
                   int(test.shape[0] * test.shape[1] if mask is None else np.count_nonzero(mask)))


def relative_error_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|t − r| / (r + ε) on luminance, per pixel.

    Luminance is Rec. 709's; ε is 1 % of the mean |luminance| of the reference (at least 1e-14).

    Parameters
    ----------
    test : numpy.ndarray
        (H, W, 3) image under test, linear RGB radiance, reduced to its luminance.
    reference : numpy.ndarray
        (H, W, 3) reference image, linear RGB radiance, reduced to its luminance (which also sets ε).

    Returns
    -------
    numpy.ndarray
        (H, W) float64 relative error (0.1 is 10 %).
    """
    t, r = luminance(np.asarray(test, np.float64)), luminance(np.asarray(reference, np.float64))
    return np.abs(t - r) / (np.abs(r) + _epsilon(r))


def error_heatmap(test: np.ndarray, reference: np.ndarray, vmax: float = 0.5) -> np.ndarray:
    """Display-encoded heat map of the relative luminance error (black 0 → pale yellow ``vmax`` and above).

    Parameters
    ----------
    test, reference : numpy.ndarray
        The images compared, as for :func:`relative_error_map`.
    vmax : float
        The relative error at the top of the ramp; larger errors show its colour. Default 0.5 (50 %).

    Returns
    -------
    numpy.ndarray
        (H, W, 3) float32 display-encoded RGB in [0, 1] (:func:`lightprobe.maps.tonemap.heatmap`); NaN shows grey.
    """
    return heatmap(relative_error_map(test, reference), vmax)
