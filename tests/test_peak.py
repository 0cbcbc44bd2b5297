"""lightprobe_engines.peak: a command's own peak memory, measured from outside it."""

from __future__ import annotations

import sys

import pytest

from lightprobe_engines.peak import run_measured


def test_the_peak_is_the_commands_own_and_its_output_is_kept():
    """A child that holds 200 MiB reads over 200, one that holds nothing far under; output, errors and the exit
    status come back as the command left them (the wrapper's own line taken out of stderr)."""
    big = "import sys\nb = bytearray(200 << 20)\nb[::4096] = b'x' * len(b[::4096])\nprint('out'); sys.exit(3)\n"
    res, peak = run_measured([sys.executable, "-c", big])
    assert peak > 200 and res.returncode == 3 and res.stdout == "out\n" and "PEAK" not in res.stderr
    res, small = run_measured([sys.executable, "-c", "import sys; sys.stderr.write('err\\n')"])
    assert small < 100 and res.returncode == 0 and res.stderr == "err\n"


def test_a_command_that_cannot_start_is_an_error_not_a_figure():
    with pytest.raises((RuntimeError, FileNotFoundError)):
        run_measured(["/nonexistent/lightprobe-command"])
