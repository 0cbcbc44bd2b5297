"""Babylon.js: the ``.env`` (GGX mips as RGBD PNGs with the irradiance polynomial), a panorama skybox, the lights.

Babylon's frame is left-handed, (x, y, −z) of world; its ``.env`` reader takes the full mip chain at
``lodGenerationScale`` 0.8 (the roughness of each mip, :func:`lightprobe.glossy.prefilter.babylon_alphas`). The
skybox is the world-frame lat-long panorama, which ``HDRCubeTexture`` turns into Babylon's frame itself (checked in
Babylon by the engine tests). With lights: the polynomial in the ``.env`` is the ambient remainder's, and
``lights.json`` holds each light as Babylon's ``DirectionalLight`` (direction, diffuse colour, intensity E⊥).
"""

from __future__ import annotations

from ...exports.containers import ENV_LOD_GENERATION_SCALE, env_file, warn_if_clipped
from ...exports.lights import export_babylon_lights
from ...exports.sh import babylon_polynomial
from ...glossy.prefilter import babylon_alphas
from ...maps.frames import BABYLON
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra, perceptual_roughness, require_full_chain, skybox_panorama

FRAME = BABYLON
ENCODINGS = ()


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``environment.env``, ``skybox.hdr`` and, with lights, ``lights.json``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        Babylon's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` and, with lights, ``lights``.
    """
    options = source.options
    require_full_chain(options, "Babylon's .env")
    alphas = babylon_alphas(options.size, ENV_LOD_GENERATION_SCALE)
    env, sh = source.diffuse()
    chain = source.chain(options.size, tuple(alphas), FRAME, env=env)
    warn_if_clipped(chain)
    folder.add_bytes("environment.env", env_file(chain, babylon_polynomial(sh, FRAME)), "specular+diffuse",
                     "radiance (specular mips); irradiance polynomial (diffuse)", "Babylon .env v2, RGBD PNG",
                     layout="cube", size=options.size, mips=len(alphas),
                     roughness=[round(float(r), 6) for r in perceptual_roughness(alphas)],
                     roughness_mapping="Babylon's lodGenerationScale 0.8: mip i holds α_i = 2^(i/0.8)/size "
                                       "(α = roughness²), mip 0 the mirror")
    skybox_panorama(source, folder, "skybox.hdr")
    if options.lights:
        folder.add_text("lights.json", export_babylon_lights(source.lights(), FRAME), "lights",
                        "irradiance E⊥ (intensity) and linear colour", "JSON")
    return manifest_extra(source, chain, FRAME)


def usage(folder: EngineFolder) -> str:
    """Babylon.js code that loads the folder.

    Parameters
    ----------
    folder : EngineFolder
        Babylon's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    names = {f["path"] for f in folder.files}
    lights = ("\n// the lights found in the probe (lights.json: Babylon's frame, intensity = E⊥)\n"
              "const found = await (await fetch('lights.json')).json();\n"
              "for (const l of found.directionalLights) {\n"
              "  const light = new BABYLON.DirectionalLight(l.name, BABYLON.Vector3.FromArray(l.direction), scene);\n"
              "  light.diffuse = BABYLON.Color3.FromArray(l.diffuse); light.intensity = l.intensity;\n}\n"
              if "lights.json" in names else "")
    return ("# Babylon.js\n\nThe prefiltered environment loads as it is: no filtering at load time.\n\n"
            "```js\n"
            "scene.environmentTexture = BABYLON.CubeTexture.CreateFromPrefilteredData('environment.env', scene);\n"
            "// the skybox, at its own resolution, without prefiltering\n"
            "const sky = new BABYLON.HDRCubeTexture('skybox.hdr', scene, 512, false, false, false, false);\n"
            "scene.createDefaultSkybox(sky, true);\n" + lights + "```\n\n"
            "`environment.env` holds the GGX mips (RGBD PNG, Babylon's roughness per mip) and the irradiance "
            "polynomial (the diffuse term), in Babylon's left-handed frame.\n")

