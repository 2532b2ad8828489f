"""Pacing a run to the wall clock, like the real bench (``daq acquire --realtime [--speed K]``).

Without pacing the emulator runs as fast as it can. A :class:`Pacer` maps simulated time to wall
time: the first paced instant is "now", and simulated time ``t`` is due ``(t - t_first) / speed``
seconds later. :class:`PacingSink` waits in every block until the block's end is due (a live view
paces itself, finer, with the same :class:`Pacer`). Pacing changes no sample: the data and the
file are those of an unpaced run.
"""

from __future__ import annotations

import math
import time

from daq.sinks import Sink
from rig.errors import ConfigError


#: bench block length [s] a paced sink asks for (:attr:`daq.sinks.Sink.block_s`; ``daq acquire
#: --realtime``): the progress and the pacing step once a block, so a paced run uses blocks of a
#: second, like an instrument's display (the cost of small blocks is nothing beside the
#: waiting; the same samples)
PACED_BLOCK_S = 1.0


class Pacer:
    """Wall-clock pacing at ``speed`` times real time (1: real time); ``block_s``: the bench
    block a sink paced by it asks for (:data:`PACED_BLOCK_S`)."""

    block_s = PACED_BLOCK_S

    def __init__(self, speed: float = 1.0, *, clock=time.monotonic, sleep=time.sleep):
        if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (
                math.isfinite(speed) and speed > 0):
            raise ConfigError(f"speed = {speed!r} is invalid: expected a number > 0 (1 = real "
                              "time, 2 = twice as fast)")
        self.speed = float(speed)
        self._clock, self._sleep = clock, sleep
        self._origin = None  # (simulated s, wall s)

    @property
    def started(self) -> bool:
        """Whether the first instant has been paced."""
        return self._origin is not None

    def wait(self, t_s: float) -> None:
        """Return when simulated time ``t_s`` is due (at once for the first call)."""
        now = self._clock()
        if self._origin is None:
            self._origin = (t_s, now)
            return
        due = self._origin[1] + (t_s - self._origin[0]) / self.speed
        if due > now:
            self._sleep(due - now)


class PacingSink(Sink):
    """Waits in each block until its end is due (a non-critical sink: it never fails a run)."""

    critical = False

    def __init__(self, pacer: Pacer):
        self.pacer = pacer
        self.block_s = pacer.block_s
        self._rate = None

    def start(self, header) -> None:
        self._rate = header.plan.rate_hz

    def block(self, block) -> None:
        if not self.pacer.started:
            self.pacer.wait(block.t0_s)
        self.pacer.wait(block.t0_s + block.samples / self._rate)
