"""Environment maps: the :class:`EnvMap` type (``map``), bad-pixel repair (``pixels``), image files (``files``) and
resampling between layouts (``resampling``). Everything is importable from here. ``resampling``'s names load on
first use (PEP 562): reading a map and projecting it (``lightprobe sh``, ``info``) never needs the resampler, whose
kernels and tables took 27 ms of a 230 ms ``lightprobe sh`` (2048×1024 .exr)."""

from .files import file_shape, from_image, read_envmap, to_image
from .envmap import EnvMap, frozen_array, owned, pixel_geometry
from .pixels import bad_pixel_counts, repair

# the resampling's public names, each with its module in maps/resampling (imported on first use)
_RESAMPLING = {"MAX_FOOTPRINT_RATIO": "resampler", "auto_samples": "resampler", "box_reduce": "resampler",
               "check_size": "budget", "link_kernels": "resampler", "resample": "resampler",
               "resample_memory": "budget", "resample_strips": "resampler", "Resampler": "cached"}

__all__ = ["EnvMap", "read_envmap", "from_image", "to_image", "file_shape", "pixel_geometry", "frozen_array",
           "owned", "bad_pixel_counts", "repair", *_RESAMPLING]


def __getattr__(name: str):
    if name in _RESAMPLING:
        from importlib import import_module

        return getattr(import_module(f"{__name__}.resampling.{_RESAMPLING[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_RESAMPLING))
