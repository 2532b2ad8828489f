"""Averaged auto and cross spectra from one shared set of segment FFTs (the 35670A's FFT engine).

Data flow
---------
``channels (records, samples)`` -> :func:`segment_ffts` -> :class:`SegmentFFTs` (detrended,
windowed, one-sided, PSD-scaled, computed once) -> :func:`auto_spectrum`, :func:`cross_spectrum`,
:func:`coherence` here and :func:`processing.frf.frequency_response` -> :class:`Spectrum` /
``MeasuredResponse``.

Segmentation
------------
Every record (one row of a channel's ``(records, samples)`` array) is cut into segments of
``nperseg`` samples starting every ``nperseg - noverlap`` samples (``sliding_window_view``, no
Python loop). Segments never straddle two records: records are contiguous blocks of one
acquisition but the boundary may be a discontinuity (re-trigger, range change), and a segment
across it would leak. The tail of a record shorter than one step is dropped, as in
:func:`scipy.signal.welch`. Segments are ordered record-major, in time order within a record (this
order matters for exponential averaging).

Scaling and sign convention
---------------------------
With ``w[n]`` the window and ``x[n]`` one detrended segment, the stored segment spectrum is::

    X[k] = c_k * sum_n w[n] x[n] exp(-2j pi k n / nperseg),   f_k = k fs / nperseg,
    c_k = sqrt(2 / (fs sum w^2)), except c_0 (and c_{nperseg/2}) = sqrt(1 / (fs sum w^2))

so that ``|X[k]|^2`` is already the one-sided power spectral density [unit^2/Hz] of that segment,
and a cross spectrum is ``G_xy = < conj(X) Y >`` (``<>`` the chosen average). With this convention
``G_xy / G_xx`` of an output ``y`` that lags ``x`` by ``tau`` seconds has phase
``-360 f tau`` degrees, matching SPEC section 5 (a physical lag shows negative phase).

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

Effective number of averages
----------------------------
Overlapping segments are correlated, so the variance of an averaged PSD of Gaussian noise is not
``1 / n_segments``. Welch (1967) gives, for weights ``c_k`` (``sum c_k = 1``) and the window overlap
correlation ``rho_j = sum_n w[n] w[n + j D] / sum_n w[n]^2`` at a shift of ``j`` steps ``D``::

    var(G) / G^2 = sum_k c_k^2 + 2 sum_j rho_j^2 sum_k c_k c_{k+j}      (pairs in the same record)
    n_effective = 1 / that

which is exact for white Gaussian noise away from 0 Hz and Nyquist and a good approximation for
spectra smooth over the window's bandwidth. For Hann at 50 % overlap ``rho_1 = 1/6``, so one long
record of ``K`` segments gives ``n_effective = K / (1 + (1 - 1/K) / 18)``, about ``0.947 K``.
Segments in different records never overlap, so they are uncorrelated. Exponential averaging enters
through its weights. Vector averaging averages complex spectra, whose correlation is
``rho_j`` times a phase that depends on the line; ``n_effective`` then uses ``|rho_j|`` (a
conservative bound, exact without overlap). Peak hold is not an average: ``n_effective = 1``.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import InitVar, dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.choices import AVERAGING, WINDOWS

#: Cosine-sum coefficients of the periodic windows (those of scipy.signal.windows.hann, .flattop).
_COSINE_SUMS = {"hann": (0.5, 0.5),
                "flattop": (0.21557895, 0.41663158, 0.277263158, 0.083578947, 0.006947368)}
DETRENDS = ("constant", "linear", None)
SCALINGS = ("density", "spectrum")


class ProcessingError(Exception):
    """Base class of every error raised by :mod:`processing`."""


class SettingsError(ProcessingError, ValueError):
    """Invalid analyzer settings, or settings that do not fit the data (e.g. ``nperseg`` longer
    than a record); the message names the field, the value and what is valid."""


class ChannelDataError(ProcessingError, ValueError):
    """Channel data of the wrong shape, non-finite, or a channel name that is not present."""


def _check_real(name: str, value, *, positive: bool = True) -> float:
    if isinstance(value, bool):
        raise SettingsError(f"{name} = {value!r} is invalid: expected a finite number")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{name} = {value!r} is invalid: expected a finite number") from None
    if not math.isfinite(v) or (positive and v <= 0):
        raise SettingsError(f"{name} = {value!r} is invalid: expected a finite number > 0")
    return v


def _check_int(name: str, value, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise SettingsError(f"{name} = {value!r} is invalid: expected an integer >= {minimum}")
    if value < minimum:
        raise SettingsError(f"{name} = {value!r} is invalid: expected an integer >= {minimum}")
    return int(value)


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
        set_(self, "fs", _check_real("fs", self.fs))
        set_(self, "nperseg", _check_int("nperseg", self.nperseg, minimum=2))
        if self.window not in WINDOWS:
            raise SettingsError(f"window = {self.window!r} is invalid: expected one of {WINDOWS}")
        if overlap is not None:
            if self.noverlap is not None:
                raise SettingsError(
                    f"noverlap = {self.noverlap!r} and overlap = {overlap!r} both given: give one")
            frac = _check_real("overlap", overlap, positive=False)
            if not 0.0 <= frac < 1.0:
                raise SettingsError(f"overlap = {overlap!r} is invalid: expected 0 <= overlap < 1")
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
        set_(self, "exp_averages", _check_int("exp_averages", self.exp_averages, minimum=1))
        frac = _check_real("force_fraction", self.force_fraction)
        if frac > 1.0:
            raise SettingsError(
                f"force_fraction = {self.force_fraction!r} is invalid: expected 0 < value <= 1")
        set_(self, "force_fraction", frac)
        tau = (self.nperseg / self.fs / 4.0 if self.exp_tau_s is None
               else _check_real("exp_tau_s", self.exp_tau_s))
        set_(self, "exp_tau_s", tau)
        if self.span_hz is not None:
            span = _check_real("span_hz", self.span_hz)
            if span > self.fs / 2 * (1 + 1e-12):
                raise SettingsError(f"span_hz = {self.span_hz!r} is invalid: expected 0 < span_hz "
                                    f"<= fs/2 = {self.fs / 2:g} Hz")
            set_(self, "span_hz", span)

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
        lines = _check_int("lines", lines, minimum=1)
        fs_v = _check_real("fs", fs)
        span = _check_real("span_hz", span_hz)
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


def _as_channels(channels) -> tuple[tuple[Hashable, ...], np.ndarray]:
    """Names and one stacked float array ``(channels, records, samples)``."""
    if isinstance(channels, Mapping):
        names = tuple(channels)
        arrays = [channels[k] for k in names]
    else:
        arr = np.asarray(channels)
        if arr.ndim == 3:
            names = tuple(range(arr.shape[0]))
            arrays = list(arr)
        elif arr.ndim in (1, 2):
            names, arrays = (0,), [arr]
        else:
            raise ChannelDataError(f"channel array has shape {arr.shape}: expected (samples,), "
                                   "(records, samples) or (channels, records, samples)")
    if not names:
        raise ChannelDataError("no channels given")
    out = []
    for name, a in zip(names, arrays):
        a = np.asarray(a)
        if np.iscomplexobj(a) or not np.issubdtype(a.dtype, np.number):
            raise ChannelDataError(f"channel {name!r} has dtype {a.dtype}: expected real numbers")
        if a.ndim == 1:
            a = a[np.newaxis, :]
        if a.ndim != 2:
            raise ChannelDataError(
                f"channel {name!r} has shape {a.shape}: expected (records, samples)")
        out.append(a.astype(np.float64, copy=False))
    shape = out[0].shape
    for name, a in zip(names, out):
        if a.shape != shape:
            raise ChannelDataError(f"channel {name!r} has shape {a.shape}, channel {names[0]!r} "
                                   f"has {shape}: all channels must share (records, samples)")
        if not np.all(np.isfinite(a)):
            raise ChannelDataError(f"channel {name!r} holds non-finite samples")
    return names, np.stack(out)


@dataclass(frozen=True, eq=False)
class SegmentFFTs:
    """The shared set of windowed, one-sided, PSD-scaled segment spectra of all channels.

    Build with :func:`segment_ffts`. ``ffts[name]`` is one channel's array ``(n_segments,
    n_freqs)`` [unit/sqrt(Hz)], scaled so that ``|X|^2`` is a one-sided PSD [unit^2/Hz].

    Attributes
    ----------
    settings : SpectralSettings
    channels : tuple
        Channel names (keys of the input mapping, or ``0, 1, ...`` for an array).
    data : numpy.ndarray
        Complex, shape ``(n_channels, n_segments, n_freqs)``, read-only.
    freqs_hz : numpy.ndarray
        Shape ``(n_freqs,)`` [Hz].
    n_records : int
        Records the segments were cut from.
    segments_per_record : int
    units : Mapping
        Channel name -> unit string of its samples ("1" if not given).
    """

    settings: SpectralSettings
    channels: tuple
    data: np.ndarray
    freqs_hz: np.ndarray
    n_records: int
    segments_per_record: int
    units: Mapping = field(default_factory=dict)

    def __getitem__(self, name) -> np.ndarray:
        return self.data[self.index(name)]

    def index(self, name) -> int:
        """Position of channel ``name`` in :attr:`data`; raises :class:`ChannelDataError`."""
        try:
            return self.channels.index(name)
        except ValueError:
            raise ChannelDataError(
                f"channel {name!r} is not present: expected one of {self.channels}") from None

    @property
    def n_segments(self) -> int:
        """Total number of segments over all records."""
        return self.n_records * self.segments_per_record

    @property
    def record_index(self) -> np.ndarray:
        """Record each segment comes from, shape ``(n_segments,)``."""
        return np.repeat(np.arange(self.n_records), self.segments_per_record)

    @cached_property
    def weights(self) -> np.ndarray:
        """Averaging weights of the segments, shape ``(n_segments,)``, summing to 1.

        Uniform ``1 / n_segments`` for RMS, vector and peak (unused there); for exponential
        averaging of ``K`` segments with number ``N``: ``(1/N)(1 - 1/N)^(K-N)`` for the first ``N``
        and ``(1/N)(1 - 1/N)^(K-k)`` for segment ``k > N`` (uniform if ``K <= N``), which is what
        the recursion ``A_k = (1 - 1/min(k, N)) A_{k-1} + X_k / min(k, N)`` leaves.
        """
        k_tot = self.n_segments
        n = self.settings.exp_averages
        if self.settings.averaging != "exponential" or k_tot <= n:
            w = np.full(k_tot, 1.0 / k_tot)
        else:
            a = 1.0 / n
            k = np.arange(1, k_tot + 1)
            w = a * (1.0 - a) ** (k_tot - k)
            w[:n] = a * (1.0 - a) ** (k_tot - n)
        w.setflags(write=False)
        return w

    @cached_property
    def n_effective(self) -> float:
        """Effective number of independent averages ``n_d`` (see the module notes): the factor by
        which the averaged estimate's variance is below one segment's."""
        if self.settings.averaging == "peak":
            return 1.0
        rho = self.settings.overlap_correlation
        rho = np.abs(rho) if self.settings.averaging == "vector" else rho**2
        c = self.weights.reshape(self.n_records, self.segments_per_record)
        var = float(np.sum(c * c))
        for j, r in enumerate(rho[: self.segments_per_record - 1], start=1):
            var += 2.0 * float(r) * float(np.sum(c[:, :-j] * c[:, j:]))
        return float(np.sum(c)) ** 2 / var


def segment_ffts(channels, settings: SpectralSettings, *,
                 units: Mapping | None = None) -> SegmentFFTs:
    """Cut records into segments, detrend, window and FFT them once, for all channels.

    Parameters
    ----------
    channels : Mapping[name, array_like] or array_like
        Per channel an array ``(records, samples)`` (or ``(samples,)`` for one record) in
        engineering units; all channels the same shape. A bare array is one channel (name ``0``)
        if 1-D or 2-D, or ``(channels, records, samples)`` named ``0, 1, ...`` if 3-D.
    settings : SpectralSettings
    units : Mapping[name, str], optional
        Unit of each channel's samples, carried into the results (default "1").

    Returns
    -------
    SegmentFFTs
        ``n_segments = records * (1 + (samples - nperseg) // (nperseg - noverlap))`` segments.

    Raises
    ------
    SettingsError
        If ``nperseg`` exceeds the record length.
    ChannelDataError
        If channels differ in shape, are not real or hold non-finite samples.
    """
    names, data = _as_channels(channels)
    n_ch, n_rec, n_samp = data.shape
    s = settings
    if s.nperseg > n_samp:
        raise SettingsError(f"nperseg = {s.nperseg} is invalid for records of {n_samp} samples: "
                            f"expected 2 <= nperseg <= {n_samp} (segments never straddle records)")
    seg = sliding_window_view(data, s.nperseg, axis=-1)[:, :, :: s.step, :]
    k_per_rec = seg.shape[2]
    if s.detrend == "constant":
        seg = seg - seg.mean(axis=-1, keepdims=True)
    elif s.detrend == "linear":
        from scipy.signal import detrend

        seg = detrend(seg, axis=-1, type="linear")
    w = s.window_array
    spec = np.fft.rfft(seg * w, axis=-1)
    scale = np.full(spec.shape[-1], math.sqrt(2.0 / (s.fs * np.dot(w, w))))
    scale[0] /= math.sqrt(2.0)
    if s.nperseg % 2 == 0:
        scale[-1] /= math.sqrt(2.0)
    freqs = s.freqs_hz
    spec = (spec[..., : freqs.size] * scale[: freqs.size]).reshape(n_ch, n_rec * k_per_rec, -1)
    spec.setflags(write=False)
    freqs.setflags(write=False)
    unit_map = {n: str((units or {}).get(n, "1")) for n in names}
    return SegmentFFTs(s, names, spec, freqs, n_rec, k_per_rec, MappingProxyType(unit_map))


def _require_cross(ffts: SegmentFFTs, what: str) -> None:
    if ffts.settings.averaging == "peak":
        raise SettingsError(f"averaging = 'peak' holds the maximum auto power per line; {what} is "
                            "undefined under peak hold: expected averaging 'rms', 'vector' or "
                            "'exponential'")


def averaged_cross(ffts: SegmentFFTs, x, y, *, power_average: bool = False) -> np.ndarray:
    """The averaged one-sided cross spectral density ``G_xy = <conj(X) Y>`` [ux uy/Hz].

    Parameters
    ----------
    ffts : SegmentFFTs
    x, y : channel names (``x == y`` gives the auto PSD as a real array)
    power_average : bool
        If True, average the segment powers with uniform weights even under vector averaging
        (used for coherence, which is 1 by construction for vector-averaged spectra).

    Returns
    -------
    numpy.ndarray
        Shape ``(n_freqs,)``: complex, or real if ``x == y``.
    """
    mode = ffts.settings.averaging
    a = ffts[x]
    if mode == "peak":
        if x != y:
            _require_cross(ffts, "a cross spectrum")
        return np.max(a.real**2 + a.imag**2, axis=0)
    if mode == "vector" and not power_average:
        am = ffts.weights @ a
        if x == y:
            return am.real**2 + am.imag**2
        return np.conj(am) * (ffts.weights @ ffts[y])
    c = ffts.weights if mode != "vector" else np.full(ffts.n_segments, 1.0 / ffts.n_segments)
    # einsum, not c @ M: a (segments, lines) matrix-vector product is too small for BLAS threads,
    # which on a busy two-core machine cost ten times the work.
    if x == y:
        return np.einsum("s,sf->f", c, a.real**2 + a.imag**2)
    return np.einsum("s,sf->f", c, np.conj(a) * ffts[y])


@dataclass(frozen=True, eq=False)
class Spectrum:
    """An averaged auto or cross spectrum on the analyzer's lines.

    Attributes
    ----------
    freqs_hz : numpy.ndarray
        Shape ``(n_freqs,)`` [Hz].
    values : numpy.ndarray
        Shape ``(n_freqs,)``; real for an auto spectrum, complex ``G_xy`` for a cross spectrum.
        ``scaling="density"``: [unit^2/Hz] (one-sided PSD / CSD); ``"spectrum"``: [unit^2] (power
        spectrum: a sine of amplitude ``A`` on a line reads ``A^2/2``).
    scaling : {"density", "spectrum"}
    channels : tuple
        ``(name,)`` for an auto spectrum, ``(x, y)`` for ``G_xy = <conj(X) Y>``.
    units : tuple of str
        Units of the channels' samples, same length as ``channels``.
    n_averages : int
        Number of segments averaged.
    n_effective : float
        Effective number of independent averages (variance reduction; see module notes).
    enbw_hz : float
        Equivalent noise bandwidth of the window [Hz]: ``spectrum = density * enbw_hz``.
    averaging : str
    """

    freqs_hz: np.ndarray
    values: np.ndarray
    scaling: str
    channels: tuple
    units: tuple
    n_averages: int
    n_effective: float
    enbw_hz: float
    averaging: str

    @property
    def is_cross(self) -> bool:
        return len(self.channels) == 2

    @property
    def value_units(self) -> str:
        """Units of :attr:`values`, e.g. ``"(m/s^2)^2/Hz"`` or ``"(m/s^2)(m)"``."""
        u = self.units
        base = f"({u[0]})({u[1]})" if self.is_cross else f"({u[0]})^2"
        return base + ("/Hz" if self.scaling == "density" else "")

    @property
    def amplitude(self) -> np.ndarray:
        """``sqrt(|values|)``: RMS linear spectrum [unit] for ``"spectrum"`` scaling, amplitude
        spectral density [unit/sqrt(Hz)] for ``"density"``."""
        return np.sqrt(np.abs(self.values))

    @property
    def magnitude_db(self) -> np.ndarray:
        """``10 log10 |values|`` [dB re 1 unit^2(/Hz)], i.e. ``20 log10`` of :attr:`amplitude`."""
        with np.errstate(divide="ignore"):
            return 10.0 * np.log10(np.abs(self.values))

    @property
    def phase_deg(self) -> np.ndarray:
        """Phase of ``values`` wrapped to ``(-180, 180]`` [deg] (0 for an auto spectrum)."""
        return _wrap_deg(np.degrees(np.angle(self.values)))

    def to_scaling(self, scaling: str) -> Spectrum:
        """The same estimate in ``"density"`` [unit^2/Hz] or ``"spectrum"`` [unit^2] scaling."""
        _check_scaling(scaling)
        if scaling == self.scaling:
            return self
        factor = self.enbw_hz if scaling == "spectrum" else 1.0 / self.enbw_hz
        return _replace_values(self, self.values * factor, scaling=scaling)

    def select(self, fmin_hz: float = 0.0, fmax_hz: float = math.inf) -> Spectrum:
        """The lines with ``fmin_hz <= f <= fmax_hz``."""
        m = (self.freqs_hz >= fmin_hz) & (self.freqs_hz <= fmax_hz)
        return _replace_values(self, self.values[m], freqs_hz=self.freqs_hz[m])


def _replace_values(s: Spectrum, values, **changes) -> Spectrum:
    fields = {k: getattr(s, k) for k in s.__dataclass_fields__}
    fields.update(values=values, **changes)
    return Spectrum(**fields)


def window_autocorrelation(settings: SpectralSettings) -> np.ndarray:
    """``r_w(tau) = sum_n w[n] w[n + tau] / sum w^2`` for ``tau = 0 .. nperseg-1`` (the window's
    normalised autocorrelation: the taper of the expected estimate, :mod:`processing.leakage`)."""
    return _autocorrelation(settings.window_array)


def _wrap_deg(p: np.ndarray) -> np.ndarray:
    return np.where(p <= -180.0, p + 360.0, p)


def _check_scaling(scaling: str) -> None:
    if scaling not in SCALINGS:
        raise SettingsError(f"scaling = {scaling!r} is invalid: expected one of {SCALINGS}")


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def auto_spectrum(ffts: SegmentFFTs, channel, *, scaling: str = "density") -> Spectrum:
    """Averaged auto spectrum ``G_xx`` of one channel.

    Parameters
    ----------
    ffts : SegmentFFTs
    channel : channel name
    scaling : {"density", "spectrum"}
        PSD [unit^2/Hz] or power spectrum [unit^2] (``amplitude`` then reads a sine's RMS).

    Returns
    -------
    Spectrum
        Real values, shape ``(n_freqs,)``. White noise of variance ``sigma^2`` reads
        ``2 sigma^2 / fs`` with relative standard deviation ``1 / sqrt(n_effective)``.
    """
    _check_scaling(scaling)
    g = averaged_cross(ffts, channel, channel)
    info = ffts.settings.window_info
    if scaling == "spectrum":
        g = g * info.enbw_hz
    return Spectrum(ffts.freqs_hz, _readonly(g), scaling, (channel,), (ffts.units[channel],),
                    ffts.n_segments, ffts.n_effective, info.enbw_hz, ffts.settings.averaging)


def cross_spectrum(ffts: SegmentFFTs, x, y, *, scaling: str = "density") -> Spectrum:
    """Averaged cross spectrum ``G_xy = <conj(X) Y>`` (complex; its phase is ``y``'s phase
    minus ``x``'s, negative when ``y`` lags ``x``).

    Parameters
    ----------
    ffts : SegmentFFTs
    x, y : channel names
    scaling : {"density", "spectrum"}
        [ux uy/Hz] or [ux uy].

    Raises
    ------
    SettingsError
        Under peak hold, where cross spectra are undefined.
    """
    _check_scaling(scaling)
    _require_cross(ffts, "a cross spectrum")
    g = averaged_cross(ffts, x, y).astype(np.complex128)
    info = ffts.settings.window_info
    if scaling == "spectrum":
        g = g * info.enbw_hz
    return Spectrum(ffts.freqs_hz, _readonly(g), scaling, (x, y),
                    (ffts.units[x], ffts.units[y]), ffts.n_segments, ffts.n_effective,
                    info.enbw_hz, ffts.settings.averaging)


def coherence(ffts: SegmentFFTs, x, y) -> np.ndarray:
    """Magnitude-squared coherence ``gamma^2 = |G_xy|^2 / (G_xx G_yy)``, shape ``(n_freqs,)``.

    Powers are averaged as set by ``averaging``, except that vector averaging uses plain RMS
    averages of the same segments (coherence of vector-averaged spectra is 1 by construction).
    Lines where ``G_xx G_yy = 0`` give NaN. The estimate is biased up by about
    ``(1 - gamma^2)^2 / n_effective`` (so uncorrelated signals read about ``1 / n_effective``).
    """
    _require_cross(ffts, "coherence")
    gxx = averaged_cross(ffts, x, x, power_average=True)
    gyy = averaged_cross(ffts, y, y, power_average=True)
    gxy = averaged_cross(ffts, x, y, power_average=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        g2 = (gxy.real**2 + gxy.imag**2) / (gxx * gyy)
    return _readonly(np.minimum(g2, 1.0))


def estimate_auto_spectra(channels, *, settings: SpectralSettings, scaling: str = "density",
                          units: Mapping | None = None) -> dict:
    """One-shot: :func:`segment_ffts` then :func:`auto_spectrum` of every channel.

    Returns
    -------
    dict[name, Spectrum]
    """
    ffts = segment_ffts(channels, settings, units=units)
    return {name: auto_spectrum(ffts, name, scaling=scaling) for name in ffts.channels}
