"""Scenes: meshes with diffuse materials, an optional ground plane, a pinhole camera, and an environment map as the
only light (visible as the background). Scene files are read by :mod:`lightprobe.render.scenefile`.

Conventions: world frame of :mod:`lightprobe.maps.frames` (+Y up, the default camera looks along −Z). Lengths are in the
meshes' own units. Every mesh is checked when it is made — after loading and after every transform — so a NaN
scale or fit can never make geometry silently vanish.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..glossy.brdf import BRDF
from ..maps import EnvMap
from ..util.errors import BudgetError, InputError, LightprobeError, short
from ..maps.frames import as_rotation
from ..maps.images import check_regular_file
from ..util.limits import max_triangles


@dataclass(frozen=True)
class Camera:
    """Pinhole camera: ``fov`` is the vertical field of view in degrees; image row 0 is the top.

    Parameters
    ----------
    eye : tuple of float
        The camera's position, world frame (+Y up), in the meshes' units. Default (0, 0.5, 3).
    target : tuple of float
        The point it looks at, world frame. Default (0, 0.3, 0): the default camera looks along −Z.
    up : tuple of float
        The world direction that appears up in the image (need not be orthogonal to the view). Default +Y.
    fov : float
        Vertical field of view in degrees, from 0.1 to 179. Default 35.
    width : int
        Image width in pixels, from 1 to 16384. Default 256.
    height : int
        Image height in pixels, from 1 to 16384. Default 256.

    Raises
    ------
    LightprobeError
        A size or field of view out of range, or ``eye``, ``target`` and ``up`` collinear (eye = target included).
    """

    eye: tuple[float, float, float] = (0.0, 0.5, 3.0)
    target: tuple[float, float, float] = (0.0, 0.3, 0.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 35.0
    width: int = 256
    height: int = 256

    def __post_init__(self) -> None:
        if not (1 <= self.width <= 16384 and 1 <= self.height <= 16384):
            raise LightprobeError(f"camera size {self.width}×{self.height} is out of range (1..16384)")
        if not 0.1 <= self.fov <= 179:
            raise LightprobeError(f"camera fov {self.fov} must be within 0.1..179 degrees")
        f = np.subtract(self.target, self.eye)
        if np.linalg.norm(f) == 0 or np.linalg.norm(np.cross(f, self.up)) == 0:
            raise LightprobeError("camera eye, target and up must not be collinear")

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward) unit vectors of the camera in the world frame.

        Returns
        -------
        tuple of numpy.ndarray
            Three (3,) float64 unit vectors: forward from ``eye`` toward ``target``; right = forward × ``up``,
            normalised; up = right × forward, the image's up, orthogonal to both.
        """
        forward = np.subtract(self.target, self.eye).astype(np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward), forward

    def rays(self, spp: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Ray origins and unit directions for spp × spp stratified samples per pixel: (H, W, spp², 3).

        Sample (i, j) of a pixel sits at ((i + ½)/spp, (j + ½)/spp) across it: spp = 1 is the pixel's centre. Row 0 is
        the image's top, column 0 its left.

        Parameters
        ----------
        spp : int
            Samples per pixel along each axis. Default 1. (The renderer allows 1 to 16.)

        Returns
        -------
        origins : numpy.ndarray
            (H, W, spp², 3) float64, every one the eye (a read-only broadcast of it), world frame.
        directions : numpy.ndarray
            (H, W, spp², 3) float64 unit directions, world frame.
        """
        right, up, forward = self.basis()
        half_h = np.tan(np.radians(self.fov) / 2)
        half_w = half_h * self.width / self.height
        sub = (np.arange(spp) + 0.5) / spp
        sx = (np.arange(self.width)[:, None] + sub[None, :]).reshape(-1)
        sy = (np.arange(self.height)[:, None] + sub[None, :]).reshape(-1)
        x = (2 * sx / self.width - 1) * half_w  # (W·spp,)
        y = (1 - 2 * sy / self.height) * half_h  # (H·spp,)
        d = (x[None, :, None] * right + y[:, None, None] * up + forward)  # (H·spp, W·spp, 3)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        d = d.reshape(self.height, spp, self.width, spp, 3).transpose(0, 2, 1, 3, 4).reshape(
            self.height, self.width, spp * spp, 3)
        return np.broadcast_to(np.asarray(self.eye, dtype=np.float64), d.shape), d


@dataclass(frozen=True)
class Material:
    """A mesh's surface: Lambertian ``albedo`` or ``texture``, or another BRDF.

    Lambertian reflectance ``albedo`` (linear RGB) or ``texture`` (linear RGB image, looked up at the mesh UVs),
    unless ``brdf`` names another BRDF (a :class:`lightprobe.glossy.brdf.BRDF`, e.g. GGX gold): then the surface is that
    BRDF, and only the methods that shade glossy surfaces (``brute``, and the Mitsuba reference) can render it.

    Parameters
    ----------
    albedo : tuple of float
        Lambertian reflectance, three linear RGB numbers in [0, 1]. Default (0.8, 0.8, 0.8).
    texture : numpy.ndarray or None
        (h, w, 3 or more) linear RGB image, row 0 the top; where the mesh has UVs it replaces ``albedo`` (looked up
        bilinearly, wrapping, UV (0, 0) the image's bottom left). Default None.
    brdf : BRDF or None
        Another BRDF for the surface; None (default): Lambertian.

    Raises
    ------
    LightprobeError
        ``albedo`` is not three finite numbers in [0, 1], or ``brdf`` is not a BRDF.
    """

    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)
    texture: np.ndarray | None = field(default=None, repr=False)
    brdf: BRDF | None = None

    def __post_init__(self) -> None:
        a = np.asarray(self.albedo, dtype=np.float64)
        if a.shape != (3,) or not np.isfinite(a).all() or (a < 0).any() or (a > 1).any():
            raise LightprobeError(f"albedo must be three numbers in [0, 1], got {short(self.albedo)}")
        if self.brdf is not None and not isinstance(self.brdf, BRDF):
            raise LightprobeError(f"a material's brdf must be a lightprobe.glossy.brdf.BRDF, got {short(self.brdf)}")

    @property
    def glossy(self) -> bool:
        """True when the surface is not the plain Lambertian albedo (``brdf`` is set)."""
        return self.brdf is not None


@dataclass(frozen=True, eq=False)
class MeshInstance:
    """Triangles in world space with per-vertex shading normals (and optional UVs) and a material.

    Build one with :func:`mesh_instance`, which checks shapes and indices and computes normals; this class itself
    checks only that the numbers are finite.

    Parameters
    ----------
    vertices : numpy.ndarray
        (V, 3) float64 positions, world frame, in the meshes' units.
    faces : numpy.ndarray
        (F, 3) int64 vertex indices of each triangle.
    normals : numpy.ndarray
        (V, 3) unit vertex normals, world frame, interpolated across triangles as shading normals.
    material : Material
        The surface. Default: Lambertian, albedo 0.8.
    uv : numpy.ndarray or None
        (V, 2) texture coordinates, v up (OpenGL/OBJ convention), or None.
    name : str
        Names the mesh in messages. Default ``mesh``.

    Raises
    ------
    LightprobeError
        Vertices, normals or UVs contain NaN or infinite numbers.
    """

    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    normals: np.ndarray  # (V, 3) unit vertex normals
    material: Material = Material()
    uv: np.ndarray | None = None  # (V, 2), v up (OpenGL/OBJ convention)
    name: str = "mesh"

    def __post_init__(self) -> None:
        for what, values in (("vertices", self.vertices), ("normals", self.normals), ("UVs", self.uv)):
            if values is not None and not np.isfinite(values).all():
                raise LightprobeError(f"{self.name}: {what} contain NaN or infinite numbers (check scale, fit and "
                                      "rotate)")


@dataclass(frozen=True, eq=False)
class Scene:
    """Meshes + camera + the environment (radiance, world frame) that lights them and is seen behind them.

    Parameters
    ----------
    meshes : tuple of MeshInstance
        The geometry, world frame.
    camera : Camera
        The pinhole camera that frames the image.
    environment : EnvMap
        The only light: radiance arriving from each direction, world frame (+Y up, front −Z), any layout.
    background : bool
        True (default): rays that hit nothing show the environment; False: they are black (0).
    name : str
        Names the scene in reports. Default ``scene``.
    """

    meshes: tuple[MeshInstance, ...]
    camera: Camera
    environment: EnvMap
    background: bool = True
    name: str = "scene"

    @property
    def triangle_count(self) -> int:
        """Triangles of all the meshes together."""
        return sum(len(m.faces) for m in self.meshes)


# ---- building meshes ----------------------------------------------------------------------------------------------
def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (the sum of the unnormalised face normals at each vertex)."""
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(n, faces[:, k], face_n)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 0, n / np.where(length > 0, length, 1), [0.0, 1.0, 0.0])


def mesh_instance(vertices, faces, material: Material = Material(), normals=None, uv=None,
                  name: str = "mesh") -> MeshInstance:
    """A checked :class:`MeshInstance` from vertices, triangles and optional normals and UVs.

    Parameters
    ----------
    vertices : array_like
        (V, 3) positions, world frame, in the meshes' units (converted to float64).
    faces : array_like
        (F, 3) vertex indices of each triangle, 0 ≤ index < V, at least one triangle (converted to int64). Computed
        normals point to the side from which a triangle's vertices run counter-clockwise.
    material : Material
        The surface. Default: Lambertian, albedo 0.8.
    normals : array_like or None
        (V, 3) unit vertex normals, taken as given. None (default): area-weighted normals, the normalised sum of the
        unnormalised face normals at each vertex (+Y where that sum is zero).
    uv : array_like or None
        (V, 2) texture coordinates, v up (OpenGL/OBJ convention), or None (default).
    name : str
        Names the mesh in messages. Default ``mesh``.

    Returns
    -------
    MeshInstance
        The mesh, arrays as float64 (indices int64).

    Raises
    ------
    LightprobeError
        Arrays of the wrong shape, no triangle, an index out of range, or numbers that are not finite.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise LightprobeError(f"{name}: a mesh needs (V, 3) vertices and (F, 3) triangles")
    if f.min() < 0 or f.max() >= len(v):
        raise LightprobeError(f"{name}: triangle indices out of range")
    n = _vertex_normals(v, f) if normals is None else np.asarray(normals, dtype=np.float64)
    return MeshInstance(v, f, n, material, None if uv is None else np.asarray(uv, dtype=np.float64), name)


TEXT_MESH_SUFFIXES = (".obj", ".off")  # formats that are text only (PLY and STL may be binary)


def load_mesh(path: str | os.PathLike, material: Material = Material()) -> MeshInstance:
    """A mesh file (OBJ, PLY, STL, glTF/GLB, OFF …) through trimesh, as one triangle mesh with smooth normals.

    The file's own normals are not used: vertex normals are area-weighted from the triangles (:func:`mesh_instance`).
    Text formats (OBJ, OFF) must be UTF-8. UVs are kept; when there are UVs, an image in the file's material becomes the
    material's texture (sRGB-decoded to linear) unless ``material`` has one already.

    Parameters
    ----------
    path : str or os.PathLike
        A regular file; trimesh reads it by its suffix.
    material : Material
        The surface. Default: Lambertian, albedo 0.8.

    Returns
    -------
    MeshInstance
        The mesh as the file has it (its units and axes, no transform), named after the file's stem.

    Raises
    ------
    InputError
        The path is not a regular file, a text format is not UTF-8, or the file is malformed or has no triangles.
    BudgetError
        More triangles than ``LIGHTPROBE_MAX_TRIANGLES`` allows.
    """
    import trimesh

    path = Path(path)
    check_regular_file(path, "mesh")
    claimed = mesh_triangles(path)
    if claimed is not None and claimed > max_triangles():  # before the mesh is read into memory
        raise BudgetError(f"refusing mesh {path}: its file says {claimed} triangles, over the limit of "
                          f"{max_triangles()} (set LIGHTPROBE_MAX_TRIANGLES to raise it)")
    if path.suffix.lower() in TEXT_MESH_SUFFIXES:  # trimesh would guess an encoding with a package we do not ship
        _check_utf8(path)
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # trimesh raises many kinds of errors for bad files
        raise InputError(f"cannot read mesh {path}: {_mesh_error(path, e)}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise InputError(f"cannot read mesh {path}: no triangles in it")
    if len(loaded.faces) > max_triangles():
        raise BudgetError(f"refusing mesh {path}: {len(loaded.faces)} triangles is over the limit of "
                          f"{max_triangles()} (set LIGHTPROBE_MAX_TRIANGLES to raise it)")
    uv = getattr(loaded.visual, "uv", None)
    texture = None
    if uv is not None and material.texture is None:
        image = getattr(getattr(loaded.visual, "material", None), "image", None)
        if image is not None:
            from ..maps.tonemap import srgb_decode

            texture = srgb_decode(np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0)
    mat = replace(material, texture=texture if texture is not None else material.texture)
    return mesh_instance(loaded.vertices, loaded.faces, mat, uv=uv, name=path.stem)


HEADER_BYTES = 1 << 16  # the most of a PLY or OFF file read for its header
GLTF_JSON_BYTES = 64 << 20  # the most of a glTF's JSON read for its accessor counts


def mesh_triangles(path: str | os.PathLike) -> int | None:
    """How many triangles a mesh file says it has, at least, read from its header alone (nothing is loaded).

    PLY: the header's ``element face N``; binary STL: its count (a file of 84 + 50 N bytes); ASCII STL and OBJ:
    their ``facet`` and ``f`` lines, counted in one pass over the file; OFF: the face count of its first line of
    numbers; glTF and GLB: the index (or, without indices, position) counts of their triangle primitives, ÷ 3. A
    face with more than three corners makes more triangles than counted here, never fewer.

    Parameters
    ----------
    path : str or os.PathLike
        The mesh file; anything but a regular file gives None.

    Returns
    -------
    int or None
        The count; None when the format is another or its header does not say (the count is then checked once the
        mesh is loaded).
    """
    import stat

    path = Path(path)
    kind = path.suffix.lower()
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO is not waited on: it is no mesh
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return None
            if kind in (".ply", ".off"):
                return _header_faces(f.read(HEADER_BYTES), kind)
            if kind == ".stl":
                head = f.read(84)
                size = os.fstat(f.fileno()).st_size
                count = int.from_bytes(head[80:84], "little") if len(head) == 84 else None
                if count is not None and (not head.lstrip().startswith(b"solid") or size == 84 + 50 * count):
                    return count
                f.seek(0)
                return _count_lines(f, b"facet")
            if kind == ".obj":
                return _count_lines(f, b"f")
            if kind in (".gltf", ".glb"):
                return _gltf_triangles(f, kind)
    except (OSError, ValueError, UnicodeDecodeError, RecursionError):
        return None
    return None


def _header_faces(head: bytes, kind: str) -> int | None:
    import re

    if kind == ".ply":
        found = re.search(rb"^element[ \t]+face[ \t]+(\d{1,20})[ \t]*\r?$", head.split(b"end_header")[0], re.M)
        return int(found.group(1)) if found else None
    lines = [ln.split(b"#")[0].split() for ln in head.splitlines()[:64]]
    counts = [ln for ln in lines if ln and ln[0][:1].isdigit()]
    return int(counts[0][1]) if counts and len(counts[0]) >= 2 and counts[0][1].isdigit() else None


def _count_lines(f, keyword: bytes, chunk: int = 1 << 24) -> int:
    """Lines of the open file that start with ``keyword`` and a space or tab (leading blanks allowed)."""
    import re

    pattern, count, rest = re.compile(rb"^[ \t]*" + keyword + rb"[ \t]", re.M), 0, b""
    for block in iter(lambda: f.read(chunk), b""):
        text = rest + block
        cut = text.rfind(b"\n") + 1
        count += len(pattern.findall(text, 0, cut))
        rest = text[cut:] if len(text) - cut <= 256 else b"#"  # a line that long is no face line's start
    return count + len(pattern.findall(rest))


def _gltf_triangles(f, kind: str) -> int | None:
    import json

    if kind == ".glb":
        head = f.read(20)
        if len(head) < 20 or head[:4] != b"glTF" or head[16:20] != b"JSON":
            return None
        length = int.from_bytes(head[12:16], "little")
        text = f.read(length) if length <= GLTF_JSON_BYTES else None
    else:
        text = f.read(GLTF_JSON_BYTES + 1)
    if text is None or len(text) > GLTF_JSON_BYTES:
        return None
    doc = json.loads(text)
    accessors, total = doc.get("accessors") or [], 0
    for mesh in doc.get("meshes") or []:
        for primitive in mesh.get("primitives") or []:
            if primitive.get("mode", 4) != 4:
                continue
            index = primitive.get("indices", (primitive.get("attributes") or {}).get("POSITION"))
            if isinstance(index, int) and 0 <= index < len(accessors) and isinstance(accessors[index], dict):
                count = accessors[index].get("count")
                total += count // 3 if isinstance(count, int) and count > 0 else 0
    return total


def _check_utf8(path: Path, chunk: int = 1 << 24) -> None:
    """InputError unless the file is UTF-8 text (decoded in chunks: a large OBJ is not held twice)."""
    import codecs

    decoder, offset = codecs.getincrementaldecoder("utf-8")(), 0
    with open(path, "rb") as f:
        while True:
            block = f.read(chunk)
            pending = len(decoder.getstate()[0])  # the bytes of a character cut by the last block, decoded with this
            try:
                decoder.decode(block, final=not block)
            except UnicodeDecodeError as e:
                raise InputError(f"cannot read mesh {path}: not a text {path.suffix[1:].upper()} file (bytes that "
                                 f"are not UTF-8 at offset {offset - pending + e.start})") from None
            if not block:
                return
            offset += len(block)


def _mesh_error(path: Path, e: Exception) -> str:
    """What was wrong with a mesh file trimesh could not load, in words (its own messages name its internals: a
    missing text-encoding guesser for bytes that are not UTF-8, an index out of bounds for a face's bad vertex)."""
    kind = path.suffix.lstrip(".").upper() or "mesh"
    if isinstance(e, ImportError):
        return f"not a readable {kind} file (text that is not UTF-8, or binary data where text was expected)"
    if isinstance(e, IndexError):
        return f"a face names a vertex that is not in the file ({kind})"
    if isinstance(e, KeyError):
        return f"malformed {kind}: no {e} where one was expected"
    text = str(e).splitlines()[0] if str(e).strip() else type(e).__name__
    return f"malformed {kind}: {text[:200]}"


def transformed(mesh: MeshInstance, scale: float = 1.0, rotation=None, translate=(0.0, 0.0, 0.0)) -> MeshInstance:
    """The mesh scaled, then rotated ((yaw, pitch, roll) degrees or a matrix), then translated.

    Parameters
    ----------
    mesh : MeshInstance
        The mesh to move; it is not changed.
    scale : float
        Uniform scale factor about the origin. Default 1.
    rotation : array_like or None
        (yaw, pitch, roll) in degrees or a 3×3 proper rotation matrix (:func:`lightprobe.maps.frames.as_rotation`),
        about the origin; None (default): no rotation.
    translate : array_like
        (3,) offset, world frame, in the meshes' units. Default (0, 0, 0).

    Returns
    -------
    MeshInstance
        A new mesh: vertices (v · scale) Rᵀ + translate, normals rotated; faces, material, UVs and name kept.

    Raises
    ------
    UsageError
        ``rotation`` is not finite numbers, or a matrix that is not a proper rotation.
    LightprobeError
        The moved vertices or normals are not finite (a NaN scale, say).
    """
    r = np.eye(3) if rotation is None else as_rotation(rotation)
    v = (mesh.vertices * scale) @ r.T + np.asarray(translate, dtype=np.float64)
    return MeshInstance(v, mesh.faces, mesh.normals @ r.T, mesh.material, mesh.uv, mesh.name)


def fitted(mesh: MeshInstance, size: float, on_ground: bool = True, ground_height: float = 0.0) -> MeshInstance:
    """Scale so the largest extent is ``size``, centre on x and z, and (optionally) stand it on the ground.

    Parameters
    ----------
    mesh : MeshInstance
        The mesh to fit; it is not changed.
    size : float
        The largest side of its axis-aligned bounding box after scaling, in world units; finite and > 0.
    on_ground : bool
        True (default): its lowest point goes to y = ``ground_height``; False: its box is centred on y = 0 too.
    ground_height : float
        The ground's y, used with ``on_ground``. Default 0.

    Returns
    -------
    MeshInstance
        The mesh scaled uniformly and translated (not rotated).

    Raises
    ------
    LightprobeError
        ``size`` is not a finite positive number.
    """
    if not (np.isfinite(size) and size > 0):
        raise LightprobeError(f"{mesh.name}: fit must be a positive number, got {size!r}")
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    s = size / max(float((hi - lo).max()), 1e-12)
    centre = (lo + hi) / 2 * s
    lift = ground_height - lo[1] * s if on_ground else -centre[1]
    return transformed(mesh, s, None, (-centre[0], lift, -centre[2]))


SPHERE_TRIANGLES = 20 * 4**5  # an icosphere of 5 subdivisions
TORUS_TRIANGLES = 2 * 96 * 48


def sphere(radius: float = 0.5, center=(0.0, 0.0, 0.0), material: Material = Material(),
           subdivisions: int = 5) -> MeshInstance:
    """An icosphere with exact sphere normals (so shading is that of a perfect sphere).

    Parameters
    ----------
    radius : float
        Radius in world units. Default 0.5.
    center : array_like
        (3,) centre, world frame. Default the origin.
    material : Material
        The surface. Default: Lambertian, albedo 0.8.
    subdivisions : int
        Icosphere subdivision level: 20 · 4^subdivisions triangles. Default 5 (:data:`SPHERE_TRIANGLES`, 20480).

    Returns
    -------
    MeshInstance
        The sphere, named ``sphere``, its normals the unit directions from the centre.
    """
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    unit = ico.vertices / np.linalg.norm(ico.vertices, axis=1, keepdims=True)
    return mesh_instance(unit * radius + np.asarray(center), ico.faces, material, normals=unit, name="sphere")


def torus(major: float = 0.35, minor: float = 0.12, center=(0.0, 0.0, 0.0), material: Material = Material(),
          rotation=(0.0, 90.0, 0.0)) -> MeshInstance:
    """A torus; by default lying flat (its axis turned from trimesh's +Z to +Y).

    Lying flat, ``center`` y = ``minor`` rests it on the ground (y = 0). It has 96 × 48 sections
    (:data:`TORUS_TRIANGLES` triangles).

    Parameters
    ----------
    major : float
        Distance from the centre to the middle of the tube, world units. Default 0.35.
    minor : float
        Radius of the tube, world units. Default 0.12.
    center : array_like
        (3,) where its centre goes, world frame, after the rotation. Default the origin.
    material : Material
        The surface. Default: Lambertian, albedo 0.8.
    rotation : array_like
        (yaw, pitch, roll) in degrees or a 3×3 rotation, applied about its centre before it is moved. Default
        (0, 90, 0): lying flat.

    Returns
    -------
    MeshInstance
        The torus, named ``torus``, with area-weighted vertex normals.
    """
    import trimesh

    t = trimesh.creation.torus(major_radius=major, minor_radius=minor, major_sections=96, minor_sections=48)
    return transformed(mesh_instance(t.vertices, t.faces, material, name="torus"), 1.0, rotation, center)


def ground_plane(size: float = 20.0, height: float = 0.0, material: Material = Material((0.5, 0.5, 0.5))) -> MeshInstance:
    """A square ground plane of two triangles facing +Y, centred on the y axis.

    Parameters
    ----------
    size : float
        Side of the square, world units. Default 20.
    height : float
        Its y, world frame. Default 0.
    material : Material
        The surface. Default: Lambertian, albedo 0.5.

    Returns
    -------
    MeshInstance
        The plane, named ``ground``, with +Y normals.
    """
    h = size / 2
    v = np.array([[-h, height, -h], [h, height, -h], [h, height, h], [-h, height, h]])
    f = np.array([[0, 2, 1], [0, 3, 2]])  # counter-clockwise seen from above: normal +Y
    return mesh_instance(v, f, material, normals=np.tile([0.0, 1.0, 0.0], (4, 1)), name="ground")


# ---- scenes -------------------------------------------------------------------------------------------------------
KEY_LIGHT_AZIMUTH = -135.0  # behind the default camera, on its left: lit fronts, shadows falling back and right


def key_light_azimuth(env: EnvMap) -> float:
    """Azimuth φ (degrees; 0 = front −Z, 90 = +X) of the pixel carrying the most light (luminance × solid angle).

    Parameters
    ----------
    env : EnvMap
        The environment, radiance, world frame, any layout; Rec. 709 luminance weighs the pixels.

    Returns
    -------
    float
        φ in degrees, in [−180, 180].
    """
    from ..maps.tonemap import luminance

    power = luminance(env.data) * env.solid_angles()
    d = env.directions()[np.unravel_index(np.argmax(power), power.shape)]
    return float(np.degrees(np.arctan2(d[0], -d[2])))


def with_key_light_at(env: EnvMap, azimuth: float = KEY_LIGHT_AZIMUTH) -> EnvMap:
    """The environment turned about +Y so its brightest light comes from ``azimuth`` (a yaw ψ moves φ to φ − ψ).

    Parameters
    ----------
    env : EnvMap
        The environment, radiance, world frame.
    azimuth : float
        Where the brightest pixel (:func:`key_light_azimuth`) goes, degrees, 0 = front −Z, 90 = +X. Default
        :data:`KEY_LIGHT_AZIMUTH` (−135: behind the default camera, on its left).

    Returns
    -------
    EnvMap
        The turned environment (resampled, same layout and size, :meth:`lightprobe.maps.EnvMap.rotated`).
    """
    return env.rotated((key_light_azimuth(env) - azimuth, 0.0, 0.0))


def builtin_scene(environment: EnvMap, width: int = 256, height: int = 256, turn_to_key_light: bool = True) -> Scene:
    """The scene commands use when given none: a sphere and a flat torus standing on a grey ground plane.

    The environment is turned so its brightest light comes from behind the camera's left.

    Parameters
    ----------
    environment : EnvMap
        The light and background, radiance, world frame.
    width : int
        Image width in pixels (1 to 16384). Default 256.
    height : int
        Image height in pixels (1 to 16384). Default 256.
    turn_to_key_light : bool
        True (default): turn ``environment`` by :func:`with_key_light_at`; False: use it as given.

    Returns
    -------
    Scene
        A sphere (radius 0.3 at (−0.35, 0.3, 0), albedo 0.75), a torus (0.26 and 0.1 at (0.42, 0.1, 0.1), albedo
        (0.8, 0.55, 0.35)), a ground plane (20 units at y = 0, albedo 0.5), the camera at (0, 0.8, 2.3) looking at
        (0, 0.2, 0) with a 35° field of view, and the background shown.
    """
    meshes = (
        sphere(0.3, (-0.35, 0.3, 0.0), Material((0.75, 0.75, 0.75))),
        torus(0.26, 0.1, (0.42, 0.1, 0.1), Material((0.8, 0.55, 0.35))),
        ground_plane(20.0, 0.0, Material((0.5, 0.5, 0.5))),
    )
    camera = Camera(eye=(0.0, 0.8, 2.3), target=(0.0, 0.2, 0.0), fov=35, width=width, height=height)
    env = with_key_light_at(environment) if turn_to_key_light else environment
    return Scene(meshes, camera, env, True, "builtin: sphere and torus on a ground plane")


def mesh_scene(mesh_path: str | os.PathLike, environment: EnvMap, width: int = 256, height: int = 256,
               ground: bool = True, albedo=(0.8, 0.8, 0.8), turn_to_key_light: bool = True) -> Scene:
    """One mesh (fitted to 1 unit, standing on a ground plane) framed by the default camera.

    The environment is turned so its brightest light comes from behind the camera's left.

    Parameters
    ----------
    mesh_path : str or os.PathLike
        The mesh file (:func:`load_mesh`).
    environment : EnvMap
        The light and background, radiance, world frame.
    width, height : int
        Image size in pixels, each from 1 to 16384. Default 256 × 256.
    ground : bool
        Add a 20-unit ground plane at y = 0, albedo 0.5. Default True.
    albedo : array_like
        The mesh's Lambertian reflectance, three linear RGB numbers in [0, 1]. Default (0.8, 0.8, 0.8).
    turn_to_key_light : bool
        As for :func:`builtin_scene`. Default True.

    Returns
    -------
    Scene
        The mesh fitted to a largest extent of 1 and stood on y = 0, the camera framing its height h from
        (0, 0.55 h + 0.35, 2.6) toward (0, 0.45 h, 0) with a 32° field of view; named after the file.

    Raises
    ------
    InputError
        The mesh file cannot be read.
    BudgetError
        The mesh has more triangles than ``LIGHTPROBE_MAX_TRIANGLES``.
    """
    mesh = fitted(load_mesh(mesh_path, Material(tuple(albedo))), 1.0, on_ground=True)
    environment = with_key_light_at(environment) if turn_to_key_light else environment
    meshes = (mesh, ground_plane(20.0, 0.0)) if ground else (mesh,)
    top = float(mesh.vertices[:, 1].max())
    camera = Camera(eye=(0.0, 0.55 * top + 0.35, 2.6), target=(0.0, 0.45 * top, 0.0), fov=32, width=width,
                    height=height)
    return Scene(meshes, camera, environment, True, Path(mesh_path).name)


def sphere_scene(environment: EnvMap, size: int = 64, fov: float = 30.0) -> Scene:
    """A unit-radius sphere alone, filling most of the frame: no shadows, no occlusion (for method checks).

    Parameters
    ----------
    environment : EnvMap
        The light and background, radiance, world frame.
    size : int
        Width and height of the image in pixels. Default 64.
    fov : float
        Vertical field of view in degrees. Default 30. The camera sits on +Z at 1.15 / sin(fov / 2) from the centre,
        looking at it.

    Returns
    -------
    Scene
        A white (albedo 1) icosphere of 6 subdivisions at the origin, the background shown.
    """
    distance = 1.15 / np.sin(np.radians(fov) / 2)
    camera = Camera(eye=(0.0, 0.0, distance), target=(0.0, 0.0, 0.0), fov=fov, width=size, height=size)
    return Scene((sphere(1.0, (0, 0, 0), Material((1.0, 1.0, 1.0)), subdivisions=6),), camera, environment, True,
                 "unshadowed sphere")
