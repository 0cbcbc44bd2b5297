"""Custom renderers: the split sum's two halves and the diffuse term as plain textures, in KTX2 (and EXR/PNG for the
lookup table), with every convention in the manifest.

* ``specular.ktx2``: the GGX-prefiltered radiance cube with its mips; level i at perceptual roughness
  r_i = i/(L − 1) for the L levels written (α = r², normal = view), so a shader picks lod = r · (L − 1).
* ``irradiance.ktx2``: the irradiance E (not divided by π) at each texel direction of a cube, the direct sum
  Σ L (n·ω)⁺ Δω over the probe reduced to REFERENCE_ROWS rows (irradiance is smooth: the reduction moves it by far
  less than the sum's float32 storage), for renderers that light diffuse surfaces from a cube; ``sh.json`` holds the
  nine radiance coefficients (lightprobe's own SH schema) for those that evaluate SH.
* ``skybox.ktx2``: the probe as a cube at ``--skybox-size``, one level.
* ``dfg.exr`` / ``dfg.png`` / ``dfg.ktx2``: the lookup table of Filament's multiple-scattering form — red DFG1 (the
  bias B), green DFG2 (A + B), blue the Charlie sheen albedo — row j at roughness (j + ½)/N, column i at
  n·v = (i + ½)/N (:mod:`lightprobe.glossy.dfg`); single scattering is E = F0·(G − R) + F90·R, and the energy
  compensation 1 + F0 (1/G − 1).

Cubes are in the world frame (+Y up, front −Z), faces +X −X +Y −Y +Z −Z in the OpenGL / Vulkan / KTX orientation,
each face's first row its top.
"""

from __future__ import annotations

import functools

import numpy as np

from ...exports.dfg import png16_bytes
from ...exports.ktx2 import VkFormat, ktx2_bytes
from ...exports.sh import export_json
from ...glossy.dfg import multiscatter_lut
from ...maps.frames import WORLD
from ...maps.layouts import CUBE, LATLONG
from ...sh.irradiance import brute_irradiance
from ..folder import EngineFolder
from ..source import BakeSource
from . import ENCODINGS as ENGINE_ENCODINGS
from .common import manifest_extra, perceptual_roughness

FRAME = WORLD
ENCODINGS = ENGINE_ENCODINGS["custom"]
VK_FORMATS = {"rgba16f": VkFormat.R16G16B16A16_SFLOAT, "rgb9e5": VkFormat.E5B9G9R9_UFLOAT_PACK32,
              "b10g11r11": VkFormat.B10G11R11_UFLOAT_PACK32, "rgba32f": VkFormat.R32G32B32A32_SFLOAT}
REFERENCE_ROWS = 128
DFG_SIZE = 128


def custom_alphas(size: int, levels: int) -> list[float]:
    """α of each level of a ``size`` chain when ``levels`` are written at r_i = i/(levels − 1).

    Parameters
    ----------
    size : int
        Face size of level 0, a power of two.
    levels : int
        Levels written (≥ 1); those below them in the full chain are given α = 1 (computed, not written).

    Returns
    -------
    list of float
        log₂(size) + 1 values of α = r², the first 0.
    """
    full = int(np.log2(size)) + 1
    rough = [i / (levels - 1) if levels > 1 else 0.0 for i in range(levels)] + [1.0] * (full - levels)
    return [r * r for r in rough]


@functools.lru_cache(maxsize=1)
def dfg_table() -> np.ndarray:
    """The DFG_SIZE² multiple-scattering table (the same for every bake: computed once a process), read-only.

    Returns
    -------
    numpy.ndarray
        (DFG_SIZE, DFG_SIZE, 3) float32: DFG1, DFG2, Charlie sheen albedo (:func:`lightprobe.glossy.dfg
        .multiscatter_lut`).
    """
    table = multiscatter_lut(DFG_SIZE, sheen=True).astype(np.float32)
    table.setflags(write=False)
    return table


def _cube_of(env, size: int) -> np.ndarray:
    return (env if env.layout is CUBE and env.grid[-1] == size else env.to(CUBE, size)).data


def irradiance_cube(source: BakeSource, size: int) -> np.ndarray:
    """E at each texel direction of a ``size`` cube, brute force over the probe reduced to REFERENCE_ROWS rows.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    size : int
        Face size.

    Returns
    -------
    numpy.ndarray
        (6, size, size, 3) float32 irradiance E (not divided by π), world frame.
    """
    normals = CUBE.directions(CUBE.grid_shape(size)).reshape(-1, 3)
    reduced = source.env.to(LATLONG, REFERENCE_ROWS)
    return brute_irradiance(reduced, normals).reshape(6, size, size, 3).astype(np.float32)


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``specular.ktx2``, ``irradiance.ktx2``, ``skybox.ktx2``, ``sh.json`` and the DFG table.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        The folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` (the SH and each specular level against brute force).
    """
    options = source.options
    encoding = options.encodings.get("custom", ENCODINGS[0])
    fmt = VK_FORMATS[encoding]
    alphas = custom_alphas(options.size, options.levels)
    chain = source.chain(options.size, tuple(alphas), FRAME)
    written = [np.maximum(level, 0) for level in chain.levels[:options.levels]]
    roughness = [round(float(r), 6) for r in perceptual_roughness(alphas[:options.levels])]
    folder.add_bytes("specular.ktx2", ktx2_bytes(written, fmt), "specular", "radiance", f"KTX2 {fmt.name}",
                     layout="cube", size=options.size, mips=options.levels, roughness=roughness,
                     roughness_mapping=f"level i at perceptual roughness i/{max(options.levels - 1, 1)} "
                                       "(α = roughness²), level 0 the mirror")
    folder.add_bytes("irradiance.ktx2", ktx2_bytes([irradiance_cube(source, options.irradiance_size)], fmt),
                     "diffuse", "irradiance E (not divided by π)", f"KTX2 {fmt.name}", layout="cube",
                     size=options.irradiance_size)
    folder.add_text("sh.json", export_json(source.sh(), FRAME), "diffuse", "radiance SH L_lm, bands 0–2", "JSON")
    folder.add_bytes("skybox.ktx2", ktx2_bytes([_cube_of(source.env, options.skybox_size)], fmt), "skybox",
                     "radiance", f"KTX2 {fmt.name}", layout="cube", size=options.skybox_size)
    dfg = dfg_table()
    lut = dict(role="dfg", quantity="DFG1 (bias), DFG2 (scale + bias), Charlie sheen albedo",
               size=[DFG_SIZE, DFG_SIZE], layout="row j: roughness (j + ½)/N; column i: n·v = (i + ½)/N")
    folder.add_image("dfg.exr", dfg, **lut)
    folder.add_bytes("dfg.png", png16_bytes(np.clip(dfg, 0, 1)), encoding="PNG 16-bit RGB", **lut)
    folder.add_bytes("dfg.ktx2", ktx2_bytes([dfg], VkFormat.R16G16B16A16_SFLOAT), encoding="KTX2 R16G16B16A16_SFLOAT",
                     **lut)
    # the whole probe's, with or without lights: custom renderers get no lights
    return manifest_extra(source, chain, whole_probe=True)


def usage(folder: EngineFolder) -> str:
    """How a renderer of one's own uses the folder.

    Parameters
    ----------
    folder : EngineFolder
        The folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    levels = next(f["mips"] for f in folder.files if f["path"] == "specular.ktx2")
    return ("# Custom renderers\n\nWorld frame (+Y up, front −Z); cube faces +X −X +Y −Y +Z −Z in the OpenGL/Vulkan "
            "orientation. The split sum, per fragment:\n\n```glsl\n"
            f"float lod = roughness * {levels - 1}.0;                   // specular.ktx2: level i at roughness "
            f"i/{max(levels - 1, 1)}\n"
            "vec3 prefiltered = textureLod(specularCube, reflect(-v, n), lod).rgb;\n"
            "vec3 dfg = texture(dfgLut, vec2(dot(n, v), roughness)).rgb;   // dfg.*: x = n·v, y = roughness\n"
            "vec3 specular = prefiltered * mix(dfg.xxx, dfg.yyy, f0);     // = F0·(DFG2 − DFG1) + DFG1\n"
            "specular *= 1.0 + f0 * (1.0 / dfg.y - 1.0);                  // multiple-scattering compensation\n"
            "vec3 diffuse = albedo * texture(irradianceCube, n).rgb / 3.14159265;  // irradiance.ktx2 holds E\n"
            "```\n\n`sh.json` holds the nine radiance coefficients L_lm (lightprobe's basis, no Condon–Shortley "
            "phase) for renderers that evaluate SH; E(n) = Σ Â_l L_lm Y_lm(n), Â = (π, 2π/3, π/4).\n")
