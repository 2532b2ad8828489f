"""Ending a run on SIGTERM and SIGHUP as on Ctrl-C (SIGINT).

``timeout``, systemd, batch schedulers and a closed terminal stop a process with SIGTERM or
SIGHUP, whose default action ends it at once, without running ``finally`` blocks: the run file
would be left "acquiring" and marked open for writing. Within :func:`stop_signals_interrupt` they
raise :class:`Stopped` instead, a :class:`KeyboardInterrupt`, so a run ends exactly as on Ctrl-C
(status "interrupted", every finished record kept, the file closed). The acquisition defers these
signals, like SIGINT, while a record is handed to the sinks (``daq.acquisition``), so a record is
written whole or not at all.

The CLI uses the same block around every long job (``daq acquire``, ``daq dataset``, ``daq
export`` ...) and :func:`exit_status` for its status: 128 + N for signal N (130 Ctrl-C, 143
SIGTERM, 129 SIGHUP).
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["STOP_SIGNALS", "Stopped", "exit_status", "signal_name", "stop_signals_interrupt"]

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


def signal_name(exc: BaseException) -> str:
    """The signal that ended the job: ``SIGTERM``/``SIGHUP`` for :class:`Stopped` (or an
    exception carrying a ``signum``), ``SIGINT`` for any other KeyboardInterrupt."""
    signum = getattr(exc, "signum", None)
    return signal.Signals(signum).name if signum else "SIGINT"


def exit_status(exc: BaseException) -> int:
    """128 + N for a job ended by signal N (:func:`signal_name`): 130, 143, 129."""
    return 128 + int(signal.Signals[signal_name(exc)])
