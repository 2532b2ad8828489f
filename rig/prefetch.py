"""Run an iterator ahead in a background thread (a bounded FIFO between two pipeline stages).

The emulator's stages (source noise -> bench -> anti-alias filter, ADC and file) are sequential
computations on long arrays in compiled code or numpy, which release the GIL; running a producing
stage in its own thread lets it work on the next block while the consumer handles the previous one
(on the paper's acquisition: 2.7 s -> 1.2 s inside ``acquire``, BENCHMARKS.md). Blocks keep their
content and order: reproducibility is untouched.
"""

from __future__ import annotations

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
