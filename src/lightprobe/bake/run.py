"""``bake``: every asked engine's folder, built aside and put in place whole.

The folders are written into a temporary folder beside ``out`` (``.NAME.lpPID-RANDOM.tmp``); only when every engine
is done does it replace ``out`` (an existing ``out`` is moved aside first and removed last), so an error, a full
disk or an interrupt leaves ``out`` as it was and nothing half-written. ``out`` must be new, empty, or — with
``force`` — anything.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

from ..exports.containers import _generator
from ..maps import EnvMap
from ..util.errors import InputError
from ..util.files import move_folder_into_place, sweep_stale_temporaries, temp_path_for
from .engines import engine_module
from .folder import EngineFolder
from .options import BakeOptions
from .source import BakeSource


def check_bake_folder(out: Path, force: bool = False) -> None:
    """Refuse an ``out`` that is a file, or a non-empty folder unless ``force``; its parent must exist.

    Parameters
    ----------
    out : Path
        The bake's folder.
    force : bool, default False
        Replace a non-empty folder.

    Raises
    ------
    InputError
        ``out`` is a file; a non-empty folder without ``force``; or its parent folder does not exist.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"cannot bake into {out}: it is a file, not a folder")
    if out.is_dir() and not force and any(out.iterdir()):
        raise InputError(f"refusing to bake into {out}: the folder is not empty (choose another -o, or --force to "
                         "replace it)")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot bake into {out}: folder {parent} does not exist")


def bake(env: EnvMap, out: str | Path, options: BakeOptions, name: str = "(in memory)", sha256: str | None = None,
         force: bool = False) -> dict[str, Path]:
    """Bake ``env`` for every engine of ``options`` into ``out``/<engine>/.

    Each engine's folder holds the files it loads (in its own frame, face order, roughness per mip, units and
    encoding), ``manifest.json`` (schema ``lightprobe.bake`` v1: every file, what its numbers are, the source's
    hash, the parameters, the accuracy) and ``USAGE.md`` (the engine code that loads it).

    Parameters
    ----------
    env : EnvMap
        The probe: linear RGB radiance, world frame (+Y up, front −Z), any layout.
    out : str or Path
        The bake's folder: new, empty, or (with ``force``) replaced.
    options : BakeOptions
        Engines, sizes, intensity, lights.
    name : str, default "(in memory)"
        The probe as the manifests name it.
    sha256 : str, optional
        The probe file's SHA-256 (default: of the map's pixels).
    force : bool, default False
        Replace a non-empty ``out``.

    Returns
    -------
    dict of str to Path
        Each engine's folder, once in place.

    Raises
    ------
    InputError
        ``out`` cannot be used (:func:`check_bake_folder`).
    UsageError
        An engine refuses the options (e.g. fewer mips than its container holds).
    """
    out = Path(out)
    check_bake_folder(out, force)
    source = BakeSource.from_map(env, options, name, sha256)
    header = {"generator": _generator(), "source": source.describe(),
              "parameters": options.as_dict()}
    sweep_stale_temporaries(out.parent if str(out.parent) else Path("."))  # bakes killed before they could clean up
    built = temp_path_for(out)
    built.mkdir()
    try:
        for engine in options.engines:
            module = engine_module(engine)
            folder = EngineFolder(built / engine, engine, module.FRAME)
            folder.path.mkdir()
            t0 = time.perf_counter()
            extra = module.bake(source, folder)
            extra["timings"] = {"engine": time.perf_counter() - t0, **source.timings}
            folder.finish(module.usage(folder), header, extra)
        move_folder_into_place(built, out)
    except BaseException:
        shutil.rmtree(built, ignore_errors=True)
        raise
    return {engine: out / engine for engine in options.engines}
