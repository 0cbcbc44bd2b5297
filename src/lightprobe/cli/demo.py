"""``lightprobe demo``: the main job, the HTML report."""

from __future__ import annotations

from pathlib import Path

from .common import add_probe, load


def register(sub) -> None:
    p = sub.add_parser("demo", help="the main job: run everything on a probe, write an HTML report",
                       description="Run what lightprobe does on a probe (default: the shipped one) and write "
                                   "index.html with pictures into --out. The report is made in a temporary folder "
                                   "and moved into place when complete; an existing folder is replaced only if it "
                                   "holds a previous report (or with --force).")
    p.add_argument("--out", "-o", type=Path, default=Path("lightprobe-demo"), help="report folder")
    p.add_argument("--force", action="store_true",
                   help="replace --out even if it is a folder that is not a previous report (its files are lost)")
    add_probe(p, "--probe", "probe to use instead of the shipped one")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..report.demo import check_report_folder, run_demo

    check_report_folder(args.out, args.force)
    env = load(args.probe, args.layout, working_bytes_per_pixel=400, kernels=True)
    index = run_demo(env, args.out, probe_name=str(args.probe) if args.probe else None, force=args.force)
    print(f"report: {index}")
