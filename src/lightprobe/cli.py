"""The ``lightprobe`` command: a thin layer over the Python API (argparse; rich for tables).

Every error caused by the input or the command line prints one line ``lightprobe: error: …`` on stderr and exits
with status 2, with no traceback and no partial output file; warnings print one line ``lightprobe: warning: …``.
Each subcommand is a ``register_*`` function adding its parser and a ``run_*`` function doing the work.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle OpenBLAS threads spin and slow numba's parallel kernels

import argparse
import json
import sys
import warnings
from pathlib import Path

from .errors import LightprobeError

LAYOUT_NAMES = ("latlong", "angular", "sphere", "cube", "cross", "hcross")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (and status 2) instead of the usage block."""

    def error(self, message: str):
        raise LightprobeError(f"{message} (see '{self.prog} --help')")


def _add_probe(p: argparse.ArgumentParser, name: str = "file", help_text: str | None = None) -> None:
    p.add_argument(name, nargs="?", type=Path,
                   help=help_text or "HDR environment map (.hdr, .exr, .pfm, .png, …); omitted: the shipped probe")
    p.add_argument("--layout", "-l", choices=LAYOUT_NAMES,
                   help="layout of the input; default: from its aspect ratio (2:1 latlong, 1:1 angular, 3:4 cross, "
                        "4:3 hcross, 6:1 cube strip)")


def _load(path: Path | None, layout: str | None, fix: bool = True):
    from .data import default_probe_path
    from .envmap import read_envmap

    return read_envmap(path or default_probe_path(), layout, fix=fix)


# ---- info ---------------------------------------------------------------------------------------------------------
def register_info(sub) -> None:
    p = sub.add_parser("info", help="size, layout, statistics and bad pixels of a map",
                       description="Size, layout, min/max/mean radiance (mean = ∫L dω / 4π), ∫L dω per channel, and "
                                   "counts of NaN, infinite and negative pixels (reported, not repaired).")
    _add_probe(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run_info)


def run_info(args) -> None:
    env = _load(args.file, args.layout, fix=False)
    stats = {"file": str(args.file or "(shipped probe)"), **env.stats()}
    if args.json:
        print(json.dumps(stats))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=stats.pop("file"), show_header=False)
    for key, value in stats.items():
        shown = "  ".join(f"{x:.6g}" for x in value) if isinstance(value, list) else (
            f"{value:.6g}" if isinstance(value, float) else str(value))
        table.add_row(key, shown)
    Console().print(table)


# ---- convert ------------------------------------------------------------------------------------------------------
def register_convert(sub) -> None:
    p = sub.add_parser("convert", help="convert between layouts (and rotate)",
                       description="Convert between layouts with footprint-aware resampling (∫L dω conserved), "
                                   "optionally turning the environment.")
    p.add_argument("src", type=Path, help="input environment map")
    p.add_argument("dst", type=Path, help="output: .exr, .hdr, .pfm, or .png/.jpg (tone-mapped)")
    p.add_argument("--to", "-t", required=True, choices=LAYOUT_NAMES, help="target layout (cube: a 6N×N strip)")
    p.add_argument("--size", type=int,
                   help="height (latlong, angular, sphere) or face edge (cube, cross, hcross); "
                        "default keeps the angular resolution")
    p.add_argument("--rotate", metavar="Y,P,R",
                   help="turn the environment by yaw,pitch,roll degrees (R = Ry·Rx·Rz, +Y up)")
    p.add_argument("--layout", "-l", choices=LAYOUT_NAMES, help="layout of the input (default: from aspect ratio)")
    p.add_argument("--half", action="store_true", help="write half floats (EXR only)")
    p.add_argument("--exposure", type=float, default=0.0, help="exposure in stops for .png/.jpg output")
    p.add_argument("--curve", choices=("srgb", "aces"), default="srgb", help="tone curve for .png/.jpg output")
    p.set_defaults(run=run_convert)


def parse_ypr(text: str):
    try:
        ypr = [float(x) for x in text.split(",")]
    except ValueError:
        ypr = []
    if len(ypr) != 3 or not all(map(lambda x: abs(x) < 1e6, ypr)):
        raise LightprobeError(f"--rotate wants 'yaw,pitch,roll' in degrees, got {text!r}")
    return ypr


def run_convert(args) -> None:
    from .envmap import resample
    from .frames import as_rotation
    from .io import WRITE_FORMATS
    from .layouts import layout as layout_named

    if args.dst.suffix.lower() not in WRITE_FORMATS:
        raise LightprobeError(f"cannot write {args.dst}: unknown image format; use one of {', '.join(WRITE_FORMATS)}")
    if args.size is not None and args.size < 1:
        raise LightprobeError(f"--size must be a positive number, got {args.size}")
    rotation = as_rotation(parse_ypr(args.rotate)) if args.rotate else None
    env = _load(args.src, args.layout)
    out = resample(env, layout_named(args.to), args.size, rotation=rotation)
    out.save(args.dst, half=args.half, exposure=args.exposure, curve=args.curve)
    print(f"wrote {args.dst} ({args.to}, size {out.size})")


# ---- demo ---------------------------------------------------------------------------------------------------------
def register_demo(sub) -> None:
    p = sub.add_parser("demo", help="the main job: run everything on a probe, write an HTML report",
                       description="Run what lightprobe does on a probe (default: the shipped one) and write "
                                   "index.html with pictures into --out.")
    p.add_argument("--out", "-o", type=Path, default=Path("lightprobe-demo"), help="report folder")
    _add_probe(p, "--probe", "probe to use instead of the shipped one")
    p.set_defaults(run=run_demo)


def run_demo(args) -> None:
    from .demo import run_demo as make_report

    index = make_report(_load(args.probe, args.layout), args.out, probe_name=str(args.probe) if args.probe else None)
    print(f"report: {index}")


COMMANDS = [register_info, register_convert, register_demo]


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="lightprobe",
                     description="HDR environment maps (light probes) → lighting for real-time renderers, "
                                 "checked against ground truth.")
    parser.add_argument("--version", action="version", version=f"lightprobe {_version()}")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND", parser_class=_Parser)
    for register in COMMANDS:
        register(sub)
    return parser


def _version() -> str:
    from . import __version__

    return __version__


def _one_line_warnings(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"lightprobe: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (0 ok, 2 bad input or usage)."""
    warnings.showwarning = _one_line_warnings
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if not hasattr(args, "run"):
            parser.print_help()
            return 2
        args.run(args)
        return 0
    except SystemExit as e:  # --help and --version
        return int(e.code or 0)
    except KeyboardInterrupt:
        print("lightprobe: error: interrupted", file=sys.stderr)
        return 130
    except LightprobeError as e:
        print(f"lightprobe: error: {e}", file=sys.stderr)
        return 2
    except MemoryError:
        print("lightprobe: error: out of memory; try a smaller --size", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"lightprobe: error: {e.strerror or e}: {e.filename or ''}".rstrip(": "), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
