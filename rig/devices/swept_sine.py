"""The analyzer's swept-sine source: a DAC sine whose frequency moves continuously along a path,
with a continuous phase (the 35670A's swept-sine option, 1D2, in its swept mode).

A :class:`SweepPath` gives the frequency [Hz] as a function of the time [s] from the sweep's
start: monotone knots ``(t_s, f_hz)`` joined linearly (between knots the frequency moves at a
constant rate), held at the first frequency for ``lead_s`` before the first knot and at the last
one for ``tail_s`` after it. :func:`chirp_path` gives the plain log or linear chirp of a given
duration; :func:`rate_path` a path whose rate [Hz/s] at every frequency is given (the bench's
rule, :func:`rig.bench.swept.rule_rate`).

The source is a stair in frequency at the output rate: over output interval ``n`` (the ``q``
DAC samples ``n q .. n q + q - 1``) the frequency is ``f_n``, the path's value at the interval's
middle, ``(n + 1/2) / rate_hz``; the phase in cycles at the interval's first DAC sample is
``phi_n``, with ``phi_{n+1} = phi_n + f_n q / fs_hz`` (it never jumps), and the DAC samples are
``v = sqrt(2) L_n sin(2 pi (phi_n + f_n j / fs_hz))``, ``j = 0..q-1`` (as a DDS whose
frequency word, and level ``L_n``, are updated at the output rate). The output sample ``n`` pairs with the phase ``phi_n``
(:func:`stair_phases`). No random stream is drawn.

Public API: :class:`SweepPath`, :func:`chirp_path`, :func:`rate_path`, :func:`stair_phases`,
:func:`swept_samples`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError
from rig.jit import njit


@dataclass(frozen=True, eq=False)
class SweepPath:
    """Frequency against time (module docstring).

    Attributes
    ----------
    t_s : (k,) increasing knot times [s] from the end of the lead-in, ``t_s[0] = 0``.
    f_hz : (k,) the frequency at the knots [Hz], monotone (up or down), > 0.
    lead_s, tail_s : holds at the first / last frequency before / after the knots [s].
    """

    t_s: np.ndarray
    f_hz: np.ndarray
    lead_s: float = 0.0
    tail_s: float = 0.0

    def __post_init__(self):
        t, f = np.asarray(self.t_s, float), np.asarray(self.f_hz, float)
        if t.ndim != 1 or t.shape != f.shape or t.size < 2 or t[0] != 0 \
                or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(t)):
            raise ConfigError("SweepPath t_s is invalid: expected >= 2 finite increasing "
                              "times from 0 s, as many as f_hz")
        df = np.diff(f)
        if not (np.all(np.isfinite(f)) and np.all(f > 0) and (np.all(df >= 0)
                                                              or np.all(df <= 0))):
            raise ConfigError("SweepPath f_hz is invalid: expected finite frequencies > 0 Hz, "
                              "monotone")
        for name in ("lead_s", "tail_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name} = {v!r} is invalid: expected a finite time >= 0 s")

    @property
    def duration_s(self) -> float:
        """The whole sweep [s]: lead-in, the knots' span and the tail."""
        return self.lead_s + float(self.t_s[-1]) + self.tail_s

    def frequency(self, t_s) -> np.ndarray:
        """The frequency [Hz] at times ``t_s`` from the sweep's start (lead-in included)."""
        return np.interp(np.asarray(t_s, float) - self.lead_s, self.t_s, self.f_hz)

    def time_at(self, f_hz) -> np.ndarray:
        """When the sweep passes ``f_hz`` [s from the sweep's start] (within the knots)."""
        f = np.asarray(f_hz, float)
        up = self.f_hz[-1] >= self.f_hz[0]
        t = (np.interp(f, self.f_hz, self.t_s) if up
             else np.interp(f, self.f_hz[::-1], self.t_s[::-1]))
        return t + self.lead_s

    def rate(self, f_hz) -> np.ndarray:
        """The path's rate |df/dt| [Hz/s] at ``f_hz`` (the knot interval holding it)."""
        up = self.f_hz[-1] >= self.f_hz[0]
        ff, tt = (self.f_hz, self.t_s) if up else (self.f_hz[::-1], self.t_s[::-1])
        slope = np.abs(np.diff(ff) / np.diff(tt))
        i = np.clip(np.searchsorted(ff, np.asarray(f_hz, float)) - 1, 0, slope.size - 1)
        return slope[i]


def chirp_path(fmin_hz: float, fmax_hz: float, duration_s: float, spacing: str = "log",
               direction: str = "up", knots: int = 4001) -> SweepPath:
    """The plain chirp: linear (constant Hz/s) or logarithmic (constant decades/s) from
    ``fmin_hz`` to ``fmax_hz`` in ``duration_s`` (reversed when ``direction`` is down)."""
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"sweep duration {duration_s!r} s is invalid: expected a finite time "
                          "> 0 s")
    u = np.linspace(0.0, 1.0, knots)
    f = (fmin_hz * (fmax_hz / fmin_hz) ** u if spacing == "log"
         else fmin_hz + (fmax_hz - fmin_hz) * u)
    return SweepPath(t_s=u * duration_s, f_hz=f if direction == "up" else f[::-1])


def rate_path(f_grid_hz: np.ndarray, rate_hz_s: np.ndarray, direction: str = "up"
              ) -> SweepPath:
    """The path that moves at ``rate_hz_s`` [Hz/s] (> 0) at the increasing frequencies
    ``f_grid_hz``: the time to cross each grid interval is its width over the mean of the
    rates at its ends' reciprocals (trapezoid of ``1 / rate``); reversed when down."""
    f, r = np.asarray(f_grid_hz, float), np.asarray(rate_hz_s, float)
    if not (np.all(np.isfinite(r)) and np.all(r > 0)):
        raise ConfigError("the sweep rate is invalid: expected finite rates > 0 Hz/s at every "
                          "frequency")
    dt = np.diff(f) * 0.5 * (1.0 / r[:-1] + 1.0 / r[1:])
    t = np.concatenate([[0.0], np.cumsum(dt)])
    if direction == "up":
        return SweepPath(t_s=t, f_hz=f)
    return SweepPath(t_s=t[-1] - t[::-1], f_hz=f[::-1])


def stair_phases(f_out_hz: np.ndarray, phase0_cycles: float, q: int, fs_hz: float
                 ) -> tuple[np.ndarray, float]:
    """The phases [cycles] ``phi_n`` at the first DAC sample of each output interval of a stair
    with frequencies ``f_out_hz`` (module docstring), from ``phase0_cycles``, and the phase
    after the last interval. The phases are not reduced (a float64 keeps 1e-10 cycles at 1e6
    cycles)."""
    steps = np.asarray(f_out_hz, float) * (q / fs_hz)
    phi = phase0_cycles + np.concatenate([[0.0], np.cumsum(steps)])
    return phi[:-1], float(phi[-1])


@njit(cache=True, nogil=True)
def _stair_kernel(f_out, phi, q, fs, amplitude, out):
    """``out[n q + j] = amplitude[n] sin(2 pi frac(phi[n] + f_out[n] j / fs))``."""
    for n in range(f_out.shape[0]):
        step = f_out[n] / fs
        p0 = phi[n] - math.floor(phi[n])
        for j in range(q):
            c = p0 + step * j
            c = c - math.floor(c)
            out[n * q + j] = amplitude[n] * math.sin(2.0 * math.pi * c)


def swept_samples(f_out_hz: np.ndarray, phases_cycles: np.ndarray, q: int, fs_hz: float,
                  level_vrms) -> np.ndarray:
    """The DAC samples [V] (``q`` per output interval) of the stair with frequencies
    ``f_out_hz`` and phases ``phases_cycles`` (:func:`stair_phases`) at ``level_vrms`` (one
    level, or one per output interval: the level too steps at the output rate)."""
    f = np.ascontiguousarray(f_out_hz, dtype=float)
    phi = np.ascontiguousarray(phases_cycles, dtype=float)
    amp = np.ascontiguousarray(np.broadcast_to(math.sqrt(2.0) * np.asarray(level_vrms, float),
                                               f.shape))
    v = np.empty(f.size * int(q))
    _stair_kernel(f, phi, int(q), float(fs_hz), amp, v)
    return v
