"""Which 360-degree branch a wrapped phase is drawn on, so that a response sitting at +-180 deg
is one band, not two.

Theta_2's phase is 180 deg at low frequency, about 0 between its modes and +-180 deg between the
2.48 Hz mode and the 4.66 Hz anti-resonance: on the usual (-180, 180] it is drawn as two bands
at the top and bottom of the panel. :func:`phase_branch` picks, among the branches (lo, lo + 360]
with lo in -180, -90, -270, 0 (in that order of preference), the one whose cut the response's
phase comes near over the least of the band (the fraction of log frequency where it is within
45 deg of the cut, so how densely a grid samples the steep transitions does not count); for
Theta_2 and H_t that is (-90, 270], where 180 and 0 both lie 90 deg from the cut.
:func:`wrap_to` wraps degrees onto a branch and :func:`branch_text` names it for an axis label.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BRANCHES", "phase_branch", "wrap_to", "branch_text", "branch_ticks"]

#: lower ends [deg] of the candidate branches (lo, lo + 360], in order of preference
BRANCHES = (-180.0, -90.0, -270.0, 0.0)
_NEAR_CUT_DEG = 45.0


def wrap_to(p_deg, lo: float = -180.0) -> np.ndarray:
    """Angles [deg] wrapped onto (lo, lo + 360] (NaN stays NaN)."""
    p = np.asarray(p_deg, float)
    return lo + 360.0 - np.mod(lo + 360.0 - p, 360.0)


def phase_branch(*curves) -> float:
    """The lower end lo [deg] of the branch (lo, lo + 360] on which the phases of ``curves``,
    pairs ``(freqs_hz, h)`` (ascending frequencies > 0, complex responses; non-finite values
    ignored), come near the cut over the least log-frequency length (module docstring); -180
    when they never come near any cut or nothing is finite."""
    ps, ws = [], []
    for f, h in curves:
        f, h = np.asarray(f, float).ravel(), np.asarray(h, complex).ravel()
        ok = np.isfinite(h) & (h != 0) & np.isfinite(f) & (f > 0)
        if ok.sum() < 2:
            continue
        logf = np.log(f[ok])
        ws.append(np.gradient(logf))  # each point's share of the log-frequency axis
        ps.append(np.degrees(np.angle(h[ok])))
    if not ps:
        return BRANCHES[0]
    p, w = np.concatenate(ps), np.abs(np.concatenate(ws))
    near = [np.sum(w * (np.abs(wrap_to(p - lo, -180.0)) < _NEAR_CUT_DEG)) for lo in BRANCHES]
    best = min(near)  # the first of (nearly) equals: the order of preference
    return next(lo for lo, n in zip(BRANCHES, near) if n <= best + 1e-3 * np.sum(w))


def branch_text(lo: float) -> str:
    """``"(-90, 270]"``: the branch as an axis label says it."""
    return f"({lo:g}, {lo + 360:g}]"


def branch_ticks(lo: float) -> list[float]:
    """Tick values every 90 deg over the branch, its ends included."""
    return [lo + 90.0 * i for i in range(5)]
