"""A quantity defined only at the analyzer's lines (an estimate, its expectation E[H1]) drawn as
what it is: one value per line, held over that line's bin, not a curve through the lines.

A straight segment from one line to the next would show values the estimate does not have (at a
resonance narrower than the line spacing, a peak between two lines that no line reads); a step
at each bin edge shows the value the analyzer gives for every frequency of the bin.
"""

from __future__ import annotations

import numpy as np

__all__ = ["line_steps"]


def line_steps(freqs_hz, values) -> tuple[np.ndarray, np.ndarray]:
    """``(f, v)``: the polyline of ``values`` (one per line of ``freqs_hz`` [Hz], ascending)
    held over each line's bin, from midway to the previous line to midway to the next (the
    first and last bins as wide as their neighbour's half-spacing on each side; the first bin's
    lower edge kept above 0 Hz): 2 points per line, alternately flat and vertical segments."""
    f = np.asarray(freqs_hz, float)
    v = np.asarray(values)
    if f.size < 2:
        return f, v
    mid = 0.5 * (f[1:] + f[:-1])
    lo = 2.0 * f[0] - mid[0]
    edges = np.concatenate([[lo if lo > 0 else f[0]], mid, [2.0 * f[-1] - mid[-1]]])
    return np.repeat(edges, 2)[1:-1], np.repeat(v, 2, axis=0)
