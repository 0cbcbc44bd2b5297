"""The batch's inputs: files, shell globs (``**`` recursive), or text files listing one path per line (``@list``
or any ``.txt``/``.lst``/``.list`` file), expanded into absolute paths in a stable order, each once."""

from __future__ import annotations

import glob
import os
from pathlib import Path

from ..util.errors import UsageError

LIST_SUFFIXES = (".txt", ".lst", ".list")
MAX_INPUTS = 10_000_000
MAX_LIST_BYTES = 1 << 30  # a list of inputs: 10⁷ paths of 100 characters


def _from_list(path: Path) -> list[str]:
    from ..maps.images import check_regular_file

    check_regular_file(path, "the list of inputs")  # /dev/zero or a FIFO would never end
    if path.stat().st_size > MAX_LIST_BYTES:
        raise UsageError(f"the list of inputs {path} is {path.stat().st_size} bytes, over the limit of "
                         f"{MAX_LIST_BYTES} (split it)")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"cannot read the list of inputs {path}: {getattr(e, 'strerror', None) or e}") from None
    base = path.parent
    lines = [line.strip() for line in text.splitlines()]
    return [str(Path(line) if Path(line).is_absolute() else base / line) for line in lines
            if line and not line.startswith("#")]


def expand_inputs(items: list[str]) -> list[str]:
    """Absolute paths of every input, in the order given (globs sorted), duplicates dropped.

    A glob that matches nothing, or an empty list, is refused with one line; a named file that does not exist is kept
    (the batch records its error).

    Parameters
    ----------
    items : list of str
        Files; shell globs (``**`` recursive; only the files they match); or lists of paths, one a line: ``@FILE``
        or an existing file ending in ``.txt``, ``.lst`` or ``.list``. In a list, blank lines and lines starting
        with ``#`` are skipped and relative paths are relative to the list's folder.

    Returns
    -------
    list of str
        Absolute paths (:func:`os.path.abspath`: symbolic links not resolved), each once, first occurrence kept.

    Raises
    ------
    UsageError
        No inputs, a glob or list that names no file, a list that is unreadable or over :data:`MAX_LIST_BYTES`, or
        over :data:`MAX_INPUTS` inputs.
    InputError
        A list is missing or not a regular file.
    """
    out: list[str] = []
    for item in items:
        if item.startswith("@") or (Path(item).suffix.lower() in LIST_SUFFIXES and Path(item).is_file()):
            listed = _from_list(Path(item.lstrip("@")))
            if not listed:
                raise UsageError(f"the list of inputs {item.lstrip('@')} names no file")
            out += listed
        elif glob.has_magic(item):
            matches = sorted(glob.glob(item, recursive=True))
            matches = [m for m in matches if Path(m).is_file()]
            if not matches:
                raise UsageError(f"no file matches {item!r}")
            out += matches
        else:
            out.append(item)
    if not out:
        raise UsageError("no inputs: give files, globs or a list of paths")
    seen, unique = set(), []
    for p in out:
        a = os.path.abspath(p)
        if a not in seen:
            seen.add(a)
            unique.append(a)
    if len(unique) > MAX_INPUTS:
        raise UsageError(f"{len(unique)} inputs is over the limit of {MAX_INPUTS} per batch")
    return unique
