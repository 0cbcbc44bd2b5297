"""numba's ``njit`` applied on a kernel's first call, so importing a module that holds kernels does not import
numba (0.3–0.4 s): ``lightprobe --help``, ``info`` and reading a map never pay for it.

Kernels written with ``prange`` name it as a module global; this module's :data:`prange` is ``range`` until the
first compilation, when numba's own ``prange`` is put in the kernel's globals so the loop is parallelised."""

from __future__ import annotations

import functools

prange = range  # replaced in each kernel's module by numba.prange when the first kernel there compiles


def use_threads() -> None:
    """numba's kernels run on :func:`lightprobe.limits.threads` threads (at most the pool numba started with)."""
    import numba

    from .limits import threads

    numba.set_num_threads(min(threads(), numba.config.NUMBA_NUM_THREADS))


def njit(**options):
    """Like ``numba.njit(**options)``, compiled on the first call (and cached on disk as numba caches it)."""
    def decorate(fn):
        compiled = None

        @functools.wraps(fn)
        def call(*args):
            nonlocal compiled
            if compiled is None:
                import numba

                use_threads()
                fn.__globals__["prange"] = numba.prange
                compiled = numba.njit(**options)(fn)
            return compiled(*args)

        call.py_func = fn
        return call

    return decorate
