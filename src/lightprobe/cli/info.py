"""``lightprobe info``: size, layout, statistics and bad pixels of a map."""

from __future__ import annotations

from .common import add_probe, load, print_json

# Peak bytes per pixel beyond reading: a disc's validity mask and the valid pixels' copy (latlong and cube maps need
# neither; the statistics are reductions in blocks). tests/test_limits.py holds every estimate between the measured
# peak and 3× it.
WORKING_BYTES_PER_PIXEL = 16


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
    # a plain aligned table, not rich's: importing rich costs more than reading a 2k map (the start-up bound: 3× `import numpy`)
    title = stats.pop("file")
    width = max(map(len, stats))
    print(title)
    for key, value in stats.items():
        shown = "  ".join(f"{x:.6g}" for x in value) if isinstance(value, list) else (
            f"{value:.6g}" if isinstance(value, float) else "—" if value is None else str(value))
        print(f"  {key:<{width}}  {shown}")
