"""What every ``INST:SEL`` mode of the emulated 35670A is: the :class:`MeasurementMode`
interface, the :class:`RunControl` the instrument hands a measurement, and the two ways a
measurement ends early (:class:`ModeConflict`, :class:`Aborted`).

A mode (:mod:`processing.instrument.measurement` registers them in ``MODES``) answers:

- ``check(scene, setup)``: raise :class:`ModeConflict` (one sentence, answered as
  ``-221,"Settings conflict; <why>"``) for what the emulated bench cannot carry;
- ``run(scene, setup, *, seed, control)``: measure; the result is what the traces read
  (:mod:`processing.instrument.traces`: ``freqs_hz``, ``frf(out, in)``, ``cross(m, n,
  scaling)``, ``time_record(ch)``, ``times_s``, ``volts_per_unit(ch)``; a feed the mode cannot
  give raises :class:`ModeConflict`) and carries its ``setup``;
- ``summary(result)``: the console's line for a finished measurement;
- ``overloads(result)``: the inputs overloaded, bit ``2^(n-1)`` for input n (``STAT:DEV``).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

__all__ = ["ModeConflict", "Aborted", "RunControl", "MeasurementMode"]


class ModeConflict(Exception):
    """What the emulated bench cannot do with these settings (one sentence)."""


class Aborted(Exception):
    """``ABOR`` (or a server shutdown) ended the measurement."""


def _no_status(bits: int) -> None:
    return None


@dataclass(frozen=True)
class RunControl:
    """What the instrument gives one measurement: ``abort`` (once set, the measurement ends at
    its next bench block or sweep point with :class:`Aborted`), ``realtime`` (pace it to the
    wall clock), ``path`` (keep its run file there; None: none) and ``oper(bits)`` (sets the
    ``STAT:OPER`` condition as the measurement goes)."""

    abort: threading.Event = field(default_factory=threading.Event)
    realtime: bool = False
    path: Path | None = None
    oper: Callable[[int], None] = _no_status


class MeasurementMode(Protocol):
    """An ``INST:SEL`` mode (module docstring)."""

    name: str

    def check(self, scene, setup) -> None: ...

    def run(self, scene, setup, *, seed: int, control: RunControl = RunControl()): ...

    def summary(self, result) -> str: ...

    def overloads(self, result) -> int: ...
