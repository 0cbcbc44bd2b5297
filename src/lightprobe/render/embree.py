"""Embree 4's occlusion query called from compiled kernels, sixteen rays a call.

embreex (through trimesh) wraps Embree for Python one ray at a time (``rtcOccluded1`` in a Cython loop): a shadow
ray then costs as much in the wrapper as in the traversal. Here the same library — the ``libembree4`` embreex
ships, found among the process's loaded libraries once embreex is imported — is called directly from numba kernels
through ``rtcOccluded16``: rays that leave one shading point toward one light go down the BVH together, and the
kernels that make the rays trace them at once, without arrays of rays in between (:mod:`lightprobe.render.sampling`).

Conventions: a ray starts at its origin (t from 0) and goes to infinity along its direction (any length: Embree
scales t, not the test); geometry is the scene's triangles in float32, as Embree stores them. A ray is *blocked*
when it meets any triangle, either side. Every Embree call that can fail is checked, and a failure is one line
(:class:`EmbreeError`).
"""

from __future__ import annotations

import ctypes
import math
import weakref

import numpy as np

from ..util.jit import njit, prange

PACKET = 16  # rays per rtcOccluded16 call
# RTCRay16: twelve arrays of 16 four-byte lanes — org_x, org_y, org_z, tnear, dir_x, dir_y, dir_z, time, tfar,
# mask, id, flags — 64-byte aligned; rtcOccluded16 sets a lane's tfar to −inf when that ray is blocked.
_ORG, _TNEAR, _DIR, _TIME, _TFAR, _MASK, _ID, _FLAGS = 0, 48, 64, 112, 128, 144, 160, 176
_RAY_FLOATS = 12 * PACKET
_ALIGN_FLOATS = 16  # 64 bytes

# Values of Embree 4's enums (rtcore_geometry.h, rtcore_buffer.h, rtcore_scene.h).
_GEOMETRY_TRIANGLE, _BUFFER_INDEX, _BUFFER_VERTEX = 0, 0, 1
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003
_SCENE_FLAG_ROBUST = 1 << 2  # no ray slips between boxes of the BVH through float rounding
_BUILD_QUALITY_HIGH = 2  # a static scene traced by millions of rays: the better tree repays its build

rtc_occluded16 = None  # numba's handle on rtcOccluded16, made by _bind before any kernel here compiles


class EmbreeError(RuntimeError):
    """Embree could not be found, or refused a call (out of memory, a bad buffer)."""


_LIBRARY: dict = {}


def library() -> ctypes.CDLL:
    """Embree 4 as ctypes sees it, with the argument types of the calls made here; loaded once per process."""
    if "lib" not in _LIBRARY:
        path = _library_path()
        lib = ctypes.CDLL(path)
        vp, size = ctypes.c_void_p, ctypes.c_size_t
        for name, res, args in (
                ("rtcNewDevice", vp, [ctypes.c_char_p]), ("rtcReleaseDevice", None, [vp]),
                ("rtcGetDeviceError", ctypes.c_int, [vp]),
                ("rtcNewScene", vp, [vp]), ("rtcReleaseScene", None, [vp]), ("rtcCommitScene", None, [vp]),
                ("rtcSetSceneFlags", None, [vp, ctypes.c_int]), ("rtcSetSceneBuildQuality", None, [vp, ctypes.c_int]),
                ("rtcNewGeometry", vp, [vp, ctypes.c_int]), ("rtcReleaseGeometry", None, [vp]),
                ("rtcCommitGeometry", None, [vp]), ("rtcAttachGeometry", ctypes.c_uint, [vp, vp]),
                ("rtcSetSharedGeometryBuffer", None, [vp, ctypes.c_int, ctypes.c_uint, ctypes.c_int, vp, size, size,
                                                      size])):
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
        _LIBRARY["lib"], _LIBRARY["path"] = lib, path
    return _LIBRARY["lib"]


def _library_path() -> str:
    """The file of the Embree 4 library embreex loads (its wheel bundles one under a mangled name), read from the
    process's memory map; else the system's ``libembree4``."""
    import ctypes.util

    try:
        import embreex.rtcore_scene  # noqa: F401 - loads the library
    except ImportError:
        pass
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                path = line.split()[-1] if len(line.split()) >= 6 else ""
                if "libembree4" in path.rsplit("/", 1)[-1]:
                    return path
    except OSError:
        pass
    found = ctypes.util.find_library("embree4")
    if not found:
        raise EmbreeError("Embree 4 was not found (install embreex: pip install embreex)")
    return found


def _bind() -> None:
    """Make rtcOccluded16 callable from the kernels: the library's symbols loaded into numba's LLVM, and the
    function declared by its C signature, ``void rtcOccluded16(const int* valid, RTCScene, RTCRay16*,
    RTCOccludedArguments*)`` (the scene handle and the null arguments passed as pointer-sized integers)."""
    global rtc_occluded16
    if rtc_occluded16 is None:
        import llvmlite.binding
        from numba import types

        library()
        llvmlite.binding.load_library_permanently(_LIBRARY["path"])
        rtc_occluded16 = types.ExternalFunction(
            "rtcOccluded16", types.void(types.voidptr, types.uintp, types.voidptr, types.uintp))


class EmbreeScene:
    """One static Embree scene of triangles (``vertices`` (V, 3), ``faces`` (F, 3) indices), for occlusion queries.
    ``handle`` is the RTCScene pointer the kernels take. Released when the object is collected."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        _bind()
        lib = library()
        # Embree reads vertices 16 bytes at a time: one spare vertex after the last keeps the read in the buffer.
        self._vertices = np.zeros((len(vertices) + 1, 3), np.float32)
        self._vertices[:-1] = vertices
        self._faces = np.ascontiguousarray(faces, dtype=np.uint32)
        device = lib.rtcNewDevice(None)
        if not device:
            raise EmbreeError("Embree could not start (rtcNewDevice failed)")
        scene = lib.rtcNewScene(device)
        self._finalizer = weakref.finalize(self, _release, lib, scene, device)
        lib.rtcSetSceneFlags(scene, _SCENE_FLAG_ROBUST)
        lib.rtcSetSceneBuildQuality(scene, _BUILD_QUALITY_HIGH)
        if len(self._faces):
            geometry = lib.rtcNewGeometry(device, _GEOMETRY_TRIANGLE)
            lib.rtcSetSharedGeometryBuffer(geometry, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3, self._vertices.ctypes.data,
                                           0, 12, len(vertices))
            lib.rtcSetSharedGeometryBuffer(geometry, _BUFFER_INDEX, 0, _FORMAT_UINT3, self._faces.ctypes.data, 0, 12,
                                           len(self._faces))
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(scene, geometry)
            lib.rtcReleaseGeometry(geometry)  # the scene holds it now
        lib.rtcCommitScene(scene)
        error = lib.rtcGetDeviceError(device)
        if error:
            self._finalizer()
            raise EmbreeError(f"Embree could not build the scene of {len(self._faces)} triangles (error {error})")
        self.handle = int(scene)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """True where the ray from each origin (N, 3) along its direction (N, 3; broadcast) meets a triangle."""
        origins, directions = (np.asarray(a, dtype=np.float32).reshape(-1, 3) for a in (origins, directions))
        origins, directions = (np.ascontiguousarray(a) for a in np.broadcast_arrays(origins, directions))
        out = np.empty(len(origins), dtype=np.bool_)
        if len(out):
            occluded_rays(self.handle, origins, directions, out)
        return out


def _release(lib, scene, device) -> None:
    lib.rtcReleaseScene(scene)
    lib.rtcReleaseDevice(device)


# ---- the kernels' side ------------------------------------------------------------------------------------------

@njit(cache=True)
def packet():  # pragma: no cover - compiled
    """A ray packet (192 float32, 64-byte aligned, as RTCRay16), the same memory as uint32 (for the mask, id and
    flags lanes) and its lane mask (16 int32, aligned) — one per block of work, reused for every call.

    The uint32 view is made here, once: made inside a parallel loop (in :func:`put_ray`, inlined), numba's parfor
    lowering lost some of its writes, and rays went untraced (seen on 2 threads, never on one)."""
    rays = np.empty(_RAY_FLOATS + _ALIGN_FLOATS, np.float32)
    start = (_ALIGN_FLOATS - (rays.ctypes.data % 64) // 4) % _ALIGN_FLOATS
    lanes = np.empty(2 * PACKET, np.int32)
    lane_start = (_ALIGN_FLOATS - (lanes.ctypes.data % 64) // 4) % _ALIGN_FLOATS
    rays = rays[start:start + _RAY_FLOATS]
    return rays, rays.view(np.uint32), lanes[lane_start:lane_start + PACKET]


@njit(cache=True, inline="always")
def put_ray(rays, ints, k, o0, o1, o2, w0, w1, w2):  # pragma: no cover - compiled
    """Lane k of the packet (``rays``, ``ints`` of :func:`packet`): the ray from (o0, o1, o2) along (w0, w1, w2),
    t in [0, ∞), every mask bit."""
    rays[_ORG + k], rays[_ORG + PACKET + k], rays[_ORG + 2 * PACKET + k] = o0, o1, o2
    rays[_DIR + k], rays[_DIR + PACKET + k], rays[_DIR + 2 * PACKET + k] = w0, w1, w2
    rays[_TNEAR + k], rays[_TIME + k], rays[_TFAR + k] = 0.0, 0.0, math.inf
    ints[_MASK + k], ints[_ID + k], ints[_FLAGS + k] = 0xFFFFFFFF, 0, 0


@njit(cache=True, inline="always")
def trace(scene, rays, lanes, count):  # pragma: no cover - compiled
    """Trace lanes 0 … count − 1 of the packet (the others are off); then :func:`blocked` reads each lane."""
    for k in range(PACKET):
        lanes[k] = -1 if k < count else 0
    rtc_occluded16(lanes.ctypes, scene, rays.ctypes, 0)


@njit(cache=True, inline="always")
def blocked(rays, k):  # pragma: no cover - compiled
    return rays[_TFAR + k] < 0.0


@njit(cache=True, parallel=True)
def occluded_rays(scene, origins, directions, out):  # pragma: no cover - compiled
    """``out[i]``: whether ray i is blocked; consecutive rays share a packet (rays from one point toward one
    light are best kept together)."""
    n = origins.shape[0]
    packets = (n + PACKET - 1) // PACKET
    chunks = min(packets, 256)
    for c in prange(chunks):
        rays, ints, lanes = packet()
        for p in range(c * packets // chunks, (c + 1) * packets // chunks):
            first = p * PACKET
            count = min(PACKET, n - first)
            for k in range(count):
                i = first + k
                put_ray(rays, ints, k, origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0], directions[i, 1],
                        directions[i, 2])
            trace(scene, rays, lanes, count)
            for k in range(count):
                out[first + k] = blocked(rays, k)
