"""What the viewer's page needs, baked by the Python API into one folder: the format ``lightprobe.view``, version 1.

Every quantity keeps the convention of the module that made it; the manifest ``bake.json`` says which:

* ``sh`` — the probe's nine **radiance** coefficients L_lm (world frame, real SH without the Condon–Shortley phase,
  :mod:`lightprobe.sh.basis`); the page forms eq. 12's matrices from them itself, so the sliders can edit L_lm.
* ``threejs.json`` — the ``threejs`` export (:func:`lightprobe.exports.sh.export_threejs`, in the frame three.js shows
  an equirectangular background in): what the page hands three.js's own ``LightProbe``.
* ``lights.json`` — the area lights and ambient SH (:mod:`lightprobe.lights.lightsfile`, world frame);
  ``ambient.f32`` the ambient's **irradiance** E(n) (SH of order :data:`lightprobe.lights.hybrid.DEFAULT_AMBIENT_ORDER`)
  on a latlong grid indexed by the normal.
* ``radiance-K.f32`` — BRDF K's radiance maps L_r(n; v_i) at the geodesic views (sphere layout, frames
  :func:`lightprobe.glossy.radiance.view_frame`), **radiance**; ``prefiltered-K.f32`` the split sum's GGX-prefiltered
  environment (radiance, latlong) with its DFG table in the manifest.
* ``background.f32`` — the probe itself (radiance, latlong), ``mesh.glb`` — the objects (world units, fitted as the
  renderer's scenes are) and the ground plane, and ``camera`` — the renderer's default camera for that scene.

Binary arrays are little-endian float32, C order, RGB last; latlong rows run from the top (+Y) down, the world
frame's convention (:class:`lightprobe.maps.layouts.LatLong`). Bakes are cached by the inputs' content and options
(:func:`cache_folder`) and written atomically: a folder there is complete or absent.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..util.errors import BudgetError, UsageError

FORMAT, VERSION = "lightprobe.view", 1
MAX_MANIFEST_BYTES = 16 << 20  # a bake.json longer than this is not one of ours
BACKGROUND_WIDTH = 1024
AMBIENT_GRID = (64, 128)
PREFILTERED_GRID = (128, 256)
SPLITSUM_CUBE = 64  # the prefiltered cube's face, resampled into PREFILTERED_GRID (a lobe of α ≥ 0.05 spans texels)
DEFAULT_BRDFS = ("ggx:alpha=0.2,conductor=gold", "plastic:alpha=0.15,albedo=0.6/0.05/0.04")
# What a browser can be asked to draw (configurable): beyond these the page would stall or the tab run out of memory.
DEFAULT_MAX_TRIANGLES = 2_000_000
DEFAULT_MAX_PIXELS = 1 << 25  # 8192 × 4096


@dataclass(frozen=True)
class BakeOptions:
    """What a bake depends on besides its input files.

    Parameters
    ----------
    brdfs : tuple of str
        BRDF specs (:func:`lightprobe.glossy.brdf.parse_brdf`), each baked as radiance maps and, for GGX, the split
        sum's prefiltered map. Default :data:`DEFAULT_BRDFS`: gold GGX (α 0.2) and a red plastic.
    views : int
        Geodesic view directions of each BRDF's radiance maps: 12 (default), 42 or 162.
    map_size : int
        Texels on a side of each radiance map. Default 128.
    background_width : int
        Largest width of the background lat-long in pixels (its height is half). Default :data:`BACKGROUND_WIDTH`
        (1024).
    light_params : dict
        Keyword arguments of :class:`lightprobe.lights.decompose.LightParams` for the decomposition; empty (default):
        the paper's defaults.
    """

    brdfs: tuple[str, ...] = DEFAULT_BRDFS
    views: int = 12
    map_size: int = 128
    background_width: int = BACKGROUND_WIDTH
    light_params: dict = field(default_factory=dict)

    def key(self) -> str:
        """The options as one canonical text, for the cache key.

        Returns
        -------
        str
            The options as JSON with sorted keys (hashed by :func:`cache_folder`).
        """
        return json.dumps(asdict(self), sort_keys=True)


def max_triangles() -> int:
    """The most triangles the viewer's page is asked to draw.

    Returns
    -------
    int
        ``LIGHTPROBE_VIEW_MAX_TRIANGLES``, or :data:`DEFAULT_MAX_TRIANGLES` (2,000,000) when it is unset or blank.

    Raises
    ------
    UsageError
        The variable is set to something other than a positive whole number.
    """
    from ..util.limits import positive_env

    return positive_env("LIGHTPROBE_VIEW_MAX_TRIANGLES", DEFAULT_MAX_TRIANGLES)


def max_pixels() -> int:
    """The most probe pixels the viewer's page is asked to show.

    Returns
    -------
    int
        ``LIGHTPROBE_VIEW_MAX_PIXELS``, or :data:`DEFAULT_MAX_PIXELS` (2²⁵, 8192 × 4096) when it is unset or blank.

    Raises
    ------
    UsageError
        The variable is set to something other than a positive whole number.
    """
    from ..util.limits import positive_env

    return positive_env("LIGHTPROBE_VIEW_MAX_PIXELS", DEFAULT_MAX_PIXELS)


def check_inputs(probe: Path, mesh: Path | None) -> None:
    """Refuse, with one line and before any baking, a probe or mesh beyond the viewer's limits.

    The limits are set by ``LIGHTPROBE_VIEW_MAX_PIXELS`` and ``LIGHTPROBE_VIEW_MAX_TRIANGLES``
    (:func:`max_pixels`, :func:`max_triangles`).

    Parameters
    ----------
    probe : Path
        The probe's image file; only its header is read, for its width × height.
    mesh : Path or None
        The mesh file, its triangles counted by :func:`mesh_triangle_count`; None: the built-in scene, not checked.

    Raises
    ------
    BudgetError
        The probe has more pixels, or the mesh more triangles, than the viewer's limit.
    InputError
        A file cannot be read.
    """
    from ..maps.images import image_header

    header = image_header(probe)
    if header.pixels > max_pixels():
        raise BudgetError(f"refusing {probe} for the viewer: {header.width}×{header.height} pixels is over its limit "
                          f"of {max_pixels()} (set LIGHTPROBE_VIEW_MAX_PIXELS to raise it)")
    if mesh is not None:
        triangles = mesh_triangle_count(mesh)
        if triangles > max_triangles():
            raise BudgetError(f"refusing mesh {mesh} for the viewer: {triangles} triangles is over its limit of "
                              f"{max_triangles()} (set LIGHTPROBE_VIEW_MAX_TRIANGLES to raise it)")


def mesh_triangle_count(path: Path) -> int:
    """Triangles in a mesh file, read from its header where the format has one (PLY), else by loading it.

    Parameters
    ----------
    path : Path
        A regular mesh file. A PLY whose first 4096 bytes state ``element face N`` is counted from that line; any
        other file is loaded (:func:`lightprobe.render.scene.load_mesh`).

    Returns
    -------
    int
        The number of triangles (for a PLY header, its face count).

    Raises
    ------
    InputError
        The path is not a regular file, or the mesh cannot be read.
    BudgetError
        Loading a mesh of more triangles than ``LIGHTPROBE_MAX_TRIANGLES``.
    """
    from ..maps.images import check_regular_file

    check_regular_file(path, "mesh")
    if path.suffix.lower() == ".ply":
        with open(path, "rb") as f:
            head = f.read(4096)
        for line in head.split(b"\n"):
            words = line.split()
            if words[:2] == [b"element", b"face"] and len(words) == 3 and words[2].isdigit():
                return int(words[2])
            if words[:1] == [b"end_header"]:
                break
    from ..render.scene import load_mesh

    return len(load_mesh(path).faces)


def cache_folder(probe: Path, mesh: Path | None, options: BakeOptions, root: Path | None = None,
                 layout: str | None = None) -> Path:
    """``root``/<key>: the key hashes the probe's and the mesh's bytes (with every file the mesh loads), the probe's
    layout, the options and the format's version.

    Parameters
    ----------
    probe : Path
        The probe's file, whose bytes are hashed.
    mesh : Path or None
        The mesh's file, whose bytes are hashed with those of every file it loads (:func:`mesh_files`); None for
        the built-in scene.
    options : BakeOptions
        The bake's options (:meth:`BakeOptions.key`).
    root : Path or None
        The cache's folder; None (default): ``$XDG_CACHE_HOME/lightprobe/view`` (``~/.cache`` without
        ``XDG_CACHE_HOME``).
    layout : str or None
        The layout the probe is read as (``--layout``); None (default): from its aspect ratio.

    Returns
    -------
    Path
        ``root`` / the first 24 hex digits of the SHA-256; not created here.
    """
    from ..util.files import digest_file

    digest = hashlib.sha256(f"{FORMAT} {VERSION} {options.key()} layout={layout}".encode())
    for path in (probe, mesh):
        digest.update(b"\0")
        if path is not None:
            digest_file(path, digest)
    for path in mesh_files(mesh)[1:] if mesh is not None else ():  # what the mesh loads: a name, then its bytes
        digest.update(b"\0" + os.fsencode(path) + b"\0")
        if path.is_file():
            digest_file(path, digest)
        else:
            digest.update(b"missing")
    root = root or Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "lightprobe" / "view"
    return root / digest.hexdigest()[:24]


MAX_MESH_INDEX_BYTES = 64 << 20  # a .gltf's JSON or an OBJ's .mtl read for the files they name


def mesh_files(mesh: Path) -> list[Path]:
    """The mesh file and every file loading it reads: a ``.gltf``'s buffers and images, an OBJ's ``mtllib`` files
    and the textures they name; each relative to the file naming it, as the loader resolves it.

    Parameters
    ----------
    mesh : Path
        The mesh file. Other formats (GLB, PLY, STL, OFF) are self-contained; a ``data:`` URI is inside the file.

    Returns
    -------
    list of Path
        ``mesh`` first, then the files it names in the order named (each once; a named file may be missing).
    """
    from urllib.parse import unquote

    files = [mesh]
    suffix = mesh.suffix.lower()
    if suffix == ".gltf" and mesh.is_file() and mesh.stat().st_size <= MAX_MESH_INDEX_BYTES:
        try:
            doc = json.loads(mesh.read_bytes())
        except (OSError, ValueError):
            doc = None
        for kind in ("buffers", "images"):
            items = doc.get(kind) if isinstance(doc, dict) else None
            for item in items if isinstance(items, list) else ():
                uri = item.get("uri") if isinstance(item, dict) else None
                if isinstance(uri, str) and uri and not uri.startswith("data:"):
                    files.append(mesh.parent / unquote(uri))
    elif suffix == ".obj" and mesh.is_file():
        libraries = []
        with open(mesh, "rb") as f:
            for line in f:
                if line.startswith(b"mtllib"):
                    libraries += [mesh.parent / os.fsdecode(name) for name in line.split()[1:]]
        files += libraries
        for library in libraries:
            if library.is_file() and library.stat().st_size <= MAX_MESH_INDEX_BYTES:
                for line in library.read_bytes().splitlines():
                    words = line.split()
                    if words and (words[0].lower().startswith(b"map_") or words[0].lower() in (b"bump", b"disp",
                                                                                             b"decal", b"refl")):
                        files.append(library.parent / os.fsdecode(words[-1]))
    return list(dict.fromkeys(files))


def read_manifest(folder: Path) -> dict | None:
    """The bake's manifest, or None when the folder holds no complete bake of this format and version.

    Parameters
    ----------
    folder : Path
        A bake folder (its ``bake.json`` is read).

    Returns
    -------
    dict or None
        The manifest as :func:`bake` wrote it; None when ``bake.json`` is missing, unreadable, not JSON, or of another
        format or version.
    """
    from ..util.errors import LightprobeError
    from ..util.files import read_bounded

    try:
        doc = json.loads(read_bounded(folder / "bake.json", MAX_MANIFEST_BYTES))
    except (LightprobeError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != VERSION:
        return None
    return doc


# ---- the parts -----------------------------------------------------------------------------------------------------
def _write_array(folder: Path, name: str, data: np.ndarray) -> dict:
    data = np.ascontiguousarray(data, dtype="<f4")
    (folder / name).write_bytes(data.tobytes())
    return {"file": name, "shape": list(data.shape)}


def _background(env, width: int) -> np.ndarray:
    """The probe as a latlong of at most ``width`` × ``width``/2 (energy-conserving resampling), radiance."""
    from ..maps.layouts import LATLONG

    if env.layout == LATLONG and env.data.shape[1] <= width:
        return env.data
    return env.to(LATLONG, width // 2).data


def _latlong_directions(rows: int, cols: int) -> np.ndarray:
    """The pixel-centre directions of a rows × cols latlong, (rows · cols, 3)."""
    from ..maps.envmap import pixel_directions
    from ..maps.layouts import LATLONG

    return pixel_directions(LATLONG, (rows, cols)).reshape(-1, 3)


def _scene(env, mesh: Path | None):
    from ..render.scene import builtin_scene, mesh_scene

    if mesh is None:
        return builtin_scene(env, turn_to_key_light=False)
    return mesh_scene(mesh, env, turn_to_key_light=False)


def _glb(scene, path: Path) -> list[dict]:
    """The scene's meshes as one GLB (nodes ``object-K`` and ``ground``, smooth normals), and their materials."""
    import trimesh

    out = trimesh.Scene()
    meshes = []
    for k, m in enumerate(scene.meshes):
        name = "ground" if m.name.startswith("ground") else f"object-{k}"
        out.add_geometry(trimesh.Trimesh(m.vertices, m.faces, vertex_normals=m.normals, process=False),
                         node_name=name, geom_name=name)
        meshes.append({"name": name, "albedo": [float(a) for a in m.material.albedo],
                       "triangles": int(len(m.faces))})
    path.write_bytes(out.export(file_type="glb", include_normals=True))
    return meshes


def _camera(scene) -> dict:
    c = scene.camera
    return {"eye": list(map(float, c.eye)), "target": list(map(float, c.target)), "up": list(map(float, c.up)),
            "fov": float(c.fov), "width": c.width, "height": c.height}


def _lights(env, folder: Path, params: dict) -> dict:
    from ..lights.hybrid import DEFAULT_AMBIENT_ORDER
    from ..lights.decompose import LightParams, decompose
    from ..lights.lightsfile import lights_json
    from ..sh.basis import project

    dec = decompose(env, LightParams(**params) if params else None)
    ambient = project(dec.ambient, DEFAULT_AMBIENT_ORDER)  # as the renderer's ``lights`` method
    (folder / "lights.json").write_text(lights_json(dec, ambient))
    rows, cols = AMBIENT_GRID
    irradiance = np.maximum(ambient.to_irradiance().evaluate(_latlong_directions(rows, cols)), 0.0)
    return {"file": "lights.json", "count": len(dec.lights),
            "ambient": {**_write_array(folder, "ambient.f32", irradiance.reshape(rows, cols, 3)),
                        "quantity": "irradiance", "order": DEFAULT_AMBIENT_ORDER}}


def _brdf_part(env, lighting, spec: str, index: int, options: BakeOptions, folder: Path) -> dict:
    from ..glossy.brdf import GGX, parse_brdf
    from ..glossy.radiance import geodesic_views
    from ..glossy.radiancefile import radiance_set
    from ..render.glossy import dfg_terms, normal_reflectance, splitsum_cube

    brdf = parse_brdf(spec)
    t0 = time.perf_counter()
    rset = radiance_set(lighting, brdf, *geodesic_views(options.views), options.map_size,
                        progress=f"radiance maps of {brdf.spec()}")
    maps = np.stack([m.data for m in rset.maps])
    part = {"spec": brdf.spec(), "central": brdf.central, "views": rset.views.tolist(),
            "triangles": rset.triangles.tolist(), "frames": rset.frames.tolist(),
            "maps": {**_write_array(folder, f"radiance-{index}.f32", maps), "quantity": "radiance"},
            "seconds": {"radiance_maps": time.perf_counter() - t0}}
    if isinstance(brdf, GGX):  # the split sum is defined for GGX (render.glossy.SplitSumMethod)
        t0 = time.perf_counter()
        rows, cols = PREFILTERED_GRID
        cube = splitsum_cube(env, brdf.alpha, SPLITSUM_CUBE)
        pre = cube.lookup(_latlong_directions(rows, cols)).reshape(rows, cols, 3)
        part["splitsum"] = {**_write_array(folder, f"prefiltered-{index}.f32", pre), "quantity": "radiance",
                            "alpha": brdf.alpha, "dfg": dfg_terms(brdf.alpha).tolist(),
                            "f0": [float(x) for x in normal_reflectance(brdf)]}
        part["seconds"]["splitsum"] = time.perf_counter() - t0
    return part


def bake(env, folder: Path, mesh: Path | None = None, options: BakeOptions = BakeOptions(),
         source: str | None = None) -> dict:
    """Bake everything the page needs for ``env`` (and ``mesh``, or the built-in scene) into ``folder``, atomically.

    The parts are written into a temporary folder beside it (``.NAME.tmp-PID``), renamed into place once complete.
    Returns the manifest.

    Parameters
    ----------
    env : EnvMap
        The probe: radiance, world frame, any layout. It is used as given (not turned toward its key light).
    folder : Path
        The bake's folder; an existing one is replaced.
    mesh : Path or None
        A mesh file, fitted and stood on a ground plane as :func:`lightprobe.render.scene.mesh_scene` does; None
        (default): the built-in sphere and torus (:func:`lightprobe.render.scene.builtin_scene`).
    options : BakeOptions
        BRDFs, views, map size, background width and light parameters. Default: :class:`BakeOptions`'s defaults.
    source : str or None
        Recorded as the manifest's ``source`` (e.g. the probe's file name). Default None.

    Returns
    -------
    dict
        The manifest written as ``bake.json``: format, version, camera, meshes, SH, background, lights, BRDFs and the
        seconds each part took (see the module docstring).

    Raises
    ------
    UsageError
        A BRDF spec is refused (check them first with :func:`check_brdfs`).
    """
    from .. import __version__
    from ..exports.sh import export_threejs
    from ..glossy.radiance import prepare
    from ..sh.basis import project

    folder = Path(folder)
    temp = folder.parent / f".{folder.name}.tmp-{os.getpid()}"
    shutil.rmtree(temp, ignore_errors=True)
    temp.mkdir(parents=True)
    try:
        seconds = {}
        t0 = time.perf_counter()
        scene = _scene(env, mesh)
        meshes = _glb(scene, temp / "mesh.glb")
        sh = project(env, 2)
        (temp / "threejs.json").write_text(export_threejs(sh))
        background = _write_array(temp, "background.f32", _background(env, options.background_width))
        seconds["scene"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        lights = _lights(env, temp, options.light_params)
        seconds["lights"] = time.perf_counter() - t0
        lighting = prepare(env) if options.brdfs else None
        brdfs = [_brdf_part(env, lighting, spec, k, options, temp) for k, spec in enumerate(options.brdfs)]
        doc = {"format": FORMAT, "version": VERSION, "lightprobe": __version__, "frame": "world",
               "source": source, "camera": _camera(scene), "meshes": meshes, "mesh": "mesh.glb",
               "sh": {"quantity": "radiance", "basis": "real, no Condon-Shortley phase", "frame": "world",
                      "coefficients": sh.coeffs[:9].tolist()},
               "threejs": "threejs.json", "background": {**background, "quantity": "radiance", "layout": "latlong"},
               "lights": lights, "brdfs": brdfs, "seconds": seconds}
        (temp / "bake.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
        if folder.exists():
            shutil.rmtree(folder)
        temp.rename(folder)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return doc


def check_brdfs(specs) -> tuple[str, ...]:
    """The BRDF specs, each parsed once so a bad one is refused before any work.

    Parameters
    ----------
    specs : iterable of str
        BRDF specs as :func:`lightprobe.glossy.brdf.parse_brdf` reads them; at most 8.

    Returns
    -------
    tuple of str
        The specs as given, in order.

    Raises
    ------
    UsageError
        A spec is refused, or there are more than 8.
    """
    from ..glossy.brdf import parse_brdf

    out = []
    for spec in specs:
        parse_brdf(spec)
        out.append(spec)
    if len(out) > 8:
        raise UsageError(f"the viewer takes at most 8 BRDFs, got {len(out)}")
    return tuple(out)
