"""Exports proven in the engines' own code (issue 8): three.js r187 in headless Chromium and Babylon.js 9.35 in Node.

For each probe, the engine computes SH from the panorama file itself, the way its users do, and lightprobe's export
of the *same file* is read by the engine; they must agree: band-1 direction within 3°, coefficients within 3 % of
L00 (or the engine's own spread between two cube sizes, if larger), and the irradiance the engine computes toward
its brightest background direction and the opposite one within 3 %. Four probes: two sunny Poly Haven maps, an
interior, and two synthetic single spots.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import shared
from lightprobe.engines import (LUMINANCE, Browser, Server, babylon, babylon_irradiance_over_pi, band1_angle,
                                coefficient_difference, missing_engines, relative)
from lightprobe.envmap import EnvMap, read_envmap
from lightprobe.export import export
from lightprobe.io import write_image
from lightprobe.layouts import LATLONG
from lightprobe.sh import project

pytestmark = pytest.mark.xdist_group("engines")  # one worker, so one browser start for all engine checks

POLYHAVEN = {"rooitou": "polyhaven_1k/rooitou_park_1k.hdr", "venice": "polyhaven_1k/venice_sunset_1k.hdr",
             "interior": "polyhaven_1k/st_fagans_interior_1k.hdr"}
SPOTS = {"spot-a": (0.6, 0.5, -0.62), "spot-b": (-0.3, -0.2, 0.93)}  # world directions
PROBES = list(POLYHAVEN) + list(SPOTS)
RESULTS: dict = {}  # engine × probe → figures, printed at the end of the module (and quoted in the closing note)


def spot_map(direction) -> np.ndarray:
    """A dim uniform sky with one bright, smooth (Gaussian, 3° wide) spot: smooth, so that the engines' point and
    bilinear resampling of the panorama into a cube do not alias it."""
    d = LATLONG.directions(LATLONG.grid_shape(256))
    s = np.asarray(direction) / np.linalg.norm(direction)
    angle = np.degrees(np.arccos(np.clip(d @ s, -1, 1)))
    return (0.02 + 300.0 * np.exp(-(angle / 3.0) ** 2)[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32)


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    """Each probe as a lat-long Radiance .hdr file: the file the engine reads and the file lightprobe exports."""
    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    folder = tmp_path_factory.mktemp("engine-probes")
    files = {name: shared(rel) for name, rel in POLYHAVEN.items()}
    for name, direction in SPOTS.items():
        files[name] = write_image(folder / f"{name}.hdr", spot_map(direction))
    return folder, files


@pytest.fixture(scope="module")
def browser(probes):
    folder, files = probes
    for name, path in files.items():
        target = folder / f"{name}.hdr"
        if not target.exists():
            target.symlink_to(path)
    server = Server(folder)
    b = Browser(server)
    yield b
    b.close()
    server.close()


def ours(path, target: str) -> str:
    return export(project(read_envmap(path), 2), target)


# ---- three.js in Chromium ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def three(browser):
    return browser.page("three.html")


@pytest.mark.parametrize("probe", PROBES)
def test_threejs_lights_from_where_its_background_shows_the_light(three, browser, probes, probe):
    folder, files = probes
    url = f"{browser.server.url}/files/{probe}.hdr"
    engine = {n: np.array(three.evaluate("([u, n]) => window.lightprobe.shFromPanorama(u, n)", [url, n])).reshape(9, 3)
              for n in (256, 512)}
    mine = np.array(three.evaluate("t => window.lightprobe.probeFromJSON(t)", ours(files[probe], "threejs"))).reshape(9, 3)
    spread = coefficient_difference(engine[256], engine[512])
    diff = coefficient_difference(mine, engine[512])
    angle = band1_angle(mine, engine[512], axes=(3, 1, 2))  # three.js: coefficient 3 is x, 1 is y, 2 is z
    # three's brightest background direction: the brightest panorama pixel through its equirectUv mapping
    image = read_envmap(files[probe]).data
    row, col = np.unravel_index(np.argmax(image @ LUMINANCE), image.shape[:2])
    phi, lat = 2 * np.pi * ((col + 0.5) / image.shape[1] - 0.5), np.pi * (0.5 - (row + 0.5) / image.shape[0])
    sun = np.array([np.cos(phi) * np.cos(lat), np.sin(lat), np.sin(phi) * np.cos(lat)])
    e = {k: np.array(three.evaluate("([c, n]) => window.lightprobe.irradiance(c, n)",
                                    [c.reshape(-1).tolist(), [sun.tolist(), (-sun).tolist()]]))
         for k, c in (("ours", mine), ("engine", engine[512]))}
    sun_err, anti_err = relative(e["ours"][0], e["engine"][0]), relative(e["ours"][1], e["engine"][1])
    RESULTS[("three.js r187", probe)] = (diff, spread, angle, sun_err, anti_err)
    assert not browser.errors, browser.errors
    assert angle < 3 and diff < max(0.03, spread), (angle, diff, spread)
    assert sun_err < 0.03 and anti_err < 0.03, (sun_err, anti_err)


# ---- Babylon.js in Node -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def babylon_answers(probes):
    _, files = probes
    jobs = {}
    for name, path in files.items():
        jobs[f"{name}/256"] = {"panorama": str(path), "size": 256}
        jobs[f"{name}/512"] = {"panorama": str(path), "size": 512}
        jobs[f"{name}/ours"] = {"export": ours(path, "babylon")}
    return babylon(jobs)


@pytest.mark.parametrize("probe", PROBES)
def test_babylon_default_path_renders_our_polynomial_as_its_own(babylon_answers, probe):
    answer = {k: {f: np.array(v) for f, v in babylon_answers[f"{probe}/{k}"].items()} for k in ("256", "512", "ours")}
    engine, mine = answer["512"]["preScaledHarmonics"], answer["ours"]["preScaledHarmonics"]
    spread = coefficient_difference(answer["256"]["preScaledHarmonics"], engine)
    diff = coefficient_difference(mine, engine)
    angle = band1_angle(mine, engine, axes=(3, 1, 2), signs=(-1, -1, 1))  # Babylon's pre-scaled x, y carry −
    coarse = answer["256"]["preScaledHarmonics"]
    sun = answer["512"]["brightest"]
    errors, spreads = [], []
    for n in (sun, -sun):
        errors.append(relative(babylon_irradiance_over_pi(mine, n), babylon_irradiance_over_pi(engine, n)))
        spreads.append(relative(babylon_irradiance_over_pi(coarse, n), babylon_irradiance_over_pi(engine, n)))
    RESULTS[("Babylon.js 9.35 (Node, default SH path)", probe)] = (diff, spread, angle, *errors)
    assert angle < 3 and diff < max(0.03, spread), (angle, diff, spread)
    # Babylon samples the panorama at the nearest pixel (CalcProjectionSpherical rounds), which under-counts a
    # sub-degree sun by 5-17 % depending on the cube size; where its own result moves that much between two cube
    # sizes, the irradiance is held to that spread instead of 3 % (said in the closing note of issue 8).
    assert errors[0] < max(0.03, spreads[0]) and errors[1] < max(0.03, spreads[1]), (errors, spreads)


# ---- Babylon.js's shader in Chromium ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def babylon_page(browser):
    return browser.page("babylon.html")


def centre_luminance(rgba: list, size: int = 128) -> float:
    """Linear luminance of the 9×9 pixels at the image centre (the sphere's point facing the camera)."""
    from lightprobe.tonemap import srgb_decode

    image = srgb_decode(np.array(rgba, np.float32).reshape(size, size, 4)[..., :3] / 255)
    c = size // 2
    return float((image[c - 4:c + 5, c - 4:c + 5] @ LUMINANCE).mean())


@pytest.mark.parametrize("probe", PROBES)
def test_babylon_shader_lights_the_sphere_as_with_its_own_panorama(babylon_page, browser, babylon_answers, probes,
                                                                     probe):
    """A white diffuse sphere under Babylon's default PBR shader, its environment loaded by Babylon from the
    panorama file (HDRCubeTexture) or given our SphericalPolynomial; the camera looks at the point facing the
    brightest direction, then the opposite one."""
    _, files = probes
    answer = babylon_answers
    sun = np.array(answer[f"{probe}/512"]["brightest"])
    ours_polynomial = json.loads(ours(files[probe], "babylon"))["polynomial"]
    pre = {n: np.array(answer[f"{probe}/{n}"]["preScaledHarmonics"]) for n in (256, 512)}
    errors, spreads = [], []
    for eye in (sun, -sun):
        expected = {n: babylon_irradiance_over_pi(pre[n], eye) @ LUMINANCE for n in pre}  # Node: the same CPU path
        exposure = 0.4 / max(expected[512], 1e-9)  # the centre at about 0.4: nothing clips
        url = f"{browser.server.url}/files/{probe}.hdr"
        own = centre_luminance(babylon_page.evaluate("([u, n, e, x]) => window.lightprobe.panorama(u, n, e, x)",
                                                     [url, 512, eye.tolist(), exposure]))
        mine = centre_luminance(babylon_page.evaluate("([p, e, x]) => window.lightprobe.polynomial(p, e, x)",
                                                      [ours_polynomial, eye.tolist(), exposure]))
        errors.append(abs(mine - own) / own)
        spreads.append(abs(expected[256] - expected[512]) / expected[512])
    RESULTS[("Babylon.js 9.35 (Chromium, PBR shader)", probe)] = (float("nan"), float("nan"), float("nan"), *errors)
    assert not browser.errors, browser.errors
    # as in the Node check: Babylon's own nearest-pixel sampling of a small sun moves its result between cube sizes
    assert errors[0] < max(0.03, spreads[0]) and errors[1] < max(0.03, spreads[1]), (errors, spreads)


def test_print_the_engine_table():
    """Not a check: the table of figures (run with -s to see it), after the engine tests of this module."""
    def shown(value, unit="%"):
        return "—" if np.isnan(value) else (f"{100 * value:.2f} %" if unit == "%" else f"{value:.2f}°")

    print("\n| engine | probe | coefficients | engine's spread | band-1 angle | E toward light | E away |")
    for (engine, probe), (diff, spread, angle, sun, anti) in sorted(RESULTS.items()):
        print(f"| {engine} | {probe} | {shown(diff)} | {shown(spread)} | {shown(angle, '°')} | {shown(sun)} | "
              f"{shown(anti)} |")
    assert json.dumps({str(k): v for k, v in RESULTS.items()})
