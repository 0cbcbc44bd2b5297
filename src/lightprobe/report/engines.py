"""Report sections on exports: every engine's numbers, and the exports drawn by the engines themselves (three.js, Babylon.js, Filament) when the engines harness of a checkout is installed."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from ..exports.sh import TARGETS, export
from ..maps.images import write_image
from ..sh.basis import project
from ..util.files import write_text
from .page import Report, engines_missing, figure, table


def section_exports(rep: Report) -> str:
    """The nine coefficients for every engine, written next to the report."""
    folder = rep.out / "exports"
    folder.mkdir(exist_ok=True)
    suffix = {"json": "json", "threejs": "json", "filament": "txt", "unity": "cs", "gltf": "json",
              "babylon": "json", "glsl": "glsl"}
    links = []
    for target in TARGETS:
        path = folder / f"{target}.{suffix[target]}"
        write_text(path, export(rep.sh(2), target, csharp=suffix[target] == "cs"))
        links.append(f'<li><a href="exports/{path.name}">{target}</a></li>')
    return ("<h2>Exports</h2><p>The same nine coefficients converted to each engine's frame, sign convention and "
            "scaling (each checked in the test suite with that engine's own reconstruction formula against a "
            "white furnace and an analytic point light):</p><ul>" + "".join(links) + "</ul>")


def _three_figures(page, url: str, ours_json: str) -> tuple[dict, dict]:
    """three.js's own SH of the panorama at ``url`` and its reading of our LightProbe JSON, with the figures."""
    from lightprobe_engines.runtimes import (
        LUMINANCE,
        band1_angle,
        coefficient_difference,
        relative,
    )

    engine = np.array(page.evaluate("([u, n]) => window.lightprobe.shFromPanorama(u, n)", [url, 512])).reshape(9, 3)
    mine = np.array(page.evaluate("t => window.lightprobe.probeFromJSON(t)", ours_json)).reshape(9, 3)
    sun = mine[[3, 1, 2]].T @ LUMINANCE  # three.js: coefficients 3, 1, 2 are x, y, z
    sun /= np.linalg.norm(sun)
    e = {k: np.array(page.evaluate("([c, n]) => window.lightprobe.irradiance(c, n)",
                                   [c.reshape(-1).tolist(), [sun.tolist(), (-sun).tolist()]]))
         for k, c in (("ours", mine), ("engine", engine))}
    figures = {"coefficients": coefficient_difference(mine, engine), "angle": band1_angle(mine, engine, (3, 1, 2)),
               "toward": relative(e["ours"][0], e["engine"][0]), "away": relative(e["ours"][1], e["engine"][1])}
    return {"ours": mine, "three.js": engine, "peak": float(e["engine"][0] @ LUMINANCE)}, figures


def _babylon_figures(panorama: Path, ours_json: str) -> dict:
    """Babylon.js's own polynomial of the panorama file against ours, both through its default shader path."""
    from lightprobe_engines.runtimes import (
        LUMINANCE,
        babylon,
        babylon_irradiance_over_pi,
        band1_angle,
        coefficient_difference,
        relative,
    )

    answer = babylon({"engine": {"panorama": str(panorama.resolve()), "size": 512}, "ours": {"export": ours_json}})
    engine, mine = (np.array(answer[k]["preScaledHarmonics"]) for k in ("engine", "ours"))
    sun = np.array(answer["engine"]["brightest"])
    return {"coefficients": coefficient_difference(mine, engine),
            "angle": band1_angle(mine, engine, (3, 1, 2), (-1, -1, 1)),
            "toward": relative(babylon_irradiance_over_pi(mine, sun), babylon_irradiance_over_pi(engine, sun)),
            "away": relative(babylon_irradiance_over_pi(mine, -sun), babylon_irradiance_over_pi(engine, -sun)),
            "sun": sun, "peak": float(babylon_irradiance_over_pi(engine, sun) @ LUMINANCE)}


def section_engines(rep: Report) -> str:
    """The exports in the engines' own code: three.js in headless Chromium draws a white sphere lit by our
    LightProbe and by the LightProbe it computes itself from the same panorama file; Babylon.js in Node computes its
    own polynomial from that file and reads ours."""
    import base64
    import json

    from lightprobe_engines.runtimes import Browser, Server

    from ..maps import read_envmap
    from ..util.files import write_bytes

    title = "<h2>Exports in the engines themselves</h2>"
    missing = engines_missing()
    if missing:  # only a missing engine is excused; a failing one fails the report
        return title + f"<p>Not run here: it needs {html.escape(', '.join(missing))} (<code>bash setup.sh</code> " \
                       "installs them).</p>"
    folder = rep.out / "engines"
    folder.mkdir()
    latlong = rep.env if rep.env.layout.name == "latlong" else rep.env.to("latlong")
    panorama = write_image(folder / "probe.hdr", latlong.data)  # the one file both the engine and lightprobe read
    sh = project(read_envmap(panorama), 2)
    server = Server(folder)
    browser = Browser(server)
    try:
        page = browser.page("three.html")
        version = page.evaluate("window.lightprobe.version")
        lights, three = _three_figures(page, f"{server.url}/files/probe.hdr", export(sh, "threejs"))
        exposure = 0.55 / max(lights["peak"] / np.pi, 1e-9)
        pictures = []
        for back in (False, True):
            for label in ("ours", "three.js"):
                url = page.evaluate("([c, s, e, b]) => window.lightprobe.renderSphere(c, s, e, b)",
                                    [lights[label].reshape(-1).tolist(), 256, exposure, back])
                name = f"engine_three_{'ours' if label == 'ours' else 'own'}_{'back' if back else 'front'}"
                write_bytes(rep.out / f"{name}.png", base64.b64decode(url.split(",", 1)[1]))
                side = "−Z" if back else "+Z"
                lit = "our export" if label == "ours" else "its own SH"
                pictures.append(figure(name, f"three.js r{version}: {lit}, from {side}", 200))
        babylon = _babylon_figures(panorama, export(sh, "babylon"))
        page = browser.page("babylon.html")
        polynomial = json.loads(export(sh, "babylon"))["polynomial"]
        # toward the light, away from it, and the container spheres' view, all from one load of each environment
        eyes = (babylon["sun"], -babylon["sun"], CONTAINER_EYE_LIFT + 0.6 * babylon["sun"])
        views = [{"eye": eye.tolist(), "exposure": 0.5 / babylon["peak"], "roughness": None} for eye in eyes]
        shots = {"ours": page.evaluate("([p, v]) => window.lightprobe.views('polynomial', [p], v, true)",
                                       [polynomial, views[:2]]),
                 "Babylon": page.evaluate("([u, v]) => window.lightprobe.views('panorama', [u, 512], v, true)",
                                          [f"{server.url}/files/probe.hdr", views])}
        for away in (False, True):
            for label in ("ours", "Babylon"):
                name = f"engine_babylon_{'ours' if label == 'ours' else 'own'}_{'away' if away else 'toward'}"
                write_bytes(rep.out / f"{name}.png", base64.b64decode(shots[label][away].split(",", 1)[1]))
                lit = "our polynomial" if label == "ours" else "its own HDRCubeTexture"
                pictures.append(figure(name, f"Babylon.js PBR: {lit}, {'away from' if away else 'toward'} the light",
                                       200))
        containers, container_text = _babylon_containers(rep, page, server, folder, sh, babylon, shots["Babylon"][2])
        pictures += _filament_spheres(rep, browser, server, folder, sh, babylon["sun"] * np.array([1, 1, -1]))
    finally:
        browser.close()
        server.close()
    rows = [[name, f"{100 * f['coefficients']:.2f} %", f"{f['angle']:.2f}°", f"{100 * f['toward']:.2f} %",
             f"{100 * f['away']:.2f} %"] for name, f in ((f"three.js r{version} (Chromium)", three),
                                                       ("Babylon.js 9.35 (Node, default SH path)", babylon))]
    return (title + "<p>Each engine reads the probe's panorama file the way its users load it and computes its own "
            "lighting; lightprobe's export of the same file is read by the engine too. Spheres: three.js draws a "
            "white Lambertian sphere with a <code>LightProbe</code> — ours, then its own, seen from three.js's +Z and −Z; "
            "Babylon's default PBR shader draws a white diffuse sphere from our polynomial and from its own "
            "<code>HDRCubeTexture</code> of the file, seen from the light and from the opposite side. The "
            "table gives the largest coefficient difference (relative to L00), the angle between the band-1 "
            "directions, and the irradiance the engine computes toward the light and away from it (the suite "
            "requires 3 %, 3° on five probes). Babylon samples panoramas at the nearest pixel, which under-counts "
            "a small sun; three.js decodes RGBE mantissas /255, a +0.4 % of its own. Filament's web build "
            "(WebAssembly, gltfio's shader) draws the sphere from our <code>sh.txt</code>; it has no panorama → SH "
            "path of its own (that is the native cmgen), so the suite holds it to what the numbers mean: E/π "
            "toward and away from the light within 3 %.</p>"
            '<div class="grid">' + "".join(pictures) + "</div>"
            + table(["engine", "coefficients", "band-1 angle", "E toward the light", "E away"], rows)
            + container_text + '<div class="grid">' + "".join(containers) + "</div>")


CONTAINER_EYE_LIFT = np.array([0.0, 0.4, 0.0])  # the container spheres are seen from 0.6 × the light's side + this


CONTAINER_SIZE = 64  # the report's .env and .glb (as the engine tests'): Babylon's own GPU prefilter of the


def _filament_spheres(rep: Report, browser, server, folder: Path, sh, sun: np.ndarray) -> list[str]:
    """Filament's web build drawing a white rough sphere lit by our sh.txt, from the light and from the opposite
    side (Filament's web build has no panorama → SH path of its own: that is its native cmgen)."""
    import base64

    from lightprobe_engines.runtimes import white_sphere_glb

    from ..exports.sh import filament_coefficients

    white_sphere_glb(folder / "sphere.glb")
    page = browser.page("filament.html")
    page.evaluate("u => window.lightprobe.setup(u)", f"{server.url}/files/sphere.glb")
    coefficients = filament_coefficients(sh)
    peak = float(sh.to_irradiance().evaluate(sun[None])[0].max() / np.pi)
    pictures = []
    for away in (False, True):
        eye = (-sun if away else sun).tolist()
        canvas = page.evaluate("([s, e]) => window.lightprobe.render(s, e)",
                               [(0.8 / peak * coefficients).reshape(-1).tolist(), eye])
        rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(128, 128, 4)[::-1]
        linear = rgba[..., :3].astype(np.float32) / 255  # Filament's output without post-processing is linear
        name = f"engine_filament_ours_{'away' if away else 'toward'}"
        write_image(rep.out / f"{name}.png", linear)  # sRGB-encoded for display, as every picture of the report
        pictures.append(figure(name, f"Filament 1.53: our sh.txt, {'away from' if away else 'toward'} the light", 200))
    return pictures


def _babylon_containers(rep: Report, page, server, folder: Path, sh, babylon: dict,
                        own_diffuse: str) -> tuple[list[str], str]:
    """Our .env and .glb of the probe in Babylon: a white metal sphere (roughness 0.3) from our .env's mips beside
    one from Babylon's own GPU prefilter of the panorama, and the diffuse sphere from our .glb through its glTF
    loader beside ``own_diffuse``, the one from its own HDRCubeTexture (a PNG data URL, drawn with the section's
    other views of that texture)."""
    import base64
    import io
    import warnings

    from PIL import Image

    from ..exports.containers import babylon_env, glb, gltf_ibl
    from ..glossy.prefilter import prefilter_cube
    from ..maps import read_envmap
    from ..maps.tonemap import srgb_decode
    from ..util.files import write_bytes

    env = read_envmap(folder / "probe.hdr")
    with warnings.catch_warnings():  # the sun's RGBD clipping is said in the text below
        warnings.simplefilter("ignore")
        env_bytes = babylon_env(env, sh, CONTAINER_SIZE)
        glb_bytes = glb(*gltf_ibl(env, sh, CONTAINER_SIZE))
    exports = rep.out / "exports"
    exports.mkdir(exist_ok=True)
    for name, data in (("probe.env", env_bytes), ("probe.glb", glb_bytes)):
        write_bytes(exports / name, data)
        write_bytes(folder / name, data)
    url = f"{server.url}/files/"
    peak = float(prefilter_cube(env, 32, [0] + [0.09] * 5).levels[1].max())
    eye = (CONTAINER_EYE_LIFT + 0.6 * babylon["sun"]).tolist()
    shots, pictures, images = [
        ("engine_babylon_env_metal", "env", [url + "probe.env"], 0.3, "our .env, metal roughness 0.3"),
        ("engine_babylon_own_metal", "prefiltered", [url + "probe.hdr", CONTAINER_SIZE], 0.3,
         "its own prefilter, metal roughness 0.3"),
        ("engine_babylon_glb_diffuse", "gltf", [url + "probe.glb"], None, "our .glb through its glTF loader"),
        ("engine_babylon_own_diffuse", None, None, None, "its own HDRCubeTexture")], [], {}
    for name, source, args, roughness, caption in shots:
        exposure = 0.6 / peak if roughness is not None else 0.5 / babylon["peak"]
        call = "([s, a, e, x, r]) => window.lightprobe.sphere(s, a, e, x, r, true)"
        data_url = own_diffuse if source is None else page.evaluate(call, [source, args, eye, exposure, roughness])
        png = base64.b64decode(data_url.split(",", 1)[1])
        write_bytes(rep.out / f"{name}.png", png)
        pictures.append(figure(name, f"Babylon.js PBR: {caption}", 200))
        images[name] = srgb_decode(np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float32) / 255).mean(-1)

    def difference(a, b):
        inside = images[b] > 0
        return float(np.abs(images[a] - images[b])[inside].mean() / images[b][inside].mean())

    text = (f"<p>The environment itself in Babylon's containers (<a href=\"exports/probe.env\">probe.env</a>, "
            f"<a href=\"exports/probe.glb\">probe.glb</a>, {CONTAINER_SIZE}² GGX-prefiltered mips in RGBD beside the "
            "SH): Babylon loads each the way its users do. Metal sphere from our mips against Babylon's own GPU "
            f"prefilter of the panorama: mean |Δ| {100 * difference('engine_babylon_env_metal', 'engine_babylon_own_metal'):.1f} %"
            " of the mean; diffuse sphere through its glTF loader against its own panorama: "
            f"{100 * difference('engine_babylon_glb_diffuse', 'engine_babylon_own_diffuse'):.1f} %. RGBD stops at 255, "
            "so the sharpest mips clip the sun (the blurrier mips and the SH keep it).</p>")
    return pictures, text
