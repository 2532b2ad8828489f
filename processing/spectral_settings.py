"""The analyzer's settings of one measurement (:class:`SpectralSettings`) and its window: the
samples, their corrections (:class:`WindowInfo`) and the overlap correlation of the segments.

Window corrections
------------------
``density`` scaling (PSD, unit^2/Hz) normalises by ``fs sum w^2`` (the noise-equivalent bandwidth);
``spectrum`` scaling (power spectrum, unit^2, the square of the 35670A's RMS linear spectrum) is the
PSD times the equivalent noise bandwidth ``ENBW = fs sum w^2 / (sum w)^2`` [Hz], which is the same
as normalising by the coherent gain, so a sine of amplitude ``A`` centred on a line reads
``A^2 / 2``. Off-centre it reads low by the window's scalloping loss
(:attr:`WindowInfo.scalloping_db`, under 0.01 dB for the flat top). For broadband noise the 0 Hz
and Nyquist lines read half the level of their neighbours (they are not doubled: scipy's
convention).
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass
from functools import cached_property

import numpy as np

from processing.choices import AVERAGING, WINDOWS
from processing.errors import SettingsError
from rig.validation import integer, number, positive

#: Cosine-sum coefficients of the periodic windows (those of scipy.signal.windows.hann, .flattop).
_COSINE_SUMS = {"hann": (0.5, 0.5),
                "flattop": (0.21557895, 0.41663158, 0.277263158, 0.083578947, 0.006947368)}
DETRENDS = ("constant", "linear", None)


def _periodic_cosine_sum(n: int, coeffs) -> np.ndarray:
    """``sum_k a_k cos(k x)`` on ``n`` of ``n + 1`` points ``x`` from -pi to pi: the periodic
    ("DFT-even") window, computed as :func:`scipy.signal.windows.general_cosine` with
    ``sym=False`` computes it (the same samples, without importing scipy.signal)."""
    if n <= 1:
        return np.ones(n)
    fac = np.linspace(-np.pi, np.pi, n + 1)
    w = np.zeros(n + 1)
    for k, a in enumerate(coeffs):
        w += a * np.cos(k * fac)
    return w[:-1]


def _autocorrelation(w: np.ndarray) -> np.ndarray:
    """``r(tau) = sum_n w[n] w[n + tau] / sum w^2`` for ``tau = 0 .. n-1`` (one FFT of twice the
    length; round-off ~1e-16 of r(0))."""
    n = w.size
    nfft = 1 << (2 * n - 1).bit_length()
    spec = np.fft.rfft(w, nfft)
    r = np.fft.irfft(spec.real**2 + spec.imag**2, nfft)[:n]
    return r / r[0]


@dataclass(frozen=True)
class WindowInfo:
    """Corrections of one window, computed once from its samples.

    Attributes
    ----------
    name : str
        Window name (one of :data:`WINDOWS`).
    nperseg : int
        Window length [samples].
    fs : float
        Sample rate [Hz].
    coherent_gain : float
        ``sum(w) / nperseg``: the amplitude gain for a sine centred on a line (1 for uniform, 0.5
        for Hann, about 0.216 for the flat top).
    enbw_bins : float
        Equivalent noise bandwidth ``nperseg sum(w^2) / sum(w)^2`` [lines] (1, 1.5, about 3.77).
    scalloping_db : float
        Largest deviation [dB, >= 0] of a sine's reading between -1/2 and +1/2 line off centre
        (3.92 dB uniform, 1.42 dB Hann, under 0.01 dB flat top), from the window's transform.
    """

    name: str
    nperseg: int
    fs: float
    coherent_gain: float
    enbw_bins: float
    scalloping_db: float

    @property
    def enbw_hz(self) -> float:
        """Equivalent noise bandwidth ``fs sum(w^2) / sum(w)^2`` [Hz]."""
        return self.enbw_bins * self.fs / self.nperseg


@dataclass(frozen=True)
class SpectralSettings:
    """Analyzer settings of one measurement (immutable, validated on construction).

    Parameters
    ----------
    fs : float
        Sample rate of the records [Hz], > 0.
    nperseg : int
        Samples per FFT segment (the 35670A's time record), >= 2. Line spacing is
        ``fs / nperseg`` [Hz]. See :meth:`from_lines` to give lines and span instead.
    window : str, default "hann"
        ``"uniform"`` (rectangular), ``"hann"`` (periodic Hann), ``"flattop"`` (periodic 5-term flat
        top of :func:`scipy.signal.windows.flattop`, amplitude-accurate to 0.01 dB),
        ``"force"`` (1 over the first ``force_fraction`` of the segment, 0 after: for the force
        channel of an impact test) or ``"exponential"`` (``exp(-t / exp_tau_s)``, ``t`` from the
        segment start: for lightly damped transient responses).
    noverlap : int, optional
        Samples shared by consecutive segments of a record, ``0 <= noverlap < nperseg``. Default
        (None, and no ``overlap``) is ``nperseg // 2`` as in :func:`scipy.signal.welch`.
    averaging : str, default "rms"
        ``"rms"``: arithmetic mean of the auto and cross powers (ordinary Welch averaging);
        ``"vector"``: mean of the complex segment spectra before forming powers (time-domain
        averaging: only meaningful when every segment starts at the same phase of a periodic or
        triggered signal; asynchronous noise averages away); ``"exponential"``: RMS averaging with
        weight ``1 / min(k, exp_averages)`` for the ``k``-th segment (linear until
        ``exp_averages`` segments, exponential after, as the 35670A); ``"peak"``: peak hold, the
        maximum of each line's auto power over segments (auto spectra only).
    detrend : {"constant", "linear", None}, default "constant"
        Per-segment detrend before windowing, as :func:`scipy.signal.detrend`. ``False`` is read as
        None.
    exp_averages : int, default 10
        Number ``N`` of exponential averaging (weight of a new segment ``1/N`` once ``N`` have
        been taken), >= 1.
    force_fraction : float, default 0.1
        Leading fraction of the segment the force window keeps, ``0 < force_fraction <= 1``.
    exp_tau_s : float, optional
        Time constant [s] of the exponential window, > 0. Default: a quarter of the segment
        duration, so the window ends at ``exp(-4)`` (1.8 %).
    span_hz : float, optional
        If given, results are truncated to lines ``0 <= f <= span_hz`` (``0 < span_hz <= fs/2``).
    overlap : float, optional, keyword only
        Overlap as a fraction of ``nperseg`` in ``[0, 1)``; sets ``noverlap = round(overlap *
        nperseg)``. Give either ``noverlap`` or ``overlap``, not both.

    Raises
    ------
    SettingsError
        (a ``ValueError``) naming the field, its value and the valid range.
    """

    fs: float
    nperseg: int
    window: str = "hann"
    noverlap: int | None = None
    averaging: str = "rms"
    detrend: str | None = "constant"
    exp_averages: int = 10
    force_fraction: float = 0.1
    exp_tau_s: float | None = None
    span_hz: float | None = None
    overlap: InitVar[float | None] = None

    def __post_init__(self, overlap):
        set_ = object.__setattr__
        set_(self, "fs", positive("fs", self.fs, error=SettingsError))
        set_(self, "nperseg", integer("nperseg", self.nperseg, minimum=2, error=SettingsError))
        if self.window not in WINDOWS:
            raise SettingsError(f"window = {self.window!r} is invalid: expected one of {WINDOWS}")
        if overlap is not None:
            if self.noverlap is not None:
                raise SettingsError(
                    f"noverlap = {self.noverlap!r} and overlap = {overlap!r} both given: give one")
            frac = number("overlap", overlap, lo=0.0, hi=1.0, hi_open=True,
                          valid="0 <= overlap < 1", error=SettingsError)
            set_(self, "noverlap", min(round(frac * self.nperseg), self.nperseg - 1))
        elif self.noverlap is None:
            set_(self, "noverlap", self.nperseg // 2)
        if isinstance(self.noverlap, bool) or not isinstance(self.noverlap, (int, np.integer)) \
                or not 0 <= self.noverlap < self.nperseg:
            raise SettingsError(f"noverlap = {self.noverlap!r} is invalid: expected an integer "
                                f"with 0 <= noverlap < nperseg = {self.nperseg}")
        set_(self, "noverlap", int(self.noverlap))
        if self.averaging not in AVERAGING:
            raise SettingsError(
                f"averaging = {self.averaging!r} is invalid: expected one of {AVERAGING}")
        if self.detrend is False:
            set_(self, "detrend", None)
        if self.detrend not in DETRENDS:
            raise SettingsError(
                f"detrend = {self.detrend!r} is invalid: expected one of {DETRENDS}")
        set_(self, "exp_averages", integer("exp_averages", self.exp_averages, minimum=1,
                                           error=SettingsError))
        set_(self, "force_fraction", positive("force_fraction", self.force_fraction, hi=1.0,
                                              valid="0 < force_fraction <= 1",
                                              error=SettingsError))
        tau = (self.nperseg / self.fs / 4.0 if self.exp_tau_s is None
               else positive("exp_tau_s", self.exp_tau_s, unit="s", error=SettingsError))
        set_(self, "exp_tau_s", tau)
        if self.span_hz is not None:
            set_(self, "span_hz", positive("span_hz", self.span_hz, hi=self.fs / 2 * (1 + 1e-12),
                                           valid=f"0 < span_hz <= fs/2 = {self.fs / 2:g} Hz",
                                           error=SettingsError))

    @classmethod
    def from_lines(cls, fs: float, lines: int, span_hz: float, *, overlap: float = 0.0,
                   **kwargs) -> SpectralSettings:
        """Settings from 35670A-style ``lines`` and ``span_hz``.

        The time record is ``lines / span_hz`` [s] and ``nperseg = fs * lines / span_hz``, which
        must be a whole number of samples (the data are not resampled). Results are truncated to
        ``0 <= f <= span_hz``: ``lines + 1`` points at spacing ``span_hz / lines`` [Hz].

        Parameters
        ----------
        fs : float
            Sample rate of the records [Hz].
        lines : int
            Number of frequency lines (the 35670A offers 100, 200, 400, 800, 1600).
        span_hz : float
            Frequency span [Hz], ``<= fs / 2``.
        overlap : float, default 0.0
            Overlap fraction in ``[0, 1)`` (the analyzer's default is none).
        **kwargs
            Any other :class:`SpectralSettings` field (``window``, ``averaging``, ...).
        """
        lines = integer("lines", lines, minimum=1, error=SettingsError)
        fs_v = positive("fs", fs, error=SettingsError)
        span = positive("span_hz", span_hz, error=SettingsError)
        n = fs_v * lines / span
        if abs(n - round(n)) > 1e-6 * max(1.0, n):
            raise SettingsError(
                f"lines = {lines}, span_hz = {span_hz!r} at fs = {fs!r} Hz give a time record of "
                f"{n:g} samples: expected a whole number (the records are not resampled)")
        return cls(fs=fs_v, nperseg=round(n), span_hz=span, overlap=overlap, **kwargs)

    @property
    def step(self) -> int:
        """Hop between segment starts, ``nperseg - noverlap`` [samples]."""
        return self.nperseg - self.noverlap

    @property
    def resolution_hz(self) -> float:
        """Line spacing ``fs / nperseg`` [Hz]."""
        return self.fs / self.nperseg

    @property
    def overlap_fraction(self) -> float:
        """``noverlap / nperseg``."""
        return self.noverlap / self.nperseg

    @cached_property
    def window_array(self) -> np.ndarray:
        """The window samples, shape ``(nperseg,)``, read-only."""
        n = self.nperseg
        if self.window == "uniform":
            w = np.ones(n)
        elif self.window in _COSINE_SUMS:
            w = _periodic_cosine_sum(n, _COSINE_SUMS[self.window])
        elif self.window == "force":
            w = np.zeros(n)
            w[:max(1, round(self.force_fraction * n))] = 1.0
        else:  # exponential
            w = np.exp(-np.arange(n) / (self.fs * self.exp_tau_s))
        w.setflags(write=False)
        return w

    @cached_property
    def window_info(self) -> WindowInfo:
        """Coherent gain, equivalent noise bandwidth and scalloping of the window."""
        w = self.window_array
        n = self.nperseg
        s1, s2 = w.sum(), (w * w).sum()
        # The window's transform from 0 to 1/2 line off centre (64 steps), relative to its centre
        # value; the phasors exp(-2j pi m n / (128 n)) by recurrence (drift ~1e-15 over 64 steps).
        step = np.exp(-2j * np.pi * np.arange(n) / (128 * n))
        phasor = np.ones(n, complex)
        vals = np.empty(65, complex)
        for m in range(65):
            vals[m] = phasor @ w
            phasor *= step
        gain = np.abs(vals) / abs(s1)
        scallop = float(np.max(np.abs(20 * np.log10(gain))))
        return WindowInfo(self.window, n, self.fs, float(s1 / n), float(n * s2 / s1**2), scallop)

    @cached_property
    def overlap_correlation(self) -> np.ndarray:
        """Welch's ``rho_j = sum_n w[n] w[n + j step] / sum_n w[n]^2`` for ``j = 1, 2, ...`` while
        segments ``j`` steps apart overlap; shape ``(n_lags,)`` (empty without overlap)."""
        w = self.window_array
        lags = np.arange(self.step, self.nperseg, self.step)
        rho = np.array([np.dot(w[: self.nperseg - d], w[d:]) for d in lags]) / np.dot(w, w)
        rho.setflags(write=False)
        return rho

    @property
    def freqs_hz(self) -> np.ndarray:
        """The lines reported, ``k fs / nperseg`` up to ``span_hz`` (or Nyquist) [Hz]."""
        f = np.fft.rfftfreq(self.nperseg, 1.0 / self.fs)
        if self.span_hz is not None:
            f = f[f <= self.span_hz * (1 + 1e-12)]
        return f


def window_autocorrelation(settings: SpectralSettings) -> np.ndarray:
    """``r_w(tau) = sum_n w[n] w[n + tau] / sum w^2`` for ``tau = 0 .. nperseg-1`` (the window's
    normalised autocorrelation: the taper of the expected estimate, :mod:`processing.leakage`)."""
    return _autocorrelation(settings.window_array)


__all__ = ["DETRENDS", "WindowInfo", "SpectralSettings", "window_autocorrelation"]
