"""PlayCanvas: the ``envAtlas`` PNG (RGBP) it lights with, six RGBP PNG faces for its skybox cubemap, the lights.

What PlayCanvas's own ``EnvLighting.generateAtlas`` (src/scene/graphics/env-lighting.js) renders at load time, a
bake writes once, so the scene needs no filtering: a square RGBP atlas of side ``A`` holding equirectangular
images in fixed rectangles (fractions of A, PNG row 0 at the top, which is texture v = 0: PlayCanvas uploads
without flipping):

* the mirror image and its halvings, rect (1 − t, 1 − t, t, t/2) for t = 2^−j, j = 0…5 (``mapShinyUv`` in its
  envAtlas chunk);
* GGX levels i = 1…6, rect (0, 1 − t, t, t/2), t = 2^−i (``mapRoughnessUv``), level i filtered with PlayCanvas's
  specular power 2048 >> 2i (at least 1) turned into roughness 1 − log₂(power)/11, α = roughness² (its
  reproject-texture.js) — roughness 2i/11 for i < 6 and 1 for level 6. Its lit shader reads level (1 − gloss)·5,
  StandardMaterial's gloss being 1 − roughness (its gloss chunk, ``glossInvert`` false);
* the ambient, E/π (Lambert, which PlayCanvas adds without a 1/π), rect (1/4, 3/4, 1/8, 1/16).

Every rect keeps a seam of A/512 texels on each side: texel p of a rect w wide is at u = (p + ½ − A/512)/(w − 2A/512)
(the ``uvMod`` of reproject-texture.js, ``mapUv`` of the envAtlas chunk), the rows likewise, past the pole on the seam
rows as its ``getDirectionEquirect`` goes. An image's (u, v) is the direction ``fromSpherical((2u − 1)π, (½ − v)π)``
of its reproject chunk, which reads an equirect panorama file the same way, so an atlas texel holds the panorama's
pixel at the same (u, v). Its lit and skybox shaders negate x before ``toSphericalUv`` (reflectionEnv, ambient, skybox
chunks): PlayCanvas shows a panorama's centre along its +Z and the image's left quarter along its +X. lightprobe's
lat-long has world −Z at the centre and +X a quarter to the right, so PlayCanvas sees the world as (−x, y, −z): the
frame :data:`PLAYCANVAS`. The atlas's images are thus lightprobe's lat-longs, texel for texel apart from the seams.

RGBP (its decode chunk): linear = (rgb · (8 − 7a))², up to 64; written as its ``encodeRGBP`` writes it. The skybox
cube is read with x negated (skybox chunk: ``dir.x *= -1`` before ``textureCube``), so a face texel at OpenGL
direction d shows PlayCanvas's (−d.x, d.y, d.z), which is world (d.x, d.y, −d.z): :data:`PLAYCANVAS_CUBE`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ...exports.containers import png_bytes
from ...maps import EnvMap
from ...maps.frames import WORLD, Frame
from ...maps.layouts import CUBE, LATLONG
from ...util.errors import LightprobeWarning
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra

PLAYCANVAS = Frame("playcanvas", np.diag([-1.0, 1.0, -1.0]),
                   "PlayCanvas as it shows an equirect panorama: (−x, y, −z) of world (image centre at its +Z)")
PLAYCANVAS_CUBE = Frame("playcanvas-cubemap", np.diag([1.0, 1.0, -1.0]),
                        "PlayCanvas cubemap texels (its shaders negate x before sampling): (x, y, −z) of world")
FRAME = PLAYCANVAS
ENCODINGS = ()

RGBP_MAX = 64.0  # (8 · 1)²: the largest linear value an RGBP texel holds
ROUGH_LEVELS = 6  # GGX levels 1…6 of the atlas
SHINY_LEVELS = 6  # the mirror image and its five halvings (calcLevels(256) − calcLevels(4) in env-lighting.js)
FACES = ("px", "nx", "py", "ny", "pz", "nz")  # WebGL's cube face order, which PlayCanvas's cubemap asset takes


def atlas_roughness(level: int) -> float:
    """The perceptual roughness PlayCanvas filters atlas level ``level`` with (0: the mirror).

    Parameters
    ----------
    level : int
        0…6.

    Returns
    -------
    float
        1 − log₂(max(1, 2048 >> 2·level))/11 (env-lighting.js's specular power, reproject-texture.js's roughness);
        0 for level 0.
    """
    if level == 0:
        return 0.0
    return 1.0 - math.log2(max(1, 2048 >> (2 * level))) / 11.0


def rgbp_encode(linear: np.ndarray) -> np.ndarray:
    """Linear RGB (..., 3) → RGBP bytes (..., 4) as PlayCanvas's ``encodeRGBP`` (encode chunk) writes them.

    Parameters
    ----------
    linear : numpy.ndarray
        (..., 3) linear values; NaN and negatives count as 0, values above :data:`RGBP_MAX` are clipped.

    Returns
    -------
    numpy.ndarray
        (..., 4) uint8: a = ⌈255·(1 − (m − 1)/7)⌉/255 with m = max √channel in [1, 8],
        rgb = √linear / (8 − 7a).
    """
    gamma = np.sqrt(np.clip(np.nan_to_num(np.asarray(linear, np.float64), nan=0.0, posinf=RGBP_MAX), 0.0, RGBP_MAX))
    peak = np.clip(gamma.max(axis=-1), 1.0, 8.0)
    a = np.ceil((1.0 - (peak - 1.0) / 7.0) * 255.0) / 255.0
    rgb = np.clip(gamma / (8.0 - 7.0 * a)[..., None], 0.0, 1.0)
    return np.rint(np.concatenate([rgb, a[..., None]], axis=-1) * 255.0).astype(np.uint8)


def rgbp_decode(rgbp: np.ndarray) -> np.ndarray:
    """RGBP bytes (..., 4) → linear RGB, as PlayCanvas's ``decodeRGBP`` (decode chunk).

    Parameters
    ----------
    rgbp : numpy.ndarray
        (..., 4) uint8.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64: (rgb · (8 − 7a))².
    """
    v = np.asarray(rgbp, np.float64) / 255.0
    return (v[..., :3] * (8.0 - 7.0 * v[..., 3:4])) ** 2


def rect_directions(width: int, height: int, seam: float) -> np.ndarray:
    """World directions of the texels of one atlas rect, ``seam`` texels of it on each side being seam.

    Parameters
    ----------
    width, height : int
        The rect in texels.
    seam : float
        Seam texels on each side (atlas side / 512).

    Returns
    -------
    numpy.ndarray
        (height, width, 3) float64 unit vectors, world frame, row 0 at the top of the PNG.
    """
    u = (np.arange(width) + 0.5 - seam) / (width - 2 * seam)
    v = (np.arange(height) + 0.5 - seam) / (height - 2 * seam)
    lon = (2 * u - 1) * np.pi
    lat = (0.5 - v) * np.pi  # beyond ±π/2 on the seam rows: over the pole, as getDirectionEquirect goes
    lon, lat = np.meshgrid(lon, lat)
    q = np.stack([np.cos(lat) * np.sin(lon), np.sin(lat), np.cos(lat) * np.cos(lon)], axis=-1)
    # q is the direction PlayCanvas reads the image at (no flip in its reproject chunk); the image is lightprobe's
    # lat-long, whose (u, v) is world (q.x, q.y, −q.z)
    return q * np.array([1.0, 1.0, -1.0])


def atlas_size(size: int) -> int:
    """The atlas side for a specular ``size``: its mirror image 4·size wide, as wide as a ``size`` cube's equator.

    Parameters
    ----------
    size : int
        The bake's ``--size`` (a power of two).

    Returns
    -------
    int
        4·size, at least 128 (level 6 is 1/64 of the atlas wide) and at most 4096.
    """
    return int(min(max(4 * size, 128), 4096))


def build_atlas(env: EnvMap, chain, side: int) -> np.ndarray:
    """The atlas's linear texels: mirror halvings, GGX levels 1…6 from ``chain``, the ambient E/π.

    Parameters
    ----------
    env : EnvMap
        The radiance (world frame).
    chain : PrefilteredCube
        World-frame GGX chain whose level i (1…6) has α = :func:`atlas_roughness` (i)².
    side : int
        The atlas side.

    Returns
    -------
    numpy.ndarray
        (side, side, 3) float64, zero outside the rects.
    """
    from ...sh.irradiance import brute_irradiance

    atlas = np.zeros((side, side, 3))
    seam = side / 512.0

    def put(x, y, w, h, values):
        atlas[y:y + h, x:x + w] = values

    for j in range(SHINY_LEVELS):
        t = side >> j
        w, h = t, max(t // 2, 1)
        mirror = env.to(LATLONG, max(h, 2))  # the mirror at this level's resolution: its footprint, not a point
        put(side - t, side - t, w, h, mirror.lookup(rect_directions(w, h, seam)))
    for i in range(1, ROUGH_LEVELS + 1):
        t = max(side >> i, 1)
        w, h = t, max(t // 2, 1)
        level = EnvMap(chain.levels[min(i, len(chain.levels) - 1)], CUBE)
        put(0, side - t, w, h, level.lookup(rect_directions(w, h, seam)))
    w, h = side // 8, side // 16
    normals = rect_directions(w, h, seam)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    # Lambert over every pixel of a 128×64 lat-long: exact to its (smooth) reduction, where PlayCanvas draws 2048
    put(side // 4, 3 * side // 4, w, h, brute_irradiance(env.to(LATLONG, 64), normals) / np.pi)
    return atlas


def ambient_accuracy(env: EnvMap, atlas: np.ndarray, side: int) -> dict:
    """The ambient rect as PlayCanvas decodes it (after RGBP) against brute-force E/π over the probe.

    Parameters
    ----------
    env : EnvMap
        The radiance the atlas was made from (world frame).
    atlas : numpy.ndarray
        (side, side, 3) linear atlas texels, before encoding.
    side : int
        The atlas side.

    Returns
    -------
    dict
        ``median``/``worst`` relative error on luminance over the rect's texels inside its seams (at most 64 of
        them, fixed seed), ``texels`` and ``reference``.
    """
    from ...sh.irradiance import brute_irradiance
    from ..accuracy import REFERENCE_ROWS, SEED, _relative

    w, h, seam = side // 8, side // 16, side / 512.0
    x0, y0 = side // 4, 3 * side // 4
    inner = int(math.ceil(seam))
    rows, cols = np.meshgrid(np.arange(inner, h - inner), np.arange(inner, w - inner), indexing="ij")
    pick = np.random.default_rng(SEED).permutation(rows.size)[:64]
    rows, cols = rows.reshape(-1)[pick], cols.reshape(-1)[pick]
    got = rgbp_decode(rgbp_encode(atlas[y0 + rows, x0 + cols]))
    normals = rect_directions(w, h, seam)[rows, cols]
    reference = brute_irradiance(env.to(LATLONG, REFERENCE_ROWS), normals) / np.pi
    return {**_relative(got, reference), "texels": int(len(pick)),
            "reference": f"Σ L (n·ω)⁺ Δω / π over a {2 * REFERENCE_ROWS}×{REFERENCE_ROWS} lat-long of the probe"}


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``envAtlas.png``, the skybox faces ``skybox_{px,nx,py,ny,pz,nz}.png`` and, with lights, ``lights.json``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        PlayCanvas's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` and, with lights, ``lights``.
    """
    options = source.options
    side = atlas_size(options.size)
    env = source.diffuse()[0]
    # level i of the chain is atlas level i (face side/4 >> i: as wide as that level's image); its levels past 6
    # are never read, filtered as the last
    cube = max(side // 4, 64)
    count = int(math.log2(cube)) + 1
    alphas = tuple(atlas_roughness(min(i, ROUGH_LEVELS)) ** 2 for i in range(count))
    chain = source.chain(cube, alphas, WORLD, env=env)
    atlas = build_atlas(env, chain, side)
    clipped = float((atlas.max(axis=-1) > RGBP_MAX).mean())
    if clipped:
        warnings.warn(LightprobeWarning(
            f"PlayCanvas's RGBP holds values up to {RGBP_MAX:g}: {100 * clipped:.2g} % of the atlas texels clip "
            "(lower --intensity to keep them)"), stacklevel=2)
    roughness = [round(atlas_roughness(i), 6) for i in range(ROUGH_LEVELS + 1)]
    folder.add_bytes("envAtlas.png", png_bytes(rgbp_encode(atlas)), "specular+diffuse",
                     "radiance (mirror and GGX levels); E/π (ambient rect)", "RGBP PNG (PlayCanvas TEXTURETYPE_RGBP)",
                     layout="PlayCanvas envAtlas (equirect rects)", size=[side, side], mips=ROUGH_LEVELS + 1,
                     roughness=roughness, frame=PLAYCANVAS.name,
                     roughness_mapping="atlas level i = (1 − gloss)·5, gloss = 1 − roughness; level i filtered at "
                                       "roughness 1 − log2(max(1, 2048 >> 2i))/11, α = roughness²")
    sky = source.chain(options.skybox_size, (0.0,) * (int(math.log2(options.skybox_size)) + 1), PLAYCANVAS_CUBE)
    for face, name in zip(sky.levels[0], FACES):
        folder.add_bytes(f"skybox_{name}.png", png_bytes(rgbp_encode(face)), "skybox", "radiance",
                         "RGBP PNG (PlayCanvas TEXTURETYPE_RGBP)", layout="cube face", size=options.skybox_size,
                         frame=PLAYCANVAS_CUBE.name)
    # PlayCanvas lights diffuse surfaces from the atlas's ambient rect, not from SH: that rect is what is measured
    # PlayCanvas's Lambert term (lightDiffuseLambert chunk) is N·L with no 1/π: intensity E⊥/π
    extra = manifest_extra(source, chain, FRAME, over_pi=True, sh=False)
    extra["accuracy"]["ambient"] = ambient_accuracy(env, atlas, side)
    if options.lights:
        import json

        folder.add_text("lights.json", json.dumps({"directionalLights": extra["lights"]}, indent=1), "lights",
                        "irradiance E⊥/π (intensity) and linear colour", "JSON")
    return extra


def usage(folder: EngineFolder) -> str:
    """PlayCanvas code that loads the folder.

    Parameters
    ----------
    folder : EngineFolder
        PlayCanvas's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    names = {f["path"] for f in folder.files}
    lights = ("\n// the lights found in the probe (lights.json: PlayCanvas's frame; intensity = E⊥/π)\n"
              "const found = await (await fetch('lights.json')).json();\n"
              "// PlayCanvas takes a light's colour as sRGB, and below intensity 1 linearises colour × intensity\n"
              "// (Light._updateLinearColor): hand it the sRGB of the linear colour, × the intensity below 1\n"
              "for (const l of found.directionalLights) {\n"
              "  const k = Math.min(l.intensity, 1);\n"
              "  const color = new pc.Color(...l.colour.map((v) => v * k)).gamma();\n"
              "  const e = new pc.Entity(); e.addComponent('light', { type: 'directional',\n"
              "    color, intensity: Math.max(l.intensity, 1) });\n"
              "  e.lookAt(...l.travel); e.rotateLocal(90, 0, 0);  // it shines along its −Y\n"
              "  app.root.addChild(e);\n}\n"
              if "lights.json" in names else "")
    return ("# PlayCanvas\n\nThe atlas is what `EnvLighting.generateAtlas` would make at load time: nothing is "
            "filtered.\n\n```js\n"
            "const atlas = new pc.Asset('envAtlas', 'texture', { url: 'envAtlas.png' },\n"
            "  { type: pc.TEXTURETYPE_RGBP, mipmaps: false });\n"
            "// the skybox: the six faces, loaded and joined by PlayCanvas's cubemap handler\n"
            "const sky = new pc.Asset('skybox', 'cubemap', null, { type: pc.TEXTURETYPE_RGBP, mipmaps: false,\n"
            "  textures: ['px', 'nx', 'py', 'ny', 'pz', 'nz'].map((f) => `skybox_${f}.png`) });\n"
            "app.assets.add(atlas); app.assets.add(sky);\n"
            "new pc.AssetListLoader([atlas, sky], app.assets).load(() => {\n"
            "  app.scene.envAtlas = atlas.resource;\n"
            "  app.scene.skybox = sky.resources[0];\n"
            "});\n" + lights + "```\n\n"
            "`envAtlas.png` holds the mirror image, six GGX levels at PlayCanvas's roughness per level and the "
            "ambient (E/π), RGBP-encoded; StandardMaterial reads them with `gloss` = 1 − roughness.\n")
