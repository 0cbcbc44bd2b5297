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
    relative_mse: float
    mare: float
    flip: float
    pixels: int

    def as_dict(self) -> dict:
        return asdict(self)


def _epsilon(reference: np.ndarray) -> float:
    return 0.01 * max(float(np.mean(np.abs(reference))), 1e-12)


def relative_mse(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    eps = _epsilon(reference if mask is None else reference[mask])
    e = (test - reference) ** 2 / (reference**2 + eps**2)
    return float(np.mean(e if mask is None else e[mask]))


def mare(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    eps = _epsilon(reference if mask is None else reference[mask])
    e = np.abs(test - reference) / (np.abs(reference) + eps)
    return float(np.mean(e if mask is None else e[mask]))


def hdr_flip(test: np.ndarray, reference: np.ndarray) -> tuple[float, np.ndarray]:
    """(mean HDR-FLIP, per-pixel FLIP map in [0, 1])."""
    import flip_evaluator

    ref = np.ascontiguousarray(np.maximum(np.nan_to_num(reference), 0), dtype=np.float32)
    tst = np.ascontiguousarray(np.maximum(np.nan_to_num(test), 0), dtype=np.float32)
    error_map, mean, _ = flip_evaluator.evaluate(ref, tst, "HDR", applyMagma=False)
    return float(mean), np.asarray(error_map, dtype=np.float32).reshape(ref.shape[:2])


def compare(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> Metrics:
    """All three measures of ``test`` against ``reference`` (both linear RGB radiance of one size)."""
    test, reference = np.asarray(test, np.float64), np.asarray(reference, np.float64)
    if test.shape != reference.shape or test.ndim != 3 or test.shape[2] != 3:
        raise LayoutError(f"images to compare must be the same H×W×3 size, got {test.shape} and {reference.shape}")
    pixel_mask = None if mask is None else np.broadcast_to(np.asarray(mask, bool)[..., None], test.shape)
    flip, _ = hdr_flip(test, reference)
    return Metrics(relative_mse(test, reference, pixel_mask), mare(test, reference, pixel_mask), flip,
                   int(test.shape[0] * test.shape[1] if mask is None else np.count_nonzero(mask)))


def relative_error_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|t − r| / (r + ε) on luminance, per pixel."""
    t, r = luminance(np.asarray(test, np.float64)), luminance(np.asarray(reference, np.float64))
    return np.abs(t - r) / (np.abs(r) + _epsilon(r))


def error_heatmap(test: np.ndarray, reference: np.ndarray, vmax: float = 0.5) -> np.ndarray:
    """Display-encoded heat map of the relative luminance error (black 0 → pale yellow ``vmax`` and above)."""
    return heatmap(relative_error_map(test, reference), vmax)
