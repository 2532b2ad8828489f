"""Averaged auto and cross spectra from one shared set of segment FFTs (the 35670A's FFT engine).

Data flow
---------
``channels (records, samples)`` -> :func:`segment_ffts` -> :class:`SegmentFFTs` (detrended,
windowed, one-sided, PSD-scaled, computed once) -> :func:`auto_spectrum`, :func:`cross_spectrum`,
:func:`coherence` here and :func:`processing.frf.frequency_response` -> :class:`Spectrum` /
``MeasuredResponse``.

The rooms: the settings and their window (:mod:`processing.spectral_settings`: window
corrections), the segment FFTs and their averages (:mod:`processing.segments`: segmentation,
scaling and sign convention, the effective number of averages), the errors
(:mod:`processing.errors`); this module holds the averaged spectra and re-exports the names
above (``from processing.spectra import SpectralSettings, segment_ffts``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from processing.choices import AVERAGING, WINDOWS
from processing.errors import ChannelDataError, ProcessingError, SettingsError
from processing.segments import SegmentFFTs, require_cross, averaged_cross, segment_ffts
from processing.spectral_settings import (DETRENDS, SpectralSettings, WindowInfo,
                                          window_autocorrelation)
from rig.readonly import readonly

SCALINGS = ("density", "spectrum")


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
        Effective number of independent averages (variance reduction; see
        :mod:`processing.segments`).
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


def _wrap_deg(p: np.ndarray) -> np.ndarray:
    return np.where(p <= -180.0, p + 360.0, p)


def _check_scaling(scaling: str) -> None:
    if scaling not in SCALINGS:
        raise SettingsError(f"scaling = {scaling!r} is invalid: expected one of {SCALINGS}")


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
    return Spectrum(ffts.freqs_hz, readonly(g), scaling, (channel,), (ffts.units[channel],),
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
    require_cross(ffts, "a cross spectrum")
    g = averaged_cross(ffts, x, y).astype(np.complex128)
    info = ffts.settings.window_info
    if scaling == "spectrum":
        g = g * info.enbw_hz
    return Spectrum(ffts.freqs_hz, readonly(g), scaling, (x, y),
                    (ffts.units[x], ffts.units[y]), ffts.n_segments, ffts.n_effective,
                    info.enbw_hz, ffts.settings.averaging)


def coherence(ffts: SegmentFFTs, x, y) -> np.ndarray:
    """Magnitude-squared coherence ``gamma^2 = |G_xy|^2 / (G_xx G_yy)``, shape ``(n_freqs,)``.

    Powers are averaged as set by ``averaging``, except that vector averaging uses plain RMS
    averages of the same segments (coherence of vector-averaged spectra is 1 by construction).
    Lines where ``G_xx G_yy = 0`` give NaN. The estimate is biased up by about
    ``(1 - gamma^2)^2 / n_effective`` (so uncorrelated signals read about ``1 / n_effective``).
    """
    require_cross(ffts, "coherence")
    gxx = averaged_cross(ffts, x, x, power_average=True)
    gyy = averaged_cross(ffts, y, y, power_average=True)
    gxy = averaged_cross(ffts, x, y, power_average=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        g2 = (gxy.real**2 + gxy.imag**2) / (gxx * gyy)
    return readonly(np.minimum(g2, 1.0))


def estimate_auto_spectra(channels, *, settings: SpectralSettings, scaling: str = "density",
                          units: Mapping | None = None) -> dict:
    """One-shot: :func:`segment_ffts` then :func:`auto_spectrum` of every channel.

    Returns
    -------
    dict[name, Spectrum]
    """
    ffts = segment_ffts(channels, settings, units=units)
    return {name: auto_spectrum(ffts, name, scaling=scaling) for name in ffts.channels}


__all__ = ["AVERAGING", "WINDOWS", "DETRENDS", "SCALINGS", "ProcessingError", "SettingsError",
           "ChannelDataError", "SpectralSettings", "WindowInfo", "SegmentFFTs", "segment_ffts",
           "averaged_cross", "Spectrum", "auto_spectrum", "cross_spectrum", "coherence",
           "estimate_auto_spectra", "window_autocorrelation"]
