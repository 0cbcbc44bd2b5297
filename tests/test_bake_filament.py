"""`lightprobe bake --for filament` proven in Filament's own web build (npm ``filament``, WebAssembly, in Chromium).

The baked ``environment_ibl.ktx`` and ``environment_skybox.ktx`` are loaded by Filament's ``createIblFromKtx1`` and
``createSkyFromKtx1``. Filament's web build has no prefilter of its own (``IBLPrefilterContext`` is not in its JS
bindings, filament.d.ts), so the spheres are compared with what the prefiltered radiance should be: the same
spheres lit by a brute-force reference in the same container — each level the direct sum over every texel of a 32²
cube of the probe at cmgen's roughness for that level, and the SH fitted to brute-force irradiance — through the
same loader and shader. The engine's own spread is that reference at two sizes (64² and 32², whose levels carry
different roughnesses that Filament's shader interpolates between). The skybox is looked at along six axes against
pinhole views of the panorama; an x-mirrored bake must fail both the spheres and the skybox.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from conftest import shared
from lightprobe_engines.probes import X_MIRROR as AXES_MIRROR, Y_QUARTER, axis_map
from lightprobe_engines.runtimes import LUMINANCE, Browser, Server, missing_engines, white_sphere_glb
from lightprobe_engines.spheres import canvas_luminance, filament_spheres
from test_engines import pinhole_luminance  # the same camera as the page's skyView

from lightprobe.maps import EnvMap, read_envmap, resample
from lightprobe.maps.layouts import CUBE, LATLONG

pytestmark = pytest.mark.xdist_group("engines")  # one worker, so one browser start for all engine checks

SIZE = 64  # the specular cube: 64, 32, 16 (cmgen stops at 16²)
SKYBOX = 128  # 1.4° texels: a 30° view holds 21 of them across, enough for 16 blocks
REFERENCE = 32  # the brute-force reference sums over a 32² cube: 2.8° texels, under a third of the α = 0.086 lobe
CANVAS = 128
PROBES = {"interior": "polyhaven_1k/st_fagans_interior_1k.hdr", "spot": None}
SPOT = (0.97, 0.1, -0.2)  # world direction of the synthetic probe's spot: in the +x view, and no mirror's
EYE = (0.3, 0.45, 0.85)
ROUGHNESSES = (None, 0.1, 0.3, 0.6, 0.9)  # None: the white diffuse sphere
LEVELS = {"ours_ibl.ktx": (64, 32, 16), "mirrored_ibl.ktx": (64, 32, 16), f"ref{SIZE}_ibl.ktx": (64, 32, 16),
          f"ref{SIZE // 2}_ibl.ktx": (32, 16)}  # cmgen's chains: down to 16²
VIEWS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
X_MIRROR = np.diag([-1.0, 1.0, 1.0])
TABLE: dict = {}  # probe → figures, printed by test_print_the_filament_table


def spot_map() -> np.ndarray:
    """A dim sky with one bright, smooth (Gaussian, 6° wide) spot that no mirror maps onto itself."""
    d = LATLONG.directions(LATLONG.grid_shape(256))
    s = np.asarray(SPOT) / np.linalg.norm(SPOT)
    angle = np.degrees(np.arccos(np.clip(d @ s, -1, 1)))
    # brighter upward and toward +x: no view is uniform, and a mirror in x turns every view's gradient round
    sky = 0.05 + 0.05 * np.clip(d[..., 1:2], 0, 1) + 0.02 * (d[..., :1] + 1)
    return (sky + 40.0 * np.exp(-(angle / 6.0) ** 2)[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32)


def direct_sum(source: EnvMap, r: np.ndarray, alpha: float) -> np.ndarray:
    """P_α(r) = Σ L D_α(h) (r·l)⁺ Δω / Σ D_α(h) (r·l)⁺ Δω over every texel l of ``source`` (n = v = r, so
    r·h = √((1 + r·l)/2)): lightprobe.glossy.prefilter's definition, summed directly in blocks of rows."""
    from lightprobe.glossy.prefilter import ggx_d

    d = source.directions().reshape(-1, 3).astype(np.float32)
    omega = source.solid_angles().reshape(-1).astype(np.float32)
    values = source.data.reshape(-1, 3).astype(np.float64)
    out = np.empty((len(r), 3))
    for start in range(0, len(r), 512):
        cos_l = r[start:start + 512].astype(np.float32) @ d.T
        w = ggx_d(np.sqrt(np.clip((1 + cos_l) / 2, 0, 1)), alpha) * np.maximum(cos_l, 0) * omega
        out[start:start + 512] = (w @ values) / w.sum(axis=1)[:, None]
    return out


def reference_ibl(env: EnvMap, size: int) -> bytes:
    """The IBL KTX1 cmgen's levels would hold, by brute force: each level the direct sum of the GGX lobe at its
    roughness over every texel of a REFERENCE² cube of ``env``; the SH fitted (least squares) to brute-force
    irradiance."""
    from lightprobe.bake.engines.filament import filament_alphas, level_count
    from lightprobe.exports.ktx1 import ktx1_bytes
    from lightprobe.exports.sh import premultiply_basis_constants
    from lightprobe.sh.basis import basis
    from lightprobe.sh.irradiance import brute_irradiance, reference_normals

    source = resample(env, CUBE, REFERENCE)
    levels = []
    for i, alpha in enumerate(filament_alphas(level_count(size))):
        s = size >> i
        if alpha == 0:
            levels.append(resample(env, CUBE, s).data)
            continue
        r = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
        levels.append(direct_sum(source, r, alpha).reshape(6, s, s, 3).astype(np.float32))
    normals = reference_normals(600)
    irradiance = brute_irradiance(env.to(LATLONG, 128), normals)
    fitted = np.linalg.lstsq(basis(2, normals), irradiance, rcond=None)[0]  # E_lm of bands 0-2
    return ktx1_bytes(levels, "r11f_g11f_b10f", sh=premultiply_basis_constants(fitted / np.pi))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Per probe, in the folder the browser serves: our bake's two KTX1 files, the x-mirrored bake's, and the
    brute-force references at 64² and 32²."""
    from lightprobe.bake import BakeOptions, bake

    if missing_engines():
        pytest.fail(f"the engine tests need {', '.join(missing_engines())}: run 'bash setup.sh --test'",
                    pytrace=False)
    folder = tmp_path_factory.mktemp("filament-bake")
    white_sphere_glb(folder / "sphere.glb")
    options = BakeOptions(("filament",), size=SIZE, skybox_size=SKYBOX)
    envs = {}
    for name, rel in PROBES.items():
        env = read_envmap(shared(rel)) if rel else EnvMap(spot_map(), LATLONG)
        envs[name] = env
        mirrored = EnvMap(resample(env, LATLONG, env.grid[0], rotation=X_MIRROR).data, LATLONG)
        for label, e in (("ours", env), ("mirrored", mirrored)):
            baked = bake(e, folder / f"{name}-{label}", options)["filament"]
            for kind in ("ibl", "skybox"):
                shutil.copyfile(baked / f"environment_{kind}.ktx", folder / f"{name}-{label}_{kind}.ktx")
        for size in (SIZE, SIZE // 2):
            (folder / f"{name}-ref{size}_ibl.ktx").write_bytes(reference_ibl(env, size))
    return folder, envs


@pytest.fixture(scope="module")
def page(files):
    folder, _ = files
    server = Server(folder)
    browser = Browser(server)
    p = browser.page("filament.html")
    assert p.evaluate("u => window.lightprobe.setup(u)", f"{server.url}/files/sphere.glb") == "ok"
    yield p, browser
    browser.close()
    server.close()


def test_filament_parses_our_files_as_cmgen_lays_them_out(files):
    """Filament's own Ktx1Bundle (its web build, in Node) reads our IBL as cmgen's: an R11F_G11F_B10F cube of 64²,
    32², 16² (cmgen stops at 16²) whose 'sh' key gives createIblFromKtx1 the numbers of sh.txt; the skybox one level.
    And the roughness per level is cmgen's: a 256² cube holds r = 0, 0.134, 0.293, 0.5, 1 (lodToPerceptualRoughness
    of i/4)."""
    from lightprobe.bake.engines.filament import level_count, perceptual_roughness
    from lightprobe_engines.runtimes import filament_ktx1

    folder, _ = files
    ibl, sky = filament_ktx1([folder / "spot-ours_ibl.ktx", folder / "spot-ours_skybox.ktx"])
    assert ibl["info"]["glInternalFormat"] == 0x8C3A and ibl["cube"] and ibl["levels"] == 3, ibl["info"]
    assert sky["cube"] and sky["levels"] == 1 and sky["info"]["pixelWidth"] == SKYBOX, sky["info"]
    text = (folder / "spot-ours" / "filament" / "sh.txt").read_text()
    numbers = np.array([[float(v) for v in line.split(")")[0].strip("( ").split(",")] for line in text.splitlines()])
    assert np.allclose(np.reshape(ibl["shFloats"], (9, 3)), numbers, rtol=1e-5, atol=1e-7), (ibl["shFloats"], text)
    assert [level_count(s) for s in (16, 32, 64, 256, 1024)] == [5, 2, 3, 5, 7]
    assert np.allclose(perceptual_roughness(5), [0, 1 - np.sqrt(0.75), 1 - np.sqrt(0.5), 0.5, 1])


def luminance(canvas: str) -> np.ndarray:
    """Linear luminance of a canvas the page returned (post-processing is off: the bytes are linear), rows bottom to
    top as the canvas holds them and as pinhole_luminance lays out the panorama's views."""
    return canvas_luminance(canvas, CANVAS, srgb=False)[::-1]


def spheres(page, url: str, gains) -> list[np.ndarray]:
    """The diffuse sphere and the metal ones lit by the IBL file at ``url``, each at its gain."""
    images, info = filament_spheres(page, url, EYE, gains, ROUGHNESSES)
    assert len(info["sh"]) == 27 and info["levels"] == len(LEVELS[url.rsplit("-", 1)[-1]]), info
    return images


def exposures(page, url: str, peak: float) -> list[float]:
    """Per sphere, the gain that puts the 99th-percentile pixel of its render from ``url`` near 0.7 of white, so
    each is measured with most of the 8 bits and little clipping (three rounds from 0.9/peak, where none clips)."""
    page.evaluate("u => window.lightprobe.loadIbl(u)", url)
    gains = []
    for r in ROUGHNESSES:
        gain = 0.9 / peak
        for _ in range(3):
            image = luminance(page.evaluate("([e, g, r]) => window.lightprobe.sphereAt(e, g, r)", [list(EYE), gain, r]))
            gain *= 0.7 / max(float(np.percentile(image[image > 0], 99)), 1 / 255)
        gains.append(gain)
    page.evaluate("() => window.lightprobe.dropIbl()")
    return gains


def differences(images, references) -> list[float]:
    """Mean |Δ| over the sphere's pixels, relative to the reference's mean there."""
    out = []
    for image, reference in zip(images, references):
        mask = (reference > 0) | (image > 0)
        out.append(float(np.abs(image - reference)[mask].mean() / reference[mask].mean()))
    return out


@pytest.mark.parametrize("probe", list(PROBES))
def test_filament_lights_spheres_from_our_bake_as_from_brute_force(page, files, probe):
    """The diffuse sphere and white metal spheres at roughness 0.1, 0.3, 0.6, 0.9, lit by our IBL file through
    createIblFromKtx1, against the brute-force reference (see the module docstring) in the same loader and shader."""
    p, browser = page
    _, envs = files
    url = f"{browser.server.url}/files/{probe}"
    gain = exposures(p, f"{url}-ref{SIZE}_ibl.ktx", float((envs[probe].data @ LUMINANCE).max()))
    reference = spheres(p, f"{url}-ref{SIZE}_ibl.ktx", gain)
    spread = differences(spheres(p, f"{url}-ref{SIZE // 2}_ibl.ktx", gain), reference)
    ours = differences(spheres(p, f"{url}-ours_ibl.ktx", gain), reference)
    mirrored = differences(spheres(p, f"{url}-mirrored_ibl.ktx", gain), reference)
    shown = [float(np.percentile(image[image > 0], 99)) for image in reference]  # how much of the 8 bits is used
    TABLE.setdefault(probe, {})["spheres"] = (ours, spread, mirrored, shown)
    assert not browser.errors, browser.errors
    # Measured (when this test was written): ours 0.0-0.5 % from the brute-force reference at every sphere; the
    # reference's own 64² → 32² spread 0.0 % (diffuse: the same SH) and 0.7-40 % (metal: Filament interpolates
    # between levels of other roughnesses); the x-mirrored bake 7-114 %.
    assert max(ours) < 0.02, (ours, spread)
    assert min(mirrored) > max(0.05, 3 * max(ours)), (mirrored, ours)


def blocks(image: np.ndarray) -> np.ndarray:
    """16×16 block means: the comparison is of where things are, not of detail."""
    return image.reshape(16, CANVAS // 16, 16, CANVAS // 16).mean(axis=(1, 3)).ravel()


def sky_figures(p, url: str, gains, expected) -> tuple[list[float], list[float]]:
    """The skybox file at ``url`` through createSkyFromKtx1, seen along each of VIEWS at its gain: per view, the
    correlation of its block means with ``expected`` and the ratio of their means."""
    p.evaluate("u => window.lightprobe.skyFromKtx1(u)", url)
    shown = [blocks(luminance(p.evaluate("([d, g]) => window.lightprobe.skyView(d, g)", [list(v), g])) / g)
             for v, g in zip(VIEWS, gains)]
    p.evaluate("() => window.lightprobe.skyFromKtx1(null)")
    return ([float(np.corrcoef(a, b)[0, 1]) for a, b in zip(shown, expected)],
            [float(a.mean() / b.mean()) for a, b in zip(shown, expected)])


@pytest.mark.parametrize("probe", list(PROBES))
def test_filament_shows_our_skybox_along_six_axes_as_the_panorama(page, files, probe):
    """Our skybox file through createSkyFromKtx1, seen from the centre along ±x, ±y, ±z, against pinhole views of
    the panorama itself: block means correlate at 0.95 or more and keep the brightness within 5 % (each view
    exposed for its own 75th percentile, what clips clipped in the prediction too); the x-mirrored bake does not."""
    p, browser = page
    _, envs = files
    # the panorama at about the skybox's texel size (256×128): fine detail is not what is compared
    panorama = envs[probe].to(LATLONG, SKYBOX)
    pinholes = [pinhole_luminance(panorama, view) for view in VIEWS]
    gains = [0.4 / float(np.percentile(image, 75)) for image in pinholes]
    expected = [blocks(np.minimum(image, 1 / gain)) for image, gain in zip(pinholes, gains)]
    figures = {label: sky_figures(p, f"{browser.server.url}/files/{probe}-{label}_skybox.ktx", gains, expected)
               for label in ("ours", "mirrored")}
    TABLE.setdefault(probe, {})["skybox"] = figures
    assert not browser.errors, browser.errors
    correlation, brightness = figures["ours"]
    # Measured: ours 0.980 / 3.4 % (interior), 0.997 / 0.7 % (spot); the x-mirrored bake -0.16 and -1.0
    assert min(correlation) > 0.95 and max(abs(b - 1) for b in brightness) < 0.05, figures["ours"]
    assert min(figures["mirrored"][0]) < 0.9, figures["mirrored"]


@pytest.fixture(scope="module")
def axes(files):
    """The axis probe (lightprobe_engines.probes) baked as it is, mirrored in x and turned a quarter about y, the
    skybox files beside the others the browser serves (the IBL at the smallest size: only the sky is looked at)."""
    from lightprobe.bake import BakeOptions, bake

    folder, _ = files
    options = BakeOptions(("filament",), size=16, skybox_size=SKYBOX)
    for label, transform in (("ours", None), ("mirrored", AXES_MIRROR), ("rotated", Y_QUARTER)):
        baked = bake(EnvMap(axis_map(256, transform), LATLONG), folder / f"axes-{label}", options)["filament"]
        shutil.copyfile(baked / "environment_skybox.ktx", folder / f"axes-{label}_skybox.ktx")
    return EnvMap(axis_map(256), LATLONG)


def test_filament_skybox_of_the_axis_probe_fails_every_view_mirrored_or_turned(page, axes):
    """The axis probe's skybox through createSkyFromKtx1 along ±x, ±y, ±z against pinhole views of the probe:
    ours correlates at 0.95 or more with the brightness within 5 %; the bakes of the probe mirrored in x and turned
    a quarter about y correlate under 0.5 in every view."""
    p, browser = page
    pinholes = [pinhole_luminance(axes.to(LATLONG, SKYBOX), view) for view in VIEWS]
    # exposed as the test above: each view's 75th percentile at 0.4 of white, what clips clipped in the prediction
    gains = [0.4 / float(np.percentile(image, 75)) for image in pinholes]
    expected = [blocks(np.minimum(image, 1 / gain)) for image, gain in zip(pinholes, gains)]
    figures = {label: sky_figures(p, f"{browser.server.url}/files/axes-{label}_skybox.ktx", gains, expected)
               for label in ("ours", "mirrored", "rotated")}
    TABLE.setdefault("axes", {})["skybox"] = figures
    assert not browser.errors, browser.errors
    correlation, brightness = figures["ours"]
    # Measured: ours 0.996 or more, brightness within 2.4 %; x-mirrored -0.29 to 0.03 per view, turned -0.22 to
    # -0.16
    assert min(correlation) > 0.95 and max(abs(b - 1) for b in brightness) < 0.05, figures["ours"]
    assert max(figures["mirrored"][0]) < 0.5 and max(figures["rotated"][0]) < 0.5, figures


def test_print_the_filament_table():
    """Not a check: the figures of this module (run with -s to see them)."""
    print("\n| Filament 1.53 | probe | sphere | ours vs brute force | brute force 64² vs 32² | x-mirrored bake | "
          "reference's 99th percentile (of white) |")
    for probe, figures in sorted(TABLE.items()):
        if "spheres" in figures:
            ours, spread, mirrored, shown = figures["spheres"]
            for i, r in enumerate(ROUGHNESSES):
                print(f"| mean |Δ|/mean | {probe} | {'diffuse' if r is None else f'metal {r}'} | "
                      f"{100 * ours[i]:.1f} % | {100 * spread[i]:.1f} % | {100 * mirrored[i]:.1f} % | {shown[i]:.2f} |")
    print("\n| Filament skybox | probe | ours: worst correlation, worst brightness | x-mirrored: worst correlation |")
    for probe, figures in sorted(TABLE.items()):
        if "skybox" in figures:
            (c, b), (cw, _) = figures["skybox"]["ours"], figures["skybox"]["mirrored"]
            print(f"| 6 axes | {probe} | {min(c):.3f}, {100 * max(abs(x - 1) for x in b):.1f} % | {min(cw):.3f} |")
            if "rotated" in figures["skybox"]:
                for label in ("mirrored", "rotated"):
                    c, b = figures["skybox"][label]
                    print(f"| {label}, per view | {probe} | correlation "
                          f"{', '.join(f'{v:.2f}' for v in c)}; brightness {', '.join(f'{v:.2f}' for v in b)} |")
