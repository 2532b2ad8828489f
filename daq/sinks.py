"""Where the acquisition stream goes: the :class:`Sink` protocol, :class:`MemorySink` and the
fan-out that sends every event to every sink.

A sink receives, in order::

    check() -> start(Header) -> block(Block) ... record(Record) ... -> stop(Footer)

``check`` runs before anything is simulated (refuse a bad output path there), ``block`` delivers
digitised samples as soon as they exist (live views), ``record`` every finished record (files,
memory), ``stop`` always comes, whatever ended the run. A sink with ``critical = True`` (files,
memory) stops the run if it fails; one with ``critical = False`` (a live view) only warns and is
dropped (:class:`Fanout`).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Iterable

import numpy as np

from daq.records import Block, Footer, Header, Record, Recording

__all__ = ["Fanout", "MemorySink", "Sink"]


class Sink:
    """Receives the stream; override what you need.

    Attributes
    ----------
    critical : a failure of this sink stops the run (True: files, memory) or only drops the
        sink with a warning (False: live views).
    target : the file the sink will write (None: none); :func:`daq.acquisition.acquire` checks
        the free space beside it before the run.
    path : after :meth:`stop`, the file that holds the run (None if none was kept); the run's
        summary reports the first sink's with a ``target``.
    block_s : the longest bench block [s] this sink wants (None: any). A paced sink steps once
        a block, so it asks for short ones; :func:`daq.acquisition.acquire` runs its default
        bench in blocks no longer than any sink's (the same samples whatever the length).
    """

    critical = True
    target: Path | None = None
    path: Path | None = None
    block_s: float | None = None

    def check(self) -> None:
        """Refuse (a ``ConfigError``) what would make the sink fail, before the run starts."""

    def start(self, header: Header) -> None:
        pass

    def block(self, block: Block) -> None:
        pass

    def record(self, record: Record) -> None:
        pass

    def stop(self, footer: Footer) -> None:
        pass


class MemorySink(Sink):
    """Keeps the run in memory; :attr:`recording` is a :class:`daq.records.Recording`."""

    def __init__(self):
        self.header = None
        self.footer = None
        self._records = []

    def start(self, header: Header) -> None:
        self.header, self.footer, self._records = header, None, []

    def record(self, record) -> None:
        self._records.append(record)

    def stop(self, footer: Footer) -> None:
        self.footer = footer

    @property
    def recording(self) -> Recording:
        h = self.header
        n, recs = h.plan.samples, self._records

        def stack(get, key, shape, dtype):
            if not recs:
                return np.empty((0, n) + shape, dtype)
            return np.stack([get(r)[key] for r in recs])

        return Recording(
            header=h,
            codes={c.name: stack(lambda r: r.codes, c.name, (), c.adc.dtype) for c in h.channels},
            clipped={c.name: stack(lambda r: r.clipped, c.name, (), bool) for c in h.channels},
            truth={t.name: stack(lambda r: r.truth, t.name, t.shape, float) for t in h.truth},
            status=self.footer.status if self.footer else "acquiring",
            saturated={c.name: stack(lambda r: r.saturated, c.name, (), bool)
                       for c in h.channels})


class Fanout:
    """Sends each event to every sink in order: a critical sink's failure propagates, a live
    one's is a ``RuntimeWarning`` and the sink is dropped."""

    def __init__(self, sinks: Iterable[Sink]):
        self.sinks = list(sinks)

    def send(self, method: str, event) -> None:
        for s in list(self.sinks):
            try:
                getattr(s, method)(event)
            except Exception as exc:
                if getattr(s, "critical", True):
                    raise
                warnings.warn(f"sink {type(s).__name__} failed in {method}() and was dropped: "
                              f"{exc}", RuntimeWarning, stacklevel=2)
                self.sinks.remove(s)

    def stop_all(self, footer: Footer) -> list[BaseException]:
        """Stop every sink; collect (not raise) their errors."""
        errors = []
        for s in self.sinks:
            try:
                s.stop(footer)
            except Exception as exc:
                if getattr(s, "critical", True):
                    errors.append(exc)
                else:
                    warnings.warn(f"sink {type(s).__name__} failed in stop(): {exc}",
                                  RuntimeWarning, stacklevel=2)
        return errors
