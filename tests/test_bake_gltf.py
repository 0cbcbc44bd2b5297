"""The glTF bake's KTX2 variant and its lights, read by the reference readers.

* ``--encoding gltf=ktx2``: ``environment_ggx.ktx2`` read back by npm ktx-parse (the KTX2 reference reader) as the
  cube lightprobe's reader finds, its mirror level showing the probe's spot on the face of its world direction, and
  a rough level against the GGX lobe summed directly over the probe.
* ``--lights``: the ``.glb``'s ``KHR_lights_punctual`` light through Babylon.js's own glTF loader (headless
  Chromium) points where the probe's spot is, with the irradiance and direction of the Babylon folder's
  ``lights.json`` through Babylon's ``DirectionalLight``.
"""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest

from lightprobe_engines.runtimes import Browser, Server, missing_engines
from test_bake_threejs import SPOT, spot_map  # a dim sky, one smooth spot 8° wide toward SPOT
from lightprobe.maps import EnvMap, resample
from lightprobe.maps.layouts import CUBE, LATLONG

pytestmark = pytest.mark.xdist_group("engines")  # one worker, so one browser start for all engine checks

SIZE = 16
@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The spot probe baked for glTF (with the KTX2 variant) and Babylon, with --lights and without."""
    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    from lightprobe.bake import BakeOptions, bake

    folder = tmp_path_factory.mktemp("bake-gltf")
    env = EnvMap(spot_map(128), LATLONG)
    plain = bake(env, folder / "plain", BakeOptions(("gltf",), size=SIZE, skybox_size=16,
                                                    encodings={"gltf": "ktx2"}))["gltf"]
    lit = bake(env, folder / "lit", BakeOptions(("gltf", "babylon"), size=SIZE, skybox_size=16, lights=True))
    return folder, env, plain, lit


def test_the_ktx2_variant_is_read_back_by_ktx_parse_as_written(baked):
    from lightprobe.exports.ktx2 import VkFormat, read_ktx2
    from lightprobe_engines.runtimes import ktx_parse

    _, _, plain, _ = baked
    path = plain / "environment_ggx.ktx2"
    mine = read_ktx2(path)
    (parsed,) = ktx_parse([path])
    assert mine.vk_format == VkFormat.R16G16B16A16_SFLOAT and mine.face_count == 6 and mine.level_count == 5
    assert (parsed["faceCount"], parsed["levelCount"], parsed["vkFormat"], parsed["pixelWidth"]) == (
        6, 5, int(VkFormat.R16G16B16A16_SFLOAT), SIZE)
    # ktx-parse's level bytes, as float16 RGBA faces, are the levels lightprobe's reader finds
    for i, (theirs, level) in enumerate(zip(parsed["levels"], mine.levels)):
        side = SIZE >> i
        stored = np.frombuffer(base64.b64decode(theirs["base64"]), np.float16).reshape(6, side, side, 4)
        assert np.array_equal(stored.astype(np.float32), np.asarray(level, np.float32)), i
    entry = next(f for f in json.loads((plain / "manifest.json").read_text())["files"]
                 if f["path"] == "environment_ggx.ktx2")
    assert entry["roughness"] == pytest.approx([0, 0.25, 0.5, 0.75, 1.0]) and entry["frame"] == "gltf"
    # the spot (world (0.6, 0.5, −0.62)) is brightest on face −Z of the mirror level (|z| largest); a mirrored
    # cube would put it on +Z
    mirror = np.asarray(mine.levels[0], np.float64)[..., :3].sum(axis=-1)
    assert np.unravel_index(np.argmax(mirror), mirror.shape)[0] == 5
    # with the .glb only (the default encoding) no KTX2 is written
    assert not (baked[3]["gltf"] / "environment_ggx.ktx2").exists()


def test_a_rough_level_of_the_ktx2_variant_is_the_ggx_lobe_summed_over_the_probe(baked):
    """Level 2 (roughness 0.5, α 0.25) against the direct sum of the GGX lobe over every texel of a 32² cube of
    the probe, at each of its 96 texels: float16 storage and the prefilter's sampling, within 2 %."""
    from lightprobe.exports.ktx2 import read_ktx2
    from test_bake_filament import direct_sum

    _, env, plain, _ = baked
    level = np.asarray(read_ktx2(plain / "environment_ggx.ktx2").levels[2], np.float64)[..., :3]
    r = CUBE.directions(CUBE.grid_shape(4)).reshape(-1, 3)
    expected = direct_sum(resample(env, CUBE, 32), r, 0.25)
    error = np.abs(level.reshape(-1, 3) - expected).max(axis=1) / expected.max(axis=1)
    # Measured: median 0.2 %, worst 1.0 %
    assert np.median(error) < 0.01 and error.max() < 0.02, (np.median(error), error.max())


def test_babylons_gltf_loader_puts_the_glb_light_where_the_spot_is(baked):
    """The .glb's KHR_lights_punctual light, through Babylon's glTF loader, points toward the spot (Babylon's frame:
    (x, y, −z) of world) and carries the irradiance Babylon's lights.json states."""
    folder, _, _, lit = baked
    server = Server(folder)
    browser = Browser(server)
    try:
        page = browser.page("babylon.html")
        from_gltf = page.evaluate("u => window.lightprobe.gltfLights(u)",
                                  f"{server.url}/files/lit/gltf/environment.glb")
        from_json = page.evaluate("t => window.lightprobe.jsonLights(t)",
                                  (lit["babylon"] / "lights.json").read_text())
    finally:
        browser.close()
        server.close()
    assert not browser.errors, browser.errors
    assert len(from_gltf) == len(from_json) >= 1
    spot = np.asarray(SPOT) * np.array([1, 1, -1]) / np.linalg.norm(SPOT)
    toward = np.asarray(from_gltf[0]["toward"])
    angle = np.degrees(np.arccos(np.clip(toward @ spot / np.linalg.norm(toward), -1, 1)))
    assert angle < 2.0, (toward, spot)  # measured: 0.2°
    assert from_gltf[0]["toward"] == pytest.approx(from_json[0]["toward"], abs=1e-5)
    assert from_gltf[0]["intensity"] == pytest.approx(from_json[0]["intensity"], rel=1e-5)
