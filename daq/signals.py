"""Ending a run on SIGTERM and SIGHUP as on Ctrl-C (SIGINT).

``timeout``, systemd, batch schedulers and a closed terminal stop a process with SIGTERM or
SIGHUP, whose default action ends it at once, without running ``finally`` blocks: the run file
would be left "acquiring" and marked open for writing. Within :func:`stop_signals_interrupt` they
raise :class:`Stopped` instead, a :class:`KeyboardInterrupt`, so a run ends exactly as on Ctrl-C
(status "interrupted", every finished record kept, the file closed). The acquisition defers these
signals, like SIGINT, while a record is handed to the sinks (``daq.acquisition``), so a record is
written whole or not at all.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["STOP_SIGNALS", "Stopped", "stop_signals_interrupt"]

#: The signals that end a run like SIGINT, besides SIGINT itself.
STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None),
                                 getattr(signal, "SIGHUP", None)) if s is not None)


class Stopped(KeyboardInterrupt):
    """A stop signal (SIGTERM, SIGHUP) arrived; ``signum`` says which."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name


def _raise_stopped(signum, frame):
    raise Stopped(signum)


@contextlib.contextmanager
def stop_signals_interrupt():
    """Within the block, SIGTERM and SIGHUP raise :class:`Stopped` (a KeyboardInterrupt); the
    previous handlers are restored afterwards. Does nothing outside the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    try:
        for s in STOP_SIGNALS:
            old[s] = signal.signal(s, _raise_stopped)
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
