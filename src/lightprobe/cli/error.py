"""``lightprobe error``: SH irradiance against brute force, both measures of docs/spec.md §3."""

from __future__ import annotations

from .common import Number, NumberList, add_option, add_probe, load, print_json

MAX_ORDER = 32
WORKING_BYTES_PER_PIXEL = 96  # the brute-force light samples and the SH projection's geometry (~80 B measured)


def register(sub) -> None:
    from ..util.names import WINDOWS

    p = sub.add_parser("error", help="SH irradiance error against brute force",
                       description="Both error measures of docs/spec.md §3 on luminance over uniformly spread normals (SH or "
                                   "the hybrid against brute force): the "
                                   "paper's |E - E_ref| / (integral of L) and the per-normal |E - E_ref| / E_ref.")
    add_probe(p)
    add_option(p, "--order", type=NumberList(int, 0, MAX_ORDER, 8), default=None,
               help="l_max, or a list such as 2,4,6 (default 2; with --method hybrid 2,12: the ambient's orders)")
    p.add_argument("--method", choices=("sh", "hybrid"), default="sh",
                   help="sh: the map's SH; hybrid: area lights exact + SH of the ambient, each order beside SH "
                        "alone of the same order")
    p.add_argument("--window", choices=WINDOWS + ("all",), default="all",
                   help="de-ringing window (default: every window, to show what each costs)")
    add_option(p, "--normals", type=Number(int, 16, 200000), default=2000, help="number of test normals")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args) -> None:
    from dataclasses import asdict

    from ..sh.irradiance import brute_irradiance, error_report, reference_normals
    from ..sh.basis import WINDOWS, project

    hybrid = args.method == "hybrid"
    if args.order is not None:
        orders = args.order
    else:
        from ..lights.hybrid import DEFAULT_AMBIENT_ORDER

        orders = [2, DEFAULT_AMBIENT_ORDER] if hybrid else [2]
    env = load(args.file, args.layout, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL, kernels=True)
    normals = reference_normals(args.normals)
    reference = brute_irradiance(env, normals)
    sh = project(env, max(orders))
    windows = WINDOWS if args.window == "all" and not hybrid else ("none",) if hybrid else (args.window,)
    reports = [error_report(env, o, w, normals, reference, sh) for o in orders for w in windows]
    if hybrid:
        from ..lights.hybrid import hybrid_error_report, hybrid_irradiance
        from ..lights.decompose import decompose

        dec = decompose(env)
        reports += [hybrid_error_report(env, normals, reference, hybrid_irradiance(env, dec, o)) for o in orders]
        reports.sort(key=lambda r: r.l_max)
    if args.json:
        print_json([asdict(r) for r in reports])
        return
    from rich.console import Console
    from rich.table import Table

    what = "SH and hybrid irradiance" if hybrid else "SH irradiance"
    table = Table(title=f"{what} vs brute force, {args.normals} normals, luminance")
    for col in ("method", "order", "window", "paper mean", "paper max", "relative mean", "relative max", "E < 0"):
        table.add_column(col, justify="right")
    for r in reports:
        table.add_row(r.method, str(r.l_max), r.window, f"{100 * r.paper_mean:.2f} %", f"{100 * r.paper_max:.2f} %",
                      f"{100 * r.relative_mean:.1f} %", f"{100 * r.relative_max:.1f} %",
                      f"{100 * r.negative_fraction:.1f} %")
    Console().print(table)
