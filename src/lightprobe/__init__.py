"""lightprobe: HDR environment maps (light probes) → lighting for real-time renderers, checked against ground truth.

Layers (nothing imports upward): ``io``, ``layouts``, ``frames``, ``tonemap`` at the bottom; ``envmap`` on them;
``demo`` and the thin ``cli`` on top.
"""

from .envmap import EnvMap, read_envmap, resample
from .errors import InputError, LayoutError, LightprobeError, LightprobeWarning
from .frames import RH2001, WORLD, rotation_from_ypr
from .layouts import LAYOUTS, detect_layout, layout

__all__ = [
    "EnvMap", "read_envmap", "resample", "LightprobeError", "InputError", "LayoutError", "LightprobeWarning",
    "WORLD", "RH2001", "rotation_from_ypr", "LAYOUTS", "layout", "detect_layout",
]
__version__ = "0.1.0"
