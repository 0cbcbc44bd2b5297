"""``lightprobe batch``: many probes into one Parquet table, on this machine's cores or a Dask cluster."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .common import Number, add_option, refuse


def register(sub) -> None:
    from ..batch.task import DEFAULT_JOBS, JOBS

    p = sub.add_parser("batch", help="many probes → one Parquet table (local pool or Dask), resumable",
                       description="Process files, globs or lists of paths (@list.txt) with the single-file "
                                   "commands' API: a row per input in OUT/results.parquet (path, sha256, size, "
                                   "layout, ∫L dω, SH, lights, artifact paths, timings), every failure in "
                                   "OUT/errors.parquet, artifacts under OUT/maps/. Results are committed in chunks: "
                                   "after a crash or kill, the same command with --resume redoes only unfinished "
                                   "inputs, each exactly once. --report OUT writes OUT/report.html.")
    p.add_argument("inputs", nargs="*", help="files, globs (quoted; ** recursive) or @LIST / LIST.txt of paths")
    p.add_argument("--out", "-o", type=Path, help="the batch folder")
    p.add_argument("--jobs", default=",".join(DEFAULT_JOBS),
                   help=f"comma-separated, of {', '.join(JOBS)} (default {','.join(DEFAULT_JOBS)})")
    add_option(p, "--order", type=Number(int, 0, 32), default=2, help="SH order l_max (sh and irradiance jobs)")
    p.add_argument("--brdf", default="ggx:alpha=0.2", help="the radiance job's BRDF (lightprobe radiance --brdf)")
    add_option(p, "--views", type=Number(int, 12, 162), default=12, help="the radiance job's views: 12, 42, 162")
    add_option(p, "--size", type=Number(int, 2, 1024), default=64, help="the radiance job's map size")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=Number(int, 1, 1024), help="local worker processes (default: the cores)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a Dask distributed scheduler (tcp://host:port)")
    where.add_argument("--dask-local", type=Number(int, 1, 256), metavar="N",
                       help="start a Dask LocalCluster of N workers on 127.0.0.1 for this batch (TLS, its "
                            "credentials made for this run: no other client can submit work to it)")
    p.add_argument("--dashboard", action="store_true",
                   help="with --dask-local: serve Dask's dashboard on 127.0.0.1 and print its URL (needs bokeh)")
    add_option(p, "--timeout", type=Number(float, 0.1, 3600), default=10.0,
               help="seconds to wait for the Dask scheduler")
    add_option(p, "--chunk", type=Number(int, 1, 100000), default=64,
               help="results per committed part file (also committed every 5 s)")
    p.add_argument("--resume", action="store_true", help="continue the batch in OUT (skips what is done)")
    p.add_argument("--force", action="store_true", help="with --resume: accept a batch of another lightprobe version")
    p.add_argument("--report", type=Path, metavar="OUT", help="write OUT/report.html for a finished batch and exit")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..batch.inputs import expand_inputs
    from ..batch.report import write_report
    from ..batch.runner import DaskPool, LocalPool, check_out, run_batch
    from ..batch.task import JOBS, JobOptions

    if args.report is not None:
        if args.inputs or args.out:
            refuse("--report OUT takes no inputs and no --out")
        print(f"wrote {write_report(args.report)}")
        return
    if args.out is None:
        refuse("--out DIR is needed")
    if args.dashboard and not args.dask_local:
        refuse("--dashboard goes with --dask-local (a scheduler of your own serves its own dashboard)")
    jobs = tuple(j.strip() for j in args.jobs.split(",") if j.strip())
    bad = [j for j in jobs if j not in JOBS]
    if bad or not jobs:
        refuse(f"--jobs: unknown {', '.join(bad) or '(none given)'}; choose from {', '.join(JOBS)}")
    if "radiance" in jobs:
        from ..glossy.brdf import parse_brdf
        from ..glossy.radiance import check_views

        parse_brdf(args.brdf)
        check_views(args.views)
    options = JobOptions(jobs=jobs, order=args.order, brdf=args.brdf, radiance_views=args.views,
                         radiance_size=args.size)
    inputs = expand_inputs(args.inputs, exclude=args.out)
    check_out(args.out, options, args.resume, args.force)  # before a cluster is started or reached
    executor = (DaskPool(args.scheduler, args.dask_local, args.timeout, args.dashboard)
                if args.scheduler or args.dask_local else LocalPool(args.workers or os.cpu_count() or 1))
    if getattr(executor, "dashboard", None):
        print(f"lightprobe batch: Dask dashboard {executor.dashboard}", file=sys.stderr, flush=True)
    try:
        summary = _with_progress(lambda progress: run_batch(inputs, args.out, options, executor, args.resume,
                                                            args.force, args.chunk, progress=progress), len(inputs))
    finally:
        executor.close()
    print(f"batch {args.out}: {summary.done} done, {summary.skipped} skipped (same content), {summary.failed} failed"
          f"{f', {summary.already} already there' if summary.already else ''}; {summary.throughput:.2f} maps/s "
          f"with {summary.workers} workers ({summary.executor}); peak worker memory "
          f"{summary.peak_rss / 2**20:.0f} MiB; results.parquet {summary.rows} rows, errors.parquet {summary.errors}")


def _with_progress(work, total: int):
    """Run ``work(progress)`` with a progress bar on stderr when it is a terminal: maps done / total, maps/s, ETA,
    failures so far."""
    from ..util.progress import progress_enabled

    if not progress_enabled():
        return work(None)
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("batch"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
               TextColumn("{task.fields[rate]:.2f} maps/s"), TimeRemainingColumn(),
               TextColumn("{task.fields[failed]} failed"))
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("batch", total=total, rate=0.0, failed=0)

        def progress(s):
            bar.update(task, completed=s.already + s.done + s.skipped + s.failed, rate=s.throughput, failed=s.failed)

        result = work(progress)
    print("", end="", file=sys.stderr)
    return result
