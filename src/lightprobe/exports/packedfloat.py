"""The two packed unsigned-float texel encodings of GPU formats: RGB9E5 (shared exponent) and B10G11R11.

Both hold three non-negative channels in 32 bits, as ``VK_FORMAT_E5B9G9R9_UFLOAT_PACK32`` /
``GL_RGB9_E5`` and ``VK_FORMAT_B10G11R11_UFLOAT_PACK32`` / ``GL_R11F_G11F_B10F`` lay them out (little-endian words):

* **RGB9E5**: red in bits 0–8, green 9–17, blue 18–26 (9-bit mantissas without an implicit leading one) and one
  5-bit exponent in bits 27–31 with bias 15; a channel is ``mantissa · 2^(exponent − 24)``. Encoded exactly as
  GL_EXT_texture_shared_exponent (and the Vulkan specification's "shared exponent" conversion) give it: clamp to
  [0, 65408], the shared exponent from the largest channel, raised by one when that channel's mantissa rounds up to
  512, and each mantissa rounded half up.
* **B10G11R11**: red in bits 0–10 and green in 11–21 (5-bit exponent, 6-bit mantissa), blue in 22–31 (5-bit
  exponent, 5-bit mantissa); the exponent bias is 15, as half floats, with denormals; no sign bit. Rounded to
  nearest, ties to even (as a float → half conversion rounds); values above the largest finite value (65024 for
  11 bits, 64512 for 10) and +∞ become that value, never ∞, so that a bright sun stays a finite light.

Both refuse NaN (one line naming how many) and clamp negative values to 0. The decoders return float64 values equal
to what a GPU reads. Pure numpy, exact: the round trips are tested bit for bit.
"""

from __future__ import annotations

import numpy as np

from ..util.errors import UsageError

RGB9E5_MAX = 65408.0  # (2⁹ − 1)/2⁹ · 2^(31 − 15): the largest value RGB9E5 holds
UF11_MAX = 65024.0  # (2 − 2⁻⁶) · 2¹⁵
UF10_MAX = 64512.0  # (2 − 2⁻⁵) · 2¹⁵
_BIAS = 15
_MANTISSA_BITS_9E5 = 9


def _channels(rgb, what: str) -> np.ndarray:
    """(..., 3) float64, NaN refused, negative → 0."""
    c = np.asarray(rgb, dtype=np.float64)
    if c.ndim < 1 or c.shape[-1] != 3:
        raise UsageError(f"{what} needs (..., 3) RGB values, not shape {c.shape}")
    nan = int(np.isnan(c).sum())
    if nan:
        raise UsageError(f"{what} cannot hold NaN: {nan} value(s) are NaN")
    return np.maximum(c, 0.0)


def _floor_log2(x: np.ndarray) -> np.ndarray:
    """⌊log₂ x⌋ for finite x > 0, exactly (frexp gives x = m·2^e with m in [0.5, 1))."""
    return np.frexp(x)[1].astype(np.int64) - 1


def encode_rgb9e5(rgb) -> np.ndarray:
    """Linear RGB → packed RGB9E5 words, exactly as GL_EXT_texture_shared_exponent encodes.

    Parameters
    ----------
    rgb : array_like
        (..., 3) linear values; negative values count as 0, values above :data:`RGB9E5_MAX` (and +∞) as that maximum.

    Returns
    -------
    numpy.ndarray
        (...) uint32 words: red mantissa in bits 0–8, green 9–17, blue 18–26, the shared exponent (bias 15) in 27–31.

    Raises
    ------
    UsageError
        A value is NaN, or the last axis is not 3.
    """
    c = np.minimum(_channels(rgb, "RGB9E5"), RGB9E5_MAX)
    peak = c.max(axis=-1)
    n = _MANTISSA_BITS_9E5
    e_floor = np.where(peak > 0, _floor_log2(np.where(peak > 0, peak, 1.0)), -_BIAS - 1)
    exp_p = np.maximum(-_BIAS - 1, e_floor) + 1 + _BIAS
    peak_s = np.floor(peak / np.exp2(exp_p - _BIAS - n) + 0.5)
    exp = np.where(peak_s >= 2 ** n, exp_p + 1, exp_p)
    mant = np.floor(c / np.exp2(exp - _BIAS - n)[..., None] + 0.5).astype(np.uint32)
    return (mant[..., 0] | (mant[..., 1] << 9) | (mant[..., 2] << 18) | (exp.astype(np.uint32) << 27)).astype(np.uint32)


def decode_rgb9e5(words) -> np.ndarray:
    """Packed RGB9E5 words → linear RGB, as a GPU samples them.

    Parameters
    ----------
    words : array_like
        (...) unsigned 32-bit words as :func:`encode_rgb9e5` makes them.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64: each channel ``mantissa · 2^(exponent − 24)``.
    """
    w = np.asarray(words, dtype=np.uint32)
    scale = np.exp2((w >> 27).astype(np.float64) - _BIAS - _MANTISSA_BITS_9E5)
    mant = np.stack([(w >> s) & 0x1FF for s in (0, 9, 18)], axis=-1).astype(np.float64)
    return mant * scale[..., None]


def _encode_small_float(c: np.ndarray, mantissa_bits: int, largest: float) -> np.ndarray:
    """Non-negative, non-NaN float64 → unsigned small-float bit patterns (5-bit exponent, bias 15), ties to even."""
    c = np.minimum(c, largest)
    e = np.where(c > 0, _floor_log2(np.where(c > 0, c, 1.0)), -_BIAS + 1)
    e = np.maximum(e, 1 - _BIAS)  # denormals share the smallest normal exponent's quantum
    quantum = np.exp2(e - mantissa_bits)
    r = np.minimum(np.rint(c / quantum) * quantum, largest)  # rint: half to even; exact (scaling by a power of 2)
    normal = r >= 2.0 ** (1 - _BIAS)
    er = np.where(normal, _floor_log2(np.where(normal, r, 1.0)), 1 - _BIAS)
    mant = np.where(normal, r / np.exp2(er - mantissa_bits) - 2 ** mantissa_bits, r / np.exp2(1 - _BIAS - mantissa_bits))
    field = np.where(normal, er + _BIAS, 0)
    return ((field.astype(np.uint32) << mantissa_bits) | mant.astype(np.uint32)).astype(np.uint32)


def _decode_small_float(bits: np.ndarray, mantissa_bits: int) -> np.ndarray:
    exp = (bits >> mantissa_bits).astype(np.int64)
    mant = (bits & ((1 << mantissa_bits) - 1)).astype(np.float64)
    one = 2.0 ** mantissa_bits
    value = np.where(exp == 0, mant / one * 2.0 ** (1 - _BIAS), (1 + mant / one) * np.exp2(exp - _BIAS))
    return np.where(exp == 31, np.where(mant == 0, np.inf, np.nan), value)


def encode_b10g11r11(rgb) -> np.ndarray:
    """Linear RGB → packed B10G11R11 unsigned-float words, rounded to nearest (ties to even).

    Parameters
    ----------
    rgb : array_like
        (..., 3) linear values; negative values count as 0; values above the largest finite value of the channel
        (:data:`UF11_MAX` for red and green, :data:`UF10_MAX` for blue) and +∞ become that value.

    Returns
    -------
    numpy.ndarray
        (...) uint32 words: red (11 bits) in bits 0–10, green (11) in 11–21, blue (10) in 22–31.

    Raises
    ------
    UsageError
        A value is NaN, or the last axis is not 3.
    """
    c = _channels(rgb, "B10G11R11")
    r = _encode_small_float(c[..., 0], 6, UF11_MAX)
    g = _encode_small_float(c[..., 1], 6, UF11_MAX)
    b = _encode_small_float(c[..., 2], 5, UF10_MAX)
    return (r | (g << 11) | (b << 22)).astype(np.uint32)


def decode_b10g11r11(words) -> np.ndarray:
    """Packed B10G11R11 words → linear RGB, as a GPU samples them.

    Parameters
    ----------
    words : array_like
        (...) unsigned 32-bit words as :func:`encode_b10g11r11` makes them.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64; an all-ones exponent reads as +∞ (mantissa 0) or NaN, as the formats define (the encoder
        never writes one).
    """
    w = np.asarray(words, dtype=np.uint32)
    return np.stack([_decode_small_float(w & 0x7FF, 6), _decode_small_float((w >> 11) & 0x7FF, 6),
                     _decode_small_float((w >> 22) & 0x3FF, 5)], axis=-1)
