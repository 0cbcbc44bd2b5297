"""Display transforms: linear radiance → display-referred values in [0, 1].

``exposure`` is in stops (the image is multiplied by 2**exposure first). Curves:

* ``srgb``: clip to [0, 1], then the sRGB transfer function (IEC 61966-2-1).
* ``aces``: Narkowicz's fit of the ACES filmic RRT+ODT (x(2.51x+0.03)/(x(2.43x+0.59)+0.14)), then sRGB.
"""

from __future__ import annotations

import numpy as np

from ..util.errors import UsageError
from ..util.names import CURVES  # the names users type: numpy-free, for the command line

MAX_EXPOSURE = 64



def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] → sRGB-encoded [0, 1] (values outside [0, 1] are clipped first).

    The IEC 61966-2-1 transfer function: 12.92 x up to 0.0031308, 1.055 x^(1/2.4) − 0.055 above.

    Parameters
    ----------
    linear : numpy.ndarray
        Linear display values, any shape; clipped to [0, 1] (NaN stays NaN).

    Returns
    -------
    numpy.ndarray
        sRGB-encoded values in [0, 1], the shape of ``linear``; float32 stays float32, other input gives float64.
    """
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded [0, 1] → linear [0, 1].

    The inverse of :func:`srgb_encode`: x / 12.92 up to 0.04045, ((x + 0.055) / 1.055)^2.4 above.

    Parameters
    ----------
    encoded : numpy.ndarray
        sRGB-encoded values (an 8/16-bit image scaled to [0, 1]), any shape; read as float32, not clipped.

    Returns
    -------
    numpy.ndarray
        float32 linear values, the shape of ``encoded``.
    """
    x = np.asarray(encoded, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4)).astype(np.float32)


def aces_filmic(linear: np.ndarray) -> np.ndarray:
    """Narkowicz 2015 ACES filmic approximation, linear → linear display [0, 1].

    x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14) of x = max(linear, 0), clipped to [0, 1]; :func:`tonemap` encodes
    it to sRGB after.

    Parameters
    ----------
    linear : numpy.ndarray
        Linear radiance (already scaled by the exposure), any shape; negative values count as 0.

    Returns
    -------
    numpy.ndarray
        Linear display values in [0, 1], the shape of ``linear``.
    """
    x = np.maximum(linear, 0.0)
    return np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def tonemap(radiance: np.ndarray, exposure: float = 0.0, curve: str = "srgb") -> np.ndarray:
    """Linear radiance → display-encoded float values in [0, 1] (NaN and negative values show as black).

    The radiance is multiplied by 2**exposure, then mapped by ``curve`` (see the module docstring). Infinite values
    show as black too.

    Parameters
    ----------
    radiance : numpy.ndarray
        Linear RGB radiance, any shape (usually (H, W, 3)); read as float32.
    exposure : float, default 0.0
        Exposure in stops, within ±:data:`MAX_EXPOSURE` (64).
    curve : str, default "srgb"
        The tone curve: ``"srgb"`` (clip to [0, 1], then the sRGB transfer function) or ``"aces"`` (Narkowicz's
        ACES filmic fit, then sRGB).

    Returns
    -------
    numpy.ndarray
        float32 sRGB-encoded display values in [0, 1], the shape of ``radiance``.

    Raises
    ------
    UsageError
        When ``curve`` is not a known tone curve, or ``exposure`` is outside ±64 stops or NaN.
    """
    if curve not in CURVES:
        raise UsageError(f"unknown tone curve {curve!r}; choose one of {', '.join(CURVES)}")
    if not -MAX_EXPOSURE <= exposure <= MAX_EXPOSURE:  # also refuses NaN; 2**1024 overflows a float
        raise UsageError(f"exposure must be within ±{MAX_EXPOSURE} stops, got {exposure}")
    x = np.nan_to_num(np.asarray(radiance, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0) * 2.0**exposure
    if curve == "aces":
        x = aces_filmic(x)
    return srgb_encode(x).astype(np.float32)


def to_uint8(display: np.ndarray) -> np.ndarray:
    """Display values in [0, 1] → 8-bit, rounded.

    Parameters
    ----------
    display : numpy.ndarray
        Display-encoded values (as :func:`tonemap` returns them), any shape; values outside [0, 1] are clipped to
        0 and 255.

    Returns
    -------
    numpy.ndarray
        uint8 values round(255 x), the shape of ``display``.
    """
    return np.clip(np.rint(np.asarray(display) * 255.0), 0, 255).astype(np.uint8)


def auto_exposure(radiance: np.ndarray, weights: np.ndarray | None = None, key: float = 0.18) -> float:
    """Exposure (stops) that maps the weighted geometric mean luminance to ``key`` (Reinhard's key value).

    Luminances are floored at 1e-6 before their logarithm; pixels whose luminance is not finite, or whose weight is
    not positive, are left out.

    Parameters
    ----------
    radiance : numpy.ndarray
        Linear RGB radiance, shape (..., 3).
    weights : numpy.ndarray or None, default None
        Per-pixel weights, the shape of ``radiance`` without its last axis (for a map: its pixels' solid angles, so
        the mean is over the sphere); None: every pixel weighs 1.
    key : float, default 0.18
        The luminance the geometric mean is brought to (linear display value; 0.18 is middle grey).

    Returns
    -------
    float
        The exposure in stops, log2(key) − log2(geometric mean); 0.0 when no pixel counts.
    """
    lum = luminance(np.asarray(radiance, dtype=np.float64))
    w = np.ones(lum.shape) if weights is None else np.asarray(weights, dtype=np.float64)
    good = np.isfinite(lum) & (w > 0)
    if not good.any():
        return 0.0
    log_mean = np.sum(w[good] * np.log(np.maximum(lum[good], 1e-6))) / np.sum(w[good])
    return float(np.log2(key) - log_mean / np.log(2))


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance 0.2126 R + 0.7152 G + 0.0722 B of linear RGB (..., 3).

    Parameters
    ----------
    rgb : numpy.ndarray
        Linear RGB (radiance, or an integral ∫L dω), shape (..., 3) or more channels (only the first three count);
        a float dtype.

    Returns
    -------
    numpy.ndarray
        Luminance in the unit of ``rgb``, shape ``rgb.shape[:-1]``, in the dtype of ``rgb``.
    """
    return np.asarray(rgb)[..., :3] @ np.array([0.2126, 0.7152, 0.0722], dtype=np.asarray(rgb).dtype)


# An inferno-like ramp (black → purple → red → orange → pale yellow), display-encoded, for error heat maps.
_HEAT_STOPS = np.array([[0.0, 0.0, 0.02], [0.34, 0.06, 0.43], [0.73, 0.21, 0.33], [0.98, 0.55, 0.04],
                        [0.99, 1.0, 0.64]], dtype=np.float32)


def heatmap(values: np.ndarray, vmax: float) -> np.ndarray:
    """Scalar values in [0, vmax] → display-encoded RGB (..., 3) on an inferno-like ramp; NaN shows as grey.

    Values are clipped to [0, vmax]: 0 is (near) black, ``vmax`` and above pale yellow, linearly between the ramp's
    five stops (black → purple → red → orange → pale yellow).

    Parameters
    ----------
    values : numpy.ndarray
        Scalar values (an error per pixel), any shape.
    vmax : float
        The value shown at the top of the ramp (> 0).

    Returns
    -------
    numpy.ndarray
        float32 display-encoded RGB in [0, 1], shape ``values.shape + (3,)``; NaN values are grey (0.5).
    """
    t = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float32) / vmax, nan=0.0), 0, 1) * (len(_HEAT_STOPS) - 1)
    i = np.minimum(t.astype(int), len(_HEAT_STOPS) - 2)
    f = (t - i)[..., None]
    rgb = _HEAT_STOPS[i] * (1 - f) + _HEAT_STOPS[i + 1] * f
    return np.where(np.isnan(np.asarray(values, dtype=np.float32))[..., None], 0.5, rgb).astype(np.float32)
