"""Scene files (YAML or JSON): read with bounds, validated field by field, built into a :class:`Scene`.

A scene file::

    probe: path/to/probe.hdr            # optional; default: the shipped probe (paths relative to the file)
    rotate: [0, 0, 0]                   # optional yaw, pitch, roll of the environment, degrees
    camera: {eye: [0, 0.6, 2.2], target: [0, 0.3, 0], up: [0, 1, 0], fov: 35, width: 256, height: 256}
    meshes:
      - {file: bunny.ply, albedo: [0.8, 0.8, 0.8], fit: 0.8, place_on_ground: true, rotate: [0, 0, 0]}
      - {shape: sphere, albedo: [0.7, 0.7, 0.7], radius: 0.3, center: [0.5, 0.3, 0]}
      - {shape: torus, major: 0.35, minor: 0.12, center: [0, 0.12, 0]}
      - {shape: sphere, radius: 0.2, center: [0, 0.2, 0.5], material: {brdf: ggx, alpha: 0.2, conductor: gold}}
    ground: {albedo: [0.5, 0.5, 0.5], size: 20, height: 0}     # or ground: false
    background: true

``fit`` scales a mesh so its largest extent is that many units and centres it on x and z; ``place_on_ground`` sets
its lowest point on the ground plane; then ``scale`` and ``translate`` apply. Albedo is linear RGB reflectance in
[0, 1]; ``texture`` (an image file) with the mesh's UVs overrides it. ``material`` makes the surface another BRDF: a
mapping with its name and parameters (``{brdf: ggx, alpha: 0.2, conductor: gold}``, ``{brdf: ggx, alpha: 0.1,
eta: [0.2, 0.9, 1.1], k: [3.9, 2.5, 2.1]}``) or the same as text (``ggx:alpha=0.2,conductor=gold``; see
:func:`lightprobe.glossy.brdf.parse_brdf`).

Top-level keys starting with ``_`` are ignored: a place for YAML anchors (``_white: &white {albedo: [1, 1, 1]}``).
Every field is checked for its type and range (:data:`RANGES`), unknown fields are refused (a typo is not silently
ignored), and errors name the field (``scene: meshes[2].radius must be a number …``) without echoing more than a
few characters of the value. The file is bounded as loaded: at most :data:`MAX_FILE_BYTES`, at most
:data:`MAX_NODES` YAML nodes *after* expanding aliases (a 573-byte alias bomb expands to billions), at most
:data:`MAX_MESHES` meshes, and the scene's triangles, all meshes together, within ``LIGHTPROBE_MAX_TRIANGLES`` —
counted before each built-in shape is made.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

from ..maps import EnvMap, read_envmap
from ..util.errors import BudgetError, InputError, UsageError, short
from ..maps.images import read_image
from ..util.limits import max_triangles
from .scene import SPHERE_TRIANGLES, TORUS_TRIANGLES, Camera, Material, MeshInstance, Scene, fitted, ground_plane, load_mesh, mesh_triangles, sphere, torus, transformed

MAX_FILE_BYTES = 16 << 20
MAX_NODES = 200_000
MAX_MESHES = 10_000
COORD = 1e6  # |coordinate| bound for positions, sizes and angles
RANGES = {  # field: (smallest, largest) — also the documentation of each number's range
    "fov": (0.1, 179.0), "width": (1, 16384), "height": (1, 16384), "radius": (1e-6, COORD),
    "major": (1e-6, COORD), "minor": (1e-6, COORD), "fit": (1e-6, COORD), "scale": (1e-6, COORD),
    "size": (1e-6, COORD), "height_of_ground": (-COORD, COORD), "albedo": (0.0, 1.0), "angle": (-36000.0, 36000.0),
    "coordinate": (-COORD, COORD),
}


class _Fields:
    """One mapping of a scene file, read field by field with checks; ``where`` names it in messages."""

    def __init__(self, spec, where: str, allowed: set[str]):
        if not isinstance(spec, dict):
            raise InputError(f"scene: {where} must be a mapping, got {short(spec)}")
        unknown = sorted(str(k) for k in spec if k not in allowed
                         and not (where == "the top level" and isinstance(k, str) and k.startswith("_")))
        if unknown:
            raise InputError(f"scene: unknown field {short(unknown[0])} in {where} (known: {', '.join(sorted(allowed))})")
        self.spec, self.where = spec, where

    def name(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where != "the top level" else key

    def has(self, key: str) -> bool:
        return self.spec.get(key) is not None

    def number(self, key: str, default: float, bounds: tuple[float, float]) -> float:
        value = self.spec.get(key, default)
        return _number(value, self.name(key), bounds)

    def integer(self, key: str, default: int, bounds: tuple[int, int]) -> int:
        value = self.spec.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            if not (isinstance(value, float) and value.is_integer()):
                raise InputError(f"scene: {self.name(key)} must be a whole number, got {short(value)}")
        value = int(value)
        if not bounds[0] <= value <= bounds[1]:
            raise InputError(f"scene: {self.name(key)} must be within {bounds[0]}..{bounds[1]}, got {value}")
        return value

    def vector(self, key: str, default, bounds: tuple[float, float] = RANGES["coordinate"]) -> tuple[float, ...]:
        value = self.spec.get(key, default)
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise InputError(f"scene: {self.name(key)} must be a list of 3 numbers, got {short(value)}")
        return tuple(_number(v, f"{self.name(key)}[{i}]", bounds) for i, v in enumerate(value))

    def flag(self, key: str, default: bool) -> bool:
        value = self.spec.get(key, default)
        if not isinstance(value, bool):
            raise InputError(f"scene: {self.name(key)} must be true or false, got {short(value)}")
        return value

    def path(self, key: str, base: Path) -> Path | None:
        value = self.spec.get(key)
        if value is None:
            return None
        if not isinstance(value, str) or not value.strip() or "\0" in value:
            raise InputError(f"scene: {self.name(key)} must be a file name, got {short(value)}")
        return base / value


def _number(value, where: str, bounds: tuple[float, float]) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"scene: {where} must be a number, got {short(value)}")
    value = float(value)
    if not bounds[0] <= value <= bounds[1]:  # also refuses NaN
        raise InputError(f"scene: {where} must be within {bounds[0]:g}..{bounds[1]:g}, got {value:g}")
    return value


# ---- reading the file ---------------------------------------------------------------------------------------------
def _expanded_size(node, memo: dict) -> int:
    """Nodes of a composed YAML tree with every alias expanded, computed once per distinct node (linear time)."""
    import yaml

    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = MAX_NODES + 1  # a node that contains itself (a recursive alias) is over any bound
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, memo) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    else:
        size = 1
    memo[key] = size
    return size


def _load_yaml(text: str, path: Path):
    import yaml

    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if _expanded_size(node, {}) > MAX_NODES:
            raise InputError(f"refusing scene {path}: it expands to more than {MAX_NODES} values (YAML aliases)")
        return loader.construct_document(node)
    finally:
        loader.dispose()


def load_scene(path: str | os.PathLike, environment: EnvMap | None = None) -> Scene:
    """A scene from a YAML or JSON file (see the module docstring); ``environment`` overrides its ``probe``.

    Parameters
    ----------
    path : str or os.PathLike
        The scene file, a regular file of at most :data:`MAX_FILE_BYTES`: read as JSON when its suffix is ``.json``,
        as YAML otherwise (UTF-8; bytes that are not UTF-8 are replaced). Paths in it are relative to its folder.
    environment : EnvMap or None
        The environment (radiance, world frame) to light the scene with instead of the file's ``probe``; the file's
        ``rotate`` still turns it. None (default): the file's ``probe``, or the shipped probe.

    Returns
    -------
    Scene
        The scene, named after the file's stem.

    Raises
    ------
    InputError
        The file is missing, not a regular file, unreadable or malformed, not a mapping, over :data:`MAX_NODES` YAML
        nodes once aliases are expanded, or a field is wrong (the message names it).
    BudgetError
        The file is over :data:`MAX_FILE_BYTES`, or the scene over :data:`MAX_MESHES` meshes or
        ``LIGHTPROBE_MAX_TRIANGLES`` triangles.
    """
    from ..util.files import read_bounded

    path = Path(path)
    text = read_bounded(path, MAX_FILE_BYTES, "scene").decode("utf-8", errors="replace")
    try:
        spec = json.loads(text) if path.suffix.lower() == ".json" else _load_yaml(text, path)
    except InputError:
        raise
    except Exception as e:  # the YAML and JSON parsers raise many kinds of errors for bad files
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise InputError(f"cannot read scene {path}: {first[:200]}") from None
    if not isinstance(spec, dict):
        raise InputError(f"cannot read scene {path}: expected a mapping at the top level")
    return scene_from_dict(spec, path.parent, environment, path.stem)


# ---- building the scene -------------------------------------------------------------------------------------------
class _TriangleBudget:
    """Triangles of the scene so far, against ``LIGHTPROBE_MAX_TRIANGLES``; checked before shapes are made."""

    def __init__(self):
        self.limit, self.used = max_triangles(), 0

    def fits(self, count: int, what: str) -> None:
        """BudgetError when ``count`` more triangles would pass the limit; nothing is taken."""
        if self.used + count > self.limit:
            raise BudgetError(f"refusing the scene: with {what} it has {self.used + count} triangles, over the limit "
                              f"of {self.limit} (set LIGHTPROBE_MAX_TRIANGLES to raise it)")

    def take(self, count: int, what: str) -> None:
        self.fits(count, what)
        self.used += count


SHAPE_TRIANGLES = {"sphere": SPHERE_TRIANGLES, "torus": TORUS_TRIANGLES}
MESH_FIELDS = {"file", "shape", "albedo", "texture", "material", "radius", "center", "major", "minor", "fit",
               "place_on_ground", "rotate", "scale", "translate"}


def _brdf(spec, where: str):
    """``material: {brdf: ggx, alpha: 0.2, conductor: gold}`` (or the spec text ``ggx:alpha=0.2,conductor=gold``)
    as a BRDF; numbers, r/g/b lists and names as :func:`lightprobe.glossy.brdf.parse_brdf` takes them."""
    from ..glossy.brdf import parse_brdf

    if isinstance(spec, str):
        text = spec
    elif isinstance(spec, dict) and isinstance(spec.get("brdf"), str):
        items = []
        for key, value in spec.items():
            if key == "brdf":
                continue
            if isinstance(value, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               for v in value):
                value = "/".join(repr(float(v)) for v in value)
            elif isinstance(value, bool) or not isinstance(value, (int, float, str)):
                raise InputError(f"scene: {where}.{short(key)} must be a number, three numbers or a name, got "
                                 f"{short(value)}")
            items.append(f"{key}={value}")
        text = spec["brdf"] + (":" + ",".join(items) if items else "")
    else:
        raise InputError(f"scene: {where} must be a mapping with a brdf name (e.g. {{brdf: ggx, alpha: 0.2}}), got "
                         f"{short(spec)}")
    try:
        return parse_brdf(text)
    except UsageError as e:
        raise InputError(f"scene: {where}: {e}") from None


def _mesh(entry, i: int, base: Path, ground_height: float, budget: _TriangleBudget, loaded: dict) -> MeshInstance:
    f = _Fields(entry, f"meshes[{i}]", MESH_FIELDS)
    material = Material(f.vector("albedo", (0.8, 0.8, 0.8), RANGES["albedo"]))
    texture = f.path("texture", base)
    if texture is not None:
        material = replace(material, texture=read_image(texture))
    if f.has("material"):
        material = replace(material, brdf=_brdf(f.spec["material"], f.name("material")))
    shape = f.spec.get("shape")
    if shape == "sphere":  # its triangles were counted before any mesh was built (see scene_from_dict)
        return sphere(f.number("radius", 0.5, RANGES["radius"]), f.vector("center", (0, 0.5, 0)), material)
    if shape == "torus":
        return torus(f.number("major", 0.35, RANGES["major"]), f.number("minor", 0.12, RANGES["minor"]),
                     f.vector("center", (0, 0.12, 0)), material)
    if shape is not None:
        raise InputError(f"scene: meshes[{i}].shape must be sphere or torus, got {short(shape)}")
    file = f.path("file", base)
    if file is None:
        raise InputError(f"scene: meshes[{i}] needs a file or a shape (sphere, torus)")
    if file not in loaded:  # the same file named many times is read once
        budget.fits(mesh_triangles(file) or 0, f"meshes[{i}] ({file.name})")  # as its file says: before loading it
        loaded[file] = load_mesh(file)
    mesh = loaded[file]
    budget.take(len(mesh.faces), f"meshes[{i}] ({file.name})")
    mesh = MeshInstance(mesh.vertices, mesh.faces, mesh.normals,
                        replace(material, texture=material.texture if material.texture is not None
                                else mesh.material.texture), mesh.uv, mesh.name)
    if f.has("rotate"):
        mesh = transformed(mesh, 1.0, f.vector("rotate", None, RANGES["angle"]))
    if f.has("fit"):
        mesh = fitted(mesh, f.number("fit", 1.0, RANGES["fit"]), f.flag("place_on_ground", True), ground_height)
    if f.has("scale") or f.has("translate"):
        mesh = transformed(mesh, f.number("scale", 1.0, RANGES["scale"]), None, f.vector("translate", (0, 0, 0)))
    return mesh


def _camera(spec) -> Camera:
    c = _Fields(spec if spec is not None else {}, "camera", {"eye", "target", "up", "fov", "width", "height"})
    return Camera(eye=c.vector("eye", Camera.eye), target=c.vector("target", Camera.target),
                  up=c.vector("up", Camera.up), fov=c.number("fov", Camera.fov, RANGES["fov"]),
                  width=c.integer("width", Camera.width, RANGES["width"]),
                  height=c.integer("height", Camera.height, RANGES["height"]))


def scene_from_dict(spec: dict, base: Path, environment: EnvMap | None = None, name: str = "scene") -> Scene:
    """Build a :class:`Scene` from the parsed file (see the module docstring); paths are relative to ``base``.

    Parameters
    ----------
    spec : dict
        The parsed file: ``probe``, ``rotate``, ``camera``, ``meshes``, ``ground``, ``background`` (keys starting with
        ``_`` are ignored), each checked for its type and range (:data:`RANGES`).
    base : Path
        The folder that relative ``probe``, ``file`` and ``texture`` paths are joined to.
    environment : EnvMap or None
        The environment (radiance, world frame) instead of ``probe``; ``rotate`` still turns it. None (default):
        ``probe`` is read, or the shipped probe when there is none.
    name : str
        The scene's name. Default ``scene``.

    Returns
    -------
    Scene
        The meshes in the file's order with the ground plane last, the camera, the environment and the background
        flag.

    Raises
    ------
    InputError
        A field is unknown, of the wrong type or out of range (the message names it), or there is nothing to render.
    BudgetError
        Over :data:`MAX_MESHES` meshes, or over ``LIGHTPROBE_MAX_TRIANGLES`` triangles (counted before the built-in
        shapes are made).
    """
    from ..data import default_probe_path

    top = _Fields(spec, "the top level", {"probe", "rotate", "camera", "meshes", "ground", "background"})
    camera = _camera(spec.get("camera"))
    ground_spec = spec.get("ground", {})
    if ground_spec is True:
        ground_spec = {}
    if ground_spec is not False and ground_spec is not None:
        ground = _Fields(ground_spec, "ground", {"albedo", "size", "height"})
        ground_height = ground.number("height", 0.0, RANGES["height_of_ground"])
    else:
        ground, ground_height = None, 0.0
    entries = spec.get("meshes") or []
    if not isinstance(entries, list):
        raise InputError(f"scene: meshes must be a list, got {short(entries)}")
    if len(entries) > MAX_MESHES:
        raise BudgetError(f"refusing the scene: {len(entries)} meshes is over {MAX_MESHES}")
    budget, loaded = _TriangleBudget(), {}
    shapes = [e.get("shape") for e in entries if isinstance(e, dict)]
    budget.take(SHAPE_TRIANGLES.get("sphere") * shapes.count("sphere") + SHAPE_TRIANGLES.get("torus")
                * shapes.count("torus"), f"its {len(shapes)} built-in shapes")  # before building any of them
    meshes = [_mesh(entry, i, base, ground_height, budget, loaded) for i, entry in enumerate(entries)]
    if ground is not None:
        meshes.append(ground_plane(ground.number("size", 20.0, RANGES["size"]), ground_height,
                                   Material(ground.vector("albedo", (0.5, 0.5, 0.5), RANGES["albedo"]))))
    if not meshes:
        raise InputError("scene: nothing to render (no meshes and no ground)")
    background = top.flag("background", True)
    if environment is None:
        probe = top.path("probe", base)
        environment = read_envmap(probe or default_probe_path())
    if top.has("rotate"):
        environment = environment.rotated(top.vector("rotate", None, RANGES["angle"]))
    return Scene(tuple(meshes), camera, environment, background, name)
