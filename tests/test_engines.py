"""Exports proven in the engines' own code: three.js r187 in headless Chromium and Babylon.js 9.35 in Node.

For each probe, the engine computes SH from the panorama file itself, the way its users do, and lightprobe's export
of the *same file* is read by the engine; they must agree: band-1 direction within 3°, coefficients within 3 % of
L00 (or the engine's own spread between two cube sizes, if larger), and the irradiance the engine computes toward
its brightest background direction and the opposite one within 3 %. Four probes: two sunny Poly Haven maps, an
interior, and two synthetic single spots.
"""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pytest

from conftest import shared
from lightprobe_engines.runtimes import ENGINES, LUMINANCE, Browser, Server, babylon, babylon_bundle, babylon_irradiance_over_pi, band1_angle, coefficient_difference, missing_engines, relative
from lightprobe.maps import EnvMap, read_envmap
from lightprobe.util.errors import LightprobeWarning
from lightprobe.exports.sh import export
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import LATLONG
from lightprobe.sh.basis import project

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
    """Babylon's own SH of each panorama with 256² and 512² cube faces, and our export read by Babylon; where its
    own irradiance toward the light moves by over 3 % between those sizes (it takes the panorama's nearest pixel,
    which misses or over-counts a small sun), also with 2048² faces — more texels than the 1k panorama has pixels,
    where it has converged (1024² → 2048² moves Rooitou Park by 0.6 %) — under ``converged``."""
    _, files = probes
    jobs = {}
    for name, path in files.items():
        jobs[f"{name}/256"] = {"panorama": str(path), "size": 256}
        jobs[f"{name}/512"] = {"panorama": str(path), "size": 512}
        jobs[f"{name}/ours"] = {"export": ours(path, "babylon")}
    answers = babylon(jobs)
    unsettled = {}
    for name, path in files.items():
        pre = {n: np.array(answers[f"{name}/{n}"]["preScaledHarmonics"]) for n in (256, 512)}
        sun = np.array(answers[f"{name}/512"]["brightest"])
        if relative(babylon_irradiance_over_pi(pre[256], sun), babylon_irradiance_over_pi(pre[512], sun)) > 0.03:
            unsettled[f"{name}/converged"] = {"panorama": str(path), "size": 2048}
    answers.update(babylon(unsettled) if unsettled else {})
    for name in files:
        answers.setdefault(f"{name}/converged", answers[f"{name}/512"])
    return answers


@pytest.mark.parametrize("probe", PROBES)
def test_babylon_default_path_renders_our_polynomial_as_its_own(babylon_answers, probe):
    """Against Babylon's converged SH of the panorama (see babylon_answers): band 1 within 3°, coefficients within
    3 % of L00 or Babylon's own spread between 256² and 512² faces, irradiance toward the brightest background
    direction and away from it within 3 %."""
    answer = {k: {f: np.array(v) for f, v in babylon_answers[f"{probe}/{k}"].items()}
              for k in ("256", "512", "converged", "ours")}
    engine, mine = answer["converged"]["preScaledHarmonics"], answer["ours"]["preScaledHarmonics"]
    spread = coefficient_difference(answer["256"]["preScaledHarmonics"], answer["512"]["preScaledHarmonics"])
    diff = coefficient_difference(mine, engine)
    angle = band1_angle(mine, engine, axes=(3, 1, 2), signs=(-1, -1, 1))  # Babylon's pre-scaled x, y carry −
    sun = answer["512"]["brightest"]
    errors = [relative(babylon_irradiance_over_pi(mine, n), babylon_irradiance_over_pi(engine, n)) for n in (sun, -sun)]
    RESULTS[("Babylon.js 9.35 (Node, default SH path)", probe)] = (diff, spread, angle, *errors)
    assert angle < 3 and diff < max(0.03, spread), (angle, diff, spread)
    assert errors[0] < 0.03 and errors[1] < 0.03, errors


# ---- Babylon.js's shader in Chromium ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def babylon_page(browser):
    return browser.page("babylon.html")


def luminance_image(canvas: str, size: int = 128) -> np.ndarray:
    """Linear luminance of a canvas the page returned (base64 RGBA bytes, sRGB-encoded)."""
    import base64

    from lightprobe.maps.tonemap import srgb_decode

    rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(size, size, 4)
    return srgb_decode(rgba[..., :3].astype(np.float32) / 255) @ LUMINANCE


def centre_luminance(canvas: str, size: int = 128) -> float:
    """Linear luminance of the 9×9 pixels at the image centre (the sphere's point facing the camera)."""
    c = size // 2
    return float(luminance_image(canvas, size)[c - 4:c + 5, c - 4:c + 5].mean())


@pytest.mark.parametrize("probe", PROBES)
def test_babylon_shader_lights_the_sphere_as_with_its_own_panorama(babylon_page, browser, babylon_answers, probes,
                                                                     probe):
    """A white diffuse sphere under Babylon's default PBR shader, its environment loaded by Babylon from the
    panorama file (HDRCubeTexture, 512² faces) or given our SphericalPolynomial; the camera looks at the point
    facing the brightest direction, then the opposite one. See shader_errors for what is held to 3 %."""
    _, files = probes
    ours_polynomial = json.loads(ours(files[probe], "babylon"))["polynomial"]
    errors = shader_errors(babylon_page, browser, babylon_answers, probe, "polynomial", [ours_polynomial])
    RESULTS[("Babylon.js 9.35 (Chromium, PBR shader)", probe)] = (float("nan"), float("nan"), float("nan"), *errors)
    assert not browser.errors, browser.errors
    assert max(errors) < 0.03, errors


def shader_errors(page, browser, answers, probe: str, source: str, args: list) -> list[float]:
    """Babylon's shader lighting the sphere from ``source`` (ours) and from its own 512² HDRCubeTexture of the
    panorama, toward the light and away: how far ours is, as rendered, from Babylon's converged irradiance.

    Babylon's 512² cube takes the panorama's nearest pixel and misses part of a small sun (11 % toward Rooitou
    Park's), so its own render is not the reference; the ratio of the two renders is, times the ratio Babylon's
    CPU path gives between its 512² and converged SH (babylon_answers): that checks the shader (it must render
    the two in the ratio of their numbers) and lands on the converged value."""
    sun = np.array(answers[f"{probe}/512"]["brightest"])
    pre = {n: np.array(answers[f"{probe}/{n}"]["preScaledHarmonics"]) for n in ("512", "converged")}
    url = f"{browser.server.url}/files/{probe}.hdr"
    errors = []
    for eye in (sun, -sun):
        expected = {n: babylon_irradiance_over_pi(pre[n], eye) @ LUMINANCE for n in pre}  # Node: the same CPU path
        exposure = 0.4 / max(expected["512"], 1e-9)  # the centre at about 0.4: nothing clips
        own = centre_luminance(page.evaluate("([u, n, e, x]) => window.lightprobe.panorama(u, n, e, x)",
                                             [url, 512, eye.tolist(), exposure]))
        mine = centre_luminance(page.evaluate("([s, a, e, x]) => window.lightprobe.sphere(s, a, e, x, null)",
                                              [source, args, eye.tolist(), exposure]))
        errors.append(abs(mine / own * expected["512"] / expected["converged"] - 1))
    return errors


# ---- the environment in Babylon's own containers: .env, and glTF through Babylon's loader -----------------------
CONTAINER_SIZE = 64  # specular cube of the container files (the diffuse checks read only their SH)


@pytest.fixture(scope="module")
def containers(probes):
    """Each probe baked for Babylon and glTF (``lightprobe.bake``: the .env and the .glb a user gets), beside the
    panoramas the browser serves."""
    from lightprobe.bake import BakeOptions, bake

    folder, files = probes
    options = BakeOptions(("babylon", "gltf"), size=CONTAINER_SIZE, skybox_size=16)
    for name, path in files.items():
        with warnings.catch_warnings():  # the sunny probes' RGBD clipping warning: measured in test_containers
            warnings.simplefilter("ignore", LightprobeWarning)
            baked = bake(read_envmap(path), folder / f"{name}-bake", options)
        shutil.copyfile(baked["babylon"] / "environment.env", folder / f"{name}.env")
        shutil.copyfile(baked["gltf"] / "environment.glb", folder / f"{name}.glb")
    return folder


@pytest.mark.parametrize("container", ["env", "glb"])
@pytest.mark.parametrize("probe", PROBES)
def test_babylon_lights_from_our_container_as_from_its_own_panorama(babylon_page, browser, babylon_answers,
                                                                      containers, probe, container):
    """The diffuse sphere under Babylon's default PBR shader, its environment our .env file (Babylon's CubeTexture)
    or our .glb (Babylon's glTF loader, EXT_lights_image_based), against Babylon's own (see shader_errors)."""
    source = "env" if container == "env" else "gltf"
    errors = shader_errors(babylon_page, browser, babylon_answers, probe, source,
                           [f"{browser.server.url}/files/{probe}.{container}"])
    what = ".env (CubeTexture)" if container == "env" else "glTF loader (EXT_lights_image_based)"
    RESULTS[(f"Babylon.js 9.35 {what}", probe)] = (float("nan"), float("nan"), float("nan"), *errors)
    assert not browser.errors, browser.errors
    assert max(errors) < 0.03, errors


VIEWS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


@pytest.mark.parametrize("probe", ["venice", "spot-a"])
def test_babylon_shows_our_env_background_where_it_shows_its_own_panorama(babylon_page, browser, containers,
                                                                          probes, probe, tmp_path):
    """Babylon's skybox of our .env against its skybox of its own HDRCubeTexture of the panorama, looking along
    each axis; the same .env made in the world frame (mirrored z, the mistake the frame fixes) must not pass."""
    from lightprobe.exports.containers import babylon_env
    from lightprobe.maps.frames import WORLD

    _, files = probes
    env = read_envmap(files[probe])
    mirrored = containers / f"{probe}-mirrored.env"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LightprobeWarning)
        mirrored.write_bytes(babylon_env(env, project(env, 2), CONTAINER_SIZE, frame=WORLD))
    url = f"{browser.server.url}/files/{probe}"
    exposure = 0.3 / float(np.percentile(env.data @ LUMINANCE, 90))

    def skyboxes(source, args):
        """One image per view, reduced to 16×16 blocks: the comparison is of where things are, not of detail
        (Babylon's panorama → cube takes the nearest pixel, ours the footprint)."""
        images = babylon_page.evaluate("([s, a, d, x]) => window.lightprobe.skyboxes(s, a, d, x)",
                                       [source, args, VIEWS, exposure])
        return [luminance_image(image).reshape(16, 8, 16, 8).mean(axis=(1, 3)) for image in images]

    own = skyboxes("panorama", [url + ".hdr", 256])

    def differences(images):
        return [float(np.abs(image - o).mean() / o.mean()) for image, o in zip(images, own)]

    ours, wrong = differences(skyboxes("env", [url + ".env"])), differences(skyboxes("env", [url + "-mirrored.env"]))
    SKYBOX[probe] = (ours, wrong)
    assert not browser.errors, browser.errors
    assert max(ours) < 0.1, ours
    assert max(wrong) > 3 * max(ours), (ours, wrong)


def test_babylon_env_skybox_of_the_axis_probe_fails_every_view_mirrored_or_turned(babylon_page, browser, probes):
    """The axis probe (lightprobe_engines.probes): Babylon's skybox of our .env matches its skybox of its own
    HDRCubeTexture of the panorama along all six axes; the .env baked from the probe mirrored in x, and turned a
    quarter about y, differs in every one of the six views."""
    from lightprobe.bake import BakeOptions, bake
    from lightprobe_engines.probes import X_MIRROR, Y_QUARTER, axis_map

    folder, _ = probes
    write_image(folder / "axes.hdr", axis_map(256))
    for label, transform in (("axes", None), ("axes-mirrored", X_MIRROR), ("axes-rotated", Y_QUARTER)):
        with warnings.catch_warnings():  # RGBD's range: the markers stay inside it, the warning is general
            warnings.simplefilter("ignore", LightprobeWarning)
            baked = bake(EnvMap(axis_map(256, transform), LATLONG), folder / f"{label}-bake",
                         BakeOptions(("babylon",), size=CONTAINER_SIZE, skybox_size=16))
        shutil.copyfile(baked["babylon"] / "environment.env", folder / f"{label}.env")
    url = f"{browser.server.url}/files/axes"
    exposure = 0.3 / float(np.percentile(axis_map(256) @ LUMINANCE, 90))

    def skyboxes(source, args):
        images = babylon_page.evaluate("([s, a, d, x]) => window.lightprobe.skyboxes(s, a, d, x)",
                                       [source, args, VIEWS, exposure])
        return [luminance_image(image).reshape(16, 8, 16, 8).mean(axis=(1, 3)) for image in images]

    own = skyboxes("panorama", [url + ".hdr", 256])
    ours, mirrored, rotated = ([float(np.abs(image - o).mean() / o.mean()) for image, o in
                                zip(skyboxes("env", [f"{url}{v}.env"]), own)] for v in ("", "-mirrored", "-rotated"))
    SKYBOX["axes"] = (ours, mirrored)
    SKYBOX["axes, quarter turn"] = (ours, rotated)
    assert not browser.errors, browser.errors
    # Measured: ours 2.0 % at worst; x-mirrored 14-28 % per view, turned 13-25 % (Babylon's 69° view holds more
    # sky round the marker than the other engines' 30-60°)
    assert max(ours) < 0.04, ours
    assert min(mirrored) > 0.1 and min(rotated) > 0.1, (mirrored, rotated)


@pytest.mark.parametrize("probe", ["interior", "spot-a", "spot-b"])
def test_babylon_glossy_metal_from_our_mips_as_from_its_own_prefiltering(babylon_page, browser, containers, probe):
    """A white metal sphere of roughness 0.25, 0.5 and 0.8 in Babylon's PBR shader: its mips from our .env and our
    glTF against those Babylon's own GPU prefilter (HDRFiltering) makes from the panorama at the same size."""
    from lightprobe.glossy.prefilter import prefilter_cube

    url = f"{browser.server.url}/files/{probe}"
    eye = [0.3, 0.45, 0.85]
    # the brightest texel of the α = 0.25² mip sets the exposure: the highlight stays below white
    peak = float(prefilter_cube(read_envmap(containers / f"{probe}.hdr"), 32, [0] + [0.0625] * 5).levels[1].max())
    roughnesses = (0.25, 0.5, 0.8)

    def spheres(source, args):
        return [luminance_image(image) for image in babylon_page.evaluate(
            "([s, a, e, x, r]) => window.lightprobe.spheres(s, a, e, x, r)",
            [source, args, eye, 0.6 / peak, roughnesses])]

    def differences(images, references):
        return [float(np.abs(i - o)[o > 0].mean() / o[o > 0].mean()) for i, o in zip(images, references)]

    own = spheres("prefiltered", [url + ".hdr", CONTAINER_SIZE])
    # Babylon's own result moves between cube sizes (it takes the panorama's nearest pixel): that spread, per
    # roughness, is the floor of what agreement can mean
    spread = differences(spheres("prefiltered", [url + ".hdr", 2 * CONTAINER_SIZE]), own)
    figures = {container: differences(spheres(source, [f"{url}.{container}"]), own)
               for container, source in (("env", "env"), ("glb", "gltf"))}
    GLOSSY[probe] = (roughnesses, figures, spread)
    assert not browser.errors, browser.errors
    # Measured (when these tests were written): .env 1.2-6.1 %, glTF 1.8-8.0 % against Babylon's own 64² prefilter, whose own
    # 64² → 128² spread is 0.6-4.0 %. The glTF path is further off because Babylon's loader leaves that texture
    # in gamma space, so its mips are blended before the 2.2 power. Mistakes measured the same way: linear RGBD in
    # the glTF (the double gamma) 37-170 %; an .env whose mips hold the glTF loader's roughness per mip (scale 1
    # for 0.8) 14-15 % on the spot probes (7 % on the interior, which this bound would not catch).
    for container, errors in figures.items():
        assert max(errors) < 0.1, (container, errors, spread)


GLOSSY: dict = {}  # probe → (roughnesses, {container: mean relative difference per roughness}, Babylon's spread)
SKYBOX: dict = {}  # probe → (ours, mirrored): difference per view
FILAMENT_SKY: dict = {}  # probe → {"ours"|"x-mirrored": (correlation per view, brightness ratio per view)}
FILAMENT: dict = {}  # probe → (worst axis error of ours, worst error of the z-mirrored numbers), of the mean E/π


# ---- Filament's web build in Chromium ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def filament_page(browser, probes):
    """Filament 1.53 (WebAssembly) with a white rough dielectric sphere loaded through its gltfio."""
    from lightprobe_engines.runtimes import white_sphere_glb

    folder, _ = probes
    white_sphere_glb(folder / "sphere.glb")
    page = browser.page("filament.html")
    assert page.evaluate("u => window.lightprobe.setup(u)", f"{browser.server.url}/files/sphere.glb") == "ok"
    return page


def filament_centre(page, coefficients: np.ndarray, eye) -> float:
    """Luminance of the 10×10 centre pixels of Filament's sphere (linear: no post-processing), centred exactly on
    the image centre, where the normal is the eye direction (half a pixel off is 0.65° there, 2 % of E/π near a
    bright spot)."""
    import base64

    c = 128 // 2
    canvas = page.evaluate("([s, e]) => window.lightprobe.render(s, e)", [coefficients.reshape(-1).tolist(), list(eye)])
    rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(128, 128, 4)
    return float((rgba[c - 5:c + 5, c - 5:c + 5, :3].astype(np.float64) / 255 @ LUMINANCE).mean())


@pytest.mark.parametrize("probe", PROBES)
def test_filament_shades_our_sh_as_the_coefficients_mean(filament_page, browser, probes, probe):
    """Filament's own shader evaluates our sh.txt numbers on a sphere: at the point facing the brightest panorama
    pixel and the opposite one it must show E/π of our radiance SH (evaluated by lightprobe.sh.basis, not by the export
    code) within 3 %, and facing ±x, ±y, ±z within 3 % of the mean E/π (some of those are near zero). Each render
    is scaled so that point sits at 0.5 of the 8-bit range, and a white furnace (E/π = 0.5 everywhere)
    calibrates Filament's constant factors at normal incidence. Filament's web build cannot compute SH from a
    panorama itself (that is its native cmgen), so the reference is what the coefficients mean; the same numbers
    stated in a z-mirrored frame must fail."""
    from lightprobe.exports.sh import filament_coefficients
    from lightprobe.maps.frames import UNITY

    _, files = probes
    env = read_envmap(files[probe])
    sh = project(env, 2)
    image = env.data
    row, col = np.unravel_index(np.argmax(image @ LUMINANCE), image.shape[:2])
    sun = env.directions()[row, col]
    furnace = np.zeros((9, 3))
    furnace[0] = 0.5
    eyes = [sun, -sun] + [np.eye(3)[i] * s for i in range(3) for s in (1, -1)]
    scale = {tuple(e): furnace_value for e, furnace_value in
             ((tuple(e), filament_centre(filament_page, furnace, e) / 0.5) for e in eyes)}
    mean = float(sh.coeffs[0] @ LUMINANCE * np.sqrt(4 * np.pi) / (4 * np.pi))  # E/π of band 0: the mean radiance
    errors = {}
    for label, coefficients in (("ours", filament_coefficients(sh)), ("mirrored", filament_coefficients(sh, UNITY))):
        errors[label] = []
        for i, eye in enumerate(eyes):
            expected = float(sh.to_irradiance().evaluate(eye[None])[0] @ LUMINANCE / np.pi)
            k = 0.5 / expected
            shown = filament_centre(filament_page, k * coefficients, eye) / scale[tuple(eye)] / k
            errors[label].append(abs(shown - expected) / (abs(expected) if i < 2 else mean))
    RESULTS[("Filament 1.53 (Chromium, gltfio shader)", probe)] = (float("nan"), float("nan"), float("nan"),
                                                                   errors["ours"][0], errors["ours"][1])
    FILAMENT[probe] = (max(errors["ours"][2:]), max(errors["mirrored"]))
    assert not browser.errors, browser.errors
    assert max(errors["ours"]) < 0.03, errors["ours"]
    assert max(errors["mirrored"]) > 0.1, errors["mirrored"]


def pinhole_luminance(env: EnvMap, direction, size: int = 128, fov: float = 30.0) -> np.ndarray:
    """What a camera at the centre looking along ``direction`` sees of ``env`` (luminance, rows bottom to top as
    WebGL reads them back): up is +Y, or +Z when looking straight up or down, as the page's lookAt."""
    d = np.asarray(direction, float)
    up = np.array([0.0, 0.0, 1.0]) if abs(d[1]) > 0.9 else np.array([0.0, 1.0, 0.0])
    right = np.cross(d, up)
    right /= np.linalg.norm(right)
    xs = ((np.arange(size) + 0.5) / (size / 2) - 1) * np.tan(np.radians(fov / 2))
    x, y = np.meshgrid(xs, xs)
    rays = d + x[..., None] * right + y[..., None] * np.cross(right, d)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    return env.lookup(rays.reshape(-1, 3)).reshape(size, size, 3) @ LUMINANCE


@pytest.mark.parametrize("probe", ["venice", "interior"])
def test_filament_shows_our_cube_map_where_our_lighting_comes_from(filament_page, browser, probes, probe):
    """lightprobe's cube layout handed to Filament's setImageCube as it is (its Skybox, seen from the centre along
    each axis) shows the environment in the directions our SH lights from (Filament's frame is the world frame):
    block means correlate at 0.95 or more with a pinhole view of that cube looked up in world directions by
    lightprobe, and keep its brightness within 3 %
    (8-bit, so each view is exposed for its own median range and what clips is clipped in the prediction too);
    the same cube mirrored in x does not."""
    import base64

    from lightprobe.maps import resample
    from lightprobe.maps.layouts import CUBE

    _, files = probes
    env = read_envmap(files[probe])
    handed = EnvMap(resample(env, CUBE, 64).data, CUBE)  # the prediction looks up the very cube Filament gets
    pinholes = [pinhole_luminance(handed, view) for view in VIEWS]
    # each view exposed for its own 75th percentile at 0.4 of white, what clips clipped in the prediction too
    gains = [0.4 / float(np.percentile(p, 75)) for p in pinholes]

    def views(rotation):
        cube = resample(env, CUBE, 64, rotation=rotation).data
        rgba = np.concatenate([cube, np.ones(cube.shape[:-1] + (1,), np.float32)], axis=-1).astype(np.float32)
        filament_page.evaluate("([f, n]) => window.lightprobe.setSkybox(f, n)",
                               [base64.b64encode(rgba.tobytes()).decode(), 64])
        shown = []
        for view, gain in zip(VIEWS, gains):
            canvas = filament_page.evaluate("([d, g]) => window.lightprobe.skyView(d, g)", [list(view), gain])
            rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(128, 128, 4)
            shown.append(rgba[..., :3].astype(np.float64) / 255 @ LUMINANCE / gain)
        filament_page.evaluate("() => window.lightprobe.setSkybox(null, 0)")
        return shown

    def blocks(image):
        return image.reshape(16, 8, 16, 8).mean(axis=(1, 3)).ravel()

    expected = [blocks(np.minimum(p, 1 / gain)) for p, gain in zip(pinholes, gains)]
    figures = {}
    for label, rotation in (("ours", None), ("x-mirrored", np.diag([-1.0, 1.0, 1.0]))):
        shown = [blocks(image) for image in views(rotation)]
        figures[label] = ([float(np.corrcoef(a, b)[0, 1]) for a, b in zip(shown, expected)],
                          [float(a.mean() / b.mean()) for a, b in zip(shown, expected)])
    FILAMENT_SKY[probe] = figures
    assert not browser.errors, browser.errors
    correlation, brightness = figures["ours"]
    assert min(correlation) > 0.95 and max(abs(b - 1) for b in brightness) < 0.03, figures["ours"]
    assert min(figures["x-mirrored"][0]) < 0.9, figures["x-mirrored"]


def test_print_the_engine_table():
    """Not a check: the table of figures (run with -s to see it), after the engine tests of this module."""
    def shown(value, unit="%"):
        return "—" if np.isnan(value) else (f"{100 * value:.2f} %" if unit == "%" else f"{value:.2f}°")

    print("\n| engine | probe | coefficients | engine's spread | band-1 angle | E toward light | E away |")
    for (engine, probe), (diff, spread, angle, sun, anti) in sorted(RESULTS.items()):
        print(f"| {engine} | {probe} | {shown(diff)} | {shown(spread)} | {shown(angle, '°')} | {shown(sun)} | "
              f"{shown(anti)} |")
    print("\n| Babylon skybox | probe | our .env, worst view | the wrong .env (world frame; axes: mirrored, turned), "
          "least and most |")
    for probe, (ours, wrong) in sorted(SKYBOX.items()):
        print(f"| 16×16 blocks | {probe} | {shown(max(ours))} | {shown(min(wrong))}, {shown(max(wrong))} |")
    print("\n| Filament | probe | ours, worst of ±x ±y ±z (of mean E/π) | z-mirrored numbers, worst |")
    for probe, (ours, wrong) in sorted(FILAMENT.items()):
        print(f"| 1.53 | {probe} | {shown(ours)} | {shown(wrong)} |")
    print("\n| Filament skybox | probe | ours: worst correlation, worst brightness | x-mirrored: worst correlation |")
    for probe, figures in sorted(FILAMENT_SKY.items()):
        (c, b), (cw, _) = figures["ours"], figures["x-mirrored"]
        print(f"| 1.53 | {probe} | {min(c):.3f}, {100 * max(abs(x - 1) for x in b):.1f} % | {min(cw):.3f} |")
    print("\n| Babylon metal sphere | probe | roughness | our .env | our glTF | Babylon 64² vs 128² |")
    for probe, (roughnesses, figures, spread) in sorted(GLOSSY.items()):
        for i, r in enumerate(roughnesses):
            print(f"| mean |Δ|/mean | {probe} | {r} | {shown(figures['env'][i])} | {shown(figures['glb'][i])} | "
                  f"{shown(spread[i])} |")
    assert json.dumps({str(k): v for k, v in RESULTS.items()})


def test_the_babylon_page_is_bundled_again_when_its_script_or_the_lock_changes(tmp_path):
    """babylon.html runs engines/dist, esbuild's join of babylon_page.mjs and the Babylon modules it imports: a bundle
    whose stamp does not match the script and package-lock.json is built again, with the page's entry points. (In a
    copy of the folder: other test workers may be drawing from the repository's bundle meanwhile.)"""
    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    for name in ("babylon_page.mjs", "package-lock.json"):
        (tmp_path / name).write_bytes((ENGINES / name).read_bytes())
    (tmp_path / "node_modules").symlink_to(ENGINES / "node_modules")
    dist = babylon_bundle(tmp_path)
    stamp = (dist / ".stamp").read_text()
    assert babylon_bundle(tmp_path) == dist and (dist / ".stamp").read_text() == stamp  # fresh: kept
    (dist / ".stamp").write_text("stale")
    assert (babylon_bundle(tmp_path) / ".stamp").read_text() == stamp
    with open(tmp_path / "babylon_page.mjs", "a") as script:
        script.write("\nwindow.changed = true;\n")
    dist = babylon_bundle(tmp_path)
    assert (dist / ".stamp").read_text() != stamp and "window.changed" in (dist / "babylon_page.js").read_text()
    page = (dist / "babylon_page.js").read_text()
    assert "window.lightprobe" in page and "HDRCubeTexture" in page
    assert sorted(p.name for p in tmp_path.iterdir()) == ["babylon_page.mjs", "dist", "node_modules",
                                                        "package-lock.json"]  # nothing left behind
