"""IEEE 488.2 / SCPI status reporting of the emulated 35670A: the standard event status register
(``*ESR?``, ``*ESE``), the status byte (``*STB?``, ``*SRE``) and the SCPI condition/event
register pairs (``STAT:OPER``, ``STAT:QUES``, ``STAT:DEV``: ``:COND?``, ``[:EVEN]?``, ``:ENAB``).

Bits the emulator sets (its own assignment where the instrument's is not documented here):

- ``STAT:OPER``: 16 measuring (from ``INIT`` to the end of the measurement), 256 averaging
  (while records are averaged, after the bench's settling), 2 settling, 8 sweeping (a
  swept-sine measurement, its first point to its last);
- ``STAT:QUES``: 1 voltage: an input overloaded in the last measurement;
- ``STAT:DEV``: 1, 2, 4, 8: input 1..4 overloaded (ADC clipping or sensor saturation) in the last
  measurement;
- ``*ESR``: 1 operation complete (``*OPC``), 4 query error, 8 device error, 16 execution error,
  32 command error, 128 power on;
- ``*STB``: 4 error queue not empty, 8 QUES summary, 32 ESB, 64 MSS, 128 OPER summary.

An event register latches the condition's rising bits and is cleared by reading it or ``*CLS``.
"""

from __future__ import annotations

import threading

__all__ = ["Register", "Status", "OPER_SETTLING", "OPER_SWEEPING", "OPER_MEASURING",
           "OPER_AVERAGING", "QUES_VOLTAGE"]

OPER_SETTLING, OPER_SWEEPING, OPER_MEASURING, OPER_AVERAGING = 2, 8, 16, 256
QUES_VOLTAGE = 1


class Register:
    """A SCPI condition register with its event latch and enable mask (16 bits)."""

    def __init__(self):
        self.condition = 0
        self.event = 0
        self.enable = 0

    def set_condition(self, bits: int) -> None:
        self.event |= bits & ~self.condition
        self.condition = bits

    def read_event(self) -> int:
        e, self.event = self.event, 0
        return e

    @property
    def summary(self) -> bool:
        return bool(self.event & self.enable)


class Status:
    """The status model (thread-safe: the measurement updates it while clients read it)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.oper, self.ques, self.dev = Register(), Register(), Register()
        self.esr, self.ese, self.sre = 128, 0, 0  # power on

    def event(self, bits: int) -> None:
        with self.lock:
            self.esr |= bits

    def read_esr(self) -> int:
        with self.lock:
            e, self.esr = self.esr, 0
            return e

    def clear(self) -> None:
        """``*CLS``: the event registers (not the enables, not the conditions)."""
        with self.lock:
            self.esr = 0
            for r in (self.oper, self.ques, self.dev):
                r.event = 0

    def stb(self, errors_waiting: bool) -> int:
        with self.lock:
            b = (4 if errors_waiting else 0) | (8 if self.ques.summary else 0) \
                | (32 if self.esr & self.ese else 0) | (128 if self.oper.summary else 0)
            return b | (64 if b & self.sre & ~64 else 0)
