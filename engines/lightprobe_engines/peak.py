"""Peak resident memory of a command, measured from outside it.

The command runs as the only child of a small wrapper process; the wrapper's ``getrusage(RUSAGE_CHILDREN)`` is then
the command's own peak. Read in the caller instead, it would be the largest of every child the caller ever waited
for (a test process has run many). Used by the memory tests and by the demo's memory figures."""

from __future__ import annotations

import os
import re
import subprocess
import sys

_WRAPPER = ("import resource, subprocess, sys\n"
            "r = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
            "sys.stdout.write(r.stdout)\n"
            "sys.stderr.write(r.stderr)\n"
            "print('PEAK', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr)\n"
            "sys.exit(r.returncode)\n")


def run_measured(argv: list[str], env: dict[str, str] | None = None,
                 timeout: float | None = None) -> tuple[subprocess.CompletedProcess, float]:
    """Run ``argv`` and return (the completed process, its stdout and stderr as text, its peak resident memory in
    MiB). ``env`` is added to this process's environment."""
    res = subprocess.run([sys.executable, "-c", _WRAPPER, *map(str, argv)], capture_output=True, text=True,
                         timeout=timeout, env={**os.environ, **(env or {})})
    found = re.search(r"PEAK (\d+)\n", res.stderr)
    if found is None:  # the wrapper itself failed: nothing was measured
        raise RuntimeError(f"could not measure {argv[:2]}: {res.stderr.strip()[-300:]}")
    res.stderr = res.stderr[:found.start()] + res.stderr[found.end():]
    return res, int(found.group(1)) / 1024
