"""``lightprobe batch --report DIR``: one HTML page of a finished batch — the dataset's thumbnails, histograms of
∫L dω (Rec. 709 luminance, radiance × sr) and of light counts, and the failures. Self-contained but for the
thumbnails, which it links where the batch wrote them; the histograms are inline SVG."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from ..util.errors import UsageError

MAX_THUMBNAILS = 500
LUMA = np.array([0.2126, 0.7152, 0.0722])


def _svg_histogram(values, title: str, bins, log_x: bool = False) -> str:
    values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if values.size == 0:
        return f"<p>{html.escape(title)}: no values.</p>"
    data = np.log10(np.maximum(values, 1e-12)) if log_x else values
    counts, edges = np.histogram(data, bins=bins)
    w, h, pad = 520, 180, 30
    top = max(int(counts.max()), 1)
    bars = []
    for i, c in enumerate(counts):
        x0 = pad + (w - 2 * pad) * i / len(counts)
        bw = (w - 2 * pad) / len(counts) - 1
        bh = (h - 2 * pad) * c / top
        label = f"{edges[i]:.3g}–{edges[i + 1]:.3g}{' (log10)' if log_x else ''}: {c}"
        bars.append(f'<rect x="{x0:.1f}" y="{h - pad - bh:.1f}" width="{max(bw, 1):.1f}" height="{bh:.1f}" '
                    f'fill="#4a7bd0"><title>{html.escape(label)}</title></rect>')
    axis = (f'<text x="{pad}" y="{h - 8}" font-size="11">{edges[0]:.3g}</text>'
            f'<text x="{w - pad}" y="{h - 8}" font-size="11" text-anchor="end">{edges[-1]:.3g}</text>'
            f'<text x="{pad}" y="14" font-size="12">{html.escape(title)} (max bin {top})</text>')
    return f'<svg width="{w}" height="{h}" xmlns="http://www.w3.org/2000/svg">{"".join(bars)}{axis}</svg>'


def write_report(out: Path) -> Path:
    """Write ``out``/report.html from ``results.parquet`` and ``errors.parquet``.

    Thumbnails of the first :data:`MAX_THUMBNAILS` rows are linked where the batch wrote them; ``errors.parquet`` is
    optional. The file is written atomically.

    Parameters
    ----------
    out : Path
        A finished batch folder (one holding ``results.parquet``).

    Returns
    -------
    Path
        ``out``/report.html.

    Raises
    ------
    UsageError
        ``out`` holds no ``results.parquet``, or a table there is not a lightprobe batch table.
    """
    from .table import read_finished

    out = Path(out)
    if not (out / "results.parquet").is_file():
        raise UsageError(f"{out} holds no finished batch (no results.parquet): run lightprobe batch first")
    rows = read_finished(out / "results.parquet", "rows").to_pylist()
    errors = (read_finished(out / "errors.parquet", "errors").to_pylist() if (out / "errors.parquet").is_file()
              else [])
    power = [float(np.asarray(r["integral"]) @ LUMA) for r in rows if r.get("integral")]
    counts = [r["light_count"] for r in rows if r.get("light_count") is not None]
    thumbs = "".join(
        f'<figure><img src="{html.escape(r["thumbnail"])}" loading="lazy" width="128" height="64" alt="">'
        f'<figcaption>{html.escape(Path(r["path"]).name)}<br>{r.get("light_count") if r.get("light_count") is not None else "–"} lights</figcaption></figure>'
        for r in rows[:MAX_THUMBNAILS] if r.get("thumbnail"))
    failures = "".join(f"<tr><td>{html.escape(e['path'])}</td><td>{html.escape(e['error_class'] or '')}</td>"
                       f"<td>{html.escape(e['message'] or '')}</td></tr>" for e in errors)
    seconds = sum(r.get("seconds") or 0 for r in rows)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>lightprobe batch report</title>
<style>body{{font:14px/1.4 system-ui,sans-serif;margin:2em;color:#222}}figure{{display:inline-block;margin:4px;
font-size:11px;text-align:center;width:132px;overflow:hidden}}table{{border-collapse:collapse}}td,th{{border:1px
solid #ccc;padding:2px 6px;text-align:left}}</style></head><body>
<h1>lightprobe batch: {html.escape(str(out))}</h1>
<p>{len(rows)} maps, {len(errors)} failures; {seconds:.1f} s of worker time in all.</p>
<h2>∫L dω (luminance)</h2>{_svg_histogram(power, "∫L dω, log10", 30, log_x=True)}
<h2>Lights per map</h2>{_svg_histogram(counts, "light count", np.arange(-0.5, max(counts + [1]) + 1.5)) if counts else "<p>no lights job</p>"}
<h2>Thumbnails</h2>{thumbs or "<p>no thumbnail job</p>"}
<h2>Failures</h2>{"<table><tr><th>path</th><th>error</th><th>message</th></tr>" + failures + "</table>" if failures else "<p>none</p>"}
</body></html>"""
    from ..util.files import write_text

    write_text(out / "report.html", page)
    return out / "report.html"
