"""The 35670A's traces: what ``CALC{n}:FEED`` names, and the numbers ``CALC{n}:DATA?`` sends in
the trace's ``CALC{n}:FORM`` and units.

Feeds (string data, long or short forms, any case)::

    XFR:POW n          power spectrum of channel n (CALC:UNIT:VOLT V2 | V2/HZ | V | V/RTHZ)
    XFR:POW:CROS m,n   cross spectrum conj(X_m) X_n (same units)
    XFR:POW:RAT m,n    frequency response X_n -> X_m, H1 = G_nm / G_nn
    XFR:POW:COH m,n    coherence
    XTIM:VOLT n        the last time record of channel n

Channels 1..3 are the bench's a, x, y; 4 is the source drive [V]. With a channel's transducer
units on (``VOLT{n}:RANG:UNIT:XDCR ON``, preloaded with the emulated sensor's calibration, the
default) its data are in engineering units (m/s^2, m, rad), else in volts; the ratio
``XFR:POW:RAT 2,1`` in engineering units is the analysis's H_t [m per m/s^2] and ``3,1`` its
Theta_2. Formats: MLOG (dB: 10 log10 of powers, 20 log10 of amplitudes and ratios), MLIN
(magnitude), PHAS (wrapped), UPH (unwrapped; degrees or radians by ``CALC:UNIT:ANGL``), REAL,
IMAG. Frequency traces have ``lines + 1`` points (0 .. span), time traces ``2.56 lines``. In
the swept-sine mode the traces are at the sweep's points (ascending frequency) and read the
fundamentals (:class:`processing.instrument.sine_mode.SineResult`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

__all__ = ["Feed", "parse_feed", "FORMS", "VOLT_UNITS", "trace_data", "x_data"]

FORMS = {"MLOGarithmic": "MLOG", "MLINear": "MLIN", "PHASe": "PHAS", "UPHase": "UPH",
         "REAL": "REAL", "IMAGinary": "IMAG"}
VOLT_UNITS = ("V2", "V2/HZ", "V", "V/RTHZ")


def _mn(long: str) -> str:
    short = "".join(c for c in long if not c.islower())
    return f"(?:{long.upper()}|{short.upper()})"


_CH = r"\s*([1-4])"
_FEEDS = (
    ("rat", re.compile(rf"^{_mn('XFRequency')}:{_mn('POWer')}:{_mn('RATio')}{_CH}\s*,{_CH}$")),
    ("coh", re.compile(rf"^{_mn('XFRequency')}:{_mn('POWer')}:{_mn('COHerence')}{_CH}\s*,{_CH}$")),
    ("cros", re.compile(rf"^{_mn('XFRequency')}:{_mn('POWer')}:{_mn('CROSs')}{_CH}\s*,{_CH}$")),
    ("pow", re.compile(rf"^{_mn('XFRequency')}:{_mn('POWer')}{_CH}$")),
    ("time", re.compile(rf"^{_mn('XTIMe')}:{_mn('VOLTage')}{_CH}$")),
)
_CANON = {"rat": "XFR:POW:RAT", "coh": "XFR:POW:COH", "cros": "XFR:POW:CROS", "pow": "XFR:POW",
          "time": "XTIM:VOLT"}


@dataclass(frozen=True)
class Feed:
    """A trace's measurement data: ``kind`` (rat, coh, cros, pow, time), ``channels``."""

    kind: str
    channels: tuple

    @property
    def text(self) -> str:
        return f"{_CANON[self.kind]} {','.join(str(c) for c in self.channels)}"


def parse_feed(text: str) -> Feed | None:
    """The feed a ``CALC:FEED`` string names, or None if it is not one emulated here."""
    t = text.strip().upper()
    for kind, rx in _FEEDS:
        m = rx.match(t)
        if m:
            return Feed(kind, tuple(int(g) for g in m.groups()))
    return None


def _complex(result, feed: Feed, volt_unit: str, eu: dict) -> tuple[np.ndarray, bool]:
    """The trace's values before formatting and whether they are a power (for MLOG)."""
    def vpu(ch):  # EU -> the channel's display unit
        return 1.0 if eu.get(ch, False) else result.volts_per_unit(ch)

    k, ch = feed.kind, feed.channels
    if k == "time":
        return result.time_record(ch[0]) * vpu(ch[0]), False
    if k == "rat":
        out, inp = ch
        return np.asarray(result.frf(out, inp).h) * (vpu(out) / vpu(inp)), False
    if k == "coh":
        return np.asarray(result.frf(ch[0], ch[1]).coherence), True
    scaling = "density" if volt_unit.endswith("HZ") else "spectrum"
    m, n = (ch[0], ch[0]) if k == "pow" else ch
    g = np.asarray(result.cross(m, n, scaling)) * (vpu(m) * vpu(n))
    if volt_unit in ("V", "V/RTHZ"):
        return (np.sqrt(g.real) if k == "pow" else np.sqrt(np.abs(g)) * np.exp(
            1j * np.angle(g))), False
    return g, True


def _unwrap(phase: np.ndarray) -> np.ndarray:
    out = np.array(phase, dtype=float)
    ok = np.isfinite(out)
    out[ok] = np.unwrap(out[ok])
    return out


def trace_data(result, feed: Feed, form: str, *, volt_unit: str = "V2", eu=None,
               degrees: bool = True) -> np.ndarray:
    """The real numbers ``CALC:DATA?`` sends for ``feed`` in ``form`` (a value of
    :data:`FORMS`)."""
    z, power = _complex(result, feed, volt_unit, eu or {})
    with np.errstate(divide="ignore", invalid="ignore"):
        if form == "MLOG":
            return (10.0 if power else 20.0) * np.log10(np.abs(z))
        if form == "MLIN":
            return np.abs(z)
        if form in ("PHAS", "UPH"):
            p = np.angle(z)
            p = _unwrap(p) if form == "UPH" else p
            return np.degrees(p) if degrees else p
        if form == "REAL":
            return np.real(z).astype(float)
        return np.imag(z).astype(float)


def x_data(result, feed: Feed) -> np.ndarray:
    """``CALC:X:DATA?``: the lines [Hz] or, for a time trace, the sample times [s]."""
    if feed.kind == "time":
        return np.asarray(result.times_s, dtype=float)
    return np.asarray(result.freqs_hz, dtype=float)
