"""Radiance-map sets on disk: a folder of sphere-layout EXRs, one per view, and its ``manifest.json``.

Schema ``{"format": "lightprobe.radiance", "version": 1, ...}``:

* ``frame``: ``world`` (docs/spec.md §1) — every direction and frame below is in it;
* ``quantity``: ``radiance`` — each texel is L_r(n; v), the radiance the BRDF sends toward the view v from a
  surface of normal n = T·n_local, n_local the texel's local normal (x, y, √(1 − x² − y²)) (docs/spec.md §4);
* ``layout``: ``sphere``, ``size`` (texels across);
* ``brdf``: ``spec`` (what :func:`lightprobe.glossy.brdf.parse_brdf` reads back), ``name``, ``central`` (``normal`` or
  ``mirror``: the warp RS-IBR uses) and its parameters;
* ``views``: each ``file`` (relative to the folder), ``direction`` (v, unit), ``up`` and ``frame`` (T as three
  columns: right, up, v, as rows of [[right], [up], [v]]);
* ``triangles``: the view mesh (indices into ``views``, counter-clockwise seen from outside) — absent for one view;
* ``smooth`` (optional, sets of views only): ``file`` — the environment box-filtered to a cube of
  ``size`` (16) faces, a 6N × N EXR strip, radiance, world frame, peaks included; with it RS-IBR sums the smooth
  part of a new view's map exactly and warps only the rest (:mod:`lightprobe.glossy.rsibr`); without it (sets written
  before it existed) synthesis warps the whole maps, as the paper does;
* ``method``: how the maps were computed (the source level of the working cube, the peaks) and ``timings``.

A set is written to a temporary folder beside the target and renamed into place, so an interrupted run leaves
the previous set (or nothing), never a half set. A single map (``--view``) is an EXR with the same manifest, one
view and no triangles, in ``OUT.json`` beside it.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .brdf import BRDF, parse_brdf
from ..maps import EnvMap, from_image
from ..util.errors import InputError, UsageError
from ..maps.layouts import CUBE, Sphere
from ..sh.shfile import versioned_document

FORMAT, VERSION = "lightprobe.radiance", 1
MAX_BYTES = 1 << 20
MAX_VIEWS = 162
SMOOTH_FILE = "smooth.exr"


@dataclass(frozen=True, eq=False)
class RadianceSet:
    """Radiance maps of one BRDF at view directions (world frame): ``maps[i]`` is for ``views[i]`` and has layout
    Sphere(``frames[i]``); ``triangles`` index the view mesh (None for a single view); ``smooth`` the
    environment's smooth cube (:attr:`lightprobe.glossy.radiance.Lighting.smooth`) or None."""

    brdf: BRDF
    views: np.ndarray  # (N, 3) unit
    frames: np.ndarray  # (N, 3, 3): columns right, up, v
    maps: tuple[EnvMap, ...]
    triangles: np.ndarray | None
    method: dict
    smooth: EnvMap | None = None

    @property
    def size(self) -> int:
        """Texels across each map (the maps are ``size``², all alike)."""
        return self.maps[0].data.shape[0]


def radiance_set(lighting, brdf: BRDF, views: np.ndarray, triangles: np.ndarray | None, size: int,
                 method: dict | None = None, progress: str | None = None) -> RadianceSet:
    """The set of ``brdf``'s radiance maps at unit ``views`` under ``lighting``.

    Each map is :func:`lightprobe.glossy.radiance.radiance_map` (``size``²), with the frame
    :func:`lightprobe.glossy.radiance.view_frame` gives its view. The environment's smooth cube is kept only for a set
    of views with triangles.

    Parameters
    ----------
    lighting : lightprobe.glossy.radiance.Lighting or lightprobe.maps.EnvMap
        The environment, radiance, world frame; an EnvMap goes through :func:`lightprobe.glossy.radiance.prepare`
        (its defaults) once, not once per view.
    brdf : lightprobe.glossy.brdf.BRDF
        The BRDF of every map.
    views : numpy.ndarray
        (N, 3) unit view directions (toward the eye), world frame.
    triangles : numpy.ndarray or None
        (F, 3) indices into ``views``, counter-clockwise seen from outside
        (:func:`lightprobe.glossy.radiance.geodesic_views`); None for a single view.
    size : int
        Texels across each map, from 2 to 2048.
    method : dict, optional
        How the maps were computed, kept as the manifest's ``method``; default ``{}``.
    progress : str, optional
        A progress bar's label; None shows no bar.

    Returns
    -------
    RadianceSet
        The maps (float32 radiance, sphere layouts of their view frames), views, frames, triangles, method and smooth
        cube.

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``size`` outside [2, 2048].
    """
    from ..util.progress import track
    from .radiance import prepare, radiance_map, view_frame

    if isinstance(lighting, EnvMap):
        lighting = prepare(lighting)  # once, not once per view
    views = np.asarray(views, dtype=np.float64)
    each = track(list(views), progress) if progress else views
    maps = tuple(radiance_map(lighting, brdf, v, size) for v in each)
    smooth = lighting.smooth if triangles is not None else None
    return RadianceSet(brdf, views, np.array([view_frame(v) for v in views]), maps, triangles, method or {}, smooth)


def manifest(rset: RadianceSet, files: list[str], timings: dict | None = None, source: str | None = None) -> dict:
    """The schema's object for a set whose maps are (to be) written as ``files``.

    Version 1 of ``lightprobe.glossy.radiance`` (the module docstring): frame ``world``, quantity ``radiance``,
    layout ``sphere``; each view's ``direction``, ``up`` and ``frame`` T stored as rows [right], [up], [v]; the
    ``triangles`` and the ``smooth`` cube's entry when the set has them.

    Parameters
    ----------
    rset : RadianceSet
        The set.
    files : list of str
        A file name per map, relative to the manifest's folder, in the order of ``rset.maps``.
    timings : dict, optional
        Seconds by step, kept as ``timings``; default ``{}``.
    source : str, optional
        Where the environment came from (its path), kept as ``source``; None is JSON null.

    Returns
    -------
    dict
        The manifest, ready for :func:`json.dumps`.
    """
    views = [{"file": f, "direction": [float(x) for x in v], "up": [float(x) for x in t[:, 1]],
              "frame": [[float(x) for x in t[:, k]] for k in range(3)]}
             for f, v, t in zip(files, rset.views, rset.frames)]
    doc = {"format": FORMAT, "version": VERSION, "frame": "world", "quantity": "radiance", "layout": "sphere",
           "size": rset.size, "brdf": {"spec": rset.brdf.spec(), **rset.brdf.describe()}, "views": views,
           "method": rset.method, "timings": timings or {}, "source": source}
    if rset.triangles is not None:
        doc["triangles"] = [[int(i) for i in tri] for tri in rset.triangles]
    if rset.smooth is not None:
        doc["smooth"] = {"file": SMOOTH_FILE, "layout": "cube", "size": rset.smooth.grid[-1]}
    return doc


def write_radiance_set(folder: str | os.PathLike, rset: RadianceSet, timings: dict | None = None,
                       source: str | None = None) -> Path:
    """Write the set as ``folder`` (EXRs ``view_000.exr`` … and ``manifest.json``), atomically.

    It is written into a temporary folder beside it, renamed into place once complete (an existing set there — a
    ``manifest.json`` of format ``lightprobe.radiance`` — is replaced; any other non-empty folder is refused). The smooth cube, when the set has one, goes in as
    ``smooth.exr``. An error on the way removes the temporary folder and puts the previous set back.

    Parameters
    ----------
    folder : str or os.PathLike
        The set's folder: new, empty, or holding a set (a ``manifest.json`` whose format is ``lightprobe.radiance``).
    rset : RadianceSet
        The set.
    timings : dict, optional
        Seconds by step, as :func:`manifest` keeps them.
    source : str, optional
        Where the environment came from, as :func:`manifest` keeps it.

    Returns
    -------
    pathlib.Path
        ``folder``.

    Raises
    ------
    lightprobe.util.errors.UsageError
        ``folder`` exists and is not a radiance-map folder: a file, or a non-empty folder without a ``manifest.json``
        of this format (another program's manifest, say).
    """
    folder = Path(folder)
    if folder.exists() and (not folder.is_dir() or (any(folder.iterdir()) and not _holds_a_set(folder))):
        raise UsageError(f"{folder} exists and is not a radiance-map folder: give a new or empty folder")
    temp = folder.parent / f".{folder.name}.tmp-{os.getpid()}"
    old = folder.parent / f".{folder.name}.old-{os.getpid()}"
    shutil.rmtree(temp, ignore_errors=True)
    temp.mkdir(parents=True)
    try:
        files = [f"view_{i:03d}.exr" for i in range(len(rset.maps))]
        for name, rmap in zip(files, rset.maps):
            rmap.save(temp / name)
        if rset.smooth is not None:
            rset.smooth.save(temp / SMOOTH_FILE)
        text = json.dumps(manifest(rset, files, timings, source), indent=1, allow_nan=False) + "\n"
        (temp / "manifest.json").write_text(text)
        if folder.exists():
            folder.rename(old)
        temp.rename(folder)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        if old.exists() and not folder.exists():
            old.rename(folder)
        raise
    shutil.rmtree(old, ignore_errors=True)
    return folder


def _holds_a_set(folder: Path) -> bool:
    """True when ``folder``/manifest.json is a regular file of at most MAX_BYTES whose JSON object's format is ours:
    the only folder :func:`write_radiance_set` replaces."""
    path = folder / "manifest.json"
    if not path.is_file():
        return False
    try:
        with open(path, "rb") as f:
            doc = json.loads(f.read(MAX_BYTES + 1))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("format") == FORMAT


def read_radiance_set(folder: str | os.PathLike, working_bytes_per_texel: int = 0,
                      kernels: bool = False) -> RadianceSet:
    """A set written by :func:`write_radiance_set` (or one map's ``OUT.json`` path), every field checked.

    A missing or wrong-sized map, a map named by two views, a frame that is not a rotation with v as its third
    column, or a bad triangle is one clear :class:`~lightprobe.util.errors.InputError`. Every map's size is checked
    from its header, and the whole set (with ``working_bytes_per_texel``) against the memory budget, before any
    pixel is read. Each frame read is snapped to the nearest rotation (JSON's decimals leave it orthonormal to ~1e-16
    only).

    Parameters
    ----------
    folder : str or os.PathLike
        The set's folder (its ``manifest.json`` is read), or the path of a single map's manifest.
    working_bytes_per_texel : int, default 0
        Bytes the caller needs per texel of every map beyond the maps themselves (12 bytes a texel), counted in the
        memory check.
    kernels : bool, default False
        The caller runs compiled (numba) kernels on the set: their memory counts too.

    Returns
    -------
    RadianceSet
        The maps as float32 radiance in sphere layouts of their frames (RGB of each EXR), the unit views (N, 3),
        frames (N, 3, 3), triangles (int64) or None, method, and the smooth cube or None.

    Raises
    ------
    lightprobe.util.errors.InputError
        No manifest; not JSON, not this format or version, or over MAX_BYTES; any field wrong; a map missing, named
        by two views, not ``size``² or holding NaN or infinity (the smooth cube: not a 6N × N strip of finite,
        non-negative radiance).
    lightprobe.util.errors.BudgetError
        Reading the maps (with ``working_bytes_per_texel``) would pass the memory budget.
    """
    from ..maps.images import image_header, read_image
    from ..util.limits import check_memory
    from ..util.files import read_bounded

    path = Path(folder)
    manifest_path = path / "manifest.json" if path.is_dir() else path
    what = f"radiance-map manifest {manifest_path}"
    if not manifest_path.is_file():
        raise InputError(f"cannot read {what}: no such file")
    doc, fail = versioned_document(read_bounded(manifest_path, MAX_BYTES, "radiance-map manifest"), what, FORMAT,
                                   VERSION, MAX_BYTES)
    if doc.get("frame") != "world" or doc.get("quantity") != "radiance" or doc.get("layout") != "sphere":
        fail("frame, quantity and layout must be world, radiance and sphere")
    size = doc.get("size")
    if not isinstance(size, int) or not 2 <= size <= 4096:
        fail("size must be a whole number from 2 to 4096")
    brdf_doc = doc.get("brdf")
    if not isinstance(brdf_doc, dict) or not isinstance(brdf_doc.get("spec"), str):
        fail("brdf.spec is missing")
    try:
        brdf = parse_brdf(brdf_doc["spec"])
    except UsageError as e:
        fail(f"brdf: {e}")
    views_doc = doc.get("views")
    if not isinstance(views_doc, list) or not 1 <= len(views_doc) <= MAX_VIEWS:
        fail(f"views must be a list of 1 to {MAX_VIEWS}")
    views, frames, paths, named, largest = [], [], [], {}, 0
    for i, view in enumerate(views_doc):
        direction, frame = _view_fields(view, i, fail)
        name = view["file"]
        if not isinstance(name, str) or "/" in name or "\\" in name or name.startswith("."):
            fail(f"views[{i}].file must be a file name in the folder")
        if name in named:  # one file named by every view would be read (and held) once per view
            fail(f"views[{i}]: the map {name} is views[{named[name]}]'s too (each view has its own map)")
        named[name] = i
        map_path = manifest_path.parent / name
        if not map_path.is_file():
            fail(f"views[{i}]: the map {name} is missing")
        header = image_header(map_path)  # its size from the header alone: no pixel is read yet
        if (header.height, header.width) != (size, size):
            fail(f"views[{i}]: the map {name} is {header.width}×{header.height}, not {size}×{size}")
        largest = max(largest, header.read_bytes())
        views.append(direction)
        frames.append(frame)
        paths.append(map_path)
    check_memory(len(paths) * size * size * (12 + working_bytes_per_texel) + largest,
                 f"the {len(paths)} maps of {size}² in {manifest_path.parent}", kernels=kernels)
    maps = []
    for name, map_path, frame in zip(named, paths, frames):
        data = read_image(map_path)[..., :3]
        if data.shape[:2] != (size, size):  # the file changed since its header was read
            fail(f"the map {name} is {data.shape[1]}×{data.shape[0]}, not {size}×{size}")
        if not np.isfinite(data).all():
            fail(f"the map {name} holds pixels that are not finite (NaN or infinity)")
        maps.append(EnvMap(np.ascontiguousarray(data, dtype=np.float32), Sphere(frame)))
    triangles = doc.get("triangles")
    if triangles is not None:
        try:
            tri = np.asarray(triangles) if isinstance(triangles, list) else np.zeros((0,))
        except ValueError:  # ragged lists
            tri = np.zeros((0,))
        if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer) or \
                (tri < 0).any() or (tri >= len(views)).any():
            fail("triangles must be index triples into views")
        triangles = tri.astype(np.int64)
    method = doc.get("method") if isinstance(doc.get("method"), dict) else {}
    smooth = _smooth_field(doc.get("smooth"), manifest_path.parent, fail) if "smooth" in doc else None
    return RadianceSet(brdf, np.array(views), np.array(frames), tuple(maps), triangles, method, smooth)


def _smooth_field(field, folder: Path, fail) -> EnvMap:
    """The manifest's ``smooth`` cube, checked: a file in the folder, a cube strip of the stated face size
    (1 to 64), finite and non-negative radiance."""
    from ..maps.images import image_header, read_image

    if not isinstance(field, dict) or field.get("file") != SMOOTH_FILE or field.get("layout") != "cube" or \
            not isinstance(field.get("size"), int) or not 1 <= field["size"] <= 64:
        fail(f"smooth must be {{file: {SMOOTH_FILE}, layout: cube, size: 1 to 64}}")
    size = field["size"]
    if not (folder / SMOOTH_FILE).is_file():
        fail(f"smooth: the map {SMOOTH_FILE} is missing")
    header = image_header(folder / SMOOTH_FILE)  # before its pixels are read: it may be any size
    if (header.height, header.width) != (size, 6 * size):
        fail(f"smooth: the map {SMOOTH_FILE} is {header.width}×{header.height}, not {6 * size}×{size}")
    data = read_image(folder / SMOOTH_FILE)[..., :3]
    if data.shape[:2] != (size, 6 * size):
        fail(f"smooth: the map {SMOOTH_FILE} is {data.shape[1]}×{data.shape[0]}, not {6 * size}×{size}")
    if not np.isfinite(data).all() or (data < 0).any():
        fail(f"smooth: the map {SMOOTH_FILE} holds pixels that are not finite non-negative radiance")
    return from_image(np.ascontiguousarray(data, dtype=np.float32), CUBE)


def _view_fields(view, i: int, fail) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(view, dict) or not {"file", "direction", "frame"} <= set(view):
        fail(f"views[{i}] needs file, direction and frame")
    try:
        direction = np.asarray(view["direction"], dtype=np.float64)
        frame = np.asarray(view["frame"], dtype=np.float64).T  # stored as rows [right], [up], [v]
    except (TypeError, ValueError):
        fail(f"views[{i}]: direction and frame must be numbers")
    if direction.shape != (3,) or frame.shape != (3, 3) or not np.isfinite(frame).all():
        fail(f"views[{i}]: direction must be 3 numbers and frame 3×3")
    if not np.allclose(frame.T @ frame, np.eye(3), atol=1e-6) or np.linalg.det(frame) < 0 or \
            not np.allclose(frame[:, 2], direction, atol=1e-6):
        fail(f"views[{i}]: frame must be a rotation whose third column is the direction")
    u, _, vt = np.linalg.svd(frame)  # the nearest rotation: JSON's decimals leave it orthonormal to ~1e-16 only
    frame = u @ vt
    return frame[:, 2].copy(), frame
