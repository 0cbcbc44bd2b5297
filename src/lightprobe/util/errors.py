"""Errors and warnings that reach a user.

Every problem caused by the input (a bad file, an impossible size, a layout that does not fit, an argument out of
its range, work that would not fit in memory) raises a :class:`LightprobeError` whose message is one complete line.
The CLI prints that line on stderr and exits with code 2; library users catch the exception. Anything else escaping
is a bug in lightprobe.
"""

from __future__ import annotations


class LightprobeError(Exception):
    """An error caused by the input, with a one-line message meant for a person."""


class InputError(LightprobeError):
    """A file that cannot be read or written, or whose contents are unusable."""


class LayoutError(LightprobeError):
    """An image whose shape does not fit the stated or detected layout."""


class UsageError(LightprobeError, ValueError):
    """An argument outside its documented range or set of choices (also a ``ValueError``, as Python expects)."""


class BudgetError(LightprobeError):
    """Work refused before it starts because it would exceed a limit (pixels, triangles, memory)."""


class LightprobeWarning(UserWarning):
    """Something was repaired on the way in (for example NaN pixels replaced by 0)."""


def short(value, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, so that no message ever echoes a whole (possibly huge) value.

    Parameters
    ----------
    value : object
        Any value to name in a message; a string is cut to ``limit + 1`` characters before its ``repr`` is taken,
        so a huge string is never copied whole.
    limit : int, default 60
        The most characters of the result.

    Returns
    -------
    str
        ``repr(value)`` on one line (newlines become spaces); when longer than ``limit``, its first ``limit − 1``
        characters followed by ``…``.
    """
    text = repr(value) if not isinstance(value, str) else repr(value[: limit + 1])
    text = text.replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 1] + "…"
