"""Limits that keep hostile or absurd input from taking the machine: pixels, triangles and memory.

Each limit has a default and an environment variable to change it; a malformed variable is reported when a limit is
used (one line, exit 2), never at import. Work is refused *before* it starts when its estimated peak memory exceeds
:func:`max_memory`, so a 0.4 MB PNG that decodes to 16384×8192 pixels gets one line, not 14 GB of swap.

* ``LIGHTPROBE_MAX_PIXELS`` (default 2²⁷): pixels of one image, read or made.
* ``LIGHTPROBE_MAX_TRIANGLES`` (default 2·10⁷): triangles of one scene, all meshes together.
* ``LIGHTPROBE_MAX_MEMORY`` (bytes, or with a suffix K, M, G; default half of the machine's physical memory): the
  estimated peak resident memory of one command.
* ``LIGHTPROBE_THREADS`` (default all cores): threads of the compiled kernels and of BLAS, so that a process pool
  or a Dask worker can run one thread per process without oversubscribing the machine.
"""

from __future__ import annotations

import os
import re

from .errors import BudgetError, UsageError

DEFAULT_MAX_PIXELS = 1 << 27
DEFAULT_MAX_TRIANGLES = 20_000_000
_SUFFIX = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def positive_env(name: str, default: int, units: bool = False) -> int:
    """The positive whole number in environment variable ``name``, or ``default`` when it is unset or blank.

    With ``units`` the value is bytes and a K/M/G/T suffix is allowed; anything else is a :class:`UsageError`
    naming the variable.

    Parameters
    ----------
    name : str
        The environment variable, e.g. ``LIGHTPROBE_MAX_PIXELS``.
    default : int
        The value when the variable is unset or blank (returned as given, unchecked).
    units : bool, default False
        Read a number of bytes: digits with an optional suffix K, M, G or T (powers of 1024, any case, optionally
        followed by ``B`` or ``iB``), e.g. ``8G``. Without it, only plain digits.

    Returns
    -------
    int
        The value, ≥ 1 (in bytes with ``units``).

    Raises
    ------
    UsageError
        The variable is set but is not a positive whole number (of bytes, with ``units``).
    """
    text = os.environ.get(name)
    if text is None or not text.strip():
        return default
    match = re.fullmatch(r"\s*(\d+)\s*([KMGT]?)(?:i?B)?\s*", text, re.I) if units else re.fullmatch(r"\s*(\d+)\s*", text)
    value = int(match.group(1)) * (_SUFFIX[match.group(2).upper()] if units else 1) if match else 0
    if value < 1:
        kind = "a positive number of bytes (e.g. 8G)" if units else "a positive whole number"
        raise UsageError(f"{name} must be {kind}, got {text[:40]!r}")
    return value


def threads() -> int:
    """Threads for numba's kernels and BLAS: ``LIGHTPROBE_THREADS``, or every core.

    Returns
    -------
    int
        The number of threads, ≥ 1.

    Raises
    ------
    UsageError
        ``LIGHTPROBE_THREADS`` is set but is not a positive whole number.
    """
    return positive_env("LIGHTPROBE_THREADS", os.cpu_count() or 1)


def max_pixels() -> int:
    """The most pixels of one image, read or made: ``LIGHTPROBE_MAX_PIXELS``, or :data:`DEFAULT_MAX_PIXELS` (2²⁷).

    Returns
    -------
    int
        The limit in pixels, ≥ 1.

    Raises
    ------
    UsageError
        ``LIGHTPROBE_MAX_PIXELS`` is set but is not a positive whole number.
    """
    return positive_env("LIGHTPROBE_MAX_PIXELS", DEFAULT_MAX_PIXELS)


def max_triangles() -> int:
    """The most triangles of one scene, all meshes together: ``LIGHTPROBE_MAX_TRIANGLES``, or 2·10⁷.

    The default is :data:`DEFAULT_MAX_TRIANGLES`.

    Returns
    -------
    int
        The limit in triangles, ≥ 1.

    Raises
    ------
    UsageError
        ``LIGHTPROBE_MAX_TRIANGLES`` is set but is not a positive whole number.
    """
    return positive_env("LIGHTPROBE_MAX_TRIANGLES", DEFAULT_MAX_TRIANGLES)


def physical_memory() -> int:
    """Bytes of physical memory (or of the cgroup limit, when one is set and smaller).

    The cgroup limit is read from ``/sys/fs/cgroup/memory.max`` (v2) or
    ``/sys/fs/cgroup/memory/memory.limit_in_bytes`` (v1); an unreadable file or one that is not a number (``max``)
    is passed over.

    Returns
    -------
    int
        Bytes: page size × physical pages, or the smaller cgroup limit.
    """
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = open(path).read().strip()
        except OSError:
            continue
        if text.isdigit():
            total = min(total, int(text))
    return total


def _address_space_left() -> int | None:
    """Bytes this process may still map under ``ulimit -v`` (RLIMIT_AS), or None when there is no such limit."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    try:
        status = open("/proc/self/status").read()
        used = int(re.search(r"VmSize:\s*(\d+) kB", status).group(1)) * 1024
    except (OSError, AttributeError):
        used = 0
    return max(soft - used, 0)


def max_memory() -> int:
    """The memory budget of one command: ``LIGHTPROBE_MAX_MEMORY``, else half the physical memory.

    It is never more than the address space a ``ulimit -v`` leaves (under such a cap Mitsuba and numba crash
    instead of raising).

    Returns
    -------
    int
        The budget in bytes: the variable's value, or half of :func:`physical_memory`, capped by the address space
        this process may still map under ``ulimit -v`` (RLIMIT_AS) when there is such a limit.

    Raises
    ------
    UsageError
        ``LIGHTPROBE_MAX_MEMORY`` is set but is not a positive number of bytes (e.g. ``8G``).
    """
    budget = positive_env("LIGHTPROBE_MAX_MEMORY", physical_memory() // 2, units=True)
    left = _address_space_left()
    return budget if left is None else min(budget, left)


def gib(n: float) -> str:
    """A byte count as people read it in a message: GiB with two decimals from 256 MiB up, else whole MiB.

    Parameters
    ----------
    n : float
        A number of bytes.

    Returns
    -------
    str
        For example ``"1.50 GiB"`` or ``"80 MiB"``.
    """
    return f"{n / (1 << 30):.2f} GiB" if n >= 1 << 28 else f"{n / (1 << 20):.0f} MiB"


def check_pixels(count: int, what: str) -> None:
    """Refuse ``count`` pixels (an exact Python integer: no overflow) over :func:`max_pixels`.

    Parameters
    ----------
    count : int
        The pixels of the image to be read or made, as an exact Python integer (a product of numpy integers could
        overflow).
    what : str
        What is refused, named at the start of the message (e.g. a file and the size its header claims).

    Raises
    ------
    BudgetError
        ``count`` is over :func:`max_pixels` (the message says to set ``LIGHTPROBE_MAX_PIXELS`` to raise it).
    UsageError
        ``LIGHTPROBE_MAX_PIXELS`` is set but is not a positive whole number.
    """
    limit = max_pixels()
    if count > limit:
        raise BudgetError(f"refusing {what}: {count} pixels is over the limit of {limit} "
                          "(set LIGHTPROBE_MAX_PIXELS to raise it)")


PROCESS_BYTES = 80 << 20  # resident memory of lightprobe before any data (Python, numpy, OpenImageIO): ~55 MB
# numba and LLVM once a compiled kernel runs: ~130 MiB resident measured, ~200 MiB on a freshly installed machine
# (resident memory counts their libraries' file pages, and all of those are in the page cache after an install)
KERNEL_BYTES = 224 << 20


def check_memory(work_bytes: int, what: str, virtual_bytes: int = 0, kernels: bool = False) -> None:
    """Refuse work whose estimated peak memory exceeds :func:`max_memory`.

    The estimated peak is :data:`PROCESS_BYTES` (plus :data:`KERNEL_BYTES` when the work runs compiled ``kernels``)
    plus ``work_bytes`` (the data's own memory). ``virtual_bytes``: address space the work maps beyond what it
    touches (a JIT's reservations), which counts only against a ``ulimit -v``.

    Parameters
    ----------
    work_bytes : int
        Bytes of the data's own memory at the work's peak.
    what : str
        What is refused, named at the start of the message (e.g. ``"rendering 1920x1080 at 4x4 …"``).
    virtual_bytes : int, default 0
        Address space mapped beyond what is touched; with ``work_bytes`` it is checked against what a ``ulimit -v``
        leaves, and against nothing else.
    kernels : bool, default False
        The work runs compiled (numba) kernels: :data:`KERNEL_BYTES` is added to the estimate.

    Raises
    ------
    BudgetError
        ``work_bytes + virtual_bytes`` is over the address space a ``ulimit -v`` leaves, or the estimated peak is
        over :func:`max_memory` (the message says to set ``LIGHTPROBE_MAX_MEMORY`` to raise it).
    UsageError
        ``LIGHTPROBE_MAX_MEMORY`` is set but is not a positive number of bytes.
    """
    limit = max_memory()
    estimate = PROCESS_BYTES + (KERNEL_BYTES if kernels else 0) + work_bytes
    left = _address_space_left()
    if left is not None and work_bytes + virtual_bytes > left:
        raise BudgetError(f"refusing {what}: it needs about {gib(work_bytes + virtual_bytes)} of address space, "
                          f"over the {gib(left)} that the process limit (ulimit -v) leaves")
    if estimate > limit:
        raise BudgetError(f"refusing {what}: it needs about {gib(estimate)} of memory, over the limit of {gib(limit)} "
                          "(set LIGHTPROBE_MAX_MEMORY to raise it)")
