"""Ground truth: the same scene path-traced by Mitsuba 3 (optional extra ``reference``: ``pip install mitsuba``).

Matching the project's renderer exactly:

* **Camera**: the same look-at (eye, target, up) and vertical field of view (``fov_axis = y``); box pixel filter.
* **Geometry**: every mesh written as a binary PLY with the renderer's own vertex normals, so both interpolate the
  same shading normals; diffuse BSDFs wrapped in ``twosided`` (the renderer flips back faces the same way).
* **Environment**: Mitsuba's ``envmap`` reads a lat-long image as u = atan2(x, −z)/2π, v = acos(y)/π (its image centre
  is +Z), ours as u = atan2(x, −z)/2π + ½: the same mapping shifted by half a turn. The map is converted to lat-long
  (if it is not one) and its columns rolled by W/2 — exact, a 180° turn about +Y, no mirror. A test proves it with a
  single bright spot.
* **Light transport**: direct lighting only by default (``path`` with max_depth 2: the papers' assumption, with
  shadows); ``global_illumination=True`` for all bounces.

Variant: ``llvm_ad_rgb`` (vectorised) when Debian's ``libllvm19`` is installed — Dr.Jit is pointed at it, because
with an older LLVM (Debian 12 also ships 14 and 15) it aborts the process — otherwise ``scalar_rgb`` (needs
nothing, slower).
"""

from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path

import numpy as np

from ..maps import EnvMap
from ..util.errors import LightprobeError, UsageError
from ..maps.images import write_image
from ..maps.layouts import LATLONG
from .renderer import Rendering
from .scene import MeshInstance, Scene

LLVM_LIBRARIES = ("/usr/lib/x86_64-linux-gnu/libLLVM-19.so", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
                  "/usr/lib/llvm-19/lib/libLLVM.so.1", "/usr/lib/llvm-19/lib/libLLVM-19.so",
                  "/usr/lib/aarch64-linux-gnu/libLLVM-19.so")


def llvm19() -> str | None:
    """Path of an LLVM 19 shared library, if installed.

    Dr.Jit's LLVM backend crashes the process (an LLVM abort, not an exception) with older LLVMs such as Debian's 15,
    so the LLVM variant is used only with this one.

    Returns
    -------
    str or None
        ``DRJIT_LIBLLVM_PATH`` when that variable is set (taken as given), else the first of
        :data:`LLVM_LIBRARIES` that exists, else None.
    """
    import os

    explicit = os.environ.get("DRJIT_LIBLLVM_PATH")
    if explicit:
        return explicit
    return next((p for p in LLVM_LIBRARIES if Path(p).exists()), None)


def mitsuba(variant: str | None = None):
    """The ``mitsuba`` module with an RGB variant set.

    ``llvm_ad_rgb`` (vectorised) when an LLVM 19 library is there, ``scalar_rgb`` otherwise (or the ``variant``
    asked for). With a library found, ``DRJIT_LIBLLVM_PATH`` is set to it in this process's environment unless it is
    set already.

    Parameters
    ----------
    variant : str or None
        The Mitsuba variant to set (e.g. ``scalar_rgb``); None (default): chosen as above.

    Returns
    -------
    module
        The imported ``mitsuba`` module, its variant set.

    Raises
    ------
    LightprobeError
        Mitsuba is not installed (the optional extra ``reference``), or the variant does not start.
    """
    import os

    library = llvm19()
    if library:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", library)
    try:
        import mitsuba as mi
    except ImportError:
        raise LightprobeError("the Mitsuba reference needs the optional extra: pip install 'lightprobe[reference]'"
                              ) from None
    name = variant or ("llvm_ad_rgb" if library else "scalar_rgb")
    try:
        mi.set_variant(name)
    except Exception as e:
        raise LightprobeError(f"Mitsuba variant {name} does not start: {str(e).splitlines()[0]}") from None
    return mi


def mitsuba_latlong(env: EnvMap) -> np.ndarray:
    """The environment as the lat-long image Mitsuba's ``envmap`` expects (columns rolled by half a turn).

    Parameters
    ----------
    env : EnvMap
        The environment, radiance, world frame, any layout (converted to lat-long, energy-conserving, if it is not one).

    Returns
    -------
    numpy.ndarray
        (H, W, 3) lat-long pixels, radiance, their columns rolled by W/2: a 180° turn about +Y, the same mapping as
        Mitsuba's.
    """
    if env.layout is not LATLONG:
        env = env.to(LATLONG)
    return np.roll(env.data, env.grid[1] // 2, axis=1)


def write_ply(path: Path, mesh: MeshInstance) -> None:
    """Binary PLY with float32 positions, normals and (if any) UVs, int32 triangle indices.

    UVs are written with v flipped: lightprobe keeps OBJ/OpenGL's convention (v = 0 at the bottom of the image),
    Mitsuba's bitmap lookup puts v = 0 at the top (its OBJ loader flips v the same way).

    Parameters
    ----------
    path : Path
        The file to write (replaced if it exists; not an atomic write).
    mesh : MeshInstance
        The mesh: vertices and vertex normals in the world frame, faces, UVs if any.
    """
    columns = [mesh.vertices, mesh.normals]
    props = ["x", "y", "z", "nx", "ny", "nz"]
    if mesh.uv is not None:
        columns.append(np.stack([mesh.uv[:, 0], 1.0 - mesh.uv[:, 1]], axis=1))
        props += ["u", "v"]
    v = np.concatenate(columns, axis=1).astype("<f4")
    f = np.empty(len(mesh.faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    f["n"], f["i"] = 3, mesh.faces
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
              + "".join(f"property float {p}\n" for p in props)
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    path.write_bytes(header.encode("ascii") + v.tobytes() + f.tobytes())


def _reflectance(mesh: MeshInstance, folder: Path, index: int) -> dict:
    """Mitsuba reflectance of a material: an RGB value, or the texture (linear, bilinear, repeating)."""
    mat = mesh.material
    if mat.texture is None or mesh.uv is None:
        return {"type": "rgb", "value": [float(x) for x in mat.albedo]}
    path = folder / f"texture{index}.exr"
    write_image(path, np.ascontiguousarray(mat.texture[..., :3], dtype=np.float32))
    return {"type": "bitmap", "filename": str(path), "raw": True, "filter_type": "bilinear", "wrap_mode": "repeat"}


def mitsuba_bsdf(mesh: MeshInstance, folder: Path, index: int) -> dict:
    """The Mitsuba 3 BSDF of a mesh's material, with the same parameters.

    The albedo (or texture) as ``diffuse``; a Lambert BRDF as ``diffuse``; GGX with a conductor's η, k as
    ``roughconductor`` (GGX, same α, η, k per RGB channel), GGX without Fresnel (f0 = 1) as ``roughconductor`` with
    ``material: none`` (Mitsuba's perfect reflector), the plastic as ``roughplastic`` (GGX, α, interior index, diffuse
    reflectance). Others have no Mitsuba equivalent with the same formula, and are refused rather than approximated.

    Parameters
    ----------
    mesh : MeshInstance
        The mesh whose material is translated.
    folder : Path
        Where a texture is written, as linear float32 ``texture{index}.exr`` (when the material has one and the mesh
        has UVs; read bilinearly, repeating).
    index : int
        Numbers the texture's file.

    Returns
    -------
    dict
        The BSDF as a Mitsuba plugin dict (one-sided; :func:`scene_dict` wraps it in ``twosided``).

    Raises
    ------
    UsageError
        The material's BRDF has no Mitsuba 3 BSDF with the same formula.
    """
    from ..glossy.brdf import GGX, Conductor, Lambert, Schlick
    from ..glossy.layered import Plastic

    brdf = mesh.material.brdf
    if brdf is None:
        return {"type": "diffuse", "reflectance": _reflectance(mesh, folder, index)}
    if isinstance(brdf, Lambert):
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(x) for x in brdf.albedo]}}
    if isinstance(brdf, GGX) and isinstance(brdf.fresnel, Conductor):
        return {"type": "roughconductor", "distribution": "ggx", "alpha": brdf.alpha,
                "eta": {"type": "rgb", "value": [float(x) for x in brdf.fresnel.eta]},
                "k": {"type": "rgb", "value": [float(x) for x in brdf.fresnel.k]}}
    if isinstance(brdf, GGX) and isinstance(brdf.fresnel, Schlick) and brdf.fresnel.f0 == (1.0, 1.0, 1.0):
        return {"type": "roughconductor", "distribution": "ggx", "alpha": brdf.alpha, "material": "none"}
    if isinstance(brdf, Plastic):  # exterior index exactly 1 (Mitsuba's default is air's 1.000277)
        return {"type": "roughplastic", "distribution": "ggx", "alpha": brdf.alpha, "int_ior": float(brdf.ior),
                "ext_ior": 1.0, "nonlinear": False,
                "diffuse_reflectance": {"type": "rgb", "value": [float(x) for x in brdf.albedo]}}
    raise UsageError(f"mesh {mesh.name!r}: {brdf.spec()} has no Mitsuba 3 BSDF with the same formula (the reference "
                     "renders Lambert, GGX with a conductor or without Fresnel, and plastic)")


def scene_dict(mi, scene: Scene, folder: Path, spp: int, global_illumination: bool, seed: int) -> dict:
    """The Mitsuba 3 scene dict of ``scene``, its files written into ``folder``.

    How it matches the project's renderer is in the module docstring: the same look-at camera and vertical field of
    view, box filter, every mesh a two-sided PLY with the renderer's normals, the environment as
    :func:`mitsuba_latlong`.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module with a variant set (:func:`mitsuba`).
    scene : Scene
        The scene to translate.
    folder : Path
        An existing folder where ``environment.exr``, ``mesh{i}.ply`` and textures are written; it must last until
        ``mi.load_dict`` has read them.
    spp : int
        Samples per pixel of the ``independent`` sampler.
    global_illumination : bool
        True: the ``path`` integrator with every bounce (max_depth −1); False: max_depth 2, direct lighting only.
    seed : int
        The sampler's seed.

    Returns
    -------
    dict
        The scene for ``mi.load_dict``: integrator (emitters hidden when the scene's ``background`` is off), sensor
        with its film and sampler, the ``envmap`` emitter, and ``mesh{i}`` for every mesh.

    Raises
    ------
    UsageError
        A material's BRDF has no Mitsuba 3 BSDF with the same formula.
    """
    cam = scene.camera
    env_path = folder / "environment.exr"
    write_image(env_path, mitsuba_latlong(scene.environment))
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1 if global_illumination else 2,
                       "hide_emitters": not scene.background},
        "sensor": {
            "type": "perspective", "fov": float(cam.fov), "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(map(float, cam.eye)),
                                                       target=list(map(float, cam.target)),
                                                       up=list(map(float, cam.up))),
            "film": {"type": "hdrfilm", "width": cam.width, "height": cam.height, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
        "environment": {"type": "envmap", "filename": str(env_path)},
    }
    for i, mesh in enumerate(scene.meshes):
        ply = folder / f"mesh{i}.ply"
        write_ply(ply, mesh)
        d[f"mesh{i}"] = {
            "type": "ply", "filename": str(ply), "face_normals": False,
            "bsdf": {"type": "twosided", "bsdf": mitsuba_bsdf(mesh, folder, i)},
        }
    return d


# Mitsuba's film (RGBA + weight, float32) and its tensor, our float64 sum of the passes and the pass being added
# (48), and the float32 result (96 alone let a 4096² render under a ulimit -v start and run out of memory)
REFERENCE_BYTES_PER_PIXEL = 144
BYTES_PER_TRIANGLE = 200  # our arrays, the PLY written for Mitsuba, and Mitsuba's own copy with its BVH
MITSUBA_ADDRESS_SPACE = 256 << 20  # address space Mitsuba maps after the check beyond its data (~50 MB measured)
MITSUBA_BYTES = 128 << 20  # Mitsuba and Dr.Jit's LLVM backend loaded (~340 MB measured with the rest)


def reference_memory(scene: Scene) -> int:
    """Estimated peak memory (bytes) of :func:`reference_render` (measured in tests/test_limits.py).

    Parameters
    ----------
    scene : Scene
        The scene: its camera's image size, its triangle count and its environment map's size.

    Returns
    -------
    int
        :data:`MITSUBA_BYTES` + :data:`REFERENCE_BYTES_PER_PIXEL` per pixel + :data:`BYTES_PER_TRIANGLE` per triangle
        + 16 bytes per value of the environment map.
    """
    cam = scene.camera
    return (MITSUBA_BYTES + cam.width * cam.height * REFERENCE_BYTES_PER_PIXEL
            + scene.triangle_count * BYTES_PER_TRIANGLE + scene.environment.data.size * 16)


SCENE_FOLDER = re.compile(r"^lightprobe-mitsuba-(\d+)-")  # the pid of the run that made the folder


def _sweep_stale_folders() -> None:
    """Remove scene folders of earlier runs that died before removing theirs (a crash inside Mitsuba, kill -9)."""
    from ..util.files import sweep_stale_temporaries

    sweep_stale_temporaries(Path(tempfile.gettempdir()), SCENE_FOLDER)


SAMPLES_PER_PASS = 1 << 24  # Dr.Jit evaluates a pass as one wavefront: its memory grows with samples per pass


def _render_in_passes(mi, loaded, pixels: int, spp: int, seed: int) -> np.ndarray:
    """``mi.render`` in passes of at most :data:`SAMPLES_PER_PASS` samples (at least one per pixel), averaged by
    their sample counts; pass k uses seed + k. One pass (same seed) when the whole render fits in it."""
    per_pass = max(1, min(spp, SAMPLES_PER_PASS // max(pixels, 1)))
    total, done, k = None, 0, 0
    while done < spp:  # in place: two float64 images at most (a 4096² pass is 384 MiB each)
        n = min(per_pass, spp - done)
        image = np.array(mi.render(loaded, spp=n, seed=seed + k), dtype=np.float64)
        image *= n
        if total is None:
            total = image
        else:
            total += image
        del image
        done, k = done + n, k + 1
    total /= spp
    return total.astype(np.float32)


def reference_render(scene: Scene, spp: int = 64, global_illumination: bool = False, seed: int = 0,
                     variant: str | None = None) -> Rendering:
    """Path-trace ``scene`` with Mitsuba 3: radiance (H, W, 3), ``spp`` samples per pixel.

    The estimated memory is checked against the budget before Mitsuba starts (under a memory cap it crashes the
    process instead of raising). The scene's files live in a temporary folder only while Mitsuba loads them.

    Parameters
    ----------
    scene : Scene
        The scene, rendered as the module docstring says the renderer sees it.
    spp : int
        Samples per pixel, from 1 to 65536. Default 64. Rendered in passes of at most :data:`SAMPLES_PER_PASS`
        samples, pass k with seed + k, averaged by their sample counts.
    global_illumination : bool
        True: every bounce; False (default): direct lighting only, the papers' assumption (with shadows).
    seed : int
        The sampler's seed. Default 0.
    variant : str or None
        The Mitsuba variant (:func:`mitsuba`); None (default): ``llvm_ad_rgb`` with LLVM 19, else ``scalar_rgb``.

    Returns
    -------
    Rendering
        The image, (H, W, 3) float32 linear RGB radiance; coverage all ones (not measured here: see
        :func:`reference_coverage`); the description (Mitsuba version, variant, transport, spp) and the seconds of
        ``load`` and ``render``.

    Raises
    ------
    LightprobeError
        ``spp`` is out of range, or Mitsuba is missing or its variant does not start.
    BudgetError
        The estimated memory is over the budget.
    UsageError
        A material's BRDF has no Mitsuba 3 BSDF with the same formula.
    """
    import os

    from ..util.limits import check_memory

    if not 1 <= spp <= 1 << 16:
        raise LightprobeError("reference samples per pixel must be within 1..65536")
    check_memory(reference_memory(scene), f"the Mitsuba reference of {scene.camera.width}x{scene.camera.height}",
                 virtual_bytes=MITSUBA_ADDRESS_SPACE)
    mi = mitsuba(variant)
    _sweep_stale_folders()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"lightprobe-mitsuba-{os.getpid()}-") as tmp:
        loaded = mi.load_dict(scene_dict(mi, scene, Path(tmp), spp, global_illumination, seed))
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    image = _render_in_passes(mi, loaded, scene.camera.width * scene.camera.height, spp, seed)[..., :3]
    transport = "global illumination" if global_illumination else "direct lighting"
    return Rendering(image, np.ones(image.shape[:2], np.float32),
                     f"Mitsuba {mi.__version__} {mi.variant()}, {transport}, {spp} spp",
                     {"load": t_load, "render": time.perf_counter() - t0})


def reference_coverage(scene: Scene, spp: int = 64, seed: int = 0, variant: str | None = None) -> np.ndarray:
    """Fraction of each pixel covered by geometry, as Mitsuba sees the scene.

    The box-filtered ``albedo`` AOV of the scene with every material white. Compared with the renderer's coverage it
    proves camera and geometry agree.

    Parameters
    ----------
    scene : Scene
        The scene; its materials are replaced by white Lambertian ones.
    spp : int
        Samples per pixel. Default 64.
    seed : int
        The sampler's seed. Default 0.
    variant : str or None
        The Mitsuba variant (:func:`mitsuba`); None (default): chosen by :func:`mitsuba`.

    Returns
    -------
    numpy.ndarray
        (H, W) float32 in [0, 1], the mean of the AOV's three channels.

    Raises
    ------
    LightprobeError
        Mitsuba is missing or its variant does not start.
    """
    mi = mitsuba(variant)
    white = Scene(tuple(type(m)(m.vertices, m.faces, m.normals, type(m.material)((1.0, 1.0, 1.0)), m.uv, m.name)
                        for m in scene.meshes), scene.camera, scene.environment, scene.background, scene.name)
    with tempfile.TemporaryDirectory(prefix="lightprobe-mitsuba-") as tmp:
        d = scene_dict(mi, white, Path(tmp), spp, False, seed)
        d["integrator"] = {"type": "aov", "aovs": "a:albedo"}
        loaded = mi.load_dict(d)
    image = np.array(mi.render(loaded, spp=spp, seed=seed), dtype=np.float32)
    return image[..., -3:].mean(axis=-1)
