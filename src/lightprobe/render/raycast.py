"""Ray casting with Embree: first hits with interpolated shading attributes (embreex, through trimesh), and shadow
rays for the lighting methods that need visibility (Embree called from compiled code, :mod:`.embree`).

All meshes of a scene go into one acceleration structure; each hit knows its mesh, triangle and barycentric
coordinates. Normals are flipped to face the viewer where the geometric normal faces away (two-sided surfaces, as
Mitsuba's ``twosided`` BSDF), so open meshes such as the Stanford bunny shade the same from both sides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Scene

SHADOW_EPSILON = 1e-4  # offset of shadow-ray origins along the normal, relative to the scene's size


@dataclass(frozen=True, eq=False)
class Hits:
    """First hits of a batch of rays; ``ray`` indexes the batch. All arrays have one row per hit."""

    ray: np.ndarray
    position: np.ndarray
    normal: np.ndarray  # interpolated shading normal, unit, facing the viewer
    geometric: np.ndarray  # face normal, unit, facing the viewer
    albedo: np.ndarray
    mesh: np.ndarray
    face: np.ndarray  # triangle index within its mesh
    barycentric: np.ndarray
    back: np.ndarray  # True where the viewer sees the back of the triangle (normals were flipped)
    view: np.ndarray  # unit direction from the hit toward the ray's origin (the eye): "wo" of the BRDFs

    def __len__(self) -> int:
        return len(self.ray)


class Tracer:
    """Embree intersector over every mesh of a scene."""

    def __init__(self, scene: Scene):
        import trimesh
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        self.scene = scene
        offsets = np.cumsum([0] + [len(m.vertices) for m in scene.meshes])
        face_offsets = np.cumsum([0] + [len(m.faces) for m in scene.meshes])
        self.vertices = np.concatenate([m.vertices for m in scene.meshes])
        self.faces = np.concatenate([m.faces + o for m, o in zip(scene.meshes, offsets[:-1])])
        self.normals = np.concatenate([m.normals for m in scene.meshes])
        self.face_mesh = np.repeat(np.arange(len(scene.meshes)), [len(m.faces) for m in scene.meshes])
        self.face_offsets = face_offsets
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False, validate=False)
        self.face_normals = mesh.face_normals
        self._intersector = RayMeshIntersector(mesh, scale_to_box=False)
        self.extent = float(np.ptp(self.vertices, axis=0).max())
        self.cone_bounds = cone_bounds([_bound(m.vertices, self.extent) for m in scene.meshes])
        self._embree = None

    def first_hits(self, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """Closest hit of each ray (rays that miss are absent)."""
        origins = np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        tri, ray, location = self._intersector.intersects_id(origins, directions, multiple_hits=False,
                                                             return_locations=True)
        order = np.argsort(ray)
        tri, ray, location = tri[order], ray[order], location[order]
        from trimesh.triangles import points_to_barycentric

        bary = points_to_barycentric(self.vertices[self.faces[tri]], location)
        geometric = self.face_normals[tri]
        shading = np.einsum("ij,ijk->ik", bary, self.normals[self.faces[tri]])
        shading /= np.maximum(np.linalg.norm(shading, axis=1, keepdims=True), 1e-12)
        facing = np.einsum("ij,ij->i", geometric, directions[ray]) > 0  # the viewer sees the back
        geometric = np.where(facing[:, None], -geometric, geometric)
        shading = np.where(facing[:, None], -shading, shading)
        mesh_id = self.face_mesh[tri]
        view = -directions[ray] / np.maximum(np.linalg.norm(directions[ray], axis=1, keepdims=True), 1e-300)
        return Hits(ray, location, shading, geometric, self._albedo(mesh_id, tri, bary), mesh_id,
                    tri - self.face_offsets[mesh_id], bary, facing, view)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """True where a ray (towards a light at infinity; directions broadcast against origins) hits any geometry:
        Embree's occlusion query, sixteen rays a call from compiled code on every core
        (:meth:`lightprobe.render.embree.EmbreeScene.occluded`), the scene in float32 as Embree stores it."""
        return self.embree.occluded(origins, directions)

    @property
    def embree(self):
        """The scene's triangles as an Embree scene for shadow rays (built on first use: renders without shadows
        never pay for it)."""
        if self._embree is None:
            from .embree import EmbreeScene

            self._embree = EmbreeScene(self.vertices, self.faces)
        return self._embree

    def shadow_origins(self, hits: Hits) -> np.ndarray:
        """Hit points nudged off the surface along the (viewer-facing) geometric normal."""
        return hits.position + hits.geometric * (SHADOW_EPSILON * max(self.extent, 1e-9))

    def _albedo(self, mesh_id: np.ndarray, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        out = np.empty((len(tri), 3))
        for k, mesh in enumerate(self.scene.meshes):
            sel = mesh_id == k
            if not sel.any():
                continue
            mat = mesh.material
            if mat.texture is not None and mesh.uv is not None:
                local = tri[sel] - self.face_offsets[k]
                uv = np.einsum("ij,ijk->ik", bary[sel], mesh.uv[mesh.faces[local]])
                out[sel] = _texture_lookup(mat.texture, uv)
            else:
                out[sel] = mat.albedo
        return out


def cone_bounds(bounds: list) -> tuple[np.ndarray, np.ndarray]:
    """The meshes' bounds (of :func:`_bound`) as the shadow kernels take them
    (:func:`lightprobe.render.sampling.cap_visible`): planes (P, 4) — unit normal, offset — and spheres (S, 4) —
    centre, radius."""
    planes = [[*a, b] for kind, a, b in bounds if kind == "plane"]
    spheres = [[*a, b] for kind, a, b in bounds if kind == "sphere"]
    return np.array(planes, dtype=np.float64).reshape(-1, 4), np.array(spheres, dtype=np.float64).reshape(-1, 4)


def _bound(vertices: np.ndarray, extent: float) -> tuple[str, np.ndarray, float]:
    """A mesh's bound for the test whether a cone of shadow rays may meet it: ("plane", unit normal, offset) when every vertex lies within
    1e-7 of the scene's size of one plane, else ("sphere", centre, radius) around its box's centre."""
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    radius = float(np.linalg.norm(vertices - centre, axis=1).max()) * (1 + 1e-9) + 1e-9 * extent
    if len(vertices) >= 3:
        _, sing, vt = np.linalg.svd(vertices - vertices.mean(axis=0), full_matrices=False)
        normal = vt[-1]
        offset = float(vertices.mean(axis=0) @ normal)
        if np.abs(vertices @ normal - offset).max() <= 1e-7 * max(extent, 1e-300):
            return "plane", normal, offset
    return "sphere", centre, radius


def _texture_lookup(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup with wrapping; uv (0, 0) is the bottom-left of the image (OBJ/OpenGL convention)."""
    h, w = image.shape[:2]
    x = (uv[:, 0] % 1.0) * w - 0.5
    y = (1.0 - uv[:, 1] % 1.0) * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    out = 0
    for dx, dy, wgt in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        out = out + wgt * image[(y0 + dy) % h, (x0 + dx) % w, :3]
    return np.clip(out, 0, 1)
