"""The PlayCanvas bake proven in PlayCanvas 2.23 itself (headless Chromium, SwiftShader WebGL2).

The baked ``envAtlas.png`` and skybox faces are loaded by PlayCanvas's own texture and cubemap asset handlers and
lit with by its StandardMaterial (engines/playcanvas_page.mjs); beside them, the same scene lit by PlayCanvas's own
``EnvLighting`` of the same panorama file (generateLightingSource → generateAtlas, generateSkyboxCubemap). A
diffuse sphere and white metal spheres at roughness 0.1 / 0.3 / 0.6 / 0.9 are compared image against image; the
skybox along six axes; a bake mirrored in z must fail that direction check.
"""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pytest
from conftest import shared
from lightprobe_engines.probes import X_MIRROR, Y_QUARTER, axis_map
from lightprobe_engines.runtimes import (
    LUMINANCE,
    Browser,
    Server,
    lit_side,
    missing_engines,
)
from lightprobe_engines.spheres import canvas_luminance, playcanvas_spheres
from lightprobe_engines.spheres import mean_difference as differences

from lightprobe.maps import EnvMap, read_envmap
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import LATLONG
from lightprobe.util.errors import LightprobeWarning

pytestmark = pytest.mark.xdist_group("engines")  # one worker, so one browser start for all engine checks

SIZE = 64  # --size: a 256² atlas
SKYBOX = 64
CANVAS = 64  # engines/playcanvas.html's canvas
ROUGHNESSES = (None, 0.1, 0.3, 0.6, 0.9)  # None: the diffuse sphere
VIEWS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
SPOT = (0.6, 0.5, -0.62)  # world direction of the synthetic probe's spot
RESULTS: dict = {}  # probe → figures, printed by the last test


def spot_map() -> np.ndarray:
    """A dim sky with one smooth spot (Gaussian, 6° wide) whose peak, 40, stays inside RGBP's range (64)."""
    d = LATLONG.directions(LATLONG.grid_shape(256))
    s = np.asarray(SPOT) / np.linalg.norm(SPOT)
    angle = np.degrees(np.arccos(np.clip(d @ s, -1, 1)))
    return (0.05 + 40.0 * np.exp(-(angle / 6.0) ** 2)[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32)


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """Each probe as a panorama file (what PlayCanvas's own path reads), its PlayCanvas bake, and a bake whose skybox
    faces are written in the world frame instead of PlayCanvas's (z mirrored)."""
    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    from lightprobe.bake import BakeOptions, bake
    from lightprobe.bake.engines.playcanvas import FACES, rgbp_encode
    from lightprobe.exports.containers import png_bytes
    from lightprobe.glossy.prefilter import prefilter_cube
    from lightprobe.maps.frames import WORLD

    folder = tmp_path_factory.mktemp("playcanvas")
    files = {"interior": shared("polyhaven_1k/st_fagans_interior_1k.hdr"),
             "venice": shared("polyhaven_1k/venice_sunset_1k.hdr"),
             "spot": write_image(folder / "spot-source.hdr", spot_map())}
    for name, path in files.items():
        # venice is only looked at as a skybox: its atlas at the smallest size
        options = BakeOptions(("playcanvas",), size=32 if name == "venice" else SIZE, skybox_size=SKYBOX)
        shutil.copyfile(path, folder / f"{name}.hdr")
        env = read_envmap(path)
        with warnings.catch_warnings():  # the interior's lamps exceed RGBP's 64 in the mirror level: PlayCanvas's too
            warnings.simplefilter("ignore", LightprobeWarning)
            bake(env, folder / f"{name}-bake", options)
        mirrored = folder / f"{name}-mirrored"
        shutil.copytree(folder / f"{name}-bake" / "playcanvas", mirrored)
        for face, face_name in zip(prefilter_cube(env, SKYBOX, [0.0] * 7, WORLD).levels[0], FACES):
            (mirrored / f"skybox_{face_name}.png").write_bytes(png_bytes(rgbp_encode(face)))
    # the axis probe (lightprobe_engines.probes): our bake, and bakes of it mirrored in x and turned a quarter
    # about y (the atlas at the smallest size: only the skybox is looked at)
    write_image(folder / "axes.hdr", axis_map(256))
    for label, transform in (("axes", None), ("axes-mirrored", X_MIRROR), ("axes-rotated", Y_QUARTER)):
        bake(EnvMap(axis_map(256, transform), LATLONG), folder / f"{label}-bake",
             BakeOptions(("playcanvas",), size=16, skybox_size=SKYBOX))
    # the spot probe with --lights (the spot as a directional light, the remainder in the atlas), and its
    # lights.json with every light mirrored in x (PlayCanvas's frame): the mistake the lit side shows
    bake(read_envmap(files["spot"]), folder / "spot-lights", BakeOptions(("playcanvas",), size=SIZE,
                                                                         skybox_size=SKYBOX, lights=True))
    found = json.loads((folder / "spot-lights" / "playcanvas" / "lights.json").read_text())
    for light in found["directionalLights"]:
        light["travel"][0], light["toward"][0] = -light["travel"][0], -light["toward"][0]
    (folder / "spot-mirrored-lights.json").write_text(json.dumps(found))
    return folder


@pytest.fixture(scope="module")
def browser(baked):
    server = Server(baked)
    browser = Browser(server)
    yield browser
    browser.close()
    server.close()


def run(browser, script: str, args: list):
    """``script`` on a fresh page: one environment per page (see lightprobe_engines.spheres.playcanvas_spheres)."""
    page = browser.page("playcanvas.html")
    try:
        return page.evaluate(script, args)
    finally:
        page.close()


def luminance(image: str) -> np.ndarray:
    return canvas_luminance(image, CANVAS)


@pytest.mark.parametrize("probe", ["interior", "spot"])
def test_playcanvas_spheres_from_our_atlas_as_from_its_own(browser, baked, probe):
    """The diffuse sphere and white metal spheres under PlayCanvas's StandardMaterial, lit by our envAtlas.png and
    skybox against PlayCanvas's own EnvLighting of the panorama with a 256² atlas (our atlas's size) from a 64²
    lighting cube; PlayCanvas's own result with a 128² atlas from a 32² cube gives its spread."""
    from lightprobe.glossy.prefilter import prefilter_cube

    url = f"{browser.server.url}/files/{probe}"
    eye = [0.3, 0.45, 0.85] if probe == "interior" else list(np.asarray(SPOT) / np.linalg.norm(SPOT) * 0.7
                                                               + np.array([0.0, 0.0, 0.3]))
    eye = list(np.asarray(eye) / np.linalg.norm(eye))
    env = read_envmap(baked / f"{probe}.hdr")
    # exposures: the brightest texel of the 0.3-roughness lobe for the metals, the mean radiance for the diffuse one
    peak = float(prefilter_cube(env, 32, [0] + [0.09] * 5).levels[1].max())
    exposures = {"diffuse": 0.4 / float(env.integral() @ LUMINANCE / (4 * np.pi)), "metal": 0.6 / peak}

    gains = [exposures["diffuse" if r is None else "metal"] for r in ROUGHNESSES]

    def spheres(source, args):
        return playcanvas_spheres(browser, source, args, eye, gains, ROUGHNESSES)

    own = spheres("own", [url + ".hdr", 4 * SIZE, SKYBOX])
    # PlayCanvas's own result moves with its atlas size: that spread, per roughness, is the floor of what agreement
    # can mean (a 128² atlas rather than 512², which takes SwiftShader four times as long as the 256²)
    spread = differences(spheres("own", [url + ".hdr", 2 * SIZE, SKYBOX]), own)
    ours = differences(spheres("baked", [f"{url}-bake/playcanvas"]), own)
    RESULTS[("spheres", probe)] = (ours, spread)
    assert not browser.errors, browser.errors
    # Measured (when this test was written), ours against PlayCanvas's own 256² atlas, with its own 256² → 128²
    # spread: interior 1.4-2.6 % (spread 0.6-8.4 %), spot 0.5-7.2 % (spread 0.9-14.8 %), the diffuse sphere 1.6 % and
    # 4.7 % (ours sums every pixel of a 128×64 reduction; PlayCanvas draws 2048 Lambert samples). The frame's
    # mistake, a skybox mirrored in z, is what the skybox test catches.
    for roughness, mine, theirs in zip(ROUGHNESSES, ours, spread):
        assert mine < max(0.1, 2 * theirs), (roughness, ours, spread)


# the spot probe is a uniform sky along every axis: nothing to place
@pytest.mark.parametrize("probe", ["interior", "venice"])
def test_playcanvas_shows_our_skybox_where_it_shows_its_own_panorama(browser, baked, probe):
    """PlayCanvas's skybox of our faces against its skybox of its own generateSkyboxCubemap of the panorama,
    looking along each axis; the faces written in the world frame (z mirrored) must not pass."""
    url = f"{browser.server.url}/files/{probe}"
    env = read_envmap(baked / f"{probe}.hdr")
    exposure = 0.3 / float(np.percentile(env.data @ LUMINANCE, 90))

    def skyboxes(source, args):
        """One image per view in 8×8 blocks: where things are, not detail."""
        images = run(browser, "([s, a, v, x]) => window.lightprobe.skyboxes(s, a, v, x)",
                     [source, args, VIEWS, exposure])
        return [luminance(i).reshape(8, CANVAS // 8, 8, CANVAS // 8).mean(axis=(1, 3)) for i in images]

    own = skyboxes("own", [url + ".hdr", 0, SKYBOX])

    def compare(images):
        return [float(np.abs(i - o).mean() / o.mean()) for i, o in zip(images, own)]

    ours = compare(skyboxes("baked", [f"{url}-bake/playcanvas"]))
    wrong = compare(skyboxes("baked", [f"{url}-mirrored"]))
    RESULTS[("skybox", probe)] = (ours, wrong)
    assert not browser.errors, browser.errors
    assert max(ours) < 0.05, ours
    # a mirror in z swaps the ±Z views and flips the others left to right; the interior's ceiling and floor
    # (±Y) are nearly symmetric under that flip (measured 4 % apart), so four views at least must fail
    assert max(wrong) > 3 * max(ours) and sum(w > 0.1 for w in wrong) >= 4, (ours, wrong)


def test_playcanvas_skybox_of_the_axis_probe_fails_every_view_mirrored_or_turned(browser, baked):
    """The axis probe (a marker of its own brightness off each axis): our skybox faces match PlayCanvas's own
    generateSkyboxCubemap of the panorama along all six axes; the bakes of the probe mirrored in x and turned a
    quarter about y differ in every one of the six views."""
    url = f"{browser.server.url}/files/axes"
    exposure = 0.3 / float(np.percentile(axis_map(256) @ LUMINANCE, 90))

    def skyboxes(source, args):
        images = run(browser, "([s, a, v, x]) => window.lightprobe.skyboxes(s, a, v, x)",
                     [source, args, VIEWS, exposure])
        return [luminance(i).reshape(8, CANVAS // 8, 8, CANVAS // 8).mean(axis=(1, 3)) for i in images]

    own = skyboxes("own", [url + ".hdr", 0, SKYBOX])
    ours, mirrored, rotated = ([float(np.abs(i - o).mean() / o.mean()) for i, o in
                                zip(skyboxes("baked", [f"{url}{v}-bake/playcanvas"]), own)]
                               for v in ("", "-mirrored", "-rotated"))
    RESULTS[("skybox", "axes")] = (ours, mirrored)
    RESULTS[("skybox", "axes, quarter turn")] = (ours, rotated)
    assert not browser.errors, browser.errors
    # Measured: ours 0.3-1.3 % per view; x-mirrored 42-71 %, turned 45-77 %
    assert max(ours) < 0.03, ours
    assert min(mirrored) > 0.2 and min(rotated) > 0.2, (mirrored, rotated)


LIT = (None, 0.6, 0.9)  # the spheres lit by the lights: diffuse (bounded), and two rough metals (printed)


def test_playcanvas_lights_and_the_remainders_atlas_light_as_its_own_atlas_of_the_whole_probe(browser, baked):
    """The spot probe baked with --lights: its lights.json as PlayCanvas directional lights (made as USAGE.md
    makes them) plus the remainder's envAtlas.png light the diffuse sphere as PlayCanvas's own EnvLighting of the
    whole panorama does, lit on the same side; the lights mirrored in x light the other side. The rough metals'
    figures are printed beside."""
    url = f"{browser.server.url}/files/spot"
    eye = list(np.asarray([0.3, 0.45, 0.85]) / np.linalg.norm([0.3, 0.45, 0.85]))
    env = read_envmap(baked / "spot.hdr")
    exposure = 0.4 / float(env.integral() @ LUMINANCE / (4 * np.pi))
    views = [{"roughness": r, "exposure": exposure} for r in LIT]

    def spheres(source, args, lights=None):
        script = ("async ([l, s, a, e, v]) => { if (l) await window.lightprobe.addLights(l); "
                  "return window.lightprobe.spheres(s, a, e, v); }")
        return [luminance(i) for i in run(browser, script, [lights, source, args, eye, views])]

    own = spheres("own", [url + ".hdr", 4 * SIZE, SKYBOX])
    spread = differences(spheres("own", [url + ".hdr", 2 * SIZE, SKYBOX]), own)
    folder = f"{url}-lights/playcanvas"
    images = {"ours": spheres("baked", [folder], f"{folder}/lights.json"),
              "mirrored": spheres("baked", [folder], f"{url}-mirrored-lights.json")}
    figures = {k: differences(v, own) for k, v in images.items()}
    moved = {k: float(np.linalg.norm(lit_side(v[0]) - lit_side(own[0]))) for k, v in images.items()}
    RESULTS[("lights", "spot")] = (figures, spread, moved)
    assert not browser.errors, browser.errors
    # Measured: the diffuse sphere 1.9-2.1 % from PlayCanvas's own (its own 256² → 128² spread 1.6 %), its lit
    # side 0.0 px (of 64) from its own; the lights mirrored in x 59 % off, the lit side 25 px away. (Handed the
    # linear colour and intensity E⊥/π = 0.43 as they are, PlayCanvas lit it 47 % too dark: it linearises colour ×
    # intensity below 1, see USAGE.md.) The metals are figures, not bounded: lit by a directional light PlayCanvas
    # draws its punctual lobe (normalised Blinn-Phong by default, its lightSpecularBlinn chunk; GGX with
    # enableGGXSpecular), not the prefiltered GGX of its atlas, so they move 15 % and 29 % (Blinn; 29 %, 46 % with
    # GGX) whoever bakes: a limit of lights in place of the sun's texels for glossy metal, not of the files
    assert figures["ours"][0] < max(0.04, 2 * spread[0]), (figures, spread)
    assert moved["ours"] < 1.0 and moved["mirrored"] > 10, moved
    assert figures["mirrored"][0] > 0.3, figures


def test_print_the_playcanvas_table():
    """The figures of this module (pytest -s shows them; the closing note quotes them)."""
    for (kind, probe), (a, b, *rest) in sorted(RESULTS.items()):
        if kind == "lights":
            for i, r in enumerate(LIT):
                print(f"PlayCanvas {probe} --lights {'diffuse' if r is None else f'r={r}':8s} ours "
                      f"{100 * a['ours'][i]:5.1f} %  own 256→128 spread {100 * b[i]:5.1f} %  mirrored lights "
                      f"{100 * a['mirrored'][i]:5.1f} %")
            print(f"PlayCanvas {probe} --lights lit side moved: ours {rest[0]['ours']:.1f} px, mirrored "
                  f"{rest[0]['mirrored']:.1f} px")
        elif kind == "spheres":
            for r, mine, theirs in zip(ROUGHNESSES, a, b):
                print(f"PlayCanvas {probe:9s} {'diffuse' if r is None else f'r={r}':8s} ours {100 * mine:5.1f} %  "
                      f"own 256→128 spread {100 * theirs:5.1f} %")
        else:
            wrong = ("x-mirrored" if probe == "axes" else "turned" if probe.startswith("axes") else "z-mirrored")
            print(f"PlayCanvas {probe:9s} skybox ours {', '.join(f'{100 * v:.1f}' for v in a)} %; "
                  f"{wrong} {', '.join(f'{100 * v:.1f}' for v in b)} %")
