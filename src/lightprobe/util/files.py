"""Writing files so that nothing is lost: temporary file, checked write, fsync, rename.

Every output of lightprobe goes through :func:`atomic_path` (or :func:`write_text` / :func:`write_bytes` on it):

* the target is refused when it is a folder, when it is one of the command's inputs (``sh in.hdr -o in.hdr``),
  (for text and binary containers) when its extension names an image format, or (for a binary container) when it
  exists and is another kind of file (no container signature: a user's image or ``.env`` settings);
* the data goes to a temporary file beside the target, named ``.NAME.lpPID-RANDOM.tmpEXT``; it is flushed and
  fsync'd, checked by the caller (an image is read back), and only then renamed over the target — so a full disk,
  a file-size limit or a crash never replaces a good file with a partial one;
* SIGTERM and SIGHUP raise :class:`Terminated` in the CLI (see :func:`raise_on_termination`), so the temporary file
  is removed on the way out; after a ``kill -9`` nothing can run, so each new write sweeps the folder for temporary
  files of this naming whose process is gone.

A command with several outputs writes them inside :func:`atomic_outputs`: each is written and checked aside as
above, and all are renamed only once every one is complete, so a failure leaves every old file.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import re
import secrets
import shutil
import signal
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from .errors import BudgetError, InputError

# Extensions of image files: text is never written over one of these (``sh probe.hdr -o probe.hdr`` style mistakes).
IMAGE_EXTENSIONS = frozenset(".hdr .rgbe .pic .exr .pfm .png .jpg .jpeg .tif .tiff .tga .bmp .webp .dds .ktx "
                             ".ktx2 .psd .gif .ppm .pnm".split())
_TEMP_NAME = re.compile(r"^\..+\.lp(\d+)-[0-9a-f]{8}\.tmp(\.[^./]*)?$")
# Inside atomic_outputs: the targets whose renames wait (resolved path -> temporary file, None until written).
_PENDING: contextvars.ContextVar[dict | None] = contextvars.ContextVar("lightprobe_pending_outputs", default=None)


class Terminated(BaseException):
    """Raised by the SIGTERM/SIGHUP handler so that ``finally`` blocks and temporary-file cleanup run."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def raise_on_termination() -> None:
    """Turn SIGTERM and SIGHUP into :class:`Terminated` (the CLI calls this once at start)."""
    def handler(signum, frame):
        raise Terminated(signum)

    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, handler)


def temp_path_for(path: Path) -> Path:
    """A fresh temporary name beside ``path`` that keeps its extension (image libraries pick formats by it).

    Parameters
    ----------
    path : Path
        The target file.

    Returns
    -------
    Path
        ``.NAME.lpPID-RANDOM.tmpEXT`` in the target's folder: NAME the target's name, PID this process's id,
        RANDOM 8 hex digits, EXT the target's extension. Nothing is created.
    """
    return path.with_name(f".{path.name}.lp{os.getpid()}-{secrets.token_hex(4)}.tmp{path.suffix}")


def process_alive(pid: int) -> bool:
    """True when process ``pid`` exists (ours or another user's).

    Parameters
    ----------
    pid : int
        A process id.

    Returns
    -------
    bool
        False only when no such process exists; a process we may not signal (another user's) counts as alive.
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def sweep_stale_temporaries(folder: Path, naming: re.Pattern = _TEMP_NAME) -> list[Path]:
    """Remove the temporary files and folders in ``folder`` left by processes that no longer exist.

    An entry is removed when its name matches ``naming`` (group 1: the pid of the process that made it; default:
    our temporary files and report folders) and that process no longer exists.

    Parameters
    ----------
    folder : Path
        The folder to sweep (not its subfolders); one that cannot be listed is left alone.
    naming : re.Pattern, optional
        The names to consider; group 1 must capture the pid. Default: ``.NAME.lpPID-RANDOM.tmpEXT``, the names of
        :func:`temp_path_for`, which the report folders use too. Entries of this process are never removed.

    Returns
    -------
    list of Path
        The files and folders removed (one that could not be removed is not listed and raises nothing).
    """
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = naming.match(entry.name)
        if match and int(match.group(1)) != os.getpid() and not process_alive(int(match.group(1))):
            with contextlib.suppress(OSError):
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path)
                else:
                    os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


def move_folder_into_place(built: Path, out: Path) -> None:
    """Put the finished folder ``built`` at ``out``; an existing ``out`` is moved aside first and removed last.

    If the move fails, the old ``out`` is put back. ``built`` and ``out`` must be on one file system (make ``built``
    beside ``out``: :func:`temp_path_for`).

    Parameters
    ----------
    built : Path
        The complete new folder.
    out : Path
        Where it goes.
    """
    old = None
    if out.exists():
        old = temp_path_for(out)
        os.replace(out, old)
    try:
        os.replace(built, out)
    except OSError:
        if old is not None:
            os.replace(old, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output(path: Path, inputs: Iterable[os.PathLike | str | None] = (), text: bool = False,
                 signature: bytes | None = None) -> Path:
    """Refuse an output path that cannot or must not be written (see the module docstring); returns it.

    Parameters
    ----------
    path : Path
        The output file (a string is accepted too).
    inputs : iterable of path-like or None, default ()
        The command's input files; writing over any of them (the same file, by ``os.path.samefile``) is refused.
        None entries are skipped.
    text : bool, default False
        The output is text: a path whose extension names an image format (:data:`IMAGE_EXTENSIONS`) is refused.
    signature : bytes, optional
        The output is a binary container whose files start with these bytes (Babylon's ``.env`` magic, glTF's
        ``glTF``): an image extension is refused as for text, and so is an existing non-empty file that does not
        start with them (it is not an earlier output of the same kind).

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    InputError
        ``path`` is a folder, its folder does not exist, it is one of ``inputs``, it has an image extension while
        ``text`` or ``signature`` is set, it exists and is not a regular file, or (``signature``) it exists and is
        another kind of file.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise InputError(f"cannot write {path}: it is a folder")
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: folder {folder} does not exist")
    for source in inputs:
        if source is not None and _same_file(path, Path(source)):
            raise InputError(f"refusing to write {path}: it is an input of this command (choose another output)")
    if (text or signature is not None) and path.suffix.lower() in IMAGE_EXTENSIONS:
        raise InputError(f"refusing to write {'text' if text else 'a binary container'} to {path}: its extension "
                         f"{path.suffix} names an image format")
    if path.exists() and not path.is_file():
        raise InputError(f"cannot write {path}: it exists and is not a regular file")
    if signature is not None and path.is_file() and _starts_otherwise(path, signature):
        raise InputError(f"refusing to overwrite {path}: it exists and is not a file of this kind (its first bytes "
                         "are not the format's signature; choose another output)")
    return path


def _starts_otherwise(path: Path, signature: bytes) -> bool:
    """True when the non-empty file ``path`` does not start with ``signature`` (an unreadable one: False, and the
    write reports it)."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(signature))
    except OSError:
        return False
    return bool(head) and head != signature


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, inputs: Iterable = (), text: bool = False,
                verify: Callable[[Path], None] | None = None, signature: bytes | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``, and rename it onto ``path`` when the block succeeds.

    When the block succeeds, fsync the temporary file, run ``verify(tmp)`` (which raises if the file is
    incomplete), give it the usual permissions and rename it onto ``path``. On any failure the temporary file is
    removed and ``path`` is untouched. OS errors become one-line :class:`InputError`\\ s that name ``path``, not the
    temporary file. Before anything is written, ``path`` is checked (:func:`check_output`) and its folder swept of
    stale temporaries (:func:`sweep_stale_temporaries`). Inside :func:`atomic_outputs`, the rename of one of its
    outputs waits until all of them are written.

    Parameters
    ----------
    path : str or path-like
        The file to write.
    inputs : iterable of path-like, default ()
        The command's input files, which ``path`` must not be (see :func:`check_output`).
    text : bool, default False
        The output is text: an image extension on ``path`` is refused.
    verify : callable taking a Path, optional
        Called on the fsync'd temporary file before the rename; it raises (an :class:`InputError`, say) if the file
        is incomplete, and then ``path`` is left untouched.
    signature : bytes, optional
        The output is a binary container starting with these bytes (see :func:`check_output`).

    Yields
    ------
    Path
        The temporary path (:func:`temp_path_for`) the block writes to; it keeps ``path``'s extension.

    Raises
    ------
    InputError
        ``path`` is refused by :func:`check_output`, the block wrote nothing, or an OS error occurred on the way.
    """
    path = check_output(Path(path), inputs, text, signature)
    sweep_stale_temporaries(path.parent if str(path.parent) else Path("."))
    tmp = temp_path_for(path)
    pending = _PENDING.get()
    key = _resolved(path)
    try:
        yield tmp
        if not tmp.is_file():
            raise InputError(f"cannot write {path}: nothing was written")
        _fsync(tmp)
        if verify is not None:
            verify(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        if pending is not None and key in pending and pending[key] is None:
            pending[key] = tmp  # renamed with the command's other outputs (atomic_outputs)
            tmp = None
        else:
            _rename(tmp, path)
    except OSError as e:
        raise InputError(f"cannot write {path}: {e.strerror or e}") from None
    finally:
        _remove(tmp)


def _rename(tmp: Path, path: Path) -> None:
    """Rename the finished ``tmp`` onto ``path`` and make the rename durable; an OS error is an InputError."""
    try:
        os.replace(tmp, path)
    except OSError as e:
        raise InputError(f"cannot write {path}: {e.strerror or e}") from None
    with contextlib.suppress(OSError):  # make the rename itself durable
        _fsync(path.parent if str(path.parent) else Path("."))


def _remove(tmp: Path | None) -> None:
    if tmp is not None:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _resolved(path: Path) -> Path:
    """``path`` with its folder resolved (symlinks, ``..``): two spellings of one output compare equal."""
    return Path(os.path.realpath(path.parent if str(path.parent) else ".")) / path.name


def distinct_outputs(paths: Iterable[os.PathLike | str | None]) -> list[Path]:
    """The outputs of one command, refused when two of them name the same file.

    Parameters
    ----------
    paths : iterable of path-like or None
        The outputs; None entries (options not given) are skipped.

    Returns
    -------
    list of Path
        The outputs as :class:`~pathlib.Path`\\ s, in the order given.

    Raises
    ------
    InputError
        Two of them are one file: the same path, two spellings of it (``a.png``, ``sub/../a.png``, a symlinked
        folder) or, for files that exist, hard links to it.
    """
    outputs = [Path(p) for p in paths if p is not None]
    seen = set()
    for path in outputs:
        key = _resolved(path)
        if key in seen or any(_same_file(path, other) for other in outputs if other is not path):
            raise InputError(f"refusing to write {path} twice: two outputs of this command name the same file")
        seen.add(key)
    return outputs


@contextlib.contextmanager
def atomic_outputs(paths: Iterable[os.PathLike | str | None]) -> Iterator[list[Path]]:
    """Commit several outputs of one command together: all of them, or none.

    Inside the block each output is written as usual (:func:`atomic_path`, or the writers built on it: written aside,
    fsync'd, checked), but its rename waits; when the block succeeds every one is renamed onto its target, back to
    back. When the block fails (an error, a refused or incomplete output, SIGTERM) every temporary file is removed
    and every old file is left as it was. (A rename that itself fails — an OS error, which a rename within one folder
    hardly meets — stops there: the outputs before it are in place, the rest keep their old files.)

    Parameters
    ----------
    paths : iterable of path-like or None
        The outputs the block writes; None entries (options not given) are skipped. Two of them naming one file
        are refused (:func:`distinct_outputs`).

    Yields
    ------
    list of Path
        The outputs, as :class:`~pathlib.Path`\\ s, in the order given.

    Raises
    ------
    InputError
        Two outputs name the same file; the block wrote nothing to one of the outputs; or a rename failed (an OS
        error). Whatever the block raises passes through, after the temporary files are removed.
    """
    outputs = distinct_outputs(paths)
    pending: dict[Path, Path | None] = {_resolved(path): None for path in outputs}
    token = _PENDING.set(pending)
    try:
        yield outputs
        _PENDING.reset(token)
        token = None
        missing = [p for p in outputs if pending[_resolved(p)] is None]
        if missing:
            raise InputError(f"cannot write {missing[0]}: nothing was written")
        for path in outputs:
            _rename(pending.pop(_resolved(path)), path)
    finally:
        if token is not None:
            _PENDING.reset(token)
        for tmp in pending.values():
            _remove(tmp)


def write_bytes(path: str | os.PathLike, data: bytes, inputs: Iterable = (), text: bool = False,
                signature: bytes | None = None) -> Path:
    """Write ``data`` to ``path`` atomically; the written size is checked before the rename.

    Parameters
    ----------
    path : str or path-like
        The file to write (see :func:`atomic_path`).
    data : bytes
        The whole contents.
    inputs : iterable of path-like, default ()
        The command's input files, which ``path`` must not be.
    text : bool, default False
        The data is text: an image extension on ``path`` is refused.
    signature : bytes, optional
        The data is a binary container starting with these bytes: an image extension on ``path``, or an existing
        file of another kind there, is refused (see :func:`check_output`).

    Returns
    -------
    Path
        ``path``, now holding ``data``.

    Raises
    ------
    InputError
        ``path`` is refused (:func:`check_output`), fewer bytes than ``len(data)`` were written, or an OS error
        occurred (a full disk, say); ``path`` is then untouched.
    """
    path = Path(path)

    def complete(tmp: Path) -> None:
        if tmp.stat().st_size != len(data):
            raise InputError(f"cannot write {path}: only {tmp.stat().st_size} of {len(data)} bytes were written")

    with atomic_path(path, inputs, text, verify=complete, signature=signature) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
    return path


def write_text(path: str | os.PathLike, text: str, inputs: Iterable = ()) -> Path:
    """Write UTF-8 text atomically; refuses a path with an image extension or one that is an input.

    Parameters
    ----------
    path : str or path-like
        The file to write (see :func:`atomic_path`).
    text : str
        The whole contents, encoded as UTF-8.
    inputs : iterable of path-like, default ()
        The command's input files, which ``path`` must not be.

    Returns
    -------
    Path
        ``path``, now holding the text.

    Raises
    ------
    InputError
        ``path`` is refused (:func:`check_output`; an image extension is refused), the write was incomplete, or an
        OS error occurred; ``path`` is then untouched.
    """
    return write_bytes(path, text.encode("utf-8"), inputs, text=True)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def digest_file(path: str | os.PathLike, digest) -> int:
    """Feed the file's bytes to ``digest`` (a hashlib object) in 1 MiB blocks; returns how many bytes there were.

    Only a regular file: a FIFO would block the open and a device (``/dev/zero``) never end (an OSError).

    Parameters
    ----------
    path : str or path-like
        The file to read.
    digest : hashlib hash object
        Anything with an ``update(bytes)`` method; it is updated in place.

    Returns
    -------
    int
        The number of bytes read.

    Raises
    ------
    OSError
        ``path`` is not a regular file (:class:`IsADirectoryError` for a folder), or it cannot be read.
    """
    import stat

    if not stat.S_ISREG(os.stat(path).st_mode):
        raise IsADirectoryError(errno.EISDIR, "a folder, not a file", str(path)) if os.path.isdir(path) else \
            OSError(errno.EINVAL, "not a regular file (a FIFO, device or socket)", str(path))
    size = 0
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return size


def read_bounded(path: str | os.PathLike, limit: int, what: str = "") -> bytes:
    """The whole of a small input file (JSON, YAML, a manifest), refused before it is read when over ``limit`` bytes.

    The file is opened without blocking (a FIFO never waits for a writer), checked to be a regular file and its size
    taken from the open file itself (``fstat``: no race with a rename); then at most ``limit + 1`` bytes are read, so
    a file that grows, or a sparse file of any claimed size, never costs more than ``limit`` bytes of memory.

    Parameters
    ----------
    path : str or path-like
        The file to read (links are followed).
    limit : int
        The most bytes accepted.
    what : str, default ""
        What the file is, put before the path in messages (``"scene"`` gives "cannot read scene PATH: …").

    Returns
    -------
    bytes
        The file's contents, at most ``limit`` bytes.

    Raises
    ------
    InputError
        The path does not exist, cannot be opened, is a folder, or is not a regular file (a FIFO, device or socket).
    BudgetError
        The file is over ``limit`` bytes.
    """
    import stat

    label = f"{what} {path}" if what else str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise InputError(f"cannot read {label}: no such file") from None
    except OSError as e:
        reason = "it is a folder, not a file" if e.errno == errno.EISDIR else e.strerror or str(e)
        raise InputError(f"cannot read {label}: {reason}") from None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(f"cannot read {label}: it is a folder, not a file")
        if not stat.S_ISREG(info.st_mode):
            raise InputError(f"cannot read {label}: it is not a regular file (a FIFO, device or socket)")
        size = info.st_size
        data = f.read(limit + 1) if size <= limit else b""
    if size > limit or len(data) > limit:
        raise BudgetError(f"refusing {label}: {max(size, len(data))} bytes is over the limit of {limit}")
    return data
