"""Unity: the environment as a lat-long EXR Unity imports as a cubemap, its ambient SH as C#, and the lights.

Unity imports a cubemap from an equirectangular image (Texture Shape: Cube, Mapping: Latitude-Longitude) and, with
Convolution Type *Specular*, prefilters its mips itself in the editor at import — never at load time in a player; it
has no file format for mips made elsewhere. The panorama is the world-frame lat-long (centre world −Z, which is
Unity's +Z forward: Unity's frame is (x, y, −z) of world). The ambient is ``RenderSettings.ambientProbe``
(Unity's SH: E/π with its own constants, :func:`lightprobe.exports.sh.unity_coefficients`); with lights, the
probe's lights as directional ``Light`` objects (intensity E⊥/π) and the ambient remainder's SH.
"""

from __future__ import annotations

from ...exports.lights import export_unity_lights
from ...exports.sh import export_unity
from ...maps.frames import UNITY
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra, skybox_panorama

FRAME = UNITY
ENCODINGS = ()


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``environment.exr`` (the panorama, skybox size), ``LightprobeAmbient.cs`` and, with lights,
    ``LightprobeLights.cs``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        Unity's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` (the SH) and, with lights, ``lights``.
    """
    skybox_panorama(source, folder, "environment.exr")
    folder.add_text("LightprobeAmbient.cs", export_unity(source.sh(), FRAME, csharp=True), "diffuse",
                    "SH of irradiance/π in Unity's convention (RenderSettings.ambientProbe)", "C#")
    if source.options.lights:
        folder.add_text("LightprobeLights.cs", export_unity_lights(source.lights(), FRAME), "lights+diffuse",
                        "directional lights: E⊥/π; ambient remainder: SH of irradiance/π", "C#")
    # LightprobeAmbient.cs is the whole probe's SH: it is what is measured
    return manifest_extra(source, lights_frame=FRAME, over_pi=True, whole_probe=True)


def usage(folder: EngineFolder) -> str:
    """Steps and code that use the folder in Unity.

    Parameters
    ----------
    folder : EngineFolder
        Unity's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    lights = ("4. With lights: call `LightprobeLights.Apply()` instead of step 3: it adds one directional light per "
              "light found and sets the ambient to the remainder.\n"
              if any(f["path"] == "LightprobeLights.cs" for f in folder.files) else "")
    return ("# Unity\n\nA linear-colour-space project.\n\n"
            "1. Import `environment.exr`; in its import settings set *Texture Shape* Cube, *Mapping* "
            "Latitude-Longitude Layout, *Convolution Type* Specular (Unity prefilters the mips here, in the editor).\n"
            "2. Use it as the skybox material's cubemap (*Skybox/Cubemap*) and as the reflection source "
            "(*Lighting > Environment*).\n"
            "3. Copy `LightprobeAmbient.cs` into `Assets/` and call its method at start-up to set "
            "`RenderSettings.ambientProbe` (Unity's SH, irradiance/π).\n" + lights)
