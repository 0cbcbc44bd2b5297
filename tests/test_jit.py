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


def test_a_kernel_first_called_on_two_threads_compiles_against_its_helpers():
    """The resampler's first call runs its kernel on several threads at once. A thread that found the kernel's
    dispatcher while another was still swapping its helpers in compiled it against the Python helpers ("Untyped
    global name '_scratch'", seen on a cold cache). Here the swap is made slow, and the second thread arrives
    during it: it must wait, and both get the compiled answer. (The swap also makes the helper's dispatcher,
    whose own swap names the kernel back: that must not recurse.)"""
    names: dict = {}
    exec(SOURCE, names)
    helper = names["helper"]
    quick = helper.lazy_dispatcher

    def slow():
        time.sleep(0.5)
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
    time.sleep(0.2)  # inside the first thread's slow swap
    second = threading.Thread(target=run)
    second.start()
    first.join()
    second.join()
    assert not errors, errors
    assert results == [4.0, 4.0]
