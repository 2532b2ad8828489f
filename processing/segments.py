"""The shared set of segment FFTs of all channels (:func:`segment_ffts`, the 35670A's FFT
engine) and their averages (:func:`averaged_cross`): records cut into segments, detrended,
windowed, one-sided, PSD-scaled, computed once.

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

Effective number of averages
----------------------------
Overlapping segments are correlated, so an averaged PSD of Gaussian noise has the variance of
``n_effective`` independent averages, by Welch (1967) from the averaging weights and the window's
overlap correlation (Hann at 50 %: about ``0.947 K`` for one record of ``K`` segments); segments
of different records are independent; vector averaging uses ``|rho_j|``; peak hold counts 1. The
formula: docs/analyzer-notes.md.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.errors import ChannelDataError, SettingsError
from processing.spectral_settings import SpectralSettings


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


def require_cross(ffts: SegmentFFTs, what: str) -> None:
    """SettingsError unless ``ffts`` can give cross products: peak-hold averaging keeps only
    the auto powers; ``what`` (e.g. ``"coherence"``) names the estimate asked for."""
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
            require_cross(ffts, "a cross spectrum")
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


__all__ = ["SegmentFFTs", "segment_ffts", "averaged_cross"]
