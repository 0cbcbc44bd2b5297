"""Ray casting with Embree (embreex, through trimesh): first hits with interpolated shading attributes, and shadow
rays for the lighting methods that need visibility.

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
        return Hits(ray, location, shading, geometric, self._albedo(mesh_id, tri, bary), mesh_id,
                    tri - self.face_offsets[mesh_id], bary, facing)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """True where a ray (towards a light at infinity) hits any geometry."""
        origins = np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        return self._intersector.intersects_any(origins, directions)

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
