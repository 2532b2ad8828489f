"""Random-phase multisines: the system-identification community's standard periodic excitation.

A multisine of period ``T = N / fs`` (``source.period_s``, N whole DAC samples) is a sum of
sines at harmonics ``l f0`` of ``f0 = 1 / T`` inside ``[fmin_hz, fmax_hz]`` (``l >= 1``), all
of one amplitude and random phases::

    v[k] = sum_l A cos(2 pi l k / N + phi_l),      A = L sqrt(2 / F)   (rms L, F lines)

The harmonic grid (``source.multisine_grid``):

``full``        every harmonic in the band;
``odd``         odd harmonics only: even nonlinearities then put power only on even lines and
                odd ones on odd lines, so the two are told apart;
``random-odd``  odd harmonics with one of every group of 4 consecutive ones left out at random
                (a detection line for odd nonlinearities inside the band).

Realisations: a new set of phases every ``source.multisine_periods`` periods (P periods per
realisation), so that R realisations of P periods each give the best linear approximation with
its noise and nonlinear-distortion variances (:mod:`processing.bla`). The phases of realisation
``r`` and the random-odd grid are drawn from a key the source's generator gives once, with
``numpy.random.default_rng([key, r])`` (the grid with ``r = -1``, as 2**63 - 1): any block split
gives the same samples. ``source.crest_iterations`` > 0 lowers the crest factor (peak / rms) of
each realisation by that many rounds of clipping at 0.9 of the peak and restoring the flat
amplitude spectrum while keeping the phases (Van der Ouderaa et al., 1988, in its simplest form);
the lines and their amplitudes stay exactly the design's, only the phases move.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rig.errors import ConfigError

__all__ = ["GRIDS", "GROUP", "excited_lines", "period", "crest_factor"]

GRIDS = ("full", "odd", "random-odd")
GROUP = 4  # random-odd: one odd line left out of every group of this many
_GRID_REALISATION = 2 ** 63 - 1


def excited_lines(grid: str, n: int, fs_hz: float, fmin_hz: float, fmax_hz: float,
                  key: int) -> np.ndarray:
    """Harmonic numbers ``l`` (ascending) excited in a period of ``n`` samples at ``fs_hz``."""
    if grid not in GRIDS:
        raise ConfigError(f"source.multisine_grid = {grid!r} is invalid: expected one of "
                          f"{', '.join(GRIDS)}")
    f0 = fs_hz / n
    lo = max(1, math.ceil(fmin_hz / f0 - 1e-9))
    hi = min(n // 2 - 1, math.floor(fmax_hz / f0 + 1e-9))
    lines = np.arange(lo, hi + 1)
    if grid != "full":
        lines = lines[lines % 2 == 1]
    if grid == "random-odd" and lines.size >= GROUP:
        rng = np.random.default_rng([key, _GRID_REALISATION])
        groups = lines.size // GROUP
        drop = np.arange(groups) * GROUP + rng.integers(0, GROUP, size=groups)
        lines = np.delete(lines, drop)
    if lines.size == 0:
        raise ConfigError(f"the multisine has no line in [{fmin_hz:g}, {fmax_hz:g}] Hz: its "
                          f"lines are {f0:g} Hz apart (1 / source.period_s); widen the band or "
                          "lengthen the period")
    return lines


@functools.lru_cache(maxsize=8)
def period(grid: str, n: int, fs_hz: float, fmin_hz: float, fmax_hz: float, level: float,
           key: int, realisation: int, crest_iterations: int) -> np.ndarray:
    """One period (``n`` samples, read-only) of realisation ``realisation`` [V]."""
    lines = excited_lines(grid, n, fs_hz, fmin_hz, fmax_hz, key)
    amp = level * math.sqrt(2.0 / lines.size)
    phases = np.random.default_rng([key, realisation]).uniform(0.0, 2 * np.pi, lines.size)
    spec = np.zeros(n // 2 + 1, complex)
    spec[lines] = 0.5 * n * amp * np.exp(1j * phases)
    v = np.fft.irfft(spec, n)
    for _ in range(crest_iterations):
        peak = np.max(np.abs(v))
        clipped = np.clip(v, -0.9 * peak, 0.9 * peak)
        s = np.fft.rfft(clipped)
        spec[lines] = 0.5 * n * amp * np.exp(1j * np.angle(s[lines]))
        v = np.fft.irfft(spec, n)
    v.setflags(write=False)
    return v


def crest_factor(v: np.ndarray) -> float:
    """Peak over rms of a signal."""
    v = np.asarray(v, float)
    return float(np.max(np.abs(v)) / math.sqrt(np.mean(v * v)))


def samples(grid: str, n: int, fs_hz: float, fmin_hz: float, fmax_hz: float, level: float,
            key: int, periods: int, crest_iterations: int, k: np.ndarray) -> np.ndarray:
    """The multisine's DAC samples at the indices ``k`` (from t = 0) [V]."""
    out = np.empty(k.size)
    q = k // n
    r = q // periods
    for real in np.unique(r):
        sel = r == real
        p = period(grid, n, fs_hz, fmin_hz, fmax_hz, level, key, int(real), crest_iterations)
        out[sel] = p[k[sel] % n]
    return out
