"""The batch's inputs: files, shell globs (``**`` recursive), or text files listing one path per line (``@list``
or any ``.txt``/``.lst``/``.list`` file), expanded into absolute paths in a stable order, each once.

A ``**`` does not descend into symbolic links to folders (a link loop would expand without end), a file reached
through two paths is one input (by its real path), and nothing under the batch's own folder is matched: a batch
whose ``--out`` is inside the globbed tree does not take its artifacts as inputs on ``--resume``."""

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


def _listdir(folder: str) -> list[os.DirEntry]:
    try:
        with os.scandir(folder or os.curdir) as entries:
            return sorted(entries, key=lambda e: e.name)
    except (OSError, ValueError):
        return []


def _below(folder: str, skip: str | None) -> list[str]:
    """``folder`` and every folder below it, not through symbolic links nor into hidden folders or ``skip``."""
    found, stack = [], [folder]
    while stack:
        current = stack.pop()
        found.append(current)
        stack += [os.path.join(current, e.name) for e in reversed(_listdir(current))
                  if not e.name.startswith(".") and e.is_dir(follow_symlinks=False)
                  and os.path.realpath(os.path.join(current, e.name)) != skip]
    return found


def _glob(pattern: str, skip: str | None) -> list[str]:
    """The files ``pattern`` matches, as :func:`glob.glob` with ``recursive=True`` matches them, except that
    ``**`` follows no symbolic link to a folder and does not enter ``skip`` (a real path)."""
    import fnmatch

    head, parts = pattern, []
    while glob.has_magic(head):
        head, part = os.path.split(head)
        parts.insert(0, part)
    candidates = [head]
    for i, part in enumerate(parts):
        last, found = i == len(parts) - 1, []
        for base in candidates:
            if part == "**":
                folders = _below(base, skip)
                found += folders + ([os.path.join(f, e.name) for f in folders for e in _listdir(f)
                                     if not e.name.startswith(".")] if last else [])
            elif glob.has_magic(part):
                found += [os.path.join(base, e.name) for e in _listdir(base) if fnmatch.fnmatchcase(e.name, part)
                          and (not e.name.startswith(".") or part.startswith("."))]
            elif os.path.lexists(os.path.join(base, part)):
                found.append(os.path.join(base, part))
        candidates = list(dict.fromkeys(found))
    return sorted(c for c in candidates if c and os.path.isfile(c))


def _inside(path: str, folder: str | None) -> bool:
    return folder is not None and (path == folder or path.startswith(folder.rstrip(os.sep) + os.sep))


def expand_inputs(items: list[str], exclude: os.PathLike | str | None = None) -> list[str]:
    """Absolute paths of every input, in the order given (globs sorted), duplicates dropped.

    A glob that matches nothing, or an empty list, is refused with one line; a named file that does not exist is kept
    (the batch records its error).

    Parameters
    ----------
    items : list of str
        Files; shell globs (``**`` recursive; only the files they match); or lists of paths, one a line: ``@FILE``
        or an existing file ending in ``.txt``, ``.lst`` or ``.list``. In a list, blank lines and lines starting
        with ``#`` are skipped and relative paths are relative to the list's folder.

    exclude : path-like, optional
        A folder (the batch's ``--out``) whose files globs never match; ``**`` does not enter it.

    Returns
    -------
    list of str
        Absolute paths (:func:`os.path.abspath`: symbolic links not resolved), each file once (by its real path,
        :func:`os.path.realpath`), first occurrence kept.

    Raises
    ------
    UsageError
        No inputs, a glob or list that names no file, a list that is unreadable or over :data:`MAX_LIST_BYTES`, or
        over :data:`MAX_INPUTS` inputs.
    InputError
        A list is missing or not a regular file.
    """
    skip = os.path.realpath(exclude) if exclude is not None else None
    out: list[str] = []
    for item in items:
        if item.startswith("@") or (Path(item).suffix.lower() in LIST_SUFFIXES and Path(item).is_file()):
            listed = _from_list(Path(item.lstrip("@")))
            if not listed:
                raise UsageError(f"the list of inputs {item.lstrip('@')} names no file")
            out += listed
        elif glob.has_magic(item):
            matches = [m for m in _glob(item, skip) if not _inside(os.path.realpath(m), skip)]
            if not matches:
                raise UsageError(f"no file matches {item!r}")
            out += matches
        else:
            out.append(item)
    if not out:
        raise UsageError("no inputs: give files, globs or a list of paths")
    seen, unique = set(), []
    for p in out:
        try:
            real = os.path.realpath(p)
        except ValueError:  # a listed path with a NUL byte, which no file can have: that input's error, later
            real = os.path.abspath(p)
        if real not in seen:
            seen.add(real)
            unique.append(os.path.abspath(p))
    if len(unique) > MAX_INPUTS:
        raise UsageError(f"{len(unique)} inputs is over the limit of {MAX_INPUTS} per batch")
    return unique
