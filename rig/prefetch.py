"""Run an iterator ahead in a background thread (a bounded FIFO between two pipeline stages).

The emulator's stages (source noise -> bench -> anti-alias filter, ADC and file) are sequential
computations on long arrays in compiled code or numpy, which release the GIL; running a producing
stage in its own thread lets it work on the next block while the consumer handles the previous one
(two cores: ~2x). Blocks keep their content and order: reproducibility is untouched.
"""

from __future__ import annotations

import queue
import threading
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")


def prefetch(items: Iterable[T], depth: int = 2) -> Iterator[T]:
    """``items``, produced by a daemon thread up to ``depth`` items ahead.

    An exception raised while producing is re-raised here, where its item would have been. When
    the consumer stops (exhausted, error, Ctrl-C or close()), the producer stops before its next
    item.
    """
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
        raise ValueError(f"depth = {depth!r} is invalid: expected an integer >= 1")
    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

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

    return _consume(q, stop, threading.Thread(target=produce, name="prefetch", daemon=True))


def _consume(q: queue.Queue, stop: threading.Event, worker: threading.Thread) -> Iterator:
    worker.start()
    try:
        while True:
            kind, x = q.get()
            if kind == "item":
                yield x
            elif kind == "error":
                raise x
            else:
                return
    finally:
        stop.set()
