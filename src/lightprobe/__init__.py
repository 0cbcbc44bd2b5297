"""lightprobe: HDR environment maps (light probes) → lighting for real-time renderers, checked against ground truth.

Layers (nothing imports upward): ``io``, ``layouts``, ``frames``, ``tonemap`` at the bottom; ``envmap`` on them;
``sh``, ``irradiance``, ``export``, ``prefilter``, ``containers``, ``render`` above; ``demo`` and the thin ``cli``
on top. The names of ``__all__`` load on first use.
"""

import os as _os

# numba keeps compiled kernels beside the source by default, which fails where the package is installed read-only;
# keep them in the user's cache folder instead (before numba is first imported, which reads this once). The folder
# is keyed by the package's sources: numba checks only a kernel's own file for changes, so a kernel that inlines a
# helper from another module would otherwise keep a stale copy of it after that module changed.


def _numba_cache_dir(root: str = _os.path.dirname(__file__)) -> str:
    import zlib

    stamp = []
    for folder, dirs, files in sorted(_os.walk(root)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(f for f in files if f.endswith(".py")):
            info = _os.stat(_os.path.join(folder, name))
            stamp.append(f"{_os.path.relpath(folder, root)}/{name}:{info.st_size}:{info.st_mtime_ns}")
    base = _os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache")
    return _os.path.join(base, "lightprobe", "numba", f"{zlib.crc32(chr(10).join(stamp).encode()):08x}")


if "NUMBA_CACHE_DIR" not in _os.environ:
    _os.environ["NUMBA_CACHE_DIR"] = _numba_cache_dir()

# One thread setting for everything below: LIGHTPROBE_THREADS sizes numba's pool and BLAS's before either loads
# (a malformed value is reported when a kernel first runs, by lightprobe.limits.threads).
if _os.environ.get("LIGHTPROBE_THREADS", "").strip().isdigit() and int(_os.environ["LIGHTPROBE_THREADS"]) > 0:
    for _name in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        _os.environ.setdefault(_name, _os.environ["LIGHTPROBE_THREADS"].strip())

from .errors import InputError, LayoutError, LightprobeError, LightprobeWarning  # noqa: E402 - after the setting

# Everything below loads on first use (PEP 562), so `import lightprobe` stays light: no numba, no OpenImageIO, no
# trimesh until a function that needs them runs. Name → module it lives in.
_LAZY = {
    "EnvMap": "envmap", "read_envmap": "envmap", "resample": "envmap", "Resampler": "envmap",
    "WORLD": "frames", "RH2001": "frames", "rotation_from_ypr": "frames", "frame": "frames",
    "LAYOUTS": "layouts", "layout": "layouts", "detect_layout": "layouts",
    "SHCoeffs": "sh", "project": "sh",
    "export": "export", "irradiance_map": "irradiance", "brute_irradiance": "irradiance",
    "error_report": "irradiance", "prefilter_cube": "prefilter", "babylon_env": "containers",
    "read_image": "io", "write_image": "io",
    "decompose": "lights", "LightParams": "lights", "AreaLight": "lights",
}

__all__ = ["LightprobeError", "InputError", "LayoutError", "LightprobeWarning", *_LAZY]
__version__ = "0.1.0"


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'lightprobe' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
