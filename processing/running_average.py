"""The analyzer's running average: H_t, Theta_2 and their coherence after each finished record.

A real analyzer shows its averaged estimate settle record by record. :class:`RunningAverage` does
the same with the analyzer's own segment FFTs (:func:`processing.spectra.segment_ffts`, the
settings of :class:`processing.analyzer.AnalyzerSettings`): every record is cut, detrended,
windowed and transformed once, and the sums of the segment cross powers ``conj(A) X``, ``conj(A)
Y`` and the auto powers are kept. After ``k`` records the averages are the sums over the ``k * s``
segments divided by their number, which is RMS averaging of all segments so far -- the same
estimate :func:`processing.analyzer.analyze` makes from the first ``k`` records of the file (equal
to rounding: it forms the same sums in another order). Only RMS averaging is running here
(exponential and vector averaging are refused).

Units: ``a`` in m/s^2, ``x`` in m, ``y`` in rad (the channels' engineering units, calibration and
sensor sign undone); H_t in m per m/s^2, Theta_2 in rad per m/s^2; coherence gamma^2 in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.spectra import SettingsError, segment_ffts

CHANNELS = ("a", "x", "y")


@dataclass(frozen=True, eq=False)
class RunningEstimate:
    """The averaged estimate after ``records`` records, on the display band's lines.

    Attributes
    ----------
    records : records averaged so far; segments : FFTs averaged.
    freqs_hz : (nf,) lines in the display band [Hz].
    h_t : (nf,) complex H_t = G_ax / G_aa [m per m/s^2]; theta_2 : G_ay / G_aa [rad per m/s^2].
    coherence_x, coherence_y : (nf,) gamma^2 of (a, x) and (a, y).
    """

    records: int
    segments: int
    freqs_hz: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    coherence_x: np.ndarray
    coherence_y: np.ndarray


class RunningAverage:
    """Accumulates the spectra of a run's records (module docstring).

    Parameters
    ----------
    header : daq.records.Header of the run (channels a, x, y; plan).
    settings : processing.analyzer.AnalyzerSettings (default: the paper's analyzer); its
        averaging must be "rms".
    """

    def __init__(self, header, settings=None):
        from processing.analyzer import AnalyzerSettings

        s = settings if settings is not None else AnalyzerSettings()
        if s.averaging != "rms":
            raise SettingsError(f"averaging = {s.averaging!r} is invalid for the running average: "
                                "expected 'rms'")
        missing = [c for c in CHANNELS if c not in header.names]
        if missing:
            raise SettingsError(f"the run has channels {', '.join(header.names)}: the running "
                                f"average needs a, x and y (missing {', '.join(missing)})")
        self.header, self.settings = header, s
        self.spectral = s.spectral(header.plan.rate_hz, header.plan.samples)
        f = self.spectral.freqs_hz
        self.band = np.flatnonzero((f >= s.fmin_hz) & (f <= s.fmax_hz))
        self.freqs_hz = f[self.band]
        self._channels = [header.channel(c) for c in CHANNELS]
        nf = self.band.size
        self._aa = np.zeros(nf)
        self._xx = np.zeros(nf)
        self._yy = np.zeros(nf)
        self._ax = np.zeros(nf, complex)
        self._ay = np.zeros(nf, complex)
        self.records = 0
        self.segments = 0

    def values(self, codes: dict) -> dict:
        """One record's ADC codes -> engineering units per channel (as
        :meth:`daq.records.Recording.values`)."""
        return {c.name: c.adc.volts(np.asarray(codes[c.name])) / c.volts_per_unit
                for c in self._channels}

    def add(self, codes: dict) -> RunningEstimate:
        """Add one finished record (``codes[name]``, (samples,)); return the estimate so far."""
        ffts = segment_ffts(self.values(codes), self.spectral)
        a, x, y = (ffts[c][:, self.band] for c in CHANNELS)
        self._aa += np.sum(a.real ** 2 + a.imag ** 2, axis=0)
        self._xx += np.sum(x.real ** 2 + x.imag ** 2, axis=0)
        self._yy += np.sum(y.real ** 2 + y.imag ** 2, axis=0)
        self._ax += np.sum(np.conj(a) * x, axis=0)
        self._ay += np.sum(np.conj(a) * y, axis=0)
        self.records += 1
        self.segments += ffts.n_segments
        return self.estimate()

    def estimate(self) -> RunningEstimate:
        """The estimate after the records added so far (NaN before the first)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            h_t = self._ax / self._aa
            theta_2 = self._ay / self._aa
            cx = (self._ax.real ** 2 + self._ax.imag ** 2) / (self._aa * self._xx)
            cy = (self._ay.real ** 2 + self._ay.imag ** 2) / (self._aa * self._yy)
        return RunningEstimate(records=self.records, segments=self.segments,
                               freqs_hz=self.freqs_hz, h_t=h_t, theta_2=theta_2,
                               coherence_x=cx, coherence_y=cy)
