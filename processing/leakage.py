"""The expected estimate ``E[H1]``: the leakage bias of an averaged H1 for a given window.

For a stationary input ``u`` and output ``x`` the averaged cross and auto spectra have the
expectations (any overlap and any power averaging; exact, no white-input assumption)::

    E[G_ux](f_k) ~ sum_tau R_ux[tau] r_w(|tau|) exp(-2j pi f_k tau / fs),   |tau| < nperseg

with ``R_ux[tau] = E[u[n] x[n + tau]]`` and ``r_w`` the window's normalised autocorrelation; so
``E[H1] = E[G_ux] / E[G_uu]`` (the ratio of expectations; the expected ratio differs by terms of
order ``1 / n_d`` inside the random error).

* :func:`expected_h1`, :func:`expected_h1_taps`, :func:`impulse_expected_h1`: a white input, for
  which ``R_ux`` is the impulse response ``g`` (causal or two-sided);
* :func:`expected_estimate`: the bench under its own source. The correlations are inverse FFTs of
  the bench's exact sampled cross spectra::

      S_ax = S_v conj(A) X |F|^2,   S_aa = (S_v |A|^2 + N_a) |F|^2 + Q_a

  ``S_v`` the source's design PSD, ``A, X`` the channels in engineering units per source volt
  (:func:`rig.bench.sampled_response`), ``F`` the anti-alias filter, ``N_a`` the
  accelerometer's white noise, ``Q_a`` the ADC's quantisation noise of channel ``a``
  (``lsb^2 / (6 rate)``). The sensor noise of x and y does not enter ``E[G_ux]``. Neglected:
  aliasing of the decimation (the filter's stop band is ~100 dB down) and the FIR's edge
  smoothing of the source band. Time aliasing of the correlations is below
  ``exp(-(n_fft - nperseg) / (fs tau))``, ``tau`` the slowest decay time of the bench
  (:attr:`ExpectedEstimate.alias_bound`). With the stage's reaction the input is not white (the
  stage acceleration has a notch at each pendulum mode), which is why the white-input formula
  does not hold for the bench (docs/analyzer-notes.md gives the paper run's numbers).

Exact for ``detrend=None``; the constant detrend changes only the lines whose window transform
overlaps 0 Hz (k <= 1 for Hann). Cost: two real FFTs of ``n_fft`` points per channel pair.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from processing.modal_model import InputSpectrum
from processing.spectra import SettingsError, SpectralSettings, window_autocorrelation
from rig.readonly import readonly

if TYPE_CHECKING:  # rig.bench is imported on use: importing processing stays light
    from rig.bench import SampledResponse

__all__ = ["ExpectedEstimate", "expected_estimate", "expected_h1", "expected_h1_taps",
           "impulse_expected_h1", "CHANNELS"]

#: Input, translation and rotation channel of a run.
CHANNELS = ("a", "x", "y")
_ALIAS_TARGET = 1e-12


def expected_h1(impulse_response, settings: SpectralSettings) -> np.ndarray:
    """Expected H1 of a discrete LTI system driven by white noise, leakage bias included.

    For white input, ``E[conj(X_k) Y_k] / E[|X_k|^2] = sum_tau h[tau] r_w(tau)
    exp(-2j pi f_k tau / fs)`` with ``r_w(tau) = sum_n w[n] w[n - tau] / sum_n w[n]^2``: the
    response of the impulse response tapered by the window's autocorrelation (zero beyond
    ``nperseg`` samples). This is exact for ``detrend=None`` and any overlap or averaging of
    powers; it is the ratio of expectations, which differs from the expected ratio only by terms
    of order ``1 / n_d`` within the random error.

    Parameters
    ----------
    impulse_response : array_like
        ``h[n]``, ``n = 0, 1, ...`` (causal), shape ``(n_taps,)`` [output unit / input unit].
    settings : SpectralSettings

    Returns
    -------
    numpy.ndarray
        Complex, shape ``(n_freqs,)`` on ``settings.freqs_hz``.
    """
    h = np.asarray(impulse_response, dtype=float)
    if h.ndim != 1 or h.size == 0:
        raise SettingsError(f"impulse_response has shape {h.shape}: expected (n_taps,)")
    n = settings.nperseg
    r = window_autocorrelation(settings)
    m = min(n, h.size)
    return np.fft.rfft(h[:m] * r[:m], n=n)[: settings.freqs_hz.size]


def expected_h1_taps(taps, settings: SpectralSettings, *, lag0: int = 0) -> np.ndarray:
    """Expected H1 for white input of a (possibly two-sided) impulse response, leakage included.

    ``E[H1](f_k) = sum_tau g[tau] r_w(|tau|) exp(-2j pi k tau / nperseg)`` over ``|tau| <
    nperseg``, with ``g[lag0 + i] = taps[i]``. For ``lag0 = 0`` this is
    :func:`expected_h1`. Exact for ``detrend=None``; the constant detrend changes
    only the lines whose window transform overlaps 0 Hz (k <= 1 for Hann).

    Returns
    -------
    numpy.ndarray : complex, shape ``(n_freqs,)`` on ``settings.freqs_hz``.
    """
    g = np.asarray(taps, dtype=float)
    if g.ndim != 1 or g.size == 0:
        raise SettingsError(f"taps has shape {g.shape}: expected (n_taps,)")
    n = settings.nperseg
    r = window_autocorrelation(settings)
    lags = np.arange(g.size) + int(lag0)
    keep = np.abs(lags) < n
    buf = np.zeros(n)
    np.add.at(buf, lags[keep] % n, g[keep] * r[np.abs(lags[keep])])
    return np.fft.rfft(buf)[: settings.freqs_hz.size]

def impulse_expected_h1(response, settings: SpectralSettings, output=None) -> np.ndarray:
    """``E[H1]`` on ``settings.freqs_hz`` of a :class:`rig.linear.ImpulseResponse` for white input
    (:func:`expected_h1_taps`): ``(nf,)`` for one named output, else ``(nf, n_out)``."""
    if abs(settings.fs - response.fs) > 1e-9 * response.fs:
        raise SettingsError(f"settings.fs = {settings.fs} Hz differs from the impulse response's "
                            f"fs = {response.fs} Hz")
    if output is not None:
        return expected_h1_taps(response.output(output), settings, lag0=response.lag0)
    return np.stack([expected_h1_taps(t, settings, lag0=response.lag0)
                     for t in response.taps], -1)


# -- the bench under its own source ----------------------------------------------------------

@dataclass(frozen=True, eq=False)
class ExpectedEstimate:
    """``E[H1]`` of the bench at the analyzer's lines (module notes).

    Attributes
    ----------
    freqs_hz : (nf,) [Hz]; h_t, theta_2 : (nf,) complex, same units as the measured ratios.
    n_fft : FFT length of the correlation functions [samples].
    tau_s : slowest decay time of the bench [s].
    alias_bound : ``exp(-(n_fft - nperseg) / (fs tau))``: bound on the time aliasing (relative).
    input_psd : (nf,) the model's ``E[G_aa]`` at the lines [(m/s^2)^2/Hz] (window-averaged).
    input_notch_db : {mode f [Hz]: input PSD at the line nearest the mode relative to its median
        over the display band [dB]} -- how coloured the input is where it matters.
    input_spectrum : processing.modal.InputSpectrum, the same input (coherent PSD, noise PSD and
        the accelerometer's high-pass as the input sensor) at any frequency, for the
        leakage-aware fits of the pendulum's own response.
    """

    freqs_hz: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    n_fft: int
    tau_s: float
    alias_bound: float
    input_psd: np.ndarray
    input_notch_db: Mapping
    input_spectrum: InputSpectrum | None = None


def _check_expected(scene, fs: float, settings: SpectralSettings) -> None:
    """A SettingsError unless E[H1] applies: the analyzer's rate is the run's, power averaging,
    a stationary noise source."""
    if abs(settings.fs - fs) > 1e-9 * fs:
        raise SettingsError(f"settings.fs = {settings.fs} Hz differs from the run's rate {fs} Hz")
    if settings.averaging == "vector":
        raise SettingsError("averaging = 'vector' averages complex spectra: E[H1] as a ratio of "
                            "averaged powers does not apply; expected rms or exponential")
    if scene.source.type not in ("random", "pink"):
        raise SettingsError(f"source.type = {scene.source.type!r}: E[H1] is modelled for "
                            "stationary noise sources (random, pink) only")


def _input_notches(lines, g_in, modes_hz, fmin_hz: float, fmax_hz: float) -> dict:
    """The input PSD at each mode in the band, in dB relative to its median over the band
    (:attr:`ExpectedEstimate.input_notch_db`)."""
    disp = (lines >= fmin_hz) & (lines <= fmax_hz)
    notch = {}
    if np.any(disp):
        med = float(np.median(g_in[disp]))
        for fm in modes_hz:
            j = int(np.argmin(np.abs(lines - fm)))
            if disp[j]:
                notch[float(fm)] = float(10 * np.log10(g_in[j] / med))
    return notch


def expected_estimate(header, settings: SpectralSettings, *, n_fft: int | None = None,
                      fmin_hz: float = 0.1, fmax_hz: float = 10.0,
                      bench: SampledResponse | None = None) -> ExpectedEstimate:
    """Expected H1 of H_t and Theta_2 for the run's bench and source under ``settings``.

    Parameters
    ----------
    header : daq.records.Header of the run (scene, channels, anti-alias filter, plan).
    settings : the analyzer's settings (window, nperseg; power averaging).
    n_fft : FFT length of the correlation functions (default: a power of two >= 4 nperseg making
        the time aliasing of the slowest mode below 1e-12).
    fmin_hz, fmax_hz : band of :attr:`ExpectedEstimate.input_notch_db`.
    bench : the run's :class:`rig.bench.SampledResponse` if already built (an analysis builds
        one and passes it on).

    Raises
    ------
    SettingsError
        For a source that is not stationary noise (``source.type`` random or pink), vector
        averaging (whose expectation is not a ratio of averaged powers), or a rate mismatch.
    """
    scene = header.scene
    fs = header.plan.rate_hz
    _check_expected(scene, fs, settings)
    source = scene.source
    acc = scene.accelerometer
    if bench is None:
        from rig.bench.sampled import sampled_response

        bench = sampled_response(scene)
    tau = bench.tau_s
    n = settings.nperseg
    if n_fft is None:
        need = max(4 * n, int(math.ceil(n + fs * tau * math.log(1.0 / _ALIAS_TARGET))))
        n_fft = 1 << (need - 1).bit_length()
    n_fft = int(n_fft)
    if n_fft < 2 * n:
        raise SettingsError(f"n_fft = {n_fft} is invalid: expected >= 2 nperseg = {2 * n}")
    ca = header.channel("a")
    vpu = {c: header.channel(c).volts_per_unit for c in CHANNELS}
    noise_a = (acc.sensitivity_vpmps2 * acc.noise_mps2_rthz / abs(vpu["a"])) ** 2
    quant_a = (ca.adc.lsb_v / vpu["a"]) ** 2 / (6.0 * fs)

    def channels(f):
        """(s_v, a, x, y in engineering units, |F|^2) at f (0 outside the source's band)."""
        s_v = source.design_psd(f)
        band = s_v > 0
        eng = {c: np.zeros(f.size, complex) for c in CHANNELS}
        r = bench(f[band])
        for c in CHANNELS:
            eng[c][band] = getattr(r, c) / vpu[c]
        return s_v, eng, np.abs(header.antialias.response(f)) ** 2

    f = np.arange(n_fft // 2 + 1) * (fs / n_fft)
    s_v, eng, f2 = channels(f)
    a_eng, x_eng, y_eng = (eng[c] for c in CHANNELS)
    s_aa = (s_v * np.abs(a_eng) ** 2 + noise_a) * f2 + quant_a
    s_ax = s_v * np.conj(a_eng) * x_eng * f2
    s_ay = s_v * np.conj(a_eng) * y_eng * f2

    def tapered(s):  # sum_tau R[tau] r_w(|tau|) exp(-2j pi f_k tau / fs), |tau| < nperseg
        rr = np.fft.irfft(s, n=n_fft)
        taps = np.concatenate([rr[-(n - 1):], rr[:n]]) if n > 1 else rr[:1]
        return expected_h1_taps(taps, settings, lag0=-(n - 1))

    g_aa = tapered(s_aa.astype(complex))
    with np.errstate(divide="ignore", invalid="ignore"):
        e_t = tapered(s_ax) / g_aa
        e_r = tapered(s_ay) / g_aa
    lines = settings.freqs_hz
    # The tapered sum of the one-sided PSD's correlation is (n_fft / 2) E[G] (irfft's 1/n_fft and
    # the two-sided density S/2): E[G_aa] in (m/s^2)^2/Hz, window-averaged.
    g_in = g_aa.real * 2.0 * fs / n_fft
    notch = _input_notches(lines, g_in, scene.chain.modes()[0], fmin_hz, fmax_hz)
    bound = math.exp(-(n_fft - n) / (fs * tau)) if tau > 0 else 0.0

    # The same input for the leakage-aware fits of the pendulum's own response (the measured
    # ratio times the accelerometer's high-pass K = a / stage acceleration).
    def psd(f):
        s_v, eng, f2 = channels(f)
        return s_v * np.abs(eng["a"]) ** 2 * f2

    def noise(f):
        return noise_a * np.abs(header.antialias.response(f)) ** 2 + quant_a

    def sensor(f):
        r = bench(f)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = r.h_t_pendulum / r.h_t
        return np.where(np.isfinite(k), k, 1.0)

    spectrum = InputSpectrum(psd, noise, sensor, decay_s=tau,
                             label="the bench's exact input spectrum")
    return ExpectedEstimate(readonly(lines), readonly(e_t), readonly(e_r), n_fft, tau, bound,
                            readonly(g_in), MappingProxyType(notch), spectrum)

