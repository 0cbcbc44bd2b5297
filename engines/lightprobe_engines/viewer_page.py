"""The viewer's page in headless Chromium (Playwright driving Debian's ``chromium``, SwiftShader WebGL2): what the
tests, the demo and the benchmark read back from the GPU.

Read-backs are linear radiance straight from the page's float render targets (no tone mapping), turned top-down
as numpy images are; alpha says what a pixel shows (0 background, 1 objects, 2 the ground).
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from lightprobe.util.errors import LightprobeError
from lightprobe.viewer.server import ViewServer

from .runtimes import launch_chromium, require_engines

def _image(answer: dict) -> np.ndarray:
    data = np.frombuffer(base64.b64decode(answer["rgba"]), dtype="<f4")
    return data.reshape(answer["height"], answer["width"], 4)[::-1].copy()


class StaticHost:
    """Any static web server, for a ``--export`` folder: the standard library's, on 127.0.0.1, nothing added."""

    def __init__(self, folder: Path):
        import functools
        import http.server
        import threading

        class Quiet(http.server.SimpleHTTPRequestHandler):
            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(folder)))
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/"

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


class ViewerPage:
    """One page in one headless Chromium, from lightprobe's server on a ``bake`` folder, or from a plain static
    server on an exported ``site``; close() (or ``with``) stops both."""

    def __init__(self, bake: Path | None = None, width: int = 900, height: int = 600, site: Path | None = None):
        require_engines()
        from playwright.sync_api import sync_playwright

        self.server = ViewServer(bake) if site is None else StaticHost(site)
        self.errors: list[str] = []
        try:
            self.playwright = sync_playwright().start()
            self.browser = launch_chromium(self.playwright)
            # Playwright's waiting helpers evaluate strings, which the page's own CSP forbids: the driver (not the
            # page) is let through; tests/test_viewer.py checks the CSP itself on the server's answers.
            self.page = self.browser.new_page(viewport={"width": width, "height": height}, bypass_csp=True)
            self.page.on("pageerror", lambda e: self.errors.append(str(e)))
            self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
            self.page.goto(self.server.url)
            self.page.wait_for_function("window.ready === true || window.failed !== undefined", timeout=120000)
            failed = self.page.evaluate("window.failed")
            if failed:
                raise LightprobeError(f"the viewer's page failed to start: {failed.splitlines()[0]}")
        except BaseException:
            self.close()
            raise

    def render(self, method: str, camera: dict | None = None, width: int = 128, height: int = 128, **state
               ) -> np.ndarray:
        """(H, W, 4) float32: linear RGB of one frame of ``method`` and alpha (0 background, 1 objects, 2 ground)."""
        options = {"method": method, "width": width, "height": height, **state}
        if camera is not None:
            options["camera"] = camera
        return _image(self.page.evaluate("(o) => window.lightprobe.render(o)", options))

    def synthesize(self, view, brdf: int = 0, stride: int = 1) -> np.ndarray:
        """The GPU-synthesised radiance map (S, S, 3) for unit ``view`` (world), top row first as the baked maps."""
        answer = self.page.evaluate("(o) => window.lightprobe.synthesize(o)",
                                    {"brdf": brdf, "view": [float(v) for v in view], "stride": stride})
        return _image(answer)[..., :3]

    def frame_time(self, method: str, size: int = 512, frames: int = 5, brdf: int = 0, ground: bool = True
                   ) -> float:
        """Median milliseconds per frame of ``method`` on a size² canvas, tone mapped to the screen (``ground``:
        whether the ground plane is drawn)."""
        return float(self.page.evaluate("(o) => window.lightprobe.frameTime(o)",
                                        {"method": method, "brdf": brdf, "width": size, "height": size,
                                         "frames": frames, "ground": ground}))

    def screenshot(self, path: Path, **state) -> Path:
        """A PNG of the whole page (panel included) in ``state`` (method, brdf, rotation, exposure, design …)."""
        self.page.evaluate("(s) => window.lightprobe.setState(s)", state)
        self.page.screenshot(path=str(path))
        return Path(path)

    def close(self) -> None:
        for stop in (lambda: self.browser.close(), lambda: self.playwright.stop(), self.server.close):
            try:
                stop()
            except Exception:  # already closed or never started
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
