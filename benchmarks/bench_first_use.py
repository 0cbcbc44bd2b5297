"""First use from an empty kernel cache: the warm-up's compile time, step by step, and the first commands.

    python benchmarks/bench_first_use.py [--commands]

Each measurement runs in a fresh process with its own empty numba cache (a temporary ``XDG_CACHE_HOME``), one at a
time. It reports CPU seconds (user + system, the process and its children) beside wall seconds: numba compiles on
one core, so on a shared machine the CPU time is the figure that does not move with the load, and on an idle one
the wall time is about the same. ``--commands`` adds the first ``convert`` (lat-long → cube, → angular), ``sh``,
``lights``, ``irradiance`` and ``export --to babylon-env`` of a fresh install, each with its own empty cache.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED, require  # sets the environment first

# Run in the child: the warm-up's steps (lightprobe.warmup.compile_kernels), each timed on its own.
STEPS = """
import resource, sys, time
def cpu():
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
import lightprobe.warmup as warmup
env = warmup._probe()
for name in ("maps", "lights", "renders", "radiance", "bake"):
    t, c = time.perf_counter(), cpu()
    getattr(warmup, "_" + name)(env)
    print(name, cpu() - c, time.perf_counter() - t, flush=True)
"""


def _child_cpu() -> float:
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return kids.ru_utime + kids.ru_stime


def fresh(argv: list[str]) -> tuple[float, float, str]:
    """Run ``argv`` with an empty kernel cache: (CPU seconds, wall seconds, its stdout)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "XDG_CACHE_HOME": cache}
        env.pop("NUMBA_CACHE_DIR", None)
        c, t = _child_cpu(), time.perf_counter()
        done = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
        return _child_cpu() - c, time.perf_counter() - t, done.stdout


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commands", action="store_true", help="also each first command, from its own empty cache")
    args = parser.parse_args()
    print(f"first use from an empty kernel cache ({os.cpu_count()} cores, load {os.getloadavg()[0]:.1f})\n")
    cpu, wall, out = fresh([sys.executable, "-c", STEPS])
    print(f"  {'warm-up step':28s} {'CPU s':>8s} {'wall s':>8s}")
    for line in out.split("\n"):
        if line.strip():
            name, step_cpu, step_wall = line.split()
            print(f"  {name:28s} {float(step_cpu):8.1f} {float(step_wall):8.1f}")
    print(f"  {'whole warm-up (with imports)':28s} {cpu:8.1f} {wall:8.1f}")
    if args.commands:
        probe = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr"
        if not require(probe):
            return 2
        exe = str(Path(sys.executable).with_name("lightprobe"))
        with tempfile.TemporaryDirectory() as folder:
            commands = {"convert --to cube": ["convert", str(probe), f"{folder}/c.exr", "--to", "cube"],
                        "convert --to angular": ["convert", str(probe), f"{folder}/a.exr", "--to", "angular"],
                        "sh": ["sh", str(probe)],
                        "lights": ["lights", str(probe)],
                        "irradiance": ["irradiance", str(probe), "--output", f"{folder}/i.exr"],
                        "export --to babylon-env": ["export", str(probe), "--to", "babylon-env", "--output",
                                                        f"{folder}/b.env"]}
            print(f"\n  {'first command':28s} {'CPU s':>8s} {'wall s':>8s}")
            for name, argv in commands.items():
                cpu, wall, _ = fresh([exe, *argv])
                print(f"  {name:28s} {cpu:8.1f} {wall:8.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
