"""Threads, shared infrastructure of the packages above: run an iterator ahead in a background
thread, and hold every loaded OpenBLAS at one thread.

:class:`Prefetch` is a bounded FIFO between two pipeline stages. The emulator's stages (source
noise -> bench -> anti-alias filter, ADC and file) are computations on long arrays in compiled
code or numpy, which release the GIL; a producing stage in its own thread works on the next block
while the consumer handles the previous one. Items keep their content and order, so
reproducibility is untouched.

:func:`single_threaded_blas` sets the OpenBLAS libraries already loaded into the process to one
thread for a ``with`` block and restores them afterwards, through the libraries' own
``*_set_num_threads`` entry points (what threadpoolctl does); where it finds none (another BLAS,
no ``/proc``) it does nothing. It is for thin products (a thousand rows by a dozen columns: the
modal fits, the bench's block products), which gain nothing from more threads while OpenBLAS's
spinning threads take the CPU from the single-threaded FFTs around them.

Measured gains (acquisition wall time, analysis CPU time): BENCHMARKS.md.
"""

from __future__ import annotations

import contextlib
import ctypes
import queue
import threading
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")


class Prefetch:
    """``items``, produced by a daemon thread started at once, up to ``depth`` items ahead.

    Iterate it like ``items``. An exception raised while producing is re-raised by ``next``,
    where its item would have been. :meth:`close` (also on garbage collection, and when
    exhausted) stops the producer before its next item.
    """

    def __init__(self, items: Iterable[T], depth: int = 2):
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
            raise ValueError(f"depth = {depth!r} is invalid: expected an integer >= 1")
        self._q: queue.Queue = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._done = False
        q, stop = self._q, self._stop  # the thread must not keep self alive

        def put(item) -> bool:
            while not stop.is_set():
                try:
                    q.put(item, timeout=0.05)
                    return True
                except queue.Full:
                    continue
            return False

        def produce():
            try:
                for x in items:
                    if not put(("item", x)):
                        return
            except BaseException as exc:  # handed to the consumer
                put(("error", exc))
                return
            put(("end", None))

        threading.Thread(target=produce, name="prefetch", daemon=True).start()

    def __iter__(self) -> "Prefetch":
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        kind, x = self._q.get()
        if kind == "item":
            return x
        self.close()
        if kind == "error":
            raise x
        raise StopIteration

    def close(self) -> None:
        """Stop the producer (it finishes the item it is making, if any)."""
        self._done = True
        self._stop.set()

    def __del__(self):
        stop = getattr(self, "_stop", None)  # None if __init__ refused its arguments
        if stop is not None:
            stop.set()


def prefetch(items: Iterable[T], depth: int = 2) -> Iterator[T]:
    """:class:`Prefetch` of ``items`` (started now)."""
    return Prefetch(items, depth)


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
