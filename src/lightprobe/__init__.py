"""lightprobe: HDR environment maps (light probes) → lighting for real-time renderers, checked against ground truth.

Folders by capability, each on a floor that imports only from floors below it: ``util`` (errors, limits, files);
``maps`` (the EnvMap, layouts, image files, resampling); ``sh`` (paper 1); ``lights`` (paper 3) and ``glossy``
(paper 2); ``exports`` (what engines load); ``render``; ``viewer`` and ``batch``; ``report`` (the demo); the thin
``cli`` on top (see docs/architecture.md). The names of ``__all__`` load on first use.
"""

import os as _os

# numba keeps compiled kernels beside the source by default, which fails where the package is installed read-only;
# keep them in the user's cache folder instead (before numba is first imported, which reads this once). The folder
# is keyed by the sources compiled code is made of: the modules holding kernels and every module they import at
# their top (transitively) — numba checks only a kernel's own file for changes, so a kernel calling a helper or
# reading a constant of another module would otherwise keep a stale copy of it. Editing the command line, the docs,
# the report or the tests changes no key, so compiles nothing again.
KERNEL_MODULES = ("util/jit.py", "maps/lookups.py", "maps/resampling/fused.py", "maps/resampling/balance.py",
                  "maps/resampling/cube_symmetry.py", "maps/resampling/polar.py", "sh/basis.py", "sh/row_sums.py",
                  "lights/decompose.py", "glossy/brdf_sums.py", "glossy/dfg.py", "glossy/rsibr.py", "render/embree.py",
                  "render/sampling.py")


def _kernel_sources(root: str) -> list[str]:
    """The files of :data:`KERNEL_MODULES` and of every lightprobe module they import at module level, transitively
    (paths relative to ``root``, sorted)."""
    import re

    top_import = re.compile(r"^from (\.+)([\w.]*) import ([^(\n]+|\([^)]*\))", re.M)
    seen, todo = set(), list(KERNEL_MODULES)
    while todo:
        rel = todo.pop()
        if rel in seen or not _os.path.isfile(_os.path.join(root, rel)):
            continue
        seen.add(rel)
        with open(_os.path.join(root, rel), encoding="utf-8") as source:
            text = source.read()
        package = _os.path.dirname(rel).split("/") if _os.path.dirname(rel) else []
        for dots, module, names in top_import.findall(text):
            base = package[:len(package) - (len(dots) - 1)] if len(dots) > 1 else package
            parts = base + [p for p in module.split(".") if p]
            for candidate in ([*parts, n.split(" as ")[0].strip()] for n in names.strip("()").split(",")):
                todo += ["/".join(candidate) + ".py", "/".join(candidate + ["__init__.py"])]
            todo += ["/".join(parts) + ".py", "/".join(parts + ["__init__.py"])]
    return sorted(seen)


def _numba_cache_dir(root: str = _os.path.dirname(__file__)) -> str:
    import zlib

    stamp = []
    for rel in _kernel_sources(root):
        info = _os.stat(_os.path.join(root, rel))
        stamp.append(f"{rel}:{info.st_size}:{info.st_mtime_ns}")
    base = _os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache")
    return _os.path.join(base, "lightprobe", "numba", f"{zlib.crc32(chr(10).join(stamp).encode()):08x}")


if "NUMBA_CACHE_DIR" not in _os.environ:
    _os.environ["NUMBA_CACHE_DIR"] = _numba_cache_dir()

# One thread setting for everything below: LIGHTPROBE_THREADS sizes numba's pool and BLAS's before either loads
# (a malformed value is reported when a kernel first runs, by lightprobe.util.limits.threads).
if _os.environ.get("LIGHTPROBE_THREADS", "").strip().isdigit() and int(_os.environ["LIGHTPROBE_THREADS"]) > 0:
    for _name in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        _os.environ.setdefault(_name, _os.environ["LIGHTPROBE_THREADS"].strip())

from .util.errors import InputError, LayoutError, LightprobeError, LightprobeWarning  # noqa: E402 - after the setting

# Everything below loads on first use (PEP 562), so `import lightprobe` stays light: no numba, no OpenImageIO, no
# trimesh until a function that needs them runs. Name → module it lives in.
_LAZY = {
    "EnvMap": "maps", "read_envmap": "maps", "resample": "maps", "Resampler": "maps",
    "WORLD": "maps.frames", "RH2001": "maps.frames", "rotation_from_ypr": "maps.frames", "frame": "maps.frames",
    "LAYOUTS": "maps.layouts", "layout": "maps.layouts", "detect_layout": "maps.layouts",
    "SHCoeffs": "sh.basis", "project": "sh.basis",
    "export": "exports.sh", "irradiance_map": "sh.irradiance", "brute_irradiance": "sh.irradiance",
    "error_report": "sh.irradiance", "prefilter_cube": "glossy.prefilter", "babylon_env": "exports.containers",
    "read_image": "maps.images", "write_image": "maps.images",
    "decompose": "lights.decompose", "LightParams": "lights.decompose", "AreaLight": "lights.decompose",
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
