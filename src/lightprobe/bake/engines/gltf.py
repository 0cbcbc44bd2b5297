"""glTF: one ``.glb`` whose scene carries the environment as ``EXT_lights_image_based`` (GGX mips as RGBD PNGs and
nine irradiance coefficients), with ``KHR_lights_punctual`` directional lights when the bake finds lights, and a
panorama skybox beside it.

Frames: the image-based light is stated in the frame Babylon's glTF loader reads it in ((x, y, −z) of world); the
lights' nodes in glTF's node space as that loader places them (:data:`lightprobe.exports.lights.GLTF_NODES`). The
specular chain is full (mip i at α = 2^i/size: the loader's lodGenerationScale for a full chain).
"""

from __future__ import annotations

from ...exports.containers import glb, gltf_alphas, gltf_ibl_document
from ...exports.lights import GLTF_NODES, add_gltf_lights
from ...maps.frames import BABYLON
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra, perceptual_roughness, require_full_chain, skybox_panorama

FRAME = BABYLON
ENCODINGS = ()


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
    return ("# glTF\n\n`environment.glb` holds the environment as `EXT_lights_image_based` (GGX mips, RGBD PNG, "
            "and nine irradiance coefficients) and, when lights were found, `KHR_lights_punctual` directional "
            "lights (intensity in lux = the irradiance they give a surface facing them, in the probe's units × "
            "the bake's intensity). Babylon.js's glTF loader reads both:\n\n```js\n"
            "import '@babylonjs/loaders/glTF';\n"
            "await BABYLON.SceneLoader.AppendAsync('./', 'environment.glb', scene);\n"
            "// the skybox, at its own resolution, without prefiltering\n"
            "const sky = new BABYLON.HDRCubeTexture('skybox.hdr', scene, 512, false, false, false, false);\n"
            "scene.createDefaultSkybox(sky, true);\n```\n")
