"""Report section on ``lightprobe view``: the exported page, screenshots of each method."""

from __future__ import annotations

import html
import time
from pathlib import Path

from ..util.errors import LightprobeError
from .glossy import GLOSSY_DEMO
from .page import Report, engines_missing, figure, table

VIEWER_STATES = [  # (file name, caption, page state): what the viewer section shows, each taken from the live page
    ("viewer-sh", "eq. 13 per pixel (Ramamoorthi & Hanrahan)", {"method": "sh"}),
    ("viewer-sh-vertex", "eq. 13 per vertex, the paper's hardware path", {"method": "sh-vertex"}),
    ("viewer-threejs", "three.js's own LightProbe fed the threejs export", {"method": "threejs"}),
    ("viewer-lights", "area lights with PCSS soft shadows + ambient SH (Arbree et al.)", {"method": "lights"}),
    ("viewer-rsibr", "RS-IBR: one map per frame synthesised on the GPU, gold GGX α 0.3", {"method": "rsibr"}),
    ("viewer-rsibr-pixel", "RS-IBR, each pixel's own view", {"method": "rsibr-pixel"}),
    ("viewer-splitsum", "split sum, gold GGX α 0.3", {"method": "splitsum"}),
    ("viewer-basis", "the basis function Y10 on the objects", {"method": "basis", "basis": 2}),
    ("viewer-design", "lighting design: L1−1 ×3 and L11 ×−1 (the sliders), the environment turned 120°",
     {"method": "sh", "design": [1, 3, 1, -1, 1, 1, 1, 1, 1], "rotation": 120}),
]


def _viewer_bake(rep: Report) -> dict:
    """The viewer's bake of the probe (SH, lights, 12 radiance maps, split sum: compiled kernels) exported as a static
    site into ``viewer/`` beside the report; returns the bake's document."""
    import tempfile

    from ..viewer.bake import BakeOptions, bake
    from ..viewer.server import export_static

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=rep.out) as temp:
        doc = bake(rep.env, Path(temp) / "bake", None, BakeOptions(brdfs=(GLOSSY_DEMO[0],), map_size=32),
                   source=rep.probe_name)
        export_static(Path(temp) / "bake", rep.out / "viewer")
    rep.timings["viewer bake (SH, lights, 12 radiance maps 32², split sum) and static export"] = \
        time.perf_counter() - t0
    return doc


def _viewer_shots(rep: Report) -> tuple[list[str], list[list]]:
    """A screenshot of each of VIEWER_STATES from the exported site in headless Chromium, and its frame time: the
    figures and the table rows. Chromium and file serving only, no compiled kernel, so it may run in a thread of its
    own."""
    from lightprobe_engines.viewer_page import ViewerPage

    t0 = time.perf_counter()
    figures, rows = [], []
    with ViewerPage(site=rep.out / "viewer", width=600, height=330) as page:
        exposure = round(rep.exposure, 1)
        for name, caption, state in VIEWER_STATES:
            full = {"brdf": 0, "rotation": 0, "design": [1] * 9, "exposure": exposure, **state}
            shot = page.page.locator("#view") if name != "viewer-sh" else page.page
            page.page.evaluate("(s) => window.lightprobe.setState(s)", full)
            shot.screenshot(path=str(rep.out / f"{name}.png"))
            ms = page.page.evaluate("window.lightprobe.viewer.frameMs")
            rows.append([caption, f"{ms:.0f} ms"])
            figures.append(figure(name, caption))
        errors = [e for e in page.errors if "404" not in e]
    if errors:
        raise LightprobeError(f"the viewer's page reported an error: {errors[0].splitlines()[0]}")
    rep.timings["viewer screenshots (headless Chromium, SwiftShader)"] = time.perf_counter() - t0
    return figures, rows


def _viewer_started(rep: Report, beside) -> tuple:
    """The viewer's bake here, then its screenshots submitted to the executor ``beside``: (the bake's document, the
    screenshots' future)."""
    doc = _viewer_bake(rep)
    return doc, beside.submit(_viewer_shots, rep)


def section_viewer(rep: Report, started: tuple | None = None) -> str:
    """``lightprobe view``: the bake exported as a static folder beside the report, opened through a plain static
    server in headless Chromium, and a screenshot of each method and control state taken from the live page.
    ``started``: :func:`_viewer_started`'s (bake, screenshots under way), when the report took them beside the
    engines section."""
    title = "<h2>The viewer: <code>lightprobe view</code></h2>"
    missing = engines_missing()
    if missing:
        return title + f"<p>Not run here: it needs {html.escape(', '.join(missing))} (<code>bash setup.sh</code>).</p>"
    doc, shots = started if started is not None else (_viewer_bake(rep), None)
    figures, rows = shots.result() if shots is not None else _viewer_shots(rep)
    return (title + "<p>The page (WebGL2; three.js from npm for the scene and the loop, lightprobe's own shaders "
            "for the lighting) with the bake of this probe — "
            f"{doc['lights']['count']} area lights, 12 radiance maps of {html.escape(doc['brdfs'][0]['spec'])} — "
            "exported by "
            "<code>lightprobe view --export</code> into <code>viewer/</code> beside this report. Module scripts "
            "need HTTP: serve it with <code>python3 -m http.server -d viewer</code> and open the address it prints. "
            "Each picture below is that exported page, served by a plain static server and drawn by headless "
            "Chromium's SwiftShader (a software rasteriser: the frame times are a floor, a GPU is far faster"
            + ("; taken while the engines section drove its own Chromium beside it" if started is not None else "")
            + "). The first shows the whole page with its controls; the tests read the same page's float render "
            "targets back and compare them with the Python renderer, three.js and "
            "<code>lightprobe radiance --synthesize</code>.</p>"
            + "".join(figures) + table(["state", "frame (300×330 canvas)"], rows))
