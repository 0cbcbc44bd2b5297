"""glTF: one ``.glb`` whose scene carries the environment as ``EXT_lights_image_based`` (GGX mips as RGBD PNGs and
nine irradiance coefficients), with ``KHR_lights_punctual`` directional lights when the bake finds lights, and a
panorama skybox beside it.

Frames: the image-based light is stated in the frame Babylon's glTF loader reads it in ((x, y, −z) of world); the
lights' nodes in glTF's node space as that loader places them (:data:`lightprobe.exports.lights.GLTF_NODES`). The
specular chain is full (mip i at α = 2^i/size: the loader's lodGenerationScale for a full chain).

``--encoding gltf=ktx2`` adds a KTX2 variant of the cube for the glTF world's other renderers:
``environment_ggx.ktx2``, the GGX chain as a KTX2 RGBA16F cube, level i at perceptual roughness i/(L − 1) (the
lod = roughness · (mipCount − 1) of the Khronos glTF Sample Renderer's ``getIBLRadianceGGX``, its ibl.glsl), in
glTF's frame with faces +X −X +Y −Y +Z −Z in the KTX/OpenGL orientation. It is a file beside the ``.glb``, not
inside it: ``EXT_lights_image_based`` names PNG/JPEG images that Babylon's loader decodes as RGBD (its
EXT_lights_image_based.ts hands them to ``RawCubeTexture.updateRGBDAsync``), so a KTX2 image there would not load.
"""

from __future__ import annotations

import numpy as np

from ...exports.containers import glb, gltf_alphas, gltf_ibl_document
from ...exports.lights import GLTF_NODES, add_gltf_lights
from ...maps.frames import BABYLON, GLTF
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra, perceptual_roughness, require_full_chain, skybox_panorama

FRAME = BABYLON
ENCODINGS = ("rgbd", "ktx2")
KTX2_FRAME = GLTF  # the KTX2 variant's cube: glTF's own frame (= world)


def ktx2_variant(source: BakeSource, folder: EngineFolder, env) -> None:
    """Write ``environment_ggx.ktx2``: ``env``'s GGX chain, level i at perceptual roughness i/(L − 1), RGBA16F.

    Parameters
    ----------
    source : BakeSource
        The bake's working form; its options give the face size and the level count (the full chain).
    folder : EngineFolder
        The folder the file is added to, with its manifest entry.
    env : EnvMap
        Radiance (world frame) to prefilter: the probe, or its ambient remainder with lights.
    """
    from ...exports.ktx2 import VkFormat, ktx2_bytes
    from .custom import custom_alphas

    size = source.options.size
    levels = source.options.full_chain
    alphas = custom_alphas(size, levels)
    chain = source.chain(size, tuple(alphas), KTX2_FRAME, env=env)
    folder.add_bytes("environment_ggx.ktx2", ktx2_bytes([np.maximum(level, 0) for level in chain.levels],
                                                         VkFormat.R16G16B16A16_SFLOAT),
                     "specular", "radiance", "KTX2 cube R16G16B16A16_SFLOAT", frame=KTX2_FRAME.name, layout="cube",
                     size=size, mips=levels, roughness=[round(float(r), 6) for r in perceptual_roughness(alphas)],
                     roughness_mapping=f"level i at perceptual roughness i/{levels - 1} (α = roughness²), level 0 "
                                       "the mirror: lod = roughness · (mipCount − 1)")


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``environment.glb`` and ``skybox.hdr``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        glTF's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` and, with lights, ``lights`` (as the file's nodes state them).
    """
    options = source.options
    require_full_chain(options, "EXT_lights_image_based")
    alphas = gltf_alphas(options.size)
    env, sh = source.diffuse()
    chain = source.chain(options.size, tuple(alphas), FRAME, env=env)
    document, images = gltf_ibl_document(chain, sh)
    if options.encodings.get("gltf", ENCODINGS[0]) == "ktx2":
        ktx2_variant(source, folder, env)
    if options.lights:
        add_gltf_lights(document, source.lights())
    folder.add_bytes("environment.glb", glb(document, images), "specular+diffuse" + ("+lights" if options.lights
                                                                                      else ""),
                     "radiance (specular mips); irradiance E_lm (irradianceCoefficients); lights: E⊥ in lux",
                     "glTF binary, EXT_lights_image_based with RGBD PNG mips", layout="cube", size=options.size,
                     mips=len(alphas), roughness=[round(float(r), 6) for r in perceptual_roughness(alphas)],
                     roughness_mapping="mip i holds α_i = 2^i/size (α = roughness²), mip 0 the mirror")
    skybox_panorama(source, folder, "skybox.hdr")
    # the lights as the file's nodes state them
    return manifest_extra(source, chain, GLTF_NODES)


def usage(folder: EngineFolder) -> str:
    """Code that loads the folder in Babylon.js (whose glTF loader reads EXT_lights_image_based).

    Parameters
    ----------
    folder : EngineFolder
        glTF's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    ktx2 = ("\n`environment_ggx.ktx2` is the same GGX chain as a KTX2 RGBA16F cube for renderers that take one "
            "(glTF's frame, faces in the KTX/OpenGL orientation): level i at roughness i/(L − 1), so a shader reads "
            "`textureLod(ggx, r, roughness * float(mipCount - 1))`, as the Khronos glTF Sample Renderer does.\n"
            if any(f["path"] == "environment_ggx.ktx2" for f in folder.files) else "")
    return ("# glTF\n\n`environment.glb` holds the environment as `EXT_lights_image_based` (GGX mips, RGBD PNG, "
            "and nine irradiance coefficients) and, when lights were found, `KHR_lights_punctual` directional "
            "lights (intensity in lux = the irradiance they give a surface facing them, in the probe's units × "
            "the bake's intensity). Babylon.js's glTF loader reads both:\n\n```js\n"
            "import '@babylonjs/loaders/glTF';\n"
            "await BABYLON.SceneLoader.AppendAsync('./', 'environment.glb', scene);\n"
            "// the skybox, at its own resolution, without prefiltering\n"
            "const sky = new BABYLON.HDRCubeTexture('skybox.hdr', scene, 512, false, false, false, false);\n"
            "scene.createDefaultSkybox(sky, true);\n```\n" + ktx2)
