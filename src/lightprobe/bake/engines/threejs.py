"""three.js (r187): the GGX mips as the cube three.js renders from without PMREM, a cube skybox, the LightProbe, the lights.

What three.js r187 reads (its own source, npm ``three`` 0.187.0):

* **No cubeUV atlas any more.** ``extras/PMREMGenerator.js`` now writes a *cube* render target whose mip ``lod``
  (0 … maxLod = log₂(size) − 3, i.e. down to 8×8 faces, its ``LOD_MIN``) holds GGX radiance at roughness
  ``1 − √(1 − lod/maxLod)`` (``lodToRoughness``); ``ShaderChunk/envmap_common_pars_fragment.glsl.js`` inverts it as
  ``roughnessToMip(r) = maxLod · r(2 − r)`` and ``envmap_physical_pars_fragment.glsl.js`` takes the diffuse term as π
  times the last mip (roughness 1) toward the normal. ``webgl/WebGLEnvironments.js`` runs no PMREM for a texture
  marked ``isPMREMTexture``, and ``webgl/WebGLPrograms.js`` takes maxLod and the size from its mip list
  (``image[0].mipmaps`` of a ``CompressedCubeTexture``). So ``environment.ktx2`` holds exactly those levels, each
  prefiltered here with α = roughness² of its lod, and three.js samples it as it is: **no PMREM runs at load time.**
* **KTX2Loader gives no float cube.** ``examples/jsm/loaders/KTX2Loader.js`` (``createRawTexture``) turns an
  uncompressed KTX2 — float16, float32, RGB9E5, B10G11R11 — into a 2D ``DataTexture`` whatever its face count, each
  level's data the six faces one after the other. The few lines in ``USAGE.md`` cut each level into its faces and
  make the ``CompressedCubeTexture`` KTX2Loader itself makes for compressed cubes (``RGBAFormat`` data is uploaded
  with ``texSubImage2D`` by ``webgl/WebGLTextures.js``). That upload sends every other format of a
  ``CompressedCubeTexture`` to ``compressedTexImage2D``, so RGB9E5 and B10G11R11 cubes cannot be shown this way:
  the encodings offered are float16 (default) and float32 RGBA.
* **Frames.** three.js shows an equirectangular panorama in :data:`lightprobe.maps.frames.THREEJS` (``sh.json``
  and ``lights.json`` are stated there). It samples a cube texture that is not a render target with x negated
  (``_m`` in ``webgl/WebGLMaterials.js`` for ``envMap``, in ``webgl/WebGLBackground.js`` for the background), so the
  cube files hold three.js direction (x, y, z) at cube direction (−x, y, z): :data:`THREEJS_CUBE`, (z, y, x) of
  world (a mirror). The engine tests render both files in three.js beside its own panorama and PMREM.
* **Skybox.** A panorama background is converted to a cube render target when first drawn
  (``WebGLCubeRenderTarget.fromEquirectangularTexture``); a cube texture is drawn as it is, so ``skybox.ktx2`` is a
  cube (level 0 only, ``--skybox-size``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...exports.ktx2 import VkFormat, ktx2_bytes
from ...exports.lights import export_threejs_lights
from ...exports.sh import export_threejs
from ...maps import resample
from ...maps.frames import THREEJS, Frame
from ...maps.layouts import CUBE
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra, perceptual_roughness

FRAME = THREEJS
# three.js's cube lookup direction of each world direction: its panorama frame with x negated (see the docstring)
THREEJS_CUBE = Frame("threejs-cube", np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
                     "three.js cube textures: (z, y, x) of world, its panorama frame seen through the x flip it "
                     "applies to cube textures that are not render targets")
ENCODINGS = ("rgba16f", "rgba32f")
VK_FORMATS = {"rgba16f": VkFormat.R16G16B16A16_SFLOAT, "rgba32f": VkFormat.R32G32B32A32_SFLOAT}
LOD_MIN = 3  # log₂ of three.js's smallest PMREM face (PMREMGenerator.js): its last mip is 8×8


def _max_lod(size: int) -> int:
    # three.js's last PMREM mip (PMREMGenerator.js: log₂ size − LOD_MIN), the 8×8 level
    return int(math.log2(size)) - LOD_MIN


def threejs_alphas(size: int) -> list[float]:
    """GGX α of each level three.js reads from a ``size`` cube, then α = 1 down to 1×1 (not written).

    three.js's ``lodToRoughness(lod, maxLod) = 1 − √(1 − lod/maxLod)`` (PMREMGenerator.js), the inverse of its
    shader's ``roughnessToMip``; α = roughness².

    Parameters
    ----------
    size : int
        Face edge of level 0, a power of two ≥ 16.

    Returns
    -------
    list of float
        log₂(size) + 1 values (the full chain :func:`lightprobe.glossy.prefilter.prefilter_cube` takes), the first
        0 (the mirror), level log₂(size) − 3 and the smaller ones 1.
    """
    top = _max_lod(size)
    rough = [1 - math.sqrt(1 - lod / top) for lod in range(top + 1)]
    return [r * r for r in rough] + [1.0] * LOD_MIN


def _levels(cube: list[np.ndarray]) -> list[np.ndarray]:
    # float32 → the writer adds alpha 1; three.js's RGBA upload needs four channels
    return [np.ascontiguousarray(level, np.float32) for level in cube]


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``environment.ktx2``, ``skybox.ktx2``, ``sh.json`` and, with lights, ``lights.json``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        three.js's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy``, ``no_pmrem`` (why none runs) and, with lights, ``lights``.
    """
    options = source.options
    encoding = options.encodings.get("threejs", ENCODINGS[0])
    vk = VK_FORMATS[encoding]
    alphas = threejs_alphas(options.size)
    top = _max_lod(options.size)
    env, sh = source.diffuse()
    chain = source.chain(options.size, tuple(alphas), THREEJS_CUBE, env=env)
    written = chain.levels[:top + 1]
    folder.add_bytes("environment.ktx2", ktx2_bytes(_levels(written), vk), "specular+diffuse",
                     "radiance (GGX mips; three.js takes the diffuse term as π × the last one)",
                     f"KTX2 cube {vk.name}", frame=THREEJS_CUBE.name, layout="cube", size=options.size,
                     mips=top + 1, roughness=[round(float(r), 6) for r in perceptual_roughness(alphas[:top + 1])],
                     roughness_mapping="three.js r187 PMREM: mip lod holds roughness 1 − √(1 − lod/maxLod), "
                                       f"maxLod = log₂(size) − 3 = {top} (α = roughness²), mip 0 the mirror")
    sky = resample(source.env, CUBE, options.skybox_size, rotation=THREEJS_CUBE.to_frame).data
    folder.add_bytes("skybox.ktx2", ktx2_bytes(_levels([sky]), vk), "skybox", "radiance",
                     f"KTX2 cube {vk.name}", frame=THREEJS_CUBE.name, layout="cube", size=options.skybox_size,
                     mips=1)
    folder.add_text("sh.json", export_threejs(sh, FRAME), "diffuse",
                    "sh-radiance (three.js LightProbe, SphericalHarmonics3)", "JSON")
    # measured on the levels written only (the chain goes on to 1×1 because prefilter_cube makes the full chain)
    shipped = dataclasses.replace(chain, levels=tuple(written), alphas=tuple(chain.alphas[:top + 1]))
    if options.lights:
        folder.add_text("lights.json", export_threejs_lights(source.lights(), FRAME), "lights",
                        "irradiance E⊥ (intensity, lux) and linear colour", "JSON")
    return manifest_extra(source, shipped, FRAME,
                          no_pmrem="environment.ktx2 holds three.js r187's PMREM levels; marked isPMREMTexture it "
                                   "is sampled as it is (WebGLEnvironments.js)")


def usage(folder: EngineFolder) -> str:
    """three.js code that loads the folder.

    Parameters
    ----------
    folder : EngineFolder
        three.js's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    names = {f["path"] for f in folder.files}
    lights = ("\n// the lights found in the probe, and the ambient remainder as a LightProbe (three.js's frame)\n"
              "scene.add(new THREE.ObjectLoader().parse(await (await fetch('lights.json')).json()));\n"
              if "lights.json" in names else "")
    return ("# three.js (r187)\n\n"
            "The GGX mips are three.js's own PMREM levels (roughness 1 − √(1 − lod/maxLod), down to 8×8): marked "
            "`isPMREMTexture`, three.js samples them as they are, so no PMREM runs at load time. KTX2Loader turns "
            "an uncompressed KTX2 into a 2D `DataTexture` holding the six faces of each level one after the other "
            "(KTX2Loader.js, `createRawTexture`); `cube()` below cuts them into the cube three.js uploads.\n\n"
            "```js\n"
            "import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';\n\n"
            "function cube(t) {  // KTX2Loader's float texture → a cube with the same mips\n"
            "  const faces = [0, 1, 2, 3, 4, 5].map((f) => ({ width: t.image.width, height: t.image.height,\n"
            "    mipmaps: t.mipmaps.map((m) => { const n = m.data.length / 6;\n"
            "      return { data: m.data.subarray(f * n, (f + 1) * n), width: m.width, height: m.height }; }) }));\n"
            "  const c = new THREE.CompressedCubeTexture(faces, t.format, t.type);\n"
            "  c.minFilter = faces[0].mipmaps.length > 1 ? THREE.LinearMipmapLinearFilter : THREE.LinearFilter;\n"
            "  c.magFilter = THREE.LinearFilter; c.generateMipmaps = false;\n"
            "  c.colorSpace = THREE.LinearSRGBColorSpace; c.needsUpdate = true;\n"
            "  return c;\n}\n\n"
            "const loader = new KTX2Loader().detectSupport(renderer);\n"
            "const environment = cube(await loader.loadAsync('environment.ktx2'));\n"
            "environment.isPMREMTexture = true;  // three.js's PMREM levels already: no PMREMGenerator\n"
            "scene.environment = environment;\n"
            "scene.background = cube(await loader.loadAsync('skybox.ktx2'));\n"
            "// or, without the environment's GGX mips, the diffuse term alone:\n"
            "// scene.add(new THREE.ObjectLoader().parse(await (await fetch('sh.json')).json()));\n"
            + lights + "```\n\n"
            "The cubes are stated as three.js samples a cube texture (its x flip included): they show the probe "
            "where three.js shows the panorama as an equirectangular background. `sh.json` is a `LightProbe` in "
            "three.js's frame. RGB9E5 and B10G11R11 are not offered: three.js r187 uploads a cube of those formats "
            "as if it were compressed (WebGLTextures.js).\n")
