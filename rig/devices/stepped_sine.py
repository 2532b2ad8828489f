"""The analyzer's stepped-sine source: a DAC sine whose frequency and level step from point to
point with a continuous phase, as the 35670A's swept-sine option (1D2) drives its source.

A measurement point (:class:`SinePoint`) holds the source at one frequency and level for a
settle time and an integration time, both whole samples of the output (ADC) rate, so every
point starts and ends at an output instant. The integration window holds whole cycles in whole
output samples: the frequency is ``cycles * rate_hz / integrate_samples`` exactly
(:func:`whole_cycle_frequency` finds the nearest such frequency to the one asked for), so a
synchronous DFT over the window rejects DC and every harmonic exactly.

The DAC samples at the simulation rate ``fs`` are ``v_k = sqrt(2) L sin(2 pi phi_k)``, with
the phase in cycles ``phi_k = phi_0 + f (k - k_0) / fs`` within a point started at sample
``k_0`` with phase ``phi_0`` (the previous point's phase at that sample): the phase never jumps,
only the frequency and the amplitude do. :class:`SineSourceState` carries the phase (in
cycles, reduced to [0, 1)) and the sample index. No random stream is drawn.

Public API: :class:`SinePoint`, :class:`SineSourceState`, :func:`sine_samples`,
:func:`whole_cycle_frequency`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError
from rig.jit import njit


@dataclass(frozen=True)
class SinePoint:
    """One point of a stepped sine (frozen).

    Attributes
    ----------
    frequency_hz : the drive frequency [Hz], ``cycles * rate_hz / integrate_samples``.
    level_vrms : rms source voltage [V] (amplitude ``sqrt(2) level_vrms``), >= 0.
    settle_samples : output samples before the integration window (>= 0).
    integrate_samples : output samples of the integration window (>= 2).
    cycles : whole cycles of the drive in the window (>= 1).
    """

    frequency_hz: float
    level_vrms: float
    settle_samples: int
    integrate_samples: int
    cycles: int

    def __post_init__(self):
        for name in ("settle_samples", "integrate_samples", "cycles"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ConfigError(f"{name} = {v!r} is invalid: expected an integer >= 0")
        if self.integrate_samples < 2 or self.cycles < 1:
            raise ConfigError(f"integrate_samples = {self.integrate_samples!r}, cycles = "
                              f"{self.cycles!r} are invalid: expected >= 2 samples and >= 1 "
                              "cycle")
        if not (math.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ConfigError(f"frequency_hz = {self.frequency_hz!r} is invalid: expected a "
                              "finite frequency > 0 Hz")
        if not (math.isfinite(self.level_vrms) and self.level_vrms >= 0):
            raise ConfigError(f"level_vrms = {self.level_vrms!r} is invalid: expected a finite "
                              "rms voltage >= 0 V")

    @property
    def samples(self) -> int:
        """Output samples of the whole point (settle + integrate)."""
        return self.settle_samples + self.integrate_samples


@dataclass(frozen=True)
class SineSourceState:
    """The source between points: ``index`` the next DAC sample, ``phase_cycles`` its phase
    in cycles, in [0, 1)."""

    index: int = 0
    phase_cycles: float = 0.0


def whole_cycle_frequency(frequency_hz: float, rate_hz: float, min_cycles: int,
                          min_samples: int, search: int = 64) -> tuple[float, int, int]:
    """The frequency nearest ``frequency_hz`` at which ``K`` whole cycles take ``N`` whole output
    samples at ``rate_hz``, with ``K >= min_cycles`` and ``N >= min_samples``: ``(K rate / N, K,
    N)``. The ``search`` smallest admissible K are tried (a longer window places the frequency
    more finely: the error is at most ``f / (2 N)``, and among the K tried about ``f / (2 N
    search)``); the first K reaching the best error wins."""
    f, rate = float(frequency_hz), float(rate_hz)
    if not (math.isfinite(f) and 0 < f < rate / 2):
        raise ConfigError(f"frequency {frequency_hz!r} Hz is invalid: expected 0 < f < "
                          f"{rate / 2:g} Hz (half the output rate)")
    k0 = max(int(min_cycles), int(math.ceil(min_samples * f / rate)), 1)
    best = None
    for k in range(k0, k0 + max(1, int(search))):
        n = max(int(round(k * rate / f)), int(min_samples), 2 * k + 1)
        err = abs(k * rate / n - f)
        if best is None or err < best[0] * (1 - 1e-12):
            best = (err, k, n)
        if err <= 1e-9 * f:
            break
    _, k, n = best
    return k * rate / n, k, n


@njit(cache=True, nogil=True)
def _sine_kernel(phase0, step, amplitude, out):
    """``out[k] = amplitude sin(2 pi frac(phase0 + step k))`` (the phase reduced to [0, 1)
    before the sine, as ``np.mod`` does)."""
    for k in range(out.shape[0]):
        c = phase0 + step * k
        c = c - math.floor(c)
        out[k] = amplitude * math.sin(2.0 * math.pi * c)


def sine_samples(point: SinePoint, state: SineSourceState, n: int, fs_hz: float
                 ) -> tuple[np.ndarray, SineSourceState]:
    """The next ``n`` DAC samples [V] of ``point`` from ``state`` and the state after them
    (module docstring). Any split into calls gives the same samples up to the phase's
    round-off (the phase is carried in cycles, reduced to [0, 1) at every call)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ConfigError(f"n = {n!r} is invalid: expected an integer number of samples >= 0")
    step = point.frequency_hz / fs_hz
    v = np.empty(int(n))
    _sine_kernel(state.phase_cycles, step, math.sqrt(2.0) * point.level_vrms, v)
    end = math.fmod(state.phase_cycles + step * int(n), 1.0)
    return v, SineSourceState(index=state.index + int(n), phase_cycles=end)
