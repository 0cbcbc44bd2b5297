"""Errors and warnings that reach a user.

Every problem caused by the input (a bad file, an impossible size, a layout that does not fit) raises a
:class:`LightprobeError` whose message is one complete line. The CLI prints that line on stderr and exits with
code 2; library users catch the exception. Anything else escaping is a bug in lightprobe.
"""

from __future__ import annotations


class LightprobeError(Exception):
    """An error caused by the input, with a one-line message meant for a person."""


class InputError(LightprobeError):
    """A file that cannot be read, or whose contents are unusable."""


class LayoutError(LightprobeError):
    """An image whose shape does not fit the stated or detected layout."""


class LightprobeWarning(UserWarning):
    """Something was repaired on the way in (for example NaN pixels replaced by 0)."""
