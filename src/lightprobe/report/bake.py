"""Report section: ``lightprobe bake`` of the probe for every engine — the files (linked), their sizes, the time, the
manifests' accuracy — and, where the engines harness of a checkout is installed, each engine's rendering of our bake
beside its own runtime prefilter of the same panorama."""

from __future__ import annotations

import html
import time
import warnings
from pathlib import Path

import numpy as np

from ..maps.layouts import LATLONG
from .page import Report, engines_missing, table

SIZE = 32  # the specular cube: small, so the bake for every engine takes a few seconds (the engine tests use 64)
SKYBOX = 32  # the skybox's face (a panorama's height): small, the section shows no skybox
ROUGHNESSES = (None, 0.1, 0.3, 0.6, 0.9)  # None: the diffuse sphere
EYE = (0.3, 0.45, 0.85)  # the camera's direction in each engine's own frame, as the engine tests look
SPHERE = 64  # each sphere's picture, pixels
# Babylon's own prefilter takes the panorama's nearest pixel into its cube: at our 32² it misses the sun, so its own
# result is drawn from a cube large enough to hold it
BABYLON_OWN = 128
FOLDER = "bake"  # under the report


def _accuracy(manifest: dict) -> tuple[str, str]:
    """The manifest's SH (or PlayCanvas's ambient) and specular figures as two short texts."""
    accuracy = manifest.get("accuracy", {})
    if "sh" in accuracy:
        sh = accuracy["sh"]
        diffuse = f"SH {100 * sh['relative_median']:.1f} % / {100 * sh['relative_worst']:.1f} %"
    elif "ambient" in accuracy:
        a = accuracy["ambient"]
        diffuse = f"ambient {100 * a['median']:.1f} % / {100 * a['worst']:.1f} %"
    else:
        diffuse = "—"
    levels = [lv for lv in accuracy.get("specular", {}).get("levels", []) if lv.get("measured")]
    specular = (f"{100 * max(lv['median'] for lv in levels):.1f} % / {100 * max(lv['worst'] for lv in levels):.1f} %"
                f" ({len(levels)} levels)" if levels else "—")
    return diffuse, specular


def _strip(images: list[np.ndarray], gains) -> np.ndarray:
    """The spheres side by side, each SPHERE pixels, as linear grey RGB in [0, 1] (``gains`` applied)."""
    out = []
    for image, gain in zip(images, gains):
        k = image.shape[0] // SPHERE
        small = image.reshape(SPHERE, k, SPHERE, k).mean(axis=(1, 3)) if k > 1 else image
        out.append(np.clip(small * gain, 0, 1))
    return np.repeat(np.concatenate(out, axis=1)[..., None], 3, axis=-1).astype(np.float32)


def _exposures(rep: Report) -> list[float]:
    """Per sphere, the factor from radiance to display: 0.8 over the brightest E/π of the probe's SH for the diffuse
    sphere, 0.6 over the brightest texel of the probe's α = 0.09 (roughness 0.3) lobe for the metals (as the engine
    tests expose them), so nothing but the sharpest highlights clips."""
    from ..glossy.prefilter import prefilter_cube
    from ..maps.tonemap import luminance
    from ..sh.irradiance import reference_normals

    diffuse = float(luminance(rep.sh(2).to_irradiance().evaluate(reference_normals(400))).max() / np.pi)
    peak = float(luminance(prefilter_cube(rep.env, 32, [0] + [0.09] * 5).levels[1]).max())
    return [0.8 / diffuse if r is None else 0.6 / peak for r in ROUGHNESSES]


def _renders(rep: Report, folder: Path, gains: list[float]) -> dict:
    """Each engine with a runtime here: its spheres lit by our bake and by its own prefilter of the panorama, as
    luminance images (three.js's unexposed: ``gains`` are applied when the pictures are made)."""
    import tempfile

    from lightprobe_engines.runtimes import Browser, Server, white_sphere_glb
    from lightprobe_engines.spheres import babylon_spheres, filament_spheres, playcanvas_spheres, threejs_spheres

    from ..maps.images import write_image

    unit = [1.0] * len(gains)
    with tempfile.TemporaryDirectory() as served:
        served = Path(served)
        (served / FOLDER).symlink_to(folder.resolve(), target_is_directory=True)
        latlong = rep.env if rep.env.layout is LATLONG else rep.env.to(LATLONG)
        write_image(served / "probe.hdr", latlong.data)  # the panorama each engine's own path reads
        white_sphere_glb(served / "sphere.glb")
        server = Server(served)
        browser = Browser(server)
        url = f"{server.url}/files"
        out = {}
        try:
            t0 = time.perf_counter()
            page = browser.page("three_bake.html")
            out["threejs"] = (threejs_spheres(page, "ours", f"{url}/{FOLDER}/threejs/environment.ktx2", EYE,
                                              ROUGHNESSES[1:], SPHERE),
                              threejs_spheres(page, "pmrem", f"{url}/probe.hdr", EYE, ROUGHNESSES[1:], SPHERE),
                              gains)
            page.close()
            t0 = _lap(rep, "three.js", t0)
            page = browser.page("babylon.html")
            own = babylon_spheres(page, "prefiltered", [f"{url}/probe.hdr", BABYLON_OWN], EYE, gains)
            out["babylon"] = (babylon_spheres(page, "env", [f"{url}/{FOLDER}/babylon/environment.env"], EYE, gains),
                              own, unit)
            out["gltf"] = (babylon_spheres(page, "gltf", [f"{url}/{FOLDER}/gltf/environment.glb"], EYE, gains),
                           own, unit)
            page.close()
            t0 = _lap(rep, "Babylon.js and glTF", t0)
            out["playcanvas"] = (playcanvas_spheres(browser, "baked", [f"{url}/{FOLDER}/playcanvas"], EYE, gains),
                                 playcanvas_spheres(browser, "own", [f"{url}/probe.hdr", 4 * SIZE, SKYBOX], EYE,
                                                    gains), unit)
            t0 = _lap(rep, "PlayCanvas", t0)
            page = browser.page("filament.html")
            page.evaluate("u => window.lightprobe.setup(u)", f"{url}/sphere.glb")
            ours, _ = filament_spheres(page, f"{url}/{FOLDER}/filament/environment_ibl.ktx", EYE, gains)
            out["filament"] = (ours, None, unit)
            _lap(rep, "Filament", t0)
            if browser.errors:
                raise RuntimeError(f"an engine page failed: {browser.errors[0]}")
        finally:
            browser.close()
            server.close()
    return out


def _lap(rep: Report, engine: str, t0: float) -> float:
    now = time.perf_counter()
    rep.timings[f"bake: {engine} drawing the spheres (Chromium)"] = now - t0
    return now


OWN = {"threejs": "its PMREMGenerator of the panorama", "babylon": f"its own GPU prefilter (HDRFiltering), {BABYLON_OWN}²",
       "gltf": f"Babylon's own GPU prefilter, {BABYLON_OWN}²", "playcanvas": f"its own EnvLighting atlas, {4 * SIZE}²"}
RUNTIME = {"threejs": "three.js r187", "babylon": "Babylon.js 9.35", "gltf": "Babylon.js 9.35's glTF loader",
           "playcanvas": "PlayCanvas 2.23", "filament": "Filament 1.53 (web build)"}


def section_bake(rep: Report) -> str:
    """``lightprobe bake --for all`` of the probe into the report's bake/ folder: per engine the files (linked),
    sizes, time and the manifest's accuracy, and the spheres each engine draws from our bake beside its own."""
    from ..bake import BakeOptions, bake
    from ..bake.manifest import read_bake_manifest
    from ..util.names import BAKE_ENGINES

    folder = rep.out / FOLDER
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:  # clipping in RGBD/RGBP: said below, not on the console
        warnings.simplefilter("always")
        bake(rep.env, folder, BakeOptions(BAKE_ENGINES, size=SIZE, skybox_size=SKYBOX), name=rep.probe_name)
    seconds = time.perf_counter() - t0
    rep.timings[f"bake for {len(BAKE_ENGINES)} engines, {SIZE}² cube"] = seconds
    rows, total = [], 0
    for engine in BAKE_ENGINES:
        manifest = read_bake_manifest((folder / engine / "manifest.json").read_bytes())
        files = manifest["files"] + [{"path": "manifest.json",
                                      "bytes": (folder / engine / "manifest.json").stat().st_size}]
        size = sum(f["bytes"] for f in files)
        total += size
        links = ", ".join(f'<a href="{FOLDER}/{engine}/{html.escape(f["path"])}">{html.escape(f["path"])}</a> '
                          f'({f["bytes"]:,} B)' for f in files)
        diffuse, specular = _accuracy(manifest)
        rows.append((engine, links, size, manifest["timings"]["engine"], diffuse, specular))
    head = "".join(f"<th>{h}</th>" for h in ("engine", "files (bytes)", "total", "time", "diffuse: median / worst",
                                             "specular: worst level's median / worst"))
    body = "".join(f"<tr><td>{e}</td><td style='text-align:left'>{links}</td><td>{size:,} B</td>"
                   f"<td>{1000 * t:.0f} ms</td><td>{d}</td><td>{s}</td></tr>"
                   for e, links, size, t, d, s in rows)
    clipped = sorted({str(w.message).split(":")[0] for w in caught})
    text = (f"<h2>Bake</h2><p><code>lightprobe bake --for all --size {SIZE} --skybox-size {SKYBOX}</code> of the "
            f"probe into <a href=\"{FOLDER}/\">{FOLDER}/</a>: {len(BAKE_ENGINES)} folders, {total:,} bytes, "
            f"{seconds:.1f} s (the SH, the lights and each GGX chain computed once and shared; an engine's time is "
            "what it added). Each folder's <code>manifest.json</code> measures the bake against brute force: the "
            "SH's irradiance at 400 normals (PlayCanvas: its ambient rect's E/π), and each prefiltered level at 32 "
            "texels against the direct sum over the probe (relative error on luminance).</p>"
            f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
    if clipped:
        text += ("<p>Clipped by the container's range (the sun is brighter than RGBD/RGBP hold), as the engines' "
                 "own loaders would clip it: " + html.escape("; ".join(clipped)) + ".</p>")
    missing = engines_missing()
    if missing:
        return text + (f"<p>Not drawn here: the engines need {html.escape(', '.join(missing))} "
                       "(<code>bash setup.sh</code> installs them).</p>")
    return text + _pictures(rep, folder)


def _pictures(rep: Report, folder: Path) -> str:
    from lightprobe_engines.spheres import mean_difference

    gains = _exposures(rep)
    t0 = time.perf_counter()
    renders = _renders(rep, folder, gains)
    rep.timings["bake: the engines' spheres (Chromium)"] = time.perf_counter() - t0
    pictures, rows = [], []
    for engine, (ours, own, gain) in renders.items():  # gain: 1 where the engine applied the exposure itself
        name = f"bake_{engine}_ours"
        pictures.append(rep.picture(name, _strip(ours, gain), f"{RUNTIME[engine]}: our bake", exposure=0.0,
                                    curve="srgb", width=5 * SPHERE))
        if own is None:
            rows.append([RUNTIME[engine], ("no prefilter in its web build (the engine tests compare with a brute-force "
                                           "reference in the same container)"), *["—"] * len(ROUGHNESSES)])
            continue
        name = f"bake_{engine}_own"
        pictures.append(rep.picture(name, _strip(own, gain), f"{RUNTIME[engine]}: {OWN[engine]}", exposure=0.0,
                                    curve="srgb", width=5 * SPHERE))
        rows.append([RUNTIME[engine], OWN[engine], *[f"{100 * d:.1f} %" for d in mean_difference(ours, own)]])
    labels = ["diffuse" if r is None else f"metal {r}" for r in ROUGHNESSES]
    return ("<p>Each engine's own runtime draws a white diffuse sphere and white metal spheres (roughness "
            f"{', '.join(str(r) for r in ROUGHNESSES[1:])}) lit by our bake, loaded the way USAGE.md says, beside "
            "the same spheres lit by its own prefilter of the same panorama (Filament's web build has none). The "
            "table gives the mean |Δ| over each sphere relative to the engine's own result; the engine tests hold "
            "these within bounds set beside the engine's own spread between two sizes.</p>"
            '<div class="grid">' + "".join(pictures) + "</div>"
            + table(["engine", "compared with", *labels], rows))
