"""Ray casting with Embree (embreex, through trimesh): first hits with interpolated shading attributes, and shadow
rays for the lighting methods that need visibility.

All meshes of a scene go into one acceleration structure; each hit knows its mesh, triangle and barycentric
coordinates. Normals are flipped to face the viewer where the geometric normal faces away (two-sided surfaces, as
Mitsuba's ``twosided`` BSDF), so open meshes such as the Stanford bunny shade the same from both sides.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .scene import Scene

OCCLUSION_CHUNK = 1 << 16  # shadow rays per Embree call and thread (fewer: the calls' overhead shows)
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
        self._bounds = [_bound(m.vertices, self.extent) for m in scene.meshes]
        self.ray_bounds = _ray_bounds(scene.meshes, self._bounds, self.extent)

    def may_block(self, points: np.ndarray, axis: np.ndarray, half_angle: float) -> np.ndarray:
        """False where no ray from the point within ``half_angle`` of unit ``axis`` can hit any mesh — a cheap,
        conservative test per mesh on its bound (below), so shadow rays are cast only where a shadow may fall.

        A flat mesh (a ground plane) cannot be hit by a ray leaving the side of its plane the point is on; any
        other mesh not by a ray whose cone clears its bounding sphere."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(points), dtype=bool)
        bound_sin = np.sin(min(half_angle, np.pi / 2))
        for kind, a, b in self._bounds:
            if kind == "plane":  # a: unit normal, b: offset (n·x = b on the plane)
                side = points @ a - b
                toward = float(axis @ a)
                out |= ~(((side >= 0) & (toward >= bound_sin)) | ((side <= 0) & (toward <= -bound_sin)))
            else:  # a: centre, b: radius
                to = a - points
                dist = np.linalg.norm(to, axis=1)
                inside = dist <= b
                cos_to = (to @ axis) / np.maximum(dist, 1e-300)
                reach = half_angle + np.arcsin(np.clip(b / np.maximum(dist, 1e-300), 0.0, 1.0))
                out |= inside | (np.arccos(np.clip(cos_to, -1.0, 1.0)) <= reach)
        return out

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
        """True where a ray (towards a light at infinity) hits any geometry.

        Embree's occlusion query (any hit ends the ray: cheaper than trimesh's ``intersects_any``, which finds the
        closest), float32 as Embree stores the scene, in chunks shared by the threads of
        :func:`lightprobe.limits.threads` — embreex releases the GIL while Embree traces."""
        from ..limits import threads

        origins, directions = (np.asarray(a, dtype=np.float32).reshape(-1, 3) for a in (origins, directions))
        origins, directions = (np.ascontiguousarray(a) for a in np.broadcast_arrays(origins, directions))
        out = np.empty(len(origins), dtype=bool)
        if not len(out):
            return out
        step = max(OCCLUSION_CHUNK, -(-len(out) // threads()))
        scene = self._intersector._scene  # trimesh's embreex scene: its ``run`` has the OCCLUDED query

        def trace(start):
            part = slice(start, start + step)
            out[part] = scene.run(origins[part], directions[part], query="OCCLUDED") == 0  # 0: blocked, −1: free

        starts = range(0, len(out), step)
        if len(starts) == 1:
            trace(0)
        else:
            list(_pool().map(trace, starts))
        return out

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


_POOL: dict = {}
os.register_at_fork(after_in_child=_POOL.clear)  # a forked child has none of its parent's threads


def _pool():
    """The shadow-ray threads, started once per process and thread count (starting them per call cost ~8 ms)."""
    from concurrent.futures import ThreadPoolExecutor

    from ..limits import threads

    n = threads()
    if n not in _POOL:
        _POOL[n] = ThreadPoolExecutor(n, thread_name_prefix="lightprobe-rays")
    return _POOL[n]


def _bound(vertices: np.ndarray, extent: float) -> tuple[str, np.ndarray, float]:
    """A mesh's bound for :meth:`Tracer.may_block`: ("plane", unit normal, offset) when every vertex lies within
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


RayBounds = tuple  # (planes (P, 4): unit normal, offset; roots (M, 2, 3); leaf ranges (M, 2); leaves (L, 2, 3))
LEAF_DEPTH = 5  # each solid mesh's triangles split in 2⁵ = 32 boxes for the per-ray test


def _ray_bounds(meshes, bounds, extent: float) -> RayBounds:
    """The scene's bounds for the shadow-ray kernels' per-ray test (:func:`lightprobe.render.sampling.may_hit`):
    each flat mesh as its plane, each other mesh as its box and the boxes of 32 groups of its triangles (split at
    the median centroid along the longest side, recursively) — a ray that enters none of them cannot hit the mesh.
    Boxes are padded by 10⁻⁵ of the scene's size, far above float32 rounding of the rays Embree traces."""
    pad = 1e-5 * max(extent, 1e-30)
    planes, roots, ranges, leaves = [], [], [], []
    for mesh, (kind, a, b) in zip(meshes, bounds):
        if kind == "plane":
            planes.append([*a, b])
            continue
        corners = mesh.vertices[mesh.faces]  # (F, 3 corners, 3)
        groups = _split(corners.mean(axis=1), np.arange(len(corners)), LEAF_DEPTH)
        ranges.append([len(leaves), len(leaves) + len(groups)])
        leaves += [[corners[g].reshape(-1, 3).min(axis=0) - pad, corners[g].reshape(-1, 3).max(axis=0) + pad]
                   for g in groups]
        roots.append([mesh.vertices.min(axis=0) - pad, mesh.vertices.max(axis=0) + pad])
    return (np.array(planes, dtype=np.float64).reshape(-1, 4), np.array(roots, dtype=np.float64).reshape(-1, 2, 3),
            np.array(ranges, dtype=np.int64).reshape(-1, 2), np.array(leaves, dtype=np.float64).reshape(-1, 2, 3))


def _split(centres: np.ndarray, which: np.ndarray, depth: int) -> list[np.ndarray]:
    """Triangle groups: ``which`` halved at the median of its centres along their widest axis, ``depth`` times."""
    if depth == 0 or len(which) < 2:
        return [which]
    c = centres[which]
    axis = int(np.argmax(np.ptp(c, axis=0)))
    order = which[np.argsort(c[:, axis], kind="stable")]
    half = len(order) // 2
    return _split(centres, order[:half], depth - 1) + _split(centres, order[half:], depth - 1)


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
