"""``lightprobe demo``: the main job. Runs what lightprobe does on one probe and writes an HTML report.

The report is a list of sections (:data:`SECTIONS`); each is a function ``(Report) → html`` that may save pictures
through :meth:`Report.picture`. Later capabilities add their sections to the list.

Nothing of the user's is lost: the report is written into a fresh temporary folder beside ``out`` and moved into
place only when complete (a report failing halfway leaves nothing); an existing ``out`` is replaced only when it is
a previous report (it holds :data:`MARKER`) or is empty, or with ``force``. Timings are of warm kernels: the
one-time compilation of the numba kernels is measured first and reported on its own line.
"""

from __future__ import annotations

import contextlib
import shutil
import time
from pathlib import Path

from ..maps import EnvMap
from ..maps.tonemap import auto_exposure
from ..util.errors import InputError
from ..util.files import move_folder_into_place, sweep_stale_temporaries, temp_path_for, write_text
from ..util.progress import track
from .bake import section_bake
from .batch import section_batch
from .engines import section_engines, section_exports
from .glossy import section_glossy
from .lights import section_lights
from .maps import section_layouts, section_probe, section_speed
from .page import MARKER, STYLE, Report, engines_missing, table
from .render import section_render
from .sh import section_design, section_errors, section_irradiance, section_sh
from .viewer import _viewer_started, section_viewer

SECTIONS = [section_probe, section_layouts, section_speed, section_sh, section_irradiance, section_errors,
            section_lights, section_design, section_exports, section_engines, section_bake, section_render,
            section_glossy, section_viewer, section_batch]


def _sections_html(rep: Report) -> str:
    """Every section of SECTIONS, in order. The viewer's screenshots are taken in a thread while the engines section
    runs: both mostly wait on their own headless Chromium (~0.7 of a core each), and the screenshots run no compiled
    kernel (the viewer's bake runs first, in this thread). Nothing the speed section times runs meanwhile."""
    from concurrent.futures import ThreadPoolExecutor

    parts, viewer = [], None
    with ThreadPoolExecutor(1) as beside:
        for section in track(SECTIONS, "writing the report", total=len(SECTIONS)):
            t0 = time.perf_counter()
            if section is section_engines and section_viewer in SECTIONS and not engines_missing():
                viewer = _viewer_started(rep, beside)
            parts.append(section_viewer(rep, viewer) if section is section_viewer else section(rep))
            rep.sections[section.__name__.removeprefix("section_")] = time.perf_counter() - t0
    return "".join(parts)


def section_shares(rep: Report, total: float) -> list[list]:
    """Rows of the timing table: each section's wall time and its share of the whole report, slowest first."""
    return [[f"section: {name}", f"{seconds:.1f} s", f"{100 * seconds / total:.0f} %"]
            for name, seconds in sorted(rep.sections.items(), key=lambda kv: -kv[1])]


def warm_up() -> float:
    """Run every compiled kernel the report uses once on tiny inputs (:func:`lightprobe.warmup.compile_kernels`), so
    the sections' timings are warm; returns the seconds it took (compilation, or loading the kernels from numba's
    cache, which ``setup.sh`` fills)."""
    from ..warmup import compile_kernels

    return compile_kernels()


def check_report_folder(out: Path, force: bool = False) -> None:
    """Refuse an ``out`` that is a file, or a non-empty folder that is not a previous report (unless ``force``)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"cannot write the report into {out}: it is a file, not a folder")
    if out.is_dir() and not force and not (out / MARKER).exists() and any(out.iterdir()):
        raise InputError(f"refusing to write the report into {out}: the folder holds files that are not a "
                         "lightprobe report (choose another --out, or --force to replace the folder)")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write the report into {out}: folder {parent} does not exist")


def run_demo(env: EnvMap, out: Path, probe_name: str | None = None, force: bool = False) -> Path:
    """Write the report for ``env`` into folder ``out`` (see the module docstring); returns the path of index.html."""
    out = Path(out)
    check_report_folder(out, force)
    parent = out.parent if str(out.parent) else Path(".")
    sweep_stale_temporaries(parent)
    building = temp_path_for(out)
    building.mkdir()
    try:
        (building / MARKER).write_text("a lightprobe demo report; lightprobe demo may replace this folder\n")
        _write_report(env, building, probe_name)
        move_folder_into_place(building, out)
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(building)
    return out / "index.html"


def _write_report(env: EnvMap, out: Path, probe_name: str | None) -> None:
    rep = Report(env, out, probe_name or "the shipped probe: Poly Haven “Rooitou Park” (CC0), 512×256 latlong",
                 exposure=auto_exposure(env.data, env.solid_angles()))
    t0 = time.perf_counter()
    compile_seconds = warm_up()
    body = _sections_html(rep)
    total = time.perf_counter() - t0
    shares = [["compiling the numba kernels, or loading them from numba's cache (setup.sh compiles them)",
               f"{compile_seconds:.1f} s", f"{100 * compile_seconds / total:.0f} %"], *section_shares(rep, total)]
    rows = [[k, f"{1000 * v:.1f} ms"] for k, v in rep.timings.items()]
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>lightprobe report</title>"
            f"<style>{STYLE}</style></head><body><h1>lightprobe report</h1>{body}"
            f"<h2>Timings</h2><p>Where the report's {total:.1f} s went: each section's wall time (the viewer's "
            "screenshots are taken during the engines section) and its share.</p>"
            f"{table(['part', 'time', 'share'], shares)}"
            f"<p>Each step timed warm, after the kernels were compiled.</p>{table(['step', 'time'], rows)}"
            f"<p><small>Made in {total:.1f} s.</small></p></body></html>")
    write_text(out / "index.html", page)
