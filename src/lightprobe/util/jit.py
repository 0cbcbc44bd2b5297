"""numba's ``njit`` applied on a kernel's first call, so importing a module that holds kernels does not import
numba (0.3–0.4 s): ``lightprobe --help``, ``info`` and reading a map never pay for it.

Kernels written with ``prange`` name it as a module global; this module's :data:`prange` is ``range`` until the
first compilation, when numba's own ``prange`` is put in the kernel's globals so the loop is parallelised."""

from __future__ import annotations

import functools
import sys
import threading

# Work (element operations: pixels × per-pixel work) from which loading numba — ~1 s and ~130 MB for its import and
# the first cached kernel, more when a kernel must compile — is repaid by its kernels, where a numpy formulation
# exists: the SH row sums cost numpy ~3.5 ns per pixel and order, so 2²⁸ is ~1 s of numpy (an 8k map at order 8).
COMPILE_WORTH = 1 << 28

prange = range  # replaced in each kernel's module by numba.prange when the first kernel there compiles
_MAKING = threading.RLock()  # held while a kernel's dispatcher is made (see njit)

# numba's array support imports scipy.linalg (its cython BLAS, ~26 MiB resident: 15 of heap, 11 of library pages —
# a convert's peak on a 4k map is ~3.4× the map) only to learn whether np.dot and np.linalg may compile in nopython
# mode. No lightprobe kernel uses them, so the ``lightprobe`` command, which runs no one else's kernels, sets this
# (:func:`lean`) and numba loads without it. A library user's process is left as numba makes it: their own kernels
# may need np.dot.
_LEAN = False
_BLAS_PROBE = "scipy.linalg.cython_blas"


def lean() -> None:
    """Load numba, when a kernel first needs it, without scipy's BLAS (see :data:`_LEAN`): for processes that run
    lightprobe's kernels only."""
    global _LEAN
    _LEAN = True


def import_numba():
    """``import numba``; under :func:`lean`, numba's array support loads with the BLAS probe's import refused — a
    None in ``sys.modules`` halts that one import, and is removed at once, so scipy imports as usual afterwards."""
    if _LEAN and "numba.np.arraymath" not in sys.modules and _BLAS_PROBE not in sys.modules:
        sys.modules[_BLAS_PROBE] = None
        try:
            import numba.np.arraymath  # noqa: F401  (its _HAVE_BLAS is False: np.dot is not compiled)
        finally:
            del sys.modules[_BLAS_PROBE]
    import numba

    return numba


def use_threads() -> None:
    """numba's kernels run on :func:`lightprobe.util.limits.threads` threads (at most the pool numba started with)."""
    numba = import_numba()

    from .limits import threads

    numba.set_num_threads(min(threads(), numba.config.NUMBA_NUM_THREADS))


def worth_compiling(work: int) -> bool:
    """Take a compiled kernel over its numpy formulation: numba is already loaded in this process (a long session),
    or ``work`` is big enough to repay loading it. A CLI run on a 2k map stays on numpy.

    The two formulations agree to the last few bits, not bit for bit; with ``LIGHTPROBE_COMPILE=by-work`` (set by
    ``lightprobe batch``'s workers) the choice depends on ``work`` alone, as in a fresh CLI process, so a result
    does not depend on what the process did before."""
    import os

    if os.environ.get("LIGHTPROBE_COMPILE") == "by-work":
        return work >= COMPILE_WORTH
    return "numba" in sys.modules or work >= COMPILE_WORTH


def njit(**options):
    """Like ``numba.njit(**options)``, compiled on the first call (and cached on disk as numba caches it).

    Kernels may call other functions decorated here (helpers, ``inline="always"`` or not): when the first kernel
    of a module compiles, every such function in its globals is swapped for its numba dispatcher, so numba can type
    the calls."""
    def decorate(fn):
        dispatcher = making = None

        def compiled():
            nonlocal dispatcher, making
            if dispatcher is None:
                # Kernels first run on several threads at once (the resampler's bands): the dispatcher is published
                # only once the helpers it calls are swapped in, or another thread would compile it against the
                # plain Python helpers ("Untyped global name"). Other threads wait on the lock; the making thread
                # takes it again while swapping, and a helper that names this function back gets ``making``.
                with _MAKING:
                    if dispatcher is None:
                        if making is not None:
                            return making
                        numba = import_numba()
                        use_threads()
                        fn.__globals__["prange"] = numba.prange
                        making = numba.njit(**options)(fn)
                        for name, value in list(fn.__globals__.items()):
                            if getattr(value, "lazy_dispatcher", None) is not None and value is not call:
                                fn.__globals__[name] = value.lazy_dispatcher()
                        dispatcher = making
            return dispatcher

        @functools.wraps(fn)
        def call(*args):
            return compiled()(*args)

        call.py_func = fn
        call.lazy_dispatcher = compiled
        return call

    return decorate


def read_only(a):
    """``a`` as a C-contiguous read-only array (a view where it is one already): numba compiles a kernel once per
    argument type, and a read-only array is another type than a writeable one, so the kernels' inputs are passed
    read-only always — a map's pixels are — and one compile serves every caller."""
    import numpy as np

    view = np.ascontiguousarray(a).view()
    view.setflags(write=False)
    return view


def dispatcher(fn):
    """numba's dispatcher of a function decorated with :func:`njit` (which may already have been swapped in for it),
    for compiled code outside the module, such as a test's kernel calling it."""
    lazy = getattr(fn, "lazy_dispatcher", None)
    return lazy() if lazy is not None else fn


# numba links even a cached kernel with LLVM, which leaves ~70 MiB of libllvmlite.so's pages resident for the rest of
# the process: a fifth of a 4k map's convert (3.35× the map with them; the bound is 3×). They are clean pages of the
# library's file — its code and constants, never written — so this process may unmap them (MADV_DONTNEED) and have any
# it touches again read back from the file. Only read-only mappings with no privately modified (Anonymous) page are
# touched: a library's relocated data (RELRO) is read-only too, but was written, and is left alone.
_MADV_DONTNEED = 4
_COMPILER_LIBRARIES = ("libllvmlite",)


def release_compiler_pages() -> int:
    """Unmap LLVM's resident file pages from this process (madvise MADV_DONTNEED on libllvmlite's read-only,
    unmodified mappings), for a process whose kernels are linked and whose data comes next (``lightprobe convert``
    links its kernels on a small map, then reads the big one). Returns the bytes advised; 0 where numba is not
    loaded, the platform has no /proc/self/smaps or the advice is refused. Nothing is lost: a page touched again (a
    kernel linked later) is read back from the library's file."""
    if "numba" not in sys.modules:
        return 0
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.madvise.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
        spans = _clean_read_only_mappings(_COMPILER_LIBRARIES)
    except (OSError, AttributeError, ValueError):
        return 0
    advised = 0
    for low, high in spans:
        if libc.madvise(low, high - low, _MADV_DONTNEED) == 0:
            advised += high - low
    return advised


def _clean_read_only_mappings(libraries) -> list[tuple[int, int]]:
    """(start, end) of this process's mappings of files named like ``libraries`` that are not writable and hold no
    privately modified page (/proc/self/smaps: ``Anonymous: 0 kB``)."""
    spans, current = [], None
    with open("/proc/self/smaps", encoding="ascii", errors="replace") as smaps:
        for line in smaps:
            fields = line.split()
            if fields and "-" in fields[0] and not fields[0].endswith(":"):  # a mapping's header line
                wanted = len(fields) >= 6 and "w" not in fields[1] and any(n in fields[5] for n in libraries)
                current = tuple(int(end, 16) for end in fields[0].split("-")) if wanted else None
            elif current is not None and fields[:1] == ["Anonymous:"]:
                if fields[1] == "0":
                    spans.append(current)
                current = None
    return spans
