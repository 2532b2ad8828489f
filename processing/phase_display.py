"""Which 360-degree branch a wrapped phase is drawn on, so that a response sitting at +-180 deg
is one band, not two.

Theta_2's phase is 180 deg at low frequency, about 0 between its modes and +-180 deg between the
2.48 Hz mode and the 4.66 Hz anti-resonance: on the usual (-180, 180] it is drawn as two bands
at the top and bottom of the panel. :func:`phase_branch` picks, among the branches (lo, lo + 360]
with lo in -180, -90, -270, 0 (in that order of preference), the one whose cut the response's
phase comes nearest least often (the fraction of its values within 45 deg of the cut); for
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


def phase_branch(*responses) -> float:
    """The lower end lo [deg] of the branch (lo, lo + 360] on which the phases of the complex
    ``responses`` (arrays; non-finite values ignored) come nearest the cut least often (module
    docstring); -180 when they never come near any cut or nothing is finite."""
    h = np.concatenate([np.asarray(r, complex).ravel() for r in responses] + [np.zeros(0)])
    h = h[np.isfinite(h) & (h != 0)]
    if h.size == 0:
        return BRANCHES[0]
    p = np.degrees(np.angle(h))
    near = [np.mean(np.abs(wrap_to(p - lo, -180.0)) < _NEAR_CUT_DEG) for lo in BRANCHES]
    return BRANCHES[int(np.argmin(near))]  # the first of equals: the order of preference


def branch_text(lo: float) -> str:
    """``"(-90, 270]"``: the branch as an axis label says it."""
    return f"({lo:g}, {lo + 360:g}]"


def branch_ticks(lo: float) -> list[float]:
    """Tick values every 90 deg over the branch, its ends included."""
    return [lo + 90.0 * i for i in range(5)]
