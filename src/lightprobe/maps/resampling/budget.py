"""What a conversion may cost, checked before anything is allocated: its target's pixel count and its peak memory."""

from __future__ import annotations

import math

import numpy as np

from ...util.errors import UsageError
from ...util.limits import check_pixels
from ..layouts import Layout
from .flux import _flux_corrects
from .taps import _face_layout

# Peak bytes of :func:`resample` beyond the source (measured on 2048×1024 and 4096×2048 sources,
# tests/test_limits.py). Per source pixel: the padded copy a cube or disc source is read from (a latlong is read in
# place), box reductions. Per target pixel: the float32 output and, for discs, the validity mask.
RESAMPLE_BYTES_PER_SOURCE_PIXEL = 24
FLUX_BYTES_PER_SOURCE_PIXEL = 160
RESAMPLE_BYTES_PER_TARGET_PIXEL = {"angular": 20, "sphere": 20}
RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT = 16


def check_size(layout: Layout, size: int) -> int:
    """Refuse sizes whose pixel count would be absurd before allocating anything; returns the pixel count.

    The count is exact: Python integers, so no size can overflow.

    Parameters
    ----------
    layout : Layout
        The layout the size is for.
    size : int
        Its size (image height, or face edge for cube layouts); a positive whole number (a numpy integer too).

    Returns
    -------
    int
        The number of pixels of the layout's grid for ``size``.

    Raises
    ------
    UsageError
        When ``size`` is not a whole number or is under 1.
    BudgetError
        When the pixel count is over the pixel limit (``LIGHTPROBE_MAX_PIXELS``).
    """
    if not isinstance(size, (int, np.integer)) or size < 1:
        raise UsageError(f"size must be a positive whole number, got {size!r}")
    n = math.prod(int(v) for v in layout.grid_shape(int(size)))
    check_pixels(n, f"size {size} for {layout.name}")
    return n


def resample_memory(source_pixels: int, target_pixels: int, target: Layout, source: Layout | None = None) -> int:
    """Estimated peak memory (bytes) of :func:`~lightprobe.maps.resampling.resampler.resample` beyond the source map.

    From ``source_pixels`` to ``target_pixels`` of ``target``; a ``source`` whose conversions are flux-corrected
    (:func:`lightprobe.maps.resampling.flux._flux_corrects`: all but a lat-long's, save small ones into discs), or not
    named, adds its correction's deliveries, flows and weights (:func:`lightprobe.maps.resampling.flux._flux_stencil`:
    measured 75–120 B a source pixel, more where a face's side is just past a power of two).

    Parameters
    ----------
    source_pixels : int
        Pixels of the source map's grid.
    target_pixels : int
        Pixels of the target's grid.
    target : Layout
        The target layout (a disc target needs more a pixel: its validity mask).
    source : Layout or None, default None
        The source's layout; None counts the flux correction's memory, as the worst case.

    Returns
    -------
    int
        Bytes: per source pixel 24 (+ 160 with the flux correction), per target pixel 16 (20 for discs).
    """
    per_target = RESAMPLE_BYTES_PER_TARGET_PIXEL.get(target.name, RESAMPLE_BYTES_PER_TARGET_PIXEL_DEFAULT)
    per_source = RESAMPLE_BYTES_PER_SOURCE_PIXEL
    if source is None or _flux_corrects(source, source_pixels, _face_layout(target)):
        per_source += FLUX_BYTES_PER_SOURCE_PIXEL
    return source_pixels * per_source + target_pixels * per_target
