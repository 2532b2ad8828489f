"""Frequency-response estimates (H1, H2, Hv) with coherence and random-error bands.

All estimates come from the averaged spectra of one :class:`processing.spectra.SegmentFFTs`, with
``G_xy = <conj(X) Y>`` for input ``x`` and output ``y`` (so ``G_yx = conj(G_xy)``):

* ``H1 = G_xy / G_xx``: unbiased by noise on the output, biased low by noise on the input;
* ``H2 = G_yy / G_yx``: unbiased by noise on the input, biased high by output noise (by
  ``1 / gamma^2`` for output noise only);
* ``Hv``: the total-least-squares estimate for equal noise power on input and output (Vold; also
  "H_s" / "H3" with unit scaling), the eigenvector of the smallest eigenvalue of the 2x2 spectral
  matrix ``[[G_xx, G_xy], [G_yx, G_yy]]``::

      Hv = (G_yy - G_xx + sqrt((G_xx - G_yy)^2 + 4 |G_xy|^2)) / (2 G_yx)

  Its magnitude lies between ``|H1|`` and ``|H2|`` and all three share the phase of ``G_xy``.
  It weights input and output noise as equal in the channels' own units, so it depends on them.

The phase of an output lagging the input by ``tau`` seconds is ``-360 f tau`` degrees
(SPEC section 5: a physical lag reads negative phase).

Random error (Bendat & Piersol, *Random Data*, 4th ed., Table 9.6), for ``n_d`` effective averages
(``SegmentFFTs.n_effective``: overlap-corrected, see :mod:`processing.spectra`)::

    eps(|H|) = sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_d))        (normalised standard deviation)
    std(phase) = eps(|H|)                                       [rad]

valid for ``n_d`` of tens or more and an estimator free of bias. It uses the measured coherence, as
the analyzer must; coherence itself is biased up by about ``(1 - gamma^2)^2 / n_d``. The same
expression holds for vector averaging of a triggered signal with output noise (the averaged noise
spectrum falls by ``n_d`` and half its power is in the magnitude direction).

The band uses the measured coherence. Where ``gamma^2`` is low its own relative error,
``sqrt(2) (1 - gamma^2) / (|gamma| sqrt(n_d))``, is large and positively correlated with the error
of ``H`` (a noise draw that happens to align with the input raises both), so the band is
optimistic there: trust it where that relative error is below about 10 %.

Leakage bias is separate and systematic: for a white input and ``detrend=None`` the expected H1 is
the transform of the system's impulse response tapered by the window's normalised
autocorrelation (:func:`processing.leakage.expected_h1`), which lets a test or a comparison
quantify it exactly.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from processing.choices import ESTIMATORS
from processing.segments import require_cross
from processing.spectra import (
    SegmentFFTs,
    SettingsError,
    SpectralSettings,
    averaged_cross,
    coherence,
    segment_ffts,
)
from rig.linear import FrequencyResponse
from rig.readonly import readonly



def random_error(coherence, n_effective) -> np.ndarray:
    """Bendat-Piersol normalised random error of ``|H|`` (and phase std [rad]).

    Parameters
    ----------
    coherence : array_like
        Magnitude-squared coherence ``gamma^2`` in ``[0, 1]``, any shape.
    n_effective : float or array_like
        Effective number of independent averages ``n_d``.

    Returns
    -------
    numpy.ndarray
        ``sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_d))``; 0 at ``gamma^2 = 1``, inf at 0.
    """
    g2 = np.clip(np.asarray(coherence, dtype=float), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(1.0 - g2) / np.sqrt(2.0 * g2 * np.asarray(n_effective, dtype=float))


@dataclass(frozen=True, eq=False)
class MeasuredResponse(FrequencyResponse):
    """An estimated frequency response ``output / input`` on the analyzer's lines: a
    :class:`rig.linear.FrequencyResponse` (``freqs_hz``, ``h``, ``names``, ``units``; gain and
    phase) with the statistics of its estimate.

    Attributes
    ----------
    freqs_hz : numpy.ndarray
        Shape ``(n_freqs,)`` [Hz].
    h : numpy.ndarray
        Complex response, shape ``(n_freqs,)`` [output unit / input unit]. NaN where undefined
        (the 0 Hz line when a detrend removed it, or lines where the input has no power).
    names : ``(output,)``; units : str, units of ``h``, e.g. ``"(m)/(m/s^2)"``.
    coherence : numpy.ndarray
        Magnitude-squared coherence ``gamma^2``, shape ``(n_freqs,)``.
    n_averages : int
        Number of segments averaged.
    n_effective : float
        Effective number of independent averages ``n_d`` used by the error bands.
    estimator : {"h1", "h2", "hv"}
    input, output : channel names

    The fields after ``units`` are keyword-only.
    """

    coherence: np.ndarray = field(kw_only=True)
    n_averages: int = field(kw_only=True)
    n_effective: float = field(kw_only=True)
    estimator: str = field(kw_only=True)
    input: object = field(default=None, kw_only=True)
    output: object = field(default=None, kw_only=True)

    @property
    def relative_error(self) -> np.ndarray:
        """Normalised random error of ``|h|``, ``sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_d))``."""
        return random_error(self.coherence, self.n_effective)

    @property
    def phase_std_deg(self) -> np.ndarray:
        """Standard deviation of the phase [deg], ``degrees(relative_error)``."""
        return np.degrees(self.relative_error)

    def gain_band_db(self, k: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """``k``-sigma band of the gain: ``20 log10(|h| (1 -/+ k eps))`` [dB] (lower -inf where
        ``k eps >= 1``)."""
        eps = self.relative_error
        mag = np.abs(self.h)
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = 20.0 * np.log10(mag * np.clip(1.0 - k * eps, 0.0, None))
            hi = 20.0 * np.log10(mag * (1.0 + k * eps))
        return lo, hi

    def phase_band_deg(self, k: float = 1.0, *,
                       unwrapped: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``k``-sigma band of the phase, ``phase -/+ k std`` [deg], around the wrapped (default)
        or unwrapped phase; the band itself is not wrapped."""
        p = self.phase_unwrapped_deg if unwrapped else self.phase_deg
        s = k * self.phase_std_deg
        return p - s, p + s

    def select(self, fmin_hz: float = 0.0, fmax_hz: float = math.inf) -> MeasuredResponse:
        """The lines with ``fmin_hz <= f <= fmax_hz``."""
        m = (self.freqs_hz >= fmin_hz) & (self.freqs_hz <= fmax_hz)
        return dataclasses.replace(self, freqs_hz=self.freqs_hz[m], h=self.h[m],
                                   coherence=self.coherence[m])


def frequency_response(ffts: SegmentFFTs, input, output, *,
                       estimator: str = "h1") -> MeasuredResponse:
    """Estimate the frequency response ``output / input`` from shared segment FFTs.

    Parameters
    ----------
    ffts : SegmentFFTs
    input, output : channel names
    estimator : {"h1", "h2", "hv"}
        See the module notes; case-insensitive.

    Returns
    -------
    MeasuredResponse

    Raises
    ------
    SettingsError
        For an unknown estimator, or under peak hold.
    """
    est = str(estimator).lower()
    if est not in ESTIMATORS:
        raise SettingsError(f"estimator = {estimator!r} is invalid: expected one of {ESTIMATORS}")
    require_cross(ffts, "a frequency response")
    gxx = averaged_cross(ffts, input, input)
    gyy = averaged_cross(ffts, output, output)
    gxy = averaged_cross(ffts, input, output)
    with np.errstate(divide="ignore", invalid="ignore"):
        if est == "h1":
            h = gxy / gxx
        elif est == "h2":
            h = gyy / np.conj(gxy)
        else:
            d = gyy - gxx
            h = (d + np.sqrt(d * d + 4.0 * (gxy.real**2 + gxy.imag**2))) / (2.0 * np.conj(gxy))
    h = np.asarray(h, dtype=np.complex128)
    g2 = np.array(coherence(ffts, input, output))
    if ffts.settings.detrend is not None and ffts.freqs_hz.size and ffts.freqs_hz[0] == 0.0:
        h[0] = np.nan  # the detrend removed the 0 Hz line: the ratio there is noise over noise
        g2[0] = np.nan
    u_in, u_out = ffts.units[input], ffts.units[output]
    return MeasuredResponse(ffts.freqs_hz, readonly(h), (output,), f"({u_out})/({u_in})",
                            coherence=readonly(g2), n_averages=ffts.n_segments,
                            n_effective=ffts.n_effective, estimator=est, input=input,
                            output=output)


def estimate_frf(channels, input, output, *, settings: SpectralSettings, estimator: str = "h1",
                 units: Mapping | None = None) -> MeasuredResponse:
    """One-shot: :func:`processing.spectra.segment_ffts` then :func:`frequency_response`.

    Parameters
    ----------
    channels : Mapping[name, array_like (records, samples)] or array_like
        As for :func:`processing.spectra.segment_ffts`.
    input, output : channel names
    settings : SpectralSettings
    estimator : {"h1", "h2", "hv"}
    units : Mapping[name, str], optional
    """
    return frequency_response(segment_ffts(channels, settings, units=units), input, output,
                              estimator=estimator)
