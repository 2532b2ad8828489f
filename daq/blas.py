"""One BLAS thread for thin matrix products: the analyzer's fits and the bench's block products.

The analysis multiplies thin matrices (a thousand rows by a dozen columns: the modal fits' least
squares, QR factorisations, covariances) hundreds of times. OpenBLAS runs products of that size on
every core, and between calls its threads spin waiting for work, taking the CPU from the
single-threaded FFTs around them: on the shared two-core machine this project runs on, the paper's
analysis took 0.55 s of CPU with the default threads and 0.21 s with one (same results; minimum
of 7 runs each). :func:`single_threaded_blas` sets the OpenBLAS libraries already loaded into the
process to one thread for the duration of a ``with`` block and restores their setting afterwards,
by the libraries' own ``*_set_num_threads`` entry points (what threadpoolctl does). Where it finds
none (another BLAS, no ``/proc``) it does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes

# (get, set) entry points of OpenBLAS builds: numpy's and scipy's wheels (scipy-openblas, 64-bit
# integers or not) and a plain OpenBLAS.
_ENTRY_POINTS = (
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
    ("openblas_get_num_threads", "openblas_set_num_threads"),
)


def _openblas_controls() -> list:
    """``(get, set)`` ctypes functions of every OpenBLAS loaded into this process."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            paths = sorted({line.split()[-1] for line in fh
                            if "openblas" in line.lower() and ".so" in line})
    except OSError:
        return []
    controls = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get_name, set_name in _ENTRY_POINTS:
            get, set_ = getattr(lib, get_name, None), getattr(lib, set_name, None)
            if get is not None and set_ is not None:
                get.restype, get.argtypes = ctypes.c_int, []
                set_.restype, set_.argtypes = None, [ctypes.c_int]
                controls.append((get, set_))
                break
    return controls


@contextlib.contextmanager
def single_threaded_blas():
    """Run the ``with`` block with one thread in every loaded OpenBLAS (restored afterwards).

    It changes a process-wide setting: other threads of the process doing linear algebra meanwhile
    run single-threaded too.
    """
    saved = [(set_, get()) for get, set_ in _openblas_controls()]
    for set_, _ in saved:
        set_(1)
    try:
        yield len(saved)
    finally:
        for set_, n in saved:
            set_(n)
