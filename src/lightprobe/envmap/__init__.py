"""Environment maps: the :class:`EnvMap` type (``map``), bad-pixel repair (``pixels``), image files (``files``) and
resampling between layouts (``resample``). Everything is importable from here."""

from .files import file_shape, from_image, read_envmap, to_image
from .map import EnvMap, frozen_array, owned, pixel_geometry
from .pixels import bad_pixel_counts, repair
from .resample import (MAX_FOOTPRINT_RATIO, auto_samples, box_reduce, check_size, resample, resample_memory,
                       resample_strips, Resampler)

__all__ = ["EnvMap", "read_envmap", "from_image", "to_image", "file_shape", "pixel_geometry", "frozen_array",
           "owned", "bad_pixel_counts", "repair", "resample", "box_reduce", "auto_samples", "check_size",
           "resample_memory", "resample_strips", "Resampler", "MAX_FOOTPRINT_RATIO"]
