"""Report section on ``lightprobe batch``: a small dataset processed into one table."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .page import Report, data_folder, table


def _demo_probes(rep: Report, folder: Path) -> tuple[list[str], str]:
    """Every probe file of ../shared/data beside the repository, or (without it) the shipped probe and seven
    rotated copies of it written into ``folder``."""
    shared = data_folder()
    found = sorted(str(p) for sub in ("debevec", "ict_lowres", "polyhaven_1k") for p in (shared / sub).rglob("*")
                   if p.suffix.lower() in (".hdr", ".exr") and p.is_file())
    if found:
        return found, f"every probe in {shared} ({len(found)} files)"
    paths = []
    for k in range(8):
        path = folder / f"shipped_turned_{45 * k:03d}.exr"
        (rep.env if k == 0 else rep.env.rotated((45.0 * k, 0.0, 0.0))).save(path)
        paths.append(str(path))
    return paths, "the shipped probe and seven copies turned by 45° steps (../shared/data is not here)"


def section_batch(rep: Report) -> str:
    """``lightprobe batch`` over the test probes: SH and a thumbnail each, on a local pool of the machine's cores,
    into ``batch/`` beside the report (results.parquet, errors.parquet, report.html)."""
    import tempfile

    from ..batch.report import write_report
    from ..batch.runner import LocalPool, run_batch
    from ..batch.task import JobOptions

    with tempfile.TemporaryDirectory(dir=rep.out) as temp:
        inputs, what = _demo_probes(rep, Path(temp))
        pool = LocalPool(os.cpu_count() or 1)
        summary = run_batch(inputs, rep.out / "batch", JobOptions(jobs=("sh", "thumbnail"), order=2), pool)
    write_report(rep.out / "batch")
    sheet = _thumbnail_sheet(rep.out / "batch")
    rep.timings[f"batch of {len(inputs)} probes (SH + thumbnail, {summary.workers} workers)"] = summary.seconds
    rows = [["inputs", what], ["done / failed", f"{summary.done} / {summary.failed}"],
            ["throughput", f"{summary.throughput:.2f} maps/s on {summary.workers} worker processes "
                           f"(start-up included)"],
            ["peak memory per worker", f"{summary.peak_rss / 2**20:.0f} MiB"]]
    return ("<h2>Dataset scale: <code>lightprobe batch</code></h2><p>The same API calls as the single-file "
            "commands, one row per input in <a href='batch/results.parquet'>batch/results.parquet</a> (pandas, "
            "polars and DuckDB read it directly), failures in <code>batch/errors.parquet</code>, committed in chunks "
            "so a killed run resumes with <code>--resume</code>; the batch's own page is "
            "<a href='batch/report.html'>batch/report.html</a>.</p>" + table(["", ""], rows)
            + rep.display_picture("batch_thumbnails", sheet, "the batch's thumbnails (tone-mapped latlong "
                                  "128×64 each, as the workers wrote them), in path order"))


def _thumbnail_sheet(folder: Path, columns: int = 6) -> np.ndarray:
    """The batch's thumbnail PNGs (display-encoded, all 128×64) tiled in path order with a 2-pixel gap."""
    import pyarrow.parquet as pq
    from PIL import Image

    rows = [r for r in pq.read_table(folder / "results.parquet", columns=["thumbnail"]).to_pylist() if r["thumbnail"]]
    tiles = [np.asarray(Image.open(folder / r["thumbnail"]).convert("RGB"), dtype=np.float32) / 255 for r in rows]
    h, w = tiles[0].shape[:2]
    sheet = np.ones((-(-len(tiles) // columns) * (h + 2), columns * (w + 2), 3), np.float32)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, columns)
        sheet[r * (h + 2):r * (h + 2) + h, c * (w + 2):c * (w + 2) + w] = tile
    return sheet
