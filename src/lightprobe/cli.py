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


def _add_probe(p: argparse.ArgumentParser, name: str = "file", help_text: str | None = None,
               layout_flag: str = "--layout") -> None:
    p.add_argument(name, nargs="?", type=Path,
                   help=help_text or "HDR environment map (.hdr, .exr, .pfm, .png, …); omitted: the shipped probe")
    flags = (layout_flag, "-l") if layout_flag == "--layout" else (layout_flag,)
    p.add_argument(*flags, dest="layout", choices=LAYOUT_NAMES,
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



# ---- sh -----------------------------------------------------------------------------------------------------------
FRAME_NAMES = ("world", "rh2001", "threejs", "filament", "gltf", "unity", "babylon")
WINDOW_NAMES = ("none", "hanning", "lanczos", "auto")


def _write_text(path: Path, text: str) -> None:
    from .io import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def register_sh(sub) -> None:
    p = sub.add_parser("sh", help="spherical-harmonic coefficients of the lighting (paper Figure 2)",
                       description="Radiance SH coefficients L_lm (real SH without Condon-Shortley phase, flat "
                                   "order l(l+1)+m) of a map, in a chosen frame.")
    _add_probe(p)
    p.add_argument("--order", type=int, default=2, help="l_max (default 2: nine coefficients)")
    p.add_argument("--frame", choices=FRAME_NAMES, default="world",
                   help="frame of the coefficients (rh2001: the paper's; world: +Y up, front -Z)")
    p.add_argument("--window", choices=WINDOW_NAMES, default="none", help="de-ringing window")
    p.add_argument("--format", choices=("json", "csv", "npy"), default="json")
    p.add_argument("--json", dest="format", action="store_const", const="json", help="same as --format json")
    p.add_argument("--output", "-o", type=Path, help="write to a file instead of stdout (needed for npy)")
    p.set_defaults(run=run_sh)


def run_sh(args) -> None:
    import numpy as np

    from .sh import name, project

    if not 0 <= args.order <= 64:
        raise LightprobeError(f"--order must be between 0 and 64, got {args.order}")
    sh = project(_load(args.file, args.layout), args.order, args.frame).windowed(args.window)
    if args.format == "npy":
        if not args.output:
            raise LightprobeError("--format npy needs --output FILE")
        from .io import atomic_path

        with atomic_path(args.output) as tmp, open(tmp, "wb") as f:
            np.save(f, sh.coeffs)
        return
    if args.format == "csv":
        from .sh import degree_order

        rows = ["name,l,m,R,G,B"] + [f"{name(i)},{degree_order(i)[0]},{degree_order(i)[1]},"
                                     + ",".join(f"{v:.9g}" for v in row) for i, row in enumerate(sh.coeffs)]
        text = "\n".join(rows) + "\n"
    else:
        text = json.dumps({"file": str(args.file or "(shipped probe)"), "frame": sh.frame.name, "order": sh.l_max,
                           "quantity": sh.quantity, "window": sh.window,
                           "basis": "real SH, no Condon-Shortley phase, flat index l(l+1)+m",
                           "names": [name(i) for i in range(len(sh.coeffs))],
                           "coefficients": sh.as_list()}) + "\n"
    if args.output:
        _write_text(args.output, text)
    else:
        sys.stdout.write(text)


# ---- irradiance ---------------------------------------------------------------------------------------------------
def parse_size(text: str, layout) -> int:
    """'N' (the layout's size: height, or face edge for cube layouts) or 'WxH' (the image file's width × height)."""
    try:
        if "x" not in text.lower():
            size = int(text)
        else:
            w, h = (int(v) for v in text.lower().split("x"))
            size = h // layout.aspect[1] if layout.faces == 1 else h
            expected = (6 * size, size) if layout.faces == 6 else layout.grid_shape(max(size, 1))[::-1]
            if (w, h) != tuple(expected):
                raise LightprobeError(f"--size {text} does not fit the {layout.name} layout "
                                      f"(an image {expected[0]}x{expected[1]} would)")
    except ValueError:
        raise LightprobeError(f"--size wants N or WxH, got {text!r}") from None
    if size < 1:
        raise LightprobeError(f"--size must be positive, got {text!r}")
    return size


def register_irradiance(sub) -> None:
    p = sub.add_parser("irradiance", help="irradiance map (SH or brute force)",
                       description="Irradiance E (not divided by pi) for every texel direction taken as a surface "
                                   "normal, by SH (fast) or by brute-force integration of the whole map (exact).")
    _add_probe(p, layout_flag="--in-layout")
    p.add_argument("--output", "-o", type=Path, required=True, help="output image (.exr, .hdr, .pfm, .png)")
    p.add_argument("--layout", dest="out_layout", choices=LAYOUT_NAMES, default="latlong", help="output layout")
    p.add_argument("--size", default="64x32", help="N or WxH of the output (default 64x32)")
    p.add_argument("--order", type=int, default=2, help="SH order l_max for --method sh")
    p.add_argument("--method", choices=("sh", "brute"), default="sh")
    p.add_argument("--window", choices=WINDOW_NAMES, default="none", help="de-ringing window for --method sh")
    p.set_defaults(run=run_irradiance)


def run_irradiance(args) -> None:
    from .envmap import check_size
    from .irradiance import irradiance_map
    from .layouts import layout as layout_named

    lay = layout_named(args.out_layout)
    size = parse_size(args.size, lay)
    check_size(lay, size)
    env = _load(args.file, args.layout)
    out = irradiance_map(env, lay, size, args.method, args.order, args.window)
    out.to_envmap_image().save(args.output)
    print(f"wrote {args.output} (irradiance, {args.method}, {lay.name} size {size})")


# ---- error --------------------------------------------------------------------------------------------------------
def register_error(sub) -> None:
    p = sub.add_parser("error", help="SH irradiance error against brute force",
                       description="Both error measures of SPEC 3 on luminance over uniformly spread normals: the "
                                   "paper's |E - E_ref| / (integral of L) and the per-normal |E - E_ref| / E_ref.")
    _add_probe(p)
    p.add_argument("--order", default="2", help="l_max, or a list such as 2,4,6")
    p.add_argument("--window", choices=WINDOW_NAMES + ("all",), default="all",
                   help="de-ringing window (default: every window, to show what each costs)")
    p.add_argument("--normals", type=int, default=2000, help="number of test normals")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run_error)


def run_error(args) -> None:
    from dataclasses import asdict

    from .irradiance import brute_irradiance, error_report, reference_normals
    from .sh import project

    try:
        orders = [int(v) for v in args.order.split(",")]
    except ValueError:
        raise LightprobeError(f"--order wants numbers such as 2 or 2,4,6, got {args.order!r}") from None
    if not all(0 <= o <= 32 for o in orders) or not 16 <= args.normals <= 200000:
        raise LightprobeError("--order must be within 0..32 and --normals within 16..200000")
    env = _load(args.file, args.layout)
    normals = reference_normals(args.normals)
    reference = brute_irradiance(env, normals)
    sh = project(env, max(orders))
    windows = WINDOW_NAMES if args.window == "all" else (args.window,)
    reports = [error_report(env, o, w, normals, reference, sh) for o in orders for w in windows]
    if args.json:
        print(json.dumps([asdict(r) for r in reports]))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"SH irradiance vs brute force, {args.normals} normals, luminance")
    for col in ("order", "window", "paper mean", "paper max", "relative mean", "relative max", "E < 0"):
        table.add_column(col, justify="right")
    for r in reports:
        table.add_row(str(r.l_max), r.window, f"{100 * r.paper_mean:.2f} %", f"{100 * r.paper_max:.2f} %",
                      f"{100 * r.relative_mean:.1f} %", f"{100 * r.relative_max:.1f} %",
                      f"{100 * r.negative_fraction:.1f} %")
    Console().print(table)


# ---- export -------------------------------------------------------------------------------------------------------
def register_export(sub) -> None:
    from .export import GLTF_SCALINGS, TARGETS

    p = sub.add_parser("export", help="SH irradiance for engines (three.js, Filament, Unity, glTF, Babylon, GLSL)",
                       description="Nine SH coefficients converted to an engine's frame, sign convention and "
                                   "scaling (see the README's table).")
    _add_probe(p)
    p.add_argument("--to", "-t", required=True, choices=TARGETS)
    p.add_argument("--output", "-o", type=Path, required=True)
    p.add_argument("--frame", choices=FRAME_NAMES, help="override the target's own frame")
    p.add_argument("--gltf-scaling", choices=GLTF_SCALINGS, default="babylon",
                   help="glTF irradianceCoefficients: pi*L_lm as Babylon.js reads them, or literal irradiance")
    p.add_argument("--window", choices=WINDOW_NAMES, default="none", help="de-ringing window")
    p.set_defaults(run=run_export)


def run_export(args) -> None:
    from .export import export
    from .sh import project

    sh = project(_load(args.file, args.layout), 2).windowed(args.window)
    text = export(sh, args.to, args.frame, args.gltf_scaling, csharp=args.output.suffix.lower() == ".cs")
    _write_text(args.output, text)
    print(f"wrote {args.output} ({args.to})")


# ---- design -------------------------------------------------------------------------------------------------------
def register_design(sub) -> None:
    p = sub.add_parser("design", help="edit SH lighting and see it on spheres (paper Figure 4)",
                       description="Edit radiance SH coefficients (world frame) and render the nine basis "
                                   "functions and the original and edited lighting on white spheres, front and back.")
    _add_probe(p)
    p.add_argument("--output", "-o", type=Path, required=True, help="PNG picture")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="Llm=V",
                   help="set a coefficient, e.g. L1-1=-0.4 or L20=0.1,0.2,0.3 (repeatable)")
    p.add_argument("--scale-band", dest="scales", action="append", default=[], metavar="L=F",
                   help="multiply band L by F, e.g. 2=0.5 (repeatable)")
    p.add_argument("--size", type=int, default=128, help="sphere size in pixels")
    p.add_argument("--json", type=Path, help="also write the edited coefficients (lightprobe JSON)")
    p.set_defaults(run=run_design)


def run_design(args) -> None:
    from .design import design_figure, edit
    from .export import export_json
    from .io import write_image
    from .sh import project

    if not 16 <= args.size <= 1024:
        raise LightprobeError(f"--size must be within 16..1024, got {args.size}")
    original = project(_load(args.file, args.layout), 2)
    edited = edit(original, args.sets, args.scales)
    write_image(args.output, design_figure(original, edited, args.size), encoded=True)
    if args.json:
        _write_text(args.json, export_json(edited))
    print(f"wrote {args.output}")


# ---- render -------------------------------------------------------------------------------------------------------
def register_render(sub) -> None:
    p = sub.add_parser("render", help="render a scene or a mesh under a probe (sh, brute, or the Mitsuba reference)",
                       description="Render a scene file (.yaml/.json) or a mesh file (.obj, .ply, .glb, ...; placed on "
                                   "a ground plane) under a probe. Output: .exr (linear radiance) or .png (tone-mapped).")
    p.add_argument("scene", nargs="?", type=Path,
                   help="scene (.yaml, .yml, .json) or mesh file; omitted: the built-in sphere-and-torus scene")
    p.add_argument("--probe", type=Path, help="environment map (default: the scene's, else the shipped probe)")
    p.add_argument("--method", "-m", choices=("sh", "brute", "reference"), default="sh")
    p.add_argument("--output", "-o", type=Path, required=True)
    p.add_argument("--size", help="image WxH (default: the scene's camera, 256x256 for meshes)")
    p.add_argument("--spp", type=int, default=2,
                   help="sh/brute: spp×spp samples per pixel (default 2); reference: samples per pixel (default 256)")
    p.add_argument("--order", type=int, default=2, help="SH order l_max")
    p.add_argument("--window", choices=WINDOW_NAMES, default="none", help="SH de-ringing window")
    p.add_argument("--per-vertex", action="store_true", help="SH evaluated at vertices and interpolated")
    p.add_argument("--gi", action="store_true", help="reference: full global illumination (default: direct only)")
    p.add_argument("--exposure", type=float, default=0.0, help="exposure in stops for .png output")
    p.set_defaults(run=run_render)


def _scene_for(args):
    from .data import default_probe_path
    from .envmap import read_envmap
    from dataclasses import replace

    from .render.scene import builtin_scene, load_scene, mesh_scene

    env = read_envmap(args.probe) if args.probe else None
    path = args.scene
    if path is None:
        scene = builtin_scene(env or read_envmap(default_probe_path()))
    elif path.suffix.lower() in (".yaml", ".yml", ".json"):
        scene = load_scene(path, env)
    else:
        scene = mesh_scene(path, env or read_envmap(default_probe_path()))
    if args.size:
        try:
            w, h = (int(v) for v in args.size.lower().split("x"))
        except ValueError:
            raise LightprobeError(f"--size wants WxH, got {args.size!r}") from None
        scene = replace(scene, camera=replace(scene.camera, width=w, height=h))
    return scene


def run_render(args) -> None:
    from .render.methods import method
    from .render.renderer import render

    if args.output.suffix.lower() not in (".exr", ".hdr", ".pfm", ".png", ".jpg", ".jpeg"):
        raise LightprobeError(f"cannot write {args.output}: use .exr, .hdr, .pfm, .png or .jpg")
    scene = _scene_for(args)
    if args.method == "reference":
        from .render.reference import reference_render

        spp = args.spp if args.spp != 2 else 256
        result = reference_render(scene, spp, args.gi)
    else:
        if not 1 <= args.spp <= 16:
            raise LightprobeError("--spp for sh and brute is per axis, within 1..16")
        options = {"order": args.order, "per_vertex": args.per_vertex, "window": args.window} \
            if args.method == "sh" else {}
        result = render(scene, method(args.method, **options), args.spp)
    from .io import write_image

    write_image(args.output, result.image, exposure=args.exposure, curve="aces")
    total = sum(result.seconds.values())
    print(f"wrote {args.output} ({result.method}; {scene.camera.width}x{scene.camera.height}, {total:.2f} s)")


# ---- compare ------------------------------------------------------------------------------------------------------
def register_compare(sub) -> None:
    p = sub.add_parser("compare", help="error of a rendering against a reference (relMSE, MARE, HDR-FLIP)",
                       description="Relative MSE, mean absolute relative error and HDR-FLIP of TEST against REF "
                                   "(linear HDR images of one size), and an error heat map.")
    p.add_argument("test", type=Path)
    p.add_argument("reference", type=Path)
    p.add_argument("--heatmap", type=Path, help="write the relative-error heat map (PNG)")
    p.add_argument("--flipmap", type=Path, help="write the FLIP error map (PNG)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run_compare)


def run_compare(args) -> None:
    from .io import read_image, write_image
    from .render.compare import compare, error_heatmap, hdr_flip
    from .tonemap import heatmap

    test, ref = read_image(args.test), read_image(args.reference)
    metrics = compare(test, ref)
    if args.heatmap:
        write_image(args.heatmap, error_heatmap(test, ref), encoded=True)
    if args.flipmap:
        write_image(args.flipmap, heatmap(hdr_flip(test, ref)[1], 1.0), encoded=True)
    if args.json:
        print(json.dumps(metrics.as_dict()))
    else:
        print(f"relative MSE {metrics.relative_mse:.4g}   MARE {metrics.mare:.4g}   HDR-FLIP {metrics.flip:.4g}   "
              f"({metrics.pixels} pixels)")


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


COMMANDS = [register_info, register_convert, register_sh, register_irradiance, register_error, register_export,
            register_design, register_render, register_compare, register_demo]


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
