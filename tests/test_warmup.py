"""The kernel warm-up setup.sh runs: it must keep running every path it names (a broken call there would fail
setup, not only slow the first command)."""

from __future__ import annotations

import subprocess
import sys


def test_the_warm_up_runs_every_step_and_says_so():
    # From an empty numba cache this compiles every kernel: 3–5 minutes on 2 idle cores, more on a busy machine. The
    # timeout only ends a hang; it is not a speed the compile must reach.
    done = subprocess.run([sys.executable, "-m", "lightprobe.warmup"], capture_output=True, text=True, timeout=3600)
    assert done.returncode == 0, done.stderr
    steps = [line for line in done.stderr.splitlines() if "compiling kernels (" in line]
    assert [s.split("(")[1].rstrip(")") for s in steps] == ["maps", "lights", "renders", "radiance", "bake"]
    assert "kernels compiled (or loaded from numba's cache) in" in done.stderr
