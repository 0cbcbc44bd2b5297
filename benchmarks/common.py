"""What the benchmark scripts share: quiet, single-threaded BLAS set-up, the test data folder, best-of timing."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI does: idle BLAS threads slow numba's kernels
os.environ.setdefault("LIGHTPROBE_PROGRESS", "0")

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def best_of(fn, repeat: int) -> float:
    """The fastest of ``repeat`` runs, in seconds (the least disturbed by a noisy machine)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def require(*paths: Path) -> bool:
    """True if every data file is there; otherwise say which is missing on stderr."""
    for path in paths:
        if not path.is_file():
            print(f"benchmark data {path} not found (../shared/data beside the project)", file=sys.stderr)
            return False
    return True
