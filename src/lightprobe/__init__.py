"""lightprobe: HDR environment maps (light probes) → lighting for real-time renderers, checked against ground truth.

Layers (nothing imports upward): ``io``, ``layouts``, ``frames``, ``tonemap`` at the bottom; ``envmap`` on them;
``demo`` and the thin ``cli`` on top.
"""

import os as _os

# numba keeps compiled kernels beside the source by default, which fails where the package is installed read-only;
# keep them in the user's cache folder instead (before numba is first imported, which reads this once).
_os.environ.setdefault("NUMBA_CACHE_DIR", _os.path.join(
    _os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache"), "lightprobe", "numba"))

from .envmap import EnvMap, read_envmap, resample  # noqa: E402 - after the cache setting
from .errors import InputError, LayoutError, LightprobeError, LightprobeWarning  # noqa: E402
from .frames import RH2001, WORLD, rotation_from_ypr  # noqa: E402
from .layouts import LAYOUTS, detect_layout, layout  # noqa: E402

__all__ = [
    "EnvMap", "read_envmap", "resample", "LightprobeError", "InputError", "LayoutError", "LightprobeWarning",
    "WORLD", "RH2001", "rotation_from_ypr", "LAYOUTS", "layout", "detect_layout",
]
__version__ = "0.1.0"
