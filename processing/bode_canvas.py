"""A Bode diagram drawn as line strips: a log-frequency axis with decades labelled in Hz.

rerun's time-series view has no log axis and no frequency axis, so the live view draws the
analyzer screen in a 2D view, like an analyzer's display: each panel maps (frequency [Hz],
value) to scene units, with its own grid, tick labels and frame. Pure numpy; the viewer module
turns the strips and labels into rerun archetypes.

Scene units: x = ``UNITS_PER_DECADE * log10(f / fmin)``; y grows downwards (image coordinates),
so a value v of a panel with top ``y0`` and range (lo, hi) is drawn at ``y0 + height (hi - v) /
(hi - lo)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

UNITS_PER_DECADE = 40.0
#: Scene units left of a panel for its value labels ("-180 deg"), centred in them.
LABEL_MARGIN = 36.0


@dataclass(frozen=True)
class Panel:
    """One panel of the analyzer screen.

    Attributes
    ----------
    fmin_hz, fmax_hz : frequency range (decades labelled) [Hz].
    lo, hi : value range (e.g. dB, degrees, gamma^2); ticks : values with a grid line and label.
    unit : label suffix ("dB", "deg", "").
    top, height : position of the panel in scene units.
    title : drawn above the panel.
    units_per_decade : scene units of a decade of frequency (sets the panel's width).
    """

    fmin_hz: float
    fmax_hz: float
    lo: float
    hi: float
    ticks: tuple
    unit: str
    top: float
    height: float
    title: str
    units_per_decade: float = UNITS_PER_DECADE

    @property
    def width(self) -> float:
        return self.units_per_decade * math.log10(self.fmax_hz / self.fmin_hz)

    def x(self, f_hz) -> np.ndarray:
        return self.units_per_decade * np.log10(np.asarray(f_hz, float) / self.fmin_hz)

    def y(self, v) -> np.ndarray:
        v = np.clip(np.asarray(v, float), self.lo, self.hi)
        return self.top + self.height * (self.hi - v) / (self.hi - self.lo)

    def curve(self, f_hz, v, *, wrap: float | None = None) -> list[np.ndarray]:
        """The polyline of ``v`` over ``f_hz`` as strips [(k, 2) arrays]: broken at NaN, and
        where a wrapped quantity (``wrap``, e.g. 360 for phase) jumps by more than half of it."""
        f, v = np.asarray(f_hz, float), np.asarray(v, float)
        ok = np.isfinite(v) & (f >= self.fmin_hz) & (f <= self.fmax_hz)
        brk = ~ok[1:] | ~ok[:-1]
        if wrap is not None:
            with np.errstate(invalid="ignore"):
                brk |= np.abs(np.diff(v)) > wrap / 2
        pts = np.stack([self.x(f), self.y(np.where(ok, v, self.lo))], axis=-1)
        strips, start = [], 0
        for i in np.flatnonzero(brk) + 1:
            seg = np.arange(start, i)[ok[start:i]]
            if seg.size >= 2:
                strips.append(pts[seg])
            start = i
        seg = np.arange(start, f.size)[ok[start:]]
        if seg.size >= 2:
            strips.append(pts[seg])
        return strips

    def grid(self) -> list[np.ndarray]:
        """Frame, decade and 2-5 minor lines, value grid lines."""
        x0, x1 = 0.0, self.width
        y0, y1 = self.top, self.top + self.height
        lines = [np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]])]
        for f in _log_lines(self.fmin_hz, self.fmax_hz):
            x = float(self.x(f))
            lines.append(np.array([[x, y0], [x, y1]]))
        for t in self.ticks:
            y = float(self.y(t))
            lines.append(np.array([[x0, y], [x1, y]]))
        return lines

    def labels(self, *, decades: bool = True) -> tuple[np.ndarray, list[str]]:
        """Tick label positions (k, 2) and texts: values at the left, decades in Hz below
        (if ``decades``)."""
        pos, text = [], []
        for t in self.ticks:
            pos.append((-LABEL_MARGIN / 2 - 2.0, float(self.y(t)) - 3.0))  # a label hangs below
            text.append(f"{t:g}{(' ' + self.unit) if self.unit else ''}")
        for f in _decades(self.fmin_hz, self.fmax_hz) if decades else ():
            pos.append((float(self.x(f)), self.top + self.height + 4.0))
            text.append(f"{f:g} Hz")
        return np.array(pos), text


def _decades(fmin: float, fmax: float) -> list[float]:
    lo, hi = math.ceil(math.log10(fmin) - 1e-9), math.floor(math.log10(fmax) + 1e-9)
    return [10.0 ** k for k in range(lo, hi + 1)]


def _log_lines(fmin: float, fmax: float) -> list[float]:
    out = []
    for k in range(math.floor(math.log10(fmin)), math.ceil(math.log10(fmax)) + 1):
        for m in range(1, 10):
            f = m * 10.0 ** k
            if fmin * (1 - 1e-9) <= f <= fmax * (1 + 1e-9):
                out.append(f)
    return out


def db_range(*gains_db, step: float = 10.0, margin: float = 5.0) -> tuple[float, float]:
    """A gain range (lo, hi) [dB] in whole ``step`` s covering the finite values given."""
    v = np.concatenate([np.asarray(g, float).ravel() for g in gains_db])
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -100.0, 0.0
    return (step * math.floor((v.min() - margin) / step),
            step * math.ceil((v.max() + margin) / step))


def ticks(lo: float, hi: float, step: float) -> tuple:
    """Values ``lo, lo + step, ..., hi``."""
    n = int(round((hi - lo) / step))
    return tuple(lo + step * i for i in range(n + 1))
