"""Light exports proven in the engines' own code: each exported light, as the engine reads it, points where the
engine's own background of the same panorama shows that light's region (three.js r187 in Chromium: ObjectLoader
and an equirectangular background; Babylon.js 9.35 in Chromium: its glTF loader with KHR_lights_punctual and its
DirectionalLight from our JSON, against its skybox of an HDRCubeTexture of the panorama).

The probe: a dim sky with two small suns of different colours (warm and cool) in two octants, so that a light
landing anywhere but on its own sun — mirrored, turned, or on the other sun — shows the wrong colour or the sky.
"""

from __future__ import annotations

import base64
import json
import math

import numpy as np
import pytest

from lightprobe_engines.runtimes import LUMINANCE, Browser, Server, missing_engines
from lightprobe.maps import EnvMap
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import LATLONG
from lightprobe.maps.tonemap import srgb_decode

pytestmark = pytest.mark.xdist_group("engines")

SUNS = {"warm": ((0.6, 0.45, -0.66), (1.0, 0.45, 0.15)), "cool": ((-0.5, 0.3, 0.81), (0.15, 0.45, 1.0))}
SUN_RADIUS_DEG, SUN_RADIANCE, SKY = 5.0, 200.0, 0.02


def two_suns() -> np.ndarray:
    data = np.full(LATLONG.grid_shape(256) + (3,), SKY, np.float32)
    dirs = EnvMap(data, LATLONG).directions()
    for direction, colour in SUNS.values():
        d = np.asarray(direction) / np.linalg.norm(direction)
        data[dirs @ d >= math.cos(math.radians(SUN_RADIUS_DEG))] = SUN_RADIANCE * np.asarray(colour)
    return data


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The panorama, its lights JSON by ``lightprobe lights`` and each engine's export by ``lightprobe export``."""
    from lightprobe.cli import main

    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    folder = tmp_path_factory.mktemp("engine-lights")
    panorama = write_image(folder / "suns.hdr", two_suns())
    assert main(["lights", str(panorama), "-o", str(folder / "lights.json")]) == 0
    for target, name in (("threejs", "three.json"), ("babylon", "babylon.json"), ("gltf", "lights.glb")):
        assert main(["export", "--lights", str(folder / "lights.json"), "--to", target, "-o", str(folder / name)]) == 0
    return folder


@pytest.fixture(scope="module")
def browser(exported):
    server = Server(exported)
    b = Browser(server)
    yield b
    b.close()
    server.close()


def check_on_its_sun(lights: list[dict], seen: list[np.ndarray], what: str) -> None:
    """Each light's colour says which sun it is; the background toward it must show that sun: its dominant
    channel and at least half the sun's radiance (the sky is 10⁴ times dimmer)."""
    assert len(lights) == 2, f"{what}: {len(lights)} lights"
    for light, rgb in zip(lights, seen):
        colour = np.asarray(light["colour"])
        sun = "warm" if colour[0] > colour[2] else "cool"
        expected = SUN_RADIANCE * np.asarray(SUNS[sun][1])
        assert np.argmax(rgb) == np.argmax(expected), (what, sun, rgb)
        assert rgb @ LUMINANCE > 0.5 * (expected @ LUMINANCE), (what, sun, rgb)


def test_threejs_lights_point_at_their_suns_in_its_background(browser, exported):
    page = browser.page("three.html")
    lights = page.evaluate("t => window.lightprobe.lightsFromJSON(t)", (exported / "three.json").read_text())
    for light in lights:
        light["colour"] = light["color"]
    seen = page.evaluate("([u, d]) => window.lightprobe.backgroundAt(u, d)",
                         [f"{browser.server.url}/files/suns.hdr", [light["toward"] for light in lights]])
    assert not browser.errors, browser.errors
    check_on_its_sun(lights, [np.array(s) for s in seen], "three.js")
    # the light three.js holds carries the irradiance the export states: E⊥ = P (1 + cos r)/2 of the cap
    doc = json.loads((exported / "lights.json").read_text())
    e_perp = sorted(max(np.array(l["power"]) * (1 + math.cos(math.radians(l["angular_radius_deg"]))) / 2)
                    for l in doc["lights"])
    assert sorted(light["intensity"] for light in lights) == pytest.approx(e_perp, rel=1e-6)


def _skybox_rgb(canvas: str, size: int = 128) -> np.ndarray:
    """Linear RGB at the centre of a skybox view (Babylon returns sRGB bytes, rows bottom to top)."""
    rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(size, size, 4)
    c = size // 2
    return srgb_decode(rgba[c - 2:c + 3, c - 2:c + 3, :3].astype(np.float32) / 255).reshape(-1, 3).mean(axis=0)


@pytest.mark.parametrize("source", ["gltf", "json"])
def test_babylon_lights_point_at_their_suns_in_its_skybox(browser, exported, source):
    page = browser.page("babylon.html")
    if source == "gltf":
        lights = page.evaluate("u => window.lightprobe.gltfLights(u)", f"{browser.server.url}/files/lights.glb")
    else:
        lights = page.evaluate("t => window.lightprobe.jsonLights(t)", (exported / "babylon.json").read_text())
        doc = json.loads((exported / "babylon.json").read_text())
        for light, ours in zip(lights, doc["directionalLights"]):
            light["diffuse"] = ours["diffuse"]  # the constructor takes no colour; ours is in the file
    for light in lights:
        light["colour"] = light["diffuse"]
    # exposure: the sun's brightest channel at 1 in the 8-bit skybox, the sky ~10⁻⁴ of it
    canvases = page.evaluate("([s, a, d, x]) => window.lightprobe.skyboxes(s, a, d, x)",
                             ["panorama", [f"{browser.server.url}/files/suns.hdr", 128],
                              [light["toward"] for light in lights], 1.0 / SUN_RADIANCE])
    assert not browser.errors, browser.errors
    seen = [_skybox_rgb(c) * SUN_RADIANCE for c in canvases]
    check_on_its_sun(lights, seen, f"Babylon ({source})")
