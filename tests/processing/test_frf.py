"""Frequency responses: sign convention, H1 against a known filter, noise bias of H1/H2/Hv,
coherence, and the Bendat-Piersol random-error bands.

Bounds: per line, 5 sigma of the Bendat-Piersol random error (a union over a few hundred lines);
for means over M independent lines, 5 sigma / sqrt(M). Leakage bias, where present, is computed
exactly (:func:`expected_h1`) and stated separately.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from processing.frf import (
    MeasuredResponse,
    estimate_frf,
    frequency_response,
    random_error,
)
from processing.leakage import expected_h1
from processing.spectra import SettingsError, SpectralSettings, segment_ffts

FS = 100.0


def _wrap(deg):
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


def _records(stream: np.ndarray, n_records: int) -> np.ndarray:
    """Cut a continuous stream into contiguous records (the tail that does not fit is dropped)."""
    n = stream.size // n_records
    return stream[: n * n_records].reshape(n_records, n)


def test_delay_reads_negative_phase():
    """y[n] = x[n - d]: H = exp(-2j pi f d / fs), phase -360 f d / fs deg (a lag is negative).
    The expected H1 has exactly that phase (window-autocorrelation taper only scales it);
    the random error comes from the d samples per segment that do not pair up."""
    rng = np.random.default_rng(11)
    d = 3
    u = rng.standard_normal(20 * 5000 + d)
    x, y = _records(u[d:], 20), _records(u[:-d], 20)
    s = SpectralSettings(fs=FS, nperseg=1000)
    fr = estimate_frf({"a": x, "x": y}, "a", "x", settings=s, units={"a": "V", "x": "V"})
    expected = -360.0 * fr.freqs_hz * d / FS
    lines = slice(1, None)  # 0 Hz is NaN: the detrend removed it
    assert np.all(np.abs(_wrap(fr.phase_deg - expected))[lines] < 5 * fr.phase_std_deg[lines])
    assert np.all(fr.phase_deg[1:100] < 0)
    assert np.all((fr.phase_deg[lines] > -180) & (fr.phase_deg[lines] <= 180))
    # Unwrapped phase is the straight line itself.
    ok = np.isfinite(fr.h)
    assert np.all(np.abs(fr.phase_unwrapped_deg[ok] - expected[ok]) < 5 * fr.phase_std_deg[ok])
    taper = expected_h1(np.eye(1, d + 1, d).ravel(), s)
    np.testing.assert_allclose(np.degrees(np.angle(taper[1:100])), expected[1:100], atol=1e-9)
    assert fr.units == "(V)/(V)"
    assert np.isnan(fr.h[0])  # 0 Hz was removed by the detrend


def _resonator(f0_hz, r):
    """A digital resonator: poles r exp(+-2j pi f0/fs), b = [1 - r]."""
    th = 2 * np.pi * f0_hz / FS
    return np.array([1 - r]), np.array([1.0, -2 * r * np.cos(th), r * r])


def test_h1_of_a_digital_filter_matches_freqz():
    """H1 of lfilter(b, a, white noise) + output noise equals freqz within 5 sigma of the
    coherence-based random error plus the leakage bias, which is computed exactly as
    |expected_h1 - freqz| (impulse response tapered by the Hann autocorrelation)."""
    rng = np.random.default_rng(2024)
    b, a = _resonator(12.0, 0.97)  # half-power bandwidth ~ (1 - r) fs / pi = 0.95 Hz
    warm = 2000
    u = rng.standard_normal(warm + 40 * 4000)
    # Output noise keeps gamma^2 >= 0.4 on every line, where gamma^2's own error (<= 5 %) leaves
    # the band from the measured coherence accurate (see processing.frf on low coherence).
    y = scipy.signal.lfilter(b, a, u) + 0.01 * rng.standard_normal(u.size)
    x, y = _records(u[warm:], 40), _records(y[warm:], 40)
    s = SpectralSettings(fs=FS, nperseg=400, detrend=None)  # 0.25 Hz lines, Hann, 50 %
    fr = estimate_frf({"a": x, "x": y}, "a", "x", settings=s)
    _, h_true = scipy.signal.freqz(b, a, worN=fr.freqs_hz, fs=FS)
    imp = scipy.signal.lfilter(b, a, np.eye(1, s.nperseg).ravel())
    h_exp = expected_h1(imp, s)
    bias = np.abs(h_exp - h_true)
    eps = fr.relative_error
    # Random error about the expected H1, magnitude and phase separately.
    assert np.all(np.abs(np.abs(fr.h) / np.abs(h_exp) - 1) < 5 * eps)
    assert np.all(np.abs(np.angle(fr.h / h_exp)) < 5 * eps)
    # Against the exact filter: random band plus the stated leakage bias.
    assert np.all(np.abs(fr.h - h_true) < 5 * math.sqrt(2) * eps * np.abs(h_true) + bias)
    # The leakage bias is real at the resonance and small elsewhere.
    k0 = np.argmin(np.abs(fr.freqs_hz - 12.0))
    assert bias[k0] / abs(h_true[k0]) > 5 * eps[k0]
    # The error band is calibrated: normalised magnitude errors have unit spread. The 200 lines
    # hold about 200/1.94 independent ones (Hann), so the sample std has sd ~ 1/sqrt(2 * 103).
    z = (np.abs(fr.h) / np.abs(h_exp) - 1)[1:-1] / eps[1:-1]
    assert abs(z.std() - 1) < 4 / math.sqrt(2 * z.size / 1.94)


@pytest.mark.parametrize("snr", [0.25, 1.0, 4.0])
def test_output_noise_bias_and_coherence(snr):
    """y = g x + n with white n: H1 unbiased, H2 = g / gamma^2 (biased up), gamma^2 = S/(S+N).
    Uniform window without overlap: lines independent, so means over M lines have std
    sd_line / sqrt(M). Coherence's own error: sd(gamma^2) = sqrt(2) |gamma| (1 - gamma^2) /
    sqrt(n_d), plus a bias (1 - gamma^2)^2 / n_d."""
    rng = np.random.default_rng(int(snr * 100))
    g, sx = 2.0, 1.0
    sn = math.sqrt(g**2 * sx**2 / snr)
    x = sx * rng.standard_normal((16, 8000))
    y = g * x + sn * rng.standard_normal(x.shape)
    s = SpectralSettings(fs=FS, nperseg=200, window="uniform", noverlap=0)
    ffts = segment_ffts({"a": x, "x": y}, s)
    h1 = frequency_response(ffts, "a", "x", estimator="h1")
    h2 = frequency_response(ffts, "a", "x", estimator="H2")
    lines = slice(1, -1)
    g2_true = snr / (1 + snr)
    n_d = ffts.n_effective
    assert ffts.n_segments == 640 and n_d == pytest.approx(640, rel=1e-12)
    eps = random_error(g2_true, n_d)
    m = h1.h[lines].size
    # Means of the complex estimate (|H| itself carries a second-order bias eps^2 / 2).
    assert abs(h1.h[lines].mean() / g - 1) < 5 * eps / math.sqrt(m)
    assert np.all(np.abs(np.abs(h1.h[lines]) / g - 1) < 5 * eps)
    assert abs(h2.h[lines].mean() / (g / g2_true) - 1) < 5 * eps / math.sqrt(m)
    assert np.all(np.abs(h2.h[lines]) > np.abs(h1.h[lines]))
    sd_g2 = math.sqrt(2) * math.sqrt(g2_true) * (1 - g2_true) / math.sqrt(n_d)
    bias_g2 = (1 - g2_true) ** 2 / n_d
    assert np.all(np.abs(h1.coherence[lines] - g2_true - bias_g2) < 5 * sd_g2)
    assert abs(h1.coherence[lines].mean() - g2_true - bias_g2) < 5 * sd_g2 / math.sqrt(m)
    np.testing.assert_array_equal(h1.coherence, h2.coherence)


def test_hv_with_equal_noise_on_input_and_output():
    """x = u + m, y = g u + n with var(m) = var(n): H1 -> g Su / (Su + Sm) (low),
    H2 -> (g^2 Su + Sn) / (g Su) (high), Hv -> g (total least squares). Complex means over M
    independent lines are checked to 5 sd_line / sqrt(M), sd_line from the measured coherence."""
    rng = np.random.default_rng(99)
    g, su, sm = 2.0, 1.0, 0.5
    u = su * rng.standard_normal((16, 8000))
    x = u + sm * rng.standard_normal(u.shape)
    y = g * u + sm * rng.standard_normal(u.shape)
    ffts = segment_ffts({"a": x, "x": y}, SpectralSettings(fs=FS, nperseg=200, window="uniform",
                                                           noverlap=0))
    lines = slice(1, -1)
    expect = {"h1": g * su**2 / (su**2 + sm**2), "h2": (g**2 * su**2 + sm**2) / (g * su**2),
              "hv": g}
    mags = {}
    for est, val in expect.items():
        fr = frequency_response(ffts, "a", "x", estimator=est)
        mean = fr.h[lines].mean()  # complex mean: |H| has a second-order bias eps^2 / 2
        sd = fr.relative_error[lines].mean() * val / math.sqrt(fr.h[lines].size)
        assert abs(mean - val) < 5 * sd, est
        mags[est] = np.abs(fr.h)
        np.testing.assert_allclose(_wrap(fr.phase_deg - np.degrees(np.angle(
            frequency_response(ffts, "a", "x").h)))[lines], 0, atol=1e-9)
    tol = 1 + 1e-12
    assert np.all(mags["h1"][lines] <= mags["hv"][lines] * tol)
    assert np.all(mags["hv"][lines] <= mags["h2"][lines] * tol)


def test_vector_averaging_of_a_periodic_excitation():
    """A multisine periodic in the segment drives a filter in steady state; vector averaging
    (uniform window, no leakage) reads freqz on every excited line within 5 sigma of the random
    error computed from the RMS coherence of the same segments."""
    rng = np.random.default_rng(4)
    n, k_seg = 256, 64
    b, a = _resonator(20.0, 0.9)
    lines = np.arange(1, n // 2)
    spec = np.zeros(n // 2 + 1, complex)
    spec[lines] = np.exp(2j * np.pi * rng.random(lines.size))
    period = np.fft.irfft(spec, n) * n / 10
    u = np.tile(period, k_seg + 8)
    y = scipy.signal.lfilter(b, a, u)[8 * n:] + 0.05 * rng.standard_normal(k_seg * n)
    u = u[8 * n:]
    s = SpectralSettings(fs=FS, nperseg=n, window="uniform", noverlap=0, averaging="vector")
    fr = estimate_frf({"a": u, "x": y}, "a", "x", settings=s)
    _, h_true = scipy.signal.freqz(b, a, worN=fr.freqs_hz, fs=FS)
    eps = fr.relative_error[lines]
    assert np.all(np.abs(np.abs(fr.h[lines] / h_true[lines]) - 1) < 5 * eps)
    assert np.all(np.abs(np.angle(fr.h[lines] / h_true[lines])) < 5 * eps)
    assert np.all(fr.coherence[lines] < 1)


def test_error_band_helpers():
    """gamma^2 = 0.5, n_d = 50: eps = sqrt(0.5) / (sqrt(0.5) sqrt(100)) = 0.1."""
    f = np.array([1.0, 2.0, 3.0])
    h = np.array([-1.0 + 0j, 10j, -2.0 - 1e-12j])
    fr = MeasuredResponse(f, h, coherence=np.full(3, 0.5), n_averages=60, n_effective=50.0,
                          estimator="h1")
    np.testing.assert_allclose(fr.relative_error, 0.1)
    lo, hi = fr.gain_band_db()
    np.testing.assert_allclose(lo, fr.magnitude_db + 20 * np.log10(0.9))
    np.testing.assert_allclose(hi, fr.magnitude_db + 20 * np.log10(1.1))
    np.testing.assert_allclose(fr.phase_std_deg, np.degrees(0.1))
    assert fr.phase_deg[0] == 180.0 and fr.phase_deg[1] == pytest.approx(90.0)
    assert fr.phase_deg[2] == pytest.approx(-180.0, abs=1e-9) and fr.phase_deg[2] > -180
    plo, phi = fr.phase_band_deg(2.0)
    np.testing.assert_allclose(phi - plo, 4 * np.degrees(0.1))
    assert np.isneginf(fr.gain_band_db(k=10.0)[0]).all()
    assert fr.magnitude_db[1] == pytest.approx(20.0)
    assert fr.select(1.5, 3.0).freqs_hz.tolist() == [2.0, 3.0]
    assert np.isinf(random_error(0.0, 10)) and random_error(1.0, 10) == 0.0


def test_bad_estimator_and_peak_hold_raise():
    x = np.random.default_rng(0).standard_normal((2, 1000))
    ffts = segment_ffts({"a": x, "x": x}, SpectralSettings(fs=FS, nperseg=100))
    with pytest.raises(SettingsError, match="estimator = 'h3'"):
        frequency_response(ffts, "a", "x", estimator="h3")
    peak = segment_ffts({"a": x, "x": x}, SpectralSettings(fs=FS, nperseg=100, averaging="peak"))
    with pytest.raises(SettingsError, match="peak"):
        frequency_response(peak, "a", "x")
