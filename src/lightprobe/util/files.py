"""Writing files so that nothing is lost: temporary file, checked write, fsync, rename.

Every output of lightprobe goes through :func:`atomic_path` (or :func:`write_text` / :func:`write_bytes` on it):

* the target is refused when it is a folder, when it is one of the command's inputs (``sh in.hdr -o in.hdr``), or
  (for text) when its extension names an image format;
* the data goes to a temporary file beside the target, named ``.NAME.lpPID-RANDOM.tmpEXT``; it is flushed and
  fsync'd, checked by the caller (an image is read back), and only then renamed over the target — so a full disk,
  a file-size limit or a crash never replaces a good file with a partial one;
* SIGTERM and SIGHUP raise :class:`Terminated` in the CLI (see :func:`raise_on_termination`), so the temporary file
  is removed on the way out; after a ``kill -9`` nothing can run, so each new write sweeps the folder for temporary
  files of this naming whose process is gone.
"""

from __future__ import annotations

import contextlib
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


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output(path: Path, inputs: Iterable[os.PathLike | str | None] = (), text: bool = False) -> Path:
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

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    InputError
        ``path`` is a folder, its folder does not exist, it is one of ``inputs``, it has an image extension while
        ``text`` is set, or it exists and is not a regular file.
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
    if text and path.suffix.lower() in IMAGE_EXTENSIONS:
        raise InputError(f"refusing to write text to {path}: its extension {path.suffix} names an image format")
    if path.exists() and not path.is_file():
        raise InputError(f"cannot write {path}: it exists and is not a regular file")
    return path


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, inputs: Iterable = (), text: bool = False,
                verify: Callable[[Path], None] | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``, and rename it onto ``path`` when the block succeeds.

    When the block succeeds, fsync the temporary file, run ``verify(tmp)`` (which raises if the file is
    incomplete), give it the usual permissions and rename it onto ``path``. On any failure the temporary file is
    removed and ``path`` is untouched. OS errors become one-line :class:`InputError`\\ s that name ``path``, not the
    temporary file. Before anything is written, ``path`` is checked (:func:`check_output`) and its folder swept of
    stale temporaries (:func:`sweep_stale_temporaries`).

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

    Yields
    ------
    Path
        The temporary path (:func:`temp_path_for`) the block writes to; it keeps ``path``'s extension.

    Raises
    ------
    InputError
        ``path`` is refused by :func:`check_output`, the block wrote nothing, or an OS error occurred on the way.
    """
    path = check_output(Path(path), inputs, text)
    sweep_stale_temporaries(path.parent if str(path.parent) else Path("."))
    tmp = temp_path_for(path)
    try:
        yield tmp
        if not tmp.is_file():
            raise InputError(f"cannot write {path}: nothing was written")
        _fsync(tmp)
        if verify is not None:
            verify(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
        with contextlib.suppress(OSError):  # make the rename itself durable
            _fsync(path.parent if str(path.parent) else Path("."))
    except OSError as e:
        raise InputError(f"cannot write {path}: {e.strerror or e}") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def write_bytes(path: str | os.PathLike, data: bytes, inputs: Iterable = (), text: bool = False) -> Path:
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

    with atomic_path(path, inputs, text, verify=complete) as tmp:
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
