"""lightprobe.util.jit: kernels compiled on their first call, with the helpers they call swapped in first."""

from __future__ import annotations

import textwrap
import threading
import time

SOURCE = textwrap.dedent('''
    from lightprobe.util.jit import njit

    @njit()
    def helper(x):
        return x + 1.0

    @njit()
    def kernel(x):
        return helper(x) * 2.0
''')


def test_a_kernel_first_called_on_two_threads_compiles_against_its_helpers(monkeypatch):
    """The resampler's first call runs its kernel on several threads at once. A thread that found the kernel's
    dispatcher while another was still swapping its helpers in compiled it against the Python helpers ("Untyped
    global name '_scratch'", seen on a cold cache). Here the swap is held until a second thread has come to the
    lock the first one holds: it must wait there, and both get the compiled answer. (The swap also makes the
    helper's dispatcher, whose own swap names the kernel back: that must not recurse.)"""
    import lightprobe.util.jit as jit

    names: dict = {}
    exec(SOURCE, names)
    helper = names["helper"]
    quick = helper.lazy_dispatcher
    lock, arrivals, swapping = jit._MAKING, [], threading.Event()

    class Watched:  # the lock, noting each thread that comes to it before it waits there
        def __enter__(self):
            arrivals.append(threading.get_ident())
            return lock.__enter__()

        def __exit__(self, *exc):
            return lock.__exit__(*exc)

    monkeypatch.setattr(jit, "_MAKING", Watched())

    def slow():  # the swap, held until the second thread waits at the lock this one holds
        swapping.set()
        deadline = time.monotonic() + 120
        while len(set(arrivals)) < 2:
            assert time.monotonic() < deadline, "the second thread never came to the lock"
            time.sleep(0.01)
        return quick()

    helper.lazy_dispatcher = slow
    results, errors = [], []

    def run():
        try:
            results.append(names["kernel"](1.0))
        except Exception as e:  # noqa: BLE001 - the test reports what the thread met
            errors.append(e)

    first = threading.Thread(target=run)
    first.start()
    assert swapping.wait(120), errors  # the first thread is inside its swap
    second = threading.Thread(target=run)
    second.start()
    first.join()
    second.join()
    assert not errors, errors
    assert results == [4.0, 4.0]
