"""Peak resident memory of each command on a 4096×2048 float32 lat-long map, as a multiple of the map (96 MiB).

    python benchmarks/bench_memory.py [--only convert]

Every command runs in a child process measured from outside (lightprobe_engines.peak.run_measured); the bound
the project holds is 3× the map. The suite keeps the cases most likely to regress (tests/test_limits.py: info,
sh, irradiance, convert to cube and to a cross); this table has every layout, the disc targets included.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

from common import SHARED, require

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engines"))

from lightprobe_engines.peak import run_measured  # noqa: E402

from lightprobe.maps import read_envmap  # noqa: E402
from lightprobe.maps.images import write_image  # noqa: E402

MAP_MIB = 4096 * 2048 * 3 * 4 / 2**20
BOUND = 3.0
COMMANDS = [
    ["info", "{m}"], ["sh", "{m}"], ["sh", "{m}", "--order", "8"], ["irradiance", "{m}", "--output", "{out}/e.exr"],
    *[["convert", "{m}", f"{{out}}/{name}.exr", "--to", name] for name in ("cube", "angular", "sphere", "hcross",
                                                                        "vcross", "latlong")],
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", help="only the commands whose name starts with this")
    args = parser.parse_args()
    probe = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr"
    if not require(probe):
        sys.exit(1)
    exe = shutil.which("lightprobe") or str(Path(sys.executable).with_name("lightprobe"))
    with tempfile.TemporaryDirectory() as tmp:
        big = write_image(Path(tmp) / "m4096.exr", read_envmap(probe).to("latlong", 2048).data)
        print(f"peak resident memory on a 4096×2048 float32 lat-long ({MAP_MIB:.0f} MiB), bound {BOUND:.0f}× the map")
        print(f"  {'command':40s} {'peak MiB':>9s} {'× map':>6s}")
        for argv in COMMANDS:
            if args.only and not argv[0].startswith(args.only):
                continue
            line = [a.format(m=big, out=tmp) for a in argv]
            res, peak = run_measured([exe, *line], env={"LIGHTPROBE_PROGRESS": "0"}, timeout=600)
            label = " ".join(argv).replace("{m}", "MAP").replace("{out}/", "")
            state = "" if res.returncode == 0 else f"  failed: {res.stderr.strip()[-120:]}"
            flag = "  over" if peak > BOUND * MAP_MIB else ""
            print(f"  {label:40s} {peak:9.0f} {peak / MAP_MIB:6.2f}{flag}{state}")


if __name__ == "__main__":
    main()
