"""``lightprobe info``: size, layout, statistics and bad pixels of a map."""

from __future__ import annotations

from .common import add_probe, load, print_json

# Peak bytes per pixel beyond reading: the direction and solid-angle tables (float64) and their temporaries, the
# valid pixels' copy and the bad-pixel masks (measured 89 B/px in all on 2048×1024 and 4096×2048 maps, reading
# included; tests/test_limits.py holds every estimate between the measured peak and 3× it).
WORKING_BYTES_PER_PIXEL = 72


def register(sub) -> None:
    p = sub.add_parser("info", help="size, layout, statistics and bad pixels of a map",
                       description="Size, layout, min/max/mean radiance (mean = ∫L dω / 4π), ∫L dω per channel, and "
                                   "counts of NaN, infinite and negative pixels (reported, not repaired; values that "
                                   "cannot be computed are null in JSON).")
    add_probe(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args) -> None:
    env = load(args.file, args.layout, fix=False, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL)
    stats = {"file": str(args.file or "(shipped probe)"), **env.stats()}
    if args.json:
        print_json(stats)
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=stats.pop("file"), show_header=False)
    for key, value in stats.items():
        shown = "  ".join(f"{x:.6g}" for x in value) if isinstance(value, list) else (
            f"{value:.6g}" if isinstance(value, float) else "—" if value is None else str(value))
        table.add_row(key, shown)
    Console().print(table)
