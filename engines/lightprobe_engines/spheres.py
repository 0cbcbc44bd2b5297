"""The engines drawing lit spheres, for the bake's tests and the demo's Bake section: a white diffuse sphere and white
metal spheres at given roughnesses, lit by lightprobe's bake or by the engine's own runtime prefilter of the same
panorama, each through the engine's page in ``engines/`` (three_bake.html, babylon.html, playcanvas.html,
filament.html).

Every function returns one linear luminance image (Rec. 709) per sphere, rows top to bottom: the pages read their
canvases bottom to top (WebGL's readPixels), so the rows are turned here once. Nothing here computes lighting.
"""

from __future__ import annotations

import base64

import numpy as np

from .runtimes import LUMINANCE

ROUGHNESSES = (None, 0.1, 0.3, 0.6, 0.9)  # None: the white diffuse sphere; then white metal at each roughness
PLAYCANVAS_CANVAS = 64  # engines/playcanvas.html's canvas
BABYLON_CANVAS = 128  # engines/babylon.html's
FILAMENT_CANVAS = 128  # engines/filament.html's


def canvas_luminance(data: str, size: int, srgb: bool = True) -> np.ndarray:
    """Linear luminance of a canvas a page returned: base64 RGBA bytes, rows bottom to top.

    Parameters
    ----------
    data : str
        The page's base64 text of size × size × 4 bytes.
    size : int
        The canvas's side, pixels.
    srgb : bool, default True
        The bytes are sRGB-encoded (Babylon, PlayCanvas); False: linear (Filament without post-processing).

    Returns
    -------
    numpy.ndarray
        (size, size) float64 luminance in [0, 1], rows top to bottom.
    """
    from lightprobe.maps.tonemap import srgb_decode

    rgba = np.frombuffer(base64.b64decode(data), np.uint8).reshape(size, size, 4)[::-1]
    rgb = rgba[..., :3].astype(np.float32) / 255
    return (srgb_decode(rgb) if srgb else rgb).astype(np.float64) @ LUMINANCE


def threejs_spheres(page, source: str, url: str, eye, roughnesses=ROUGHNESSES[1:], size: int = 64) -> list:
    """three.js r187 (three_bake.html, MeshStandardMaterial) lighting the diffuse sphere then a metal sphere per
    roughness from ``source``: "ours" (a bake's ``environment.ktx2`` at ``url``, marked as three.js's PMREM) or
    "pmrem" (its own ``PMREMGenerator.fromEquirectangular`` of the panorama file at ``url``).

    Parameters
    ----------
    page : playwright Page
        three_bake.html, loaded.
    source : str
        "ours" or "pmrem".
    url : str
        The file the page fetches.
    eye : sequence of float
        Camera direction in three.js's frame (the camera at 4.2 × its unit vector, looking at the sphere).
    roughnesses : sequence of float
        The metal spheres' roughness (the diffuse sphere always comes first).
    size : int, default 64
        The float render target's side.

    Returns
    -------
    list of numpy.ndarray
        1 + len(roughnesses) (size, size) linear luminance images (no exposure, no tone mapping).
    """
    images = page.evaluate("([s, u, e, r, n]) => window.lightprobe.spheres(s, u, e, r, n)",
                           [source, url, list(eye), list(roughnesses), size])
    return [np.asarray(i, np.float64).reshape(size, size)[::-1] for i in images]


def babylon_spheres(page, source: str, args: list, eye, exposures, roughnesses=ROUGHNESSES) -> list:
    """Babylon.js's PBR shader (babylon.html) lighting a white sphere per roughness (None: diffuse) from ``source``:
    "env" ([url of an .env]), "gltf" ([url of a .glb], its glTF loader) or "prefiltered" ([url of a panorama, cube
    size]: Babylon's own GPU prefilter, HDRFiltering), one environment load for all.

    Parameters
    ----------
    page : playwright Page
        babylon.html, loaded.
    source : str
        A source of the page's ``sources``.
    args : list
        Its arguments.
    eye : sequence of float
        Camera direction, Babylon's frame (the camera at 4 × eye).
    exposures : sequence of float
        Babylon's exposure per sphere.
    roughnesses : sequence of float or None
        Per sphere: None for the diffuse one, else the metal's roughness.

    Returns
    -------
    list of numpy.ndarray
        (128, 128) linear luminance per sphere, after the exposure, clipped at 1 as the canvas is.
    """
    views = [{"eye": list(eye), "exposure": x, "roughness": r} for r, x in zip(roughnesses, exposures)]
    shots = page.evaluate("([s, a, v]) => window.lightprobe.views(s, a, v, false)", [source, args, views])
    return [canvas_luminance(shot, BABYLON_CANVAS) for shot in shots]


def playcanvas_spheres(browser, source: str, args: list, eye, exposures, roughnesses=ROUGHNESSES) -> list:
    """PlayCanvas's StandardMaterial (playcanvas.html) lighting a white sphere per roughness (None: diffuse) from
    ``source``: "baked" ([url of a bake's playcanvas folder]) or "own" ([panorama url, atlas size, skybox size]:
    its own EnvLighting). Each call on a fresh page: a second environment in one PlayCanvas application rendered
    the metal spheres wrong (upside down and darker, 70–130 % off the same environment on a fresh page).

    Parameters
    ----------
    browser : lightprobe_engines.runtimes.Browser
        The browser the page opens in.
    source : str
        "baked" or "own".
    args : list
        Its arguments.
    eye : sequence of float
        Unit camera direction, PlayCanvas's frame (the camera at 4 × eye).
    exposures : sequence of float
        PlayCanvas's scene exposure per sphere.
    roughnesses : sequence of float or None
        Per sphere: None for the diffuse one, else the metal's roughness.

    Returns
    -------
    list of numpy.ndarray
        (64, 64) linear luminance per sphere, after the exposure.
    """
    views = [{"roughness": r, "exposure": x} for r, x in zip(roughnesses, exposures)]
    page = browser.page("playcanvas.html")
    try:
        shots = page.evaluate("([s, a, e, v]) => window.lightprobe.spheres(s, a, e, v)",
                              [source, args, list(eye), views])
    finally:
        page.close()
    return [canvas_luminance(shot, PLAYCANVAS_CANVAS) for shot in shots]


def filament_spheres(page, url: str, eye, gains, roughnesses=ROUGHNESSES) -> tuple[list, dict]:
    """Filament's web build (filament.html, gltfio's shader) lighting a white sphere per roughness (None: diffuse)
    from the IBL KTX1 at ``url``, loaded by ``createIblFromKtx1`` with its SH. The page must have been set up with
    the sphere (``window.lightprobe.setup``).

    Parameters
    ----------
    page : playwright Page
        filament.html, set up.
    url : str
        The IBL file.
    eye : sequence of float
        Camera direction, Filament's (the world) frame.
    gains : sequence of float
        Per sphere, the factor from radiance to the canvas (exposure 1/gain).
    roughnesses : sequence of float or None
        Per sphere: None for the diffuse one, else the metal's roughness.

    Returns
    -------
    list of numpy.ndarray
        (128, 128) linear luminance per sphere, clipped at 1.
    dict
        What the page loaded: ``levels`` (the cube's mip count) and ``sh`` (the 27 numbers it lights with).
    """
    info = page.evaluate("u => window.lightprobe.loadIbl(u)", url)
    # one frame per call: Filament may skip a frame asked for within the same task
    images = [canvas_luminance(page.evaluate("([e, g, r]) => window.lightprobe.sphereAt(e, g, r)", [list(eye), g, r]),
                               FILAMENT_CANVAS, srgb=False) for r, g in zip(roughnesses, gains)]
    page.evaluate("() => window.lightprobe.dropIbl()")
    return images, info


def mean_difference(images, references) -> list[float]:
    """Mean |image − reference| over the reference's lit pixels, relative to their mean, per pair.

    Parameters
    ----------
    images, references : sequence of numpy.ndarray
        Luminance images of the same shape, pair by pair.

    Returns
    -------
    list of float
        One relative difference per pair.
    """
    return [float(np.abs(i - o)[o > 0].mean() / o[o > 0].mean()) for i, o in zip(images, references)]
