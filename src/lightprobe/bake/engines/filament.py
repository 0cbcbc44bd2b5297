"""Filament: what ``cmgen --deploy`` writes — the IBL KTX1 (specular mips, the SH in its ``sh`` key), the skybox KTX1
and ``sh.txt`` — for ``Engine.createIblFromKtx1`` / ``createSkyFromKtx1`` (and the native ``ktxreader``).

Facts from Filament's own source (tools/cmgen/src/cmgen.cpp, shaders/src/light_indirect.fs, web/filament-js):

* **Levels.** cmgen prefilters level 0 at ``--size`` and stops at ``IBL_DEFAULT_MIN_LOD_SIZE`` (16²): a 256 cube has
  5 levels (256 … 16); a cube of 16 or less keeps the full chain. ``--mips`` overrides the count.
* **Roughness per level.** Level i of n holds perceptual roughness r = ``lodToPerceptualRoughness(i / (n − 1))``,
  the inverse of the shader's ``perceptualRoughnessToLod`` (lod = (n − 1) · r(2 − r)): r = 1 − √(1 − i/(n − 1)),
  prefiltered with α = r² (cmgen's "roughness"); level 0 is the mirror and the last level is r = 1.
* **Quantity.** Radiance, as it is (cmgen's ``roughnessFilter`` is called with a unit colour scale); the texel format
  R11F_G11F_B10F, cmgen's for both files (unsigned floats: negatives are 0, at most 65024).
* **Diffuse.** The ``sh`` key holds the irradiance SH pre-scaled for Filament's shader as ``--sh-shader`` makes it
  (:func:`lightprobe.exports.sh.filament_coefficients`: the bare polynomial gives E/π), six significant digits, and
  ``sh.txt`` the same nine triples in cmgen's text form. The web build's ``createIblFromKtx1`` builds the
  ``IndirectLight`` from the cube alone and leaves the 27 numbers in ``ibl.shfloats``; Filament's samples pass them
  to ``IndirectLight.Builder().irradianceSh(3, …)`` (USAGE.md does).
* **Frame and faces.** Filament's world is lightprobe's world frame. cmgen mirrors its input cube in x by default
  ("we mirror by default", ``CubemapUtils::mirrorCubemap``) because its ``Cubemap`` class addresses faces its own
  way; what matters is what Filament shows, and Filament samples a cube map handed to it in the OpenGL face
  orientation of world directions — lightprobe's cube layout — at those very directions (the skybox along six axes
  and the metal spheres, tests/test_bake_filament.py; an x-mirrored file fails). So the faces are written as
  lightprobe's cube holds them, +X, −X, +Y, −Y, +Z, −Z.
* **Skybox.** One level at ``--skybox-size`` (cmgen writes it at ``--size``; here it has its own size), radiance.

With lights: ``lights.json`` as :func:`lightprobe.exports.lights.export_filament_lights` writes it (the brightest
light as Filament's SUN; Filament takes one), the specular chain is the ambient remainder's, and the SH (``sh`` key,
``sh.txt``) is the remainder's with the other lights folded in, the same nine triples as ``lights.json``'s
``irradiance``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ...exports.ktx1 import ktx1_bytes
from ...exports.lights import ambient_sh, export_filament_lights, perpendicular_irradiance
from ...exports.packedfloat import UF10_MAX
from ...exports.sh import export_filament, filament_coefficients
from ...glossy.prefilter import PrefilteredCube
from ...maps.frames import FILAMENT
from ...maps.layouts import CUBE
from ...maps.resampling.resampler import resample
from ...util.errors import LightprobeWarning
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra

FRAME = FILAMENT
ENCODINGS = ()  # cmgen writes R11F_G11F_B10F only, and the web build's createIblFromKtx1 expects a float format
MIN_LOD_SIZE = 16  # cmgen's IBL_DEFAULT_MIN_LOD_SIZE: the smallest level it writes
IBL = "environment_ibl.ktx"
SKYBOX = "environment_skybox.ktx"
FORMAT = "r11f_g11f_b10f"


def level_count(size: int, mips: int | None = None) -> int:
    """The number of specular levels cmgen writes for a ``size`` cube: down to 16², or the full chain at 16 or less.

    Parameters
    ----------
    size : int
        Face edge of level 0 (a power of two).
    mips : int, optional
        A count asked for (``--mips``), which wins.

    Returns
    -------
    int
        log₂(size) + 1 − log₂(16) when size > 16, else log₂(size) + 1; or ``mips``.
    """
    if mips is not None:
        return mips
    exponent = int(math.log2(size))
    low = int(math.log2(MIN_LOD_SIZE))
    return exponent + 1 - (low if low < exponent else 0)


def perceptual_roughness(levels: int) -> np.ndarray:
    """Filament's perceptual roughness of each of ``levels`` levels: r = 1 − √(1 − i/(n − 1)).

    cmgen's ``lodToPerceptualRoughness`` of lod = i/(n − 1); the shader reads roughness r at lod (n − 1)·r(2 − r).

    Parameters
    ----------
    levels : int
        The chain's level count n (1: the mirror alone).

    Returns
    -------
    numpy.ndarray
        (n,) float64, 0 at level 0 and 1 at the last.
    """
    if levels == 1:
        return np.zeros(1)
    lod = np.arange(levels) / (levels - 1.0)
    return 1.0 - np.sqrt(np.clip(1.0 - lod, 0.0, 1.0))


def filament_alphas(levels: int) -> list[float]:
    """The GGX α = r² each level is prefiltered with (see :func:`perceptual_roughness`).

    Parameters
    ----------
    levels : int
        The chain's level count.

    Returns
    -------
    list of float
        α per level, 0 for the mirror.
    """
    return [float(r * r) for r in perceptual_roughness(levels)]


def warn_if_clipped(levels, what: str) -> None:
    """Warn when texels pass R11F_G11F_B10F's largest value (65024; blue 64512), which the encoding clamps to.

    Parameters
    ----------
    levels : sequence of numpy.ndarray
        The cube's levels, radiance.
    what : str
        The file, for the message.

    Warns
    -----
    LightprobeWarning
        Some texel of level 0 is above 64512 in a channel: the share of level 0's power above it.
    """
    level = np.asarray(levels[0], dtype=np.float64)
    over = np.maximum(level - UF10_MAX, 0.0).sum()
    if over > 0:
        warnings.warn(LightprobeWarning(
            f"{what}: R11F_G11F_B10F holds radiance up to {UF10_MAX:g}; {100 * over / level.sum():.2g} % of level "
            "0's power is above it and clamped (--intensity scales the probe down)"), stacklevel=3)


def _diffuse_sh(source: BakeSource):
    """The radiance SH the diffuse term holds: the probe's, or with lights the remainder plus every light but the
    brightest (which becomes the SUN), as export_filament_lights folds them."""
    lights = source.lights() if source.options.lights else None
    if lights is None or not len(lights.radii):
        return source.diffuse()[1]
    e = [float(perpendicular_irradiance(lights.radii[i], lights.powers[i]).max()) for i in range(len(lights.radii))]
    sun = int(np.argmax(e))
    return ambient_sh(lights, [i for i in range(len(e)) if i != sun])


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``environment_ibl.ktx``, ``environment_skybox.ktx``, ``sh.txt`` and, with lights, ``lights.json``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        Filament's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` (SH and specular chain) and, with lights, ``lights``.
    """
    options = source.options
    n = level_count(options.size, options.mips)
    alphas = filament_alphas(n)
    env = source.diffuse()[0]
    # the prefilter makes the whole chain down to 1²; the levels past cmgen's last repeat its α = 1 and are dropped
    full = source.chain(options.size, tuple(alphas + [alphas[-1]] * (options.full_chain - n)), FRAME, env=env)
    chain = PrefilteredCube(full.levels[:n], full.alphas[:n], full.frame)
    warn_if_clipped(chain.levels, IBL)
    sh = _diffuse_sh(source)
    coefficients = filament_coefficients(sh, FRAME)
    folder.add_bytes(IBL, ktx1_bytes(list(chain.levels), FORMAT, sh=coefficients), "specular+diffuse",
                     "radiance (specular mips); SH of irradiance/π pre-scaled for Filament's shader (key 'sh')",
                     "KTX1 R11F_G11F_B10F", layout="cube", size=options.size, mips=n,
                     roughness=[round(float(r), 6) for r in perceptual_roughness(n)],
                     roughness_mapping="cmgen's lodToPerceptualRoughness: mip i of n holds r = 1 − √(1 − i/(n − 1)) "
                                       "(α = r²); Filament reads r at lod (n − 1)·r(2 − r)")
    sky = resample(source.env, CUBE, options.skybox_size, rotation=FRAME.to_frame)
    warn_if_clipped([sky.data], SKYBOX)
    folder.add_bytes(SKYBOX, ktx1_bytes([sky.data], FORMAT), "skybox", "radiance", "KTX1 R11F_G11F_B10F",
                     layout="cube", size=options.skybox_size, mips=1)
    folder.add_text("sh.txt", export_filament(sh, FRAME), "diffuse",
                    "SH of irradiance/π pre-scaled for Filament's shader (IndirectLight irradiance(3, sh))",
                    "cmgen sh.txt")
    # the SH is measured against the map it describes: the probe, or the remainder (the folded lights are caps)
    extra = manifest_extra(source, chain, FRAME)
    if options.lights:
        folder.add_text("lights.json", export_filament_lights(source.lights(), FRAME), "lights+diffuse",
                        "SUN: E⊥ in lux with the IndirectLight at intensity 1; irradiance: as sh.txt", "JSON")
        extra["lights"] = extra["lights"][:1]  # Filament's one SUN; the others are folded into the SH
    return extra


def usage(folder: EngineFolder) -> str:
    """Filament (web build) code that loads the folder; the native calls are the same names.

    Parameters
    ----------
    folder : EngineFolder
        Filament's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    lights = ("  // the brightest light found in the probe as Filament's sun (lights.json: world frame, lux)\n"
              "  const found = await (await fetch('lights.json')).json();\n"
              "  if (found.sun) {\n"
              "    const sun = Filament.EntityManager.get().create();\n"
              "    Filament.LightManager.Builder(Filament.LightManager$Type.SUN).direction(found.sun.direction)\n"
              "      .color(found.sun.color).intensity(found.sun.intensity)\n"
              "      .sunAngularRadius(found.sun.sunAngularRadius).build(engine, sun);\n"
              "    scene.addEntity(sun);\n  }\n"
              if any(f["path"] == "lights.json" for f in folder.files) else "")
    return ("# Filament\n\nThe files `cmgen --deploy` would write, prefiltered: nothing is filtered at load time.\n\n"
            "```js\n"
            f"Filament.init(['{IBL}', '{SKYBOX}'], async () => {{  // engine, scene: yours\n"
            f"  const loaded = engine.createIblFromKtx1('{IBL}');\n"
            "  // createIblFromKtx1 leaves the diffuse SH (the 'sh' key) in shfloats: hand it to the light\n"
            "  const ibl = Filament.IndirectLight.Builder().reflections(loaded.getReflectionsTexture())\n"
            "    .irradianceSh(3, new Float32Array(loaded.shfloats)).intensity(1.0).build(engine);\n"
            "  scene.setIndirectLight(ibl);\n"
            f"  scene.setSkybox(engine.createSkyFromKtx1('{SKYBOX}'));\n" + lights + "});\n```\n\n"
            f"`{IBL}` holds the GGX mips (R11F_G11F_B10F radiance, cmgen's roughness per mip, 16² the smallest) "
            "and, in its `sh` key, the irradiance SH pre-scaled for Filament's shader; `sh.txt` holds the same nine "
            "triples for `IndirectLight.Builder().irradianceSh(3, …)`. Natively: `ktxreader::Ktx1Reader::createTexture`"
            " and `IndirectLight::Builder().reflections(…).irradiance(3, sh)`. Filament's frame is the world frame.\n")
