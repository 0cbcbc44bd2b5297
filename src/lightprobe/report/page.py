"""The report's page: what sections share (:class:`Report`), figures and tables, the style."""

from __future__ import annotations

import html
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..maps import EnvMap
from ..maps.images import write_image
from ..sh.basis import SHCoeffs, project


@dataclass
class Report:
    """What sections share: the probe, the output folder, a fixed exposure, and timings."""

    env: EnvMap
    out: Path
    probe_name: str
    exposure: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    shared: dict = field(default_factory=dict)  # results later sections reuse (SH coefficients, references)
    sections: dict[str, float] = field(default_factory=dict)  # each section's wall time, seconds

    def sh(self, l_max: int = 6) -> SHCoeffs:
        """Radiance SH of the probe up to ``l_max`` (computed once)."""
        if self.shared.get("sh") is None or self.shared["sh"].l_max < l_max:
            t0 = time.perf_counter()
            self.shared["sh"] = project(self.env, l_max)
            self.timings[f"SH projection, order {l_max}"] = time.perf_counter() - t0
        return self.shared["sh"].truncated(l_max)

    def display_picture(self, name: str, display: np.ndarray, caption: str, width: int | None = None) -> str:
        """Save display-encoded RGB as ``name``.png and return an HTML figure."""
        write_image(self.out / f"{name}.png", display, encoded=True)
        return figure(name, caption, width)

    def picture(self, name: str, rgb: np.ndarray, caption: str, exposure: float | None = None,
                curve: str = "aces", width: int | None = None) -> str:
        """Save linear RGB as ``name``.png (tone-mapped) and return an HTML figure for it (``width`` in CSS px)."""
        write_image(self.out / f"{name}.png", rgb, exposure=self.exposure if exposure is None else exposure,
                    curve=curve)
        return figure(name, caption, width)


def figure(name: str, caption: str, width: int | None = None) -> str:
    """An HTML figure for ``name``.png; small pictures are shown enlarged (pixelated, so nothing is invented)."""
    style = f' style="width:{width}px;max-height:none;image-rendering:pixelated"' if width else ""
    return (f'<figure><img src="{name}.png" alt="{html.escape(caption)}"{style}>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def table(header: list[str], rows: list[list], fmt: str = "{:.6g}") -> str:
    """A small HTML table; floats are formatted with ``fmt``."""
    def cell(v):
        return html.escape(fmt.format(v) if isinstance(v, float) else str(v))

    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


STYLE = """body{font:15px/1.45 system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{margin-top:2em;border-bottom:1px solid #ccc}table{border-collapse:collapse;margin:1em 0}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;font-variant-numeric:tabular-nums}
td:first-child,th:first-child{text-align:left}figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}
figure img{max-width:100%;max-height:300px}.grid figure img{max-height:220px}figcaption{font-size:.85em;color:#555}
"""


MARKER = ".lightprobe-report"  # the file that makes a folder a previous report, safe to replace


HARNESS = "the engines harness of a lightprobe checkout (engines/, installed by its bash setup.sh)"


def engines_missing() -> list[str]:
    """What the sections drawn by the engines need that is not here (empty when all is): the development harness
    (``lightprobe_engines``, never part of the wheel) and what it runs — Chromium, Node, the pinned npm packages."""
    try:
        from lightprobe_engines.runtimes import missing_engines
    except ImportError:
        return [HARNESS]
    return missing_engines()


def data_folder() -> Path:
    """Sample data the report draws on when it is there — the Stanford meshes and more probes: the folder
    ``LIGHTPROBE_SHARED_DATA`` names, else ``../shared/data`` seen from the current folder (a checkout's root, with
    the project's shared data beside it). It may be absent: the sections that use it say what they skip."""
    import os

    return Path(os.environ.get("LIGHTPROBE_SHARED_DATA", Path("..") / "shared" / "data"))
