"""The engines themselves, for the tests and the demo: three.js in headless Chromium (Playwright driving Debian's
``chromium``) and Babylon.js in Node, from the npm packages pinned in the repository's ``engines/package.json``
(installed by ``setup.sh``; never copied into the repository).

Nothing here computes lighting: the page and the script in ``engines/`` call the engines' own functions; this module
only serves files, starts the browser once, and compares what comes back (coefficients relative to L00, band-1
angles, irradiance ratios, all on Rec. 709 luminance).
"""

from __future__ import annotations

import http.server
import os
import json
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np

from lightprobe.util.errors import LightprobeError

# This package lives in the repository's engines/ folder, beside the npm packages it runs (never in a wheel).
ENGINES = Path(os.environ.get("LIGHTPROBE_ENGINES", Path(__file__).resolve().parents[1]))
CHROMIUM = "/usr/bin/chromium"
# SwiftShader for WebGL2; no sandbox (root in CI); none of Chromium's own network traffic, which this machine's closed
# network refuses
CHROMIUM_ARGS = ["--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--no-sandbox",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"]


def launch_chromium(playwright):
    """Debian's Chromium, headless, through a started Playwright (never a browser Playwright downloads)."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
PACKAGES = ("three", "@babylonjs/core", "@babylonjs/loaders", "filament", "esbuild", "ktx-parse", "playcanvas")  # pinned in engines/package.json
BABYLON_PAGE = "babylon_page.mjs"  # babylon.html's script, served bundled from engines/dist (see babylon_bundle)


def missing_engines() -> list[str]:
    """What is missing to run the engines here (empty when everything is installed)."""
    try:
        import playwright  # noqa: F401
        has_playwright = True
    except ImportError:
        has_playwright = False
    return [what for what, ok in (
        ("engines/node_modules (npm ci in engines/)",
         all((ENGINES / "node_modules" / package).is_dir() for package in PACKAGES)),
        ("node", shutil.which("node") is not None), (CHROMIUM, Path(CHROMIUM).exists()),
        ("the playwright package", has_playwright)) if not ok]


def require_engines() -> None:
    """Raise a one-line error naming what to install when the engines are not there."""
    missing = missing_engines()
    if missing:
        raise LightprobeError(f"the engine checks need {', '.join(missing)}: run 'bash setup.sh'")


def babylon_bundle(engines: Path = ENGINES, page: str = BABYLON_PAGE, folder: str = "dist") -> Path:
    """``engines/dist`` (of the repository's engines folder unless given): babylon.html's script (:data:`BABYLON_PAGE`;
    another ``page`` into another ``folder``, e.g. prefilter_peers.mjs into dist-prefilter)
    bundled by esbuild (pinned in package.json) with the Babylon.js modules it imports, so Chromium fetches one file
    and the shader chunks a scene asks for instead of ~750 modules, each found only once its importer has arrived (a
    page load here: 3.0–3.5 s → 1.0 s). Built again when the script or package-lock.json changes (a stamp of both),
    into a folder of its own renamed into place, so parallel test workers never read half a bundle. Babylon's own
    code either way: esbuild only joins its files."""
    import hashlib
    import secrets

    dist = engines / folder
    stamp = hashlib.sha256(b"".join((engines / name).read_bytes() for name in (page, "package-lock.json")))
    stamp = stamp.hexdigest()[:16]
    if (dist / ".stamp").is_file() and (dist / ".stamp").read_text() == stamp:
        return dist
    building = engines / f".dist-{os.getpid()}-{secrets.token_hex(4)}"
    # --ignore-annotations: Babylon's package.json declares which of its files have side effects and leaves out the
    # .env loader, which registers itself on import; esbuild would drop that import otherwise
    result = subprocess.run([str(engines / "node_modules" / ".bin" / "esbuild"), page, "--bundle",
                             "--format=esm", "--splitting", "--ignore-annotations", f"--outdir={building.name}",
                             "--log-level=error"], cwd=engines, capture_output=True, text=True)
    if result.returncode:
        shutil.rmtree(building, ignore_errors=True)
        raise LightprobeError(f"esbuild could not bundle engines/{page}: {result.stderr.strip()[:300]}")
    (building / ".stamp").write_text(stamp)
    old = engines / f".dist-old-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        if dist.exists():
            os.replace(dist, old)
        os.replace(building, dist)
    except OSError:  # another process put its bundle in place meanwhile: the same files
        shutil.rmtree(building, ignore_errors=True)
    shutil.rmtree(old, ignore_errors=True)
    return dist


class Server:
    """A static file server on 127.0.0.1: /engines/… from the repository's engines folder, /files/… from ``files``."""

    def __init__(self, files: Path):
        engines, files = str(ENGINES), str(files)

        class Handler(http.server.SimpleHTTPRequestHandler):
            def translate_path(self, path):
                path = path.split("?", 1)[0]
                for prefix, folder in (("/engines/", engines), ("/files/", files)):
                    if path.startswith(prefix):
                        return str(Path(folder) / path[len(prefix):])
                return str(Path(files) / "nothing-here")

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"

    def close(self):
        self.httpd.shutdown()


class Browser:
    """One headless Chromium (SwiftShader WebGL2) for all engine checks."""

    def __init__(self, server: Server):
        from playwright.sync_api import sync_playwright

        self.playwright = sync_playwright().start()
        self.browser = launch_chromium(self.playwright)
        self.server = server
        self.errors: list[str] = []

    def page(self, name: str):
        if name == "babylon.html":
            babylon_bundle()
        page = self.browser.new_page()
        page.on("pageerror", lambda e: self.errors.append(str(e)))
        page.goto(f"{self.server.url}/engines/{name}")
        page.wait_for_function("window.ready === true", timeout=60000)
        return page

    def close(self):
        self.browser.close()
        self.playwright.stop()


def white_sphere_glb(path: Path) -> Path:
    """A unit sphere (icosphere, 20k triangles, smooth normals) with a white rough dielectric glTF material, for
    engines that draw only glTF assets (Filament's gltfio)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    sphere.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        baseColorFactor=[255, 255, 255, 255], metallicFactor=0.0, roughnessFactor=1.0))
    sphere.export(path)
    return Path(path)


def babylon(jobs: dict) -> dict:
    """Run ../engines/babylon_sh.mjs in Node on ``jobs`` (see that file) and return its answer."""
    res = subprocess.run(["node", str(ENGINES / "babylon_sh.mjs")], input=json.dumps(jobs), capture_output=True,
                         text=True, cwd=ENGINES, timeout=300)
    if res.returncode != 0:
        raise RuntimeError(f"Babylon.js in Node failed: {res.stderr[-2000:]}")
    return json.loads(res.stdout)


def _node_json(script: str, paths, what: str):
    res = subprocess.run(["node", str(ENGINES / script), *map(str, paths)], capture_output=True, text=True,
                         cwd=ENGINES, timeout=300)
    if res.returncode != 0:
        raise RuntimeError(f"{what} in Node failed: {res.stderr[-2000:]}")
    return json.loads(res.stdout)


def ktx_parse(paths) -> list[dict]:
    """Each KTX2 file as npm ktx-parse reads it (../engines/ktx_parse_check.mjs: header, descriptor, key/values and
    the levels' stored bytes in base64)."""
    return _node_json("ktx_parse_check.mjs", paths, "ktx-parse")


def filament_ktx1(paths) -> list[dict]:
    """Each KTX1 file as Filament's web build parses it in Node (../engines/filament_ktx1_check.mjs: Ktx1Bundle's
    info, levels, cube flag, the "sh" metadata and the 27 numbers createIblFromKtx1 takes from it, each level's
    blob in base64)."""
    return _node_json("filament_ktx1_check.mjs", paths, "Filament's Ktx1Bundle")


# ---- comparisons ----------------------------------------------------------------------------------------------------
def coefficient_difference(ours: np.ndarray, engine: np.ndarray) -> float:
    """max |Δc| over the nine coefficients and three channels, relative to the engine's L00 of that channel."""
    return float((np.abs(ours - engine) / np.abs(engine[0])).max())


def band1_angle(ours: np.ndarray, engine: np.ndarray, axes: tuple[int, int, int], signs=(1, 1, 1)) -> float:
    """Angle (degrees) between the luminance band-1 vectors; ``axes`` are the flat indices holding x, y, z."""
    def vector(c):
        return np.array([signs[k] * c[axes[k]] @ LUMINANCE for k in range(3)])

    a, b = vector(ours), vector(engine)
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))))


def babylon_irradiance_over_pi(pre_scaled: np.ndarray, n) -> np.ndarray:
    """E/π at unit normal ``n`` (Babylon's frame) as Babylon's computeEnvironmentIrradiance evaluates its
    ``preScaledHarmonics`` (9 × RGB, numbers Babylon made): the bare polynomials 1, y, z, x, yx, yz, 3z²−1, zx,
    x²−y²."""
    x, y, z = n
    return np.array([1, y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y]) @ pre_scaled


def relative(a: np.ndarray, b: np.ndarray) -> float:
    """|a − b| / b on luminance."""
    return float(abs((a - b) @ LUMINANCE) / abs(b @ LUMINANCE))


def lit_side(image: np.ndarray) -> np.ndarray:
    """Where a sphere in ``image`` (luminance, 0 off the sphere) is lit: the centroid (x, y, pixels) of its
    brightest fifth."""
    lit = image > np.percentile(image[image > 0], 80)
    rows, cols = np.nonzero(lit)
    return np.array([cols.mean(), rows.mean()])
