"""Frequency grids on which a sampled response shows every resonance and notch it has.

A log grid steps over a sharp mode: the paper's 2.48 Hz mode is 4.7 mHz wide, and 1000 log
points over 0.1-10 Hz step 11 mHz there, so the drawn peak comes out ~8 dB low.
:func:`resolving_grid` starts from the log grid (``points`` frequencies, the base grid) and adds:

- around each known mode (frequency f0, quality factor Q; half-power half-width f0 / 2Q) points
  at f0 + {0, +-1/4, +-1/2, +-1, +-2, +-4, +-8, +-16} half-widths;
- at each known anti-resonance (a zero on or near the axis) the same offsets with a half-width
  of 1e-3 f0;
- the exact extremum of each channel's gain near each mode (maximum) and anti-resonance
  (minimum), found by a bounded scalar search (scipy.optimize.minimize_scalar) to 1e-9 f0;
- then, repeatedly, the geometric midpoint of every interval whose midpoint value differs from
  the straight line between its ends (gain in dB over log frequency, as plotted) by more than
  ``tol_db``, or whose phase differs from the line by more than ``tol_deg``, or whose ends'
  phases differ by more than ``max_step_deg`` (so a mode's circle in a Nyquist plot is round);
  until none does (or ``max_rounds`` rounds, or intervals narrower than 1e-9 of their
  frequency).

So the peak and notch values a person reads off the curve are the true extrema (to the search's
tolerance), and between the grid's points linear interpolation is within ``tol_db`` at every
midpoint tested. :func:`scene_features` gives a scene's modes and the mirror channels'
anti-resonances (the exact linear model's poles and zeros) for the pendulum's responses.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["resolving_grid", "scene_features", "TOL_DB"]

#: the largest gain deviation [dB] between the drawn (interpolated) curve and the exact response
TOL_DB = 0.1
_OFFSETS = np.array([0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0])
_NOTCH_HALF_WIDTH = 1e-3


def scene_features(scene, weights=None) -> tuple[tuple[tuple[float, float], ...],
                                                  tuple[float, ...]]:
    """``(modes, notches)`` of ``scene``'s linearised pendulum: ``((f_hz, Q), ...)`` of its damped
    modes and the anti-resonance frequencies [Hz] of the outputs ``weights . theta`` (a sequence
    of weight vectors; default: the mirror channels x and y)."""
    chain = scene.chain
    if weights is None:
        weights = (scene.mirror_weights(), np.eye(chain.n)[scene.mirror.body])
    f_modes, q_modes = chain.modes()
    notches = np.concatenate([chain.antiresonances_hz(w) for w in weights] + [np.zeros(0)])
    return (tuple((float(f), float(q)) for f, q in zip(f_modes, q_modes)),
            tuple(float(f) for f in np.unique(notches)))


def _values(response, f) -> np.ndarray:
    h = np.asarray(response(np.asarray(f, float)), complex)
    return h.reshape(h.shape[0], -1)


def _extremum(response, lo: float, hi: float, channel: int, sign: float) -> float:
    """The frequency in [lo, hi] where channel's |H| is largest (sign +1) or smallest (-1)."""
    from scipy.optimize import minimize_scalar

    def cost(f):
        with np.errstate(divide="ignore"):
            return -sign * math.log(abs(_values(response, [f])[0, channel]) + 1e-300)

    res = minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-9 * hi})
    return float(res.x)


def _seeds(response, fmin, fmax, modes, notches, n_channels) -> list[np.ndarray]:
    parts = []
    features = [(f0, f0 / (2 * q) if math.isfinite(q) and q > 0.5 else _NOTCH_HALF_WIDTH * f0,
                 1.0) for f0, q in modes]
    features += [(f0, _NOTCH_HALF_WIDTH * f0, -1.0) for f0 in notches]
    for f0, half, sign in features:
        if not (math.isfinite(f0) and f0 > 0):
            continue
        parts.append(f0 + half * np.concatenate([-_OFFSETS[1:], _OFFSETS]))
        lo, hi = max(fmin, f0 - 4 * half), min(fmax, f0 + 4 * half)
        if lo < hi:
            parts.append(np.array([_extremum(response, lo, hi, c, sign)
                                   for c in range(n_channels)]))
    return parts


def _misfit(f, h, fm, hm, tol_db, tol_deg, max_step_deg) -> np.ndarray:
    """Which intervals' midpoint values (fm, hm) leave the straight line between their ends, or
    whose ends' phases differ by more than ``max_step_deg``."""
    x = np.log(f)
    w = ((np.log(fm) - x[:-1]) / (x[1:] - x[:-1]))[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        g = 20 * np.log10(np.abs(h))
        gm = 20 * np.log10(np.abs(hm))
        bad_gain = np.abs(g[:-1] + w * (g[1:] - g[:-1]) - gm) > tol_db
        step = np.angle(h[1:] / h[:-1])
        line = np.angle(h[:-1]) + w * step
        dev = np.degrees(np.abs(np.angle(np.exp(1j * (np.angle(hm) - line)))))
    bad = np.where(np.isfinite(gm) & np.isfinite(g[:-1]) & np.isfinite(g[1:]),
                   bad_gain | (dev > tol_deg) | (np.degrees(np.abs(step)) > max_step_deg), False)
    return bad.any(axis=1)


def resolving_grid(response: Callable, fmin_hz: float, fmax_hz: float, points: int, *,
                   modes: Sequence[tuple[float, float]] = (), notches: Sequence[float] = (),
                   tol_db: float = TOL_DB, tol_deg: float = 1.0, max_step_deg: float = 5.0,
                   max_rounds: int = 40) -> np.ndarray:
    """An ascending grid in [fmin_hz, fmax_hz] [Hz] on which ``response`` (``f -> (nf,)`` or
    ``(nf, k)`` complex) shows every mode ``(f_hz, Q)`` and anti-resonance ``f_hz`` it is given
    (module docstring): the ``points`` log-spaced frequencies plus the added ones."""
    f = np.geomspace(fmin_hz, fmax_hz, points)
    n_channels = _values(response, f[:1]).shape[1]
    parts = [f] + _seeds(response, fmin_hz, fmax_hz, modes, notches, n_channels)
    f = np.unique(np.concatenate(parts))
    f = f[(f >= fmin_hz) & (f <= fmax_hz)]
    h = _values(response, f)
    for _ in range(max_rounds):
        fm = np.sqrt(f[:-1] * f[1:])
        hm = _values(response, fm)
        bad = (_misfit(f, h, fm, hm, tol_db, tol_deg, max_step_deg)
               & (f[1:] - f[:-1] > 1e-9 * f[1:]))
        if not bad.any():
            break
        f = np.concatenate([f, fm[bad]])
        h = np.concatenate([h, hm[bad]])
        order = np.argsort(f)
        f, h = f[order], h[order]
    return f
