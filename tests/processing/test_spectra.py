"""Averaged spectra: levels, window corrections, averaging modes, the effective number of averages.

Tolerances come from stated error estimates, never from the observed result: an averaged PSD of
Gaussian noise has relative standard deviation ``1 / sqrt(n_d)`` per line; bounds are a few sigma
(5 sigma where a union over ~100 lines is taken).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from processing.spectra import (
    WINDOWS,
    ChannelDataError,
    SettingsError,
    SpectralSettings,
    auto_spectrum,
    coherence,
    cross_spectrum,
    estimate_auto_spectra,
    segment_ffts,
)

FS = 100.0


def _band_mean_sd(s: SpectralSettings, n_records: int, n_samples: int) -> float:
    """Relative std of the PSD averaged over all lines, for white Gaussian noise.

    By Parseval the line average is ``sum_t u_t x_t^2 / sigma^2`` with ``u_t`` the total weight
    ``w^2`` each sample receives from the segments covering it (normalised to sum 1), so its
    relative variance is ``2 sum_t u_t^2`` (the 0 Hz and Nyquist lines, left out, carry 1/nperseg
    of it)."""
    k = 1 + (n_samples - s.nperseg) // s.step
    starts = np.zeros((k - 1) * s.step + 1)
    starts[:: s.step] = 1.0
    u = np.tile(np.convolve(starts, s.window_array**2), n_records)
    u /= u.sum()
    return math.sqrt(2 * np.sum(u**2))


@pytest.mark.parametrize("window", WINDOWS)
def test_white_noise_psd_level(window):
    """Two-sided variance sigma^2 reads one-sided PSD 2 sigma^2 / fs on every line but 0 Hz and
    Nyquist (which read half, the scipy convention, and are excluded)."""
    rng = np.random.default_rng(20240601)
    sigma = 0.7
    x = sigma * rng.standard_normal((32, 8192))
    s = SpectralSettings(fs=FS, nperseg=256, window=window, detrend=None)
    ffts = segment_ffts({"v": x}, s, units={"v": "V"})
    sp = auto_spectrum(ffts, "v")
    assert sp.value_units == "(V)^2/Hz"
    assert sp.n_averages == 32 * (1 + (8192 - 256) // 128)
    ratio = sp.values[1:-1] / (2 * sigma**2 / FS)
    sd_line = 1 / math.sqrt(sp.n_effective)
    # Every line: relative std 1/sqrt(n_d); 5 sigma covers a union over 127 lines.
    assert np.all(np.abs(ratio - 1) < 5 * sd_line)
    # The band mean, to a few tenths of a percent.
    assert abs(ratio.mean() - 1) < 5 * _band_mean_sd(s, *x.shape)
    # DC and Nyquist read half the level (real-valued lines without a negative-frequency twin).
    assert abs(sp.values[0] / (sigma**2 / FS) - 1) < 5 * math.sqrt(2) * sd_line


def test_psd_matches_scipy_welch():
    """Same settings as scipy.signal.welch (Hann, 50 %, constant detrend): same numbers."""
    rng = np.random.default_rng(7)
    x = rng.standard_normal(4096)
    s = SpectralSettings(fs=FS, nperseg=256)
    sp = auto_spectrum(segment_ffts(x, s), 0)
    f, p = scipy.signal.welch(x, fs=FS, nperseg=256)
    np.testing.assert_allclose(sp.freqs_hz, f)
    np.testing.assert_allclose(sp.values, p, rtol=1e-12, atol=1e-18)
    sp2 = auto_spectrum(segment_ffts(x, s), 0, scaling="spectrum")
    f, p2 = scipy.signal.welch(x, fs=FS, nperseg=256, scaling="spectrum")
    np.testing.assert_allclose(sp2.values, p2, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("offset_lines", [0.0, 0.1, 0.25, 0.37, 0.5])
def test_flattop_reads_sine_rms_within_scalloping(offset_lines):
    """A flat-top linear spectrum reads a sine's RMS within the window's scalloping (< 0.01 dB),
    wherever the sine falls between lines. Extra allowance 0.001 dB: the image at -f and the
    removed mean leak in through sidelobes below -90 dB (<= 3e-4 dB)."""
    s = SpectralSettings(fs=FS, nperseg=1000, window="flattop")
    assert s.window_info.scalloping_db < 0.01
    f0 = (123 + offset_lines) * s.resolution_hz
    t = np.arange(20000) / FS
    rms = 3.0
    x = rms * math.sqrt(2) * np.sin(2 * np.pi * f0 * t + 0.3)
    sp = auto_spectrum(segment_ffts({"a": x.reshape(2, -1)}, s, units={"a": "m/s^2"}), "a",
                       scaling="spectrum")
    assert sp.value_units == "(m/s^2)^2"
    err_db = 20 * math.log10(sp.amplitude.max() / rms)
    assert abs(err_db) <= s.window_info.scalloping_db + 1e-3


@pytest.mark.parametrize("window", ["hann", "uniform"])
def test_sine_rms_exact_on_a_line(window):
    """On a line, Hann (coherent gain 1/2) and uniform read the RMS to rounding."""
    s = SpectralSettings(fs=FS, nperseg=500, window=window)
    t = np.arange(5000) / FS
    x = 2.5 * np.cos(2 * np.pi * 40 * s.resolution_hz * t + 1.0)
    sp = auto_spectrum(segment_ffts(x, s), 0, scaling="spectrum")
    k = np.argmax(sp.values)
    assert sp.freqs_hz[k] == pytest.approx(40 * s.resolution_hz)
    assert sp.amplitude[k] == pytest.approx(2.5 / math.sqrt(2), rel=1e-12)
    # Density and spectrum scalings differ by the equivalent noise bandwidth.
    dens = sp.to_scaling("density")
    np.testing.assert_allclose(dens.values * s.window_info.enbw_hz, sp.values, rtol=1e-14)


@pytest.mark.parametrize("window", ["hann", "flattop"])
@pytest.mark.parametrize("n", [2, 7, 1024, 10_000])
def test_windows_are_scipys_periodic_windows(window, n):
    """The windows are computed without scipy, sample for sample as scipy.signal computes them."""
    got = SpectralSettings(fs=FS, nperseg=n, window=window).window_array
    np.testing.assert_array_equal(got, scipy.signal.get_window(window, n, fftbins=True))


def test_window_autocorrelation_by_fft_equals_the_direct_sum():
    from processing.spectral_settings import _autocorrelation

    for window in WINDOWS:
        w = SpectralSettings(fs=FS, nperseg=1000, window=window).window_array
        direct = np.correlate(w, w, mode="full")[999:] / np.dot(w, w)
        np.testing.assert_allclose(_autocorrelation(w), direct, rtol=0, atol=1e-13)


def test_window_constants():
    assert SpectralSettings(fs=FS, nperseg=1024, window="hann").window_info.enbw_bins == \
        pytest.approx(1.5)
    assert SpectralSettings(fs=FS, nperseg=1024, window="hann").window_info.coherent_gain == \
        pytest.approx(0.5)
    info = SpectralSettings(fs=FS, nperseg=1024, window="uniform").window_info
    assert info.scalloping_db == pytest.approx(3.92, abs=0.01)
    assert info.enbw_hz == pytest.approx(FS / 1024)
    force = SpectralSettings(fs=FS, nperseg=1000, window="force", force_fraction=0.2)
    assert force.window_array[:200].min() == 1.0 and force.window_array[200:].max() == 0.0
    expo = SpectralSettings(fs=FS, nperseg=1000, window="exponential", exp_tau_s=2.0)
    assert expo.window_array[200] == pytest.approx(math.exp(-1))
    assert SpectralSettings(fs=FS, nperseg=1000, window="exponential").exp_tau_s == 2.5


def test_from_lines_like_the_35670a():
    s = SpectralSettings.from_lines(FS, 800, 10.0, window="flattop")
    assert s.nperseg == 8000 and s.noverlap == 0
    assert s.freqs_hz.size == 801 and s.freqs_hz[-1] == pytest.approx(10.0)
    assert s.resolution_hz == pytest.approx(0.0125)
    s = SpectralSettings.from_lines(FS, 400, 25.0, overlap=0.5)
    assert s.nperseg == 1600 and s.noverlap == 800
    with pytest.raises(SettingsError, match="12.3"):
        SpectralSettings.from_lines(FS, 800, 12.3)


def test_segments_never_straddle_records():
    """Two records of a line-centred sine with a phase jump between them: per record there is no
    leakage at all (uniform window); the same samples as one record leak through the segment
    across the jump."""
    s = SpectralSettings(fs=FS, nperseg=200, window="uniform", noverlap=100, detrend=None)
    n = 400
    t = np.arange(n) / FS
    f0 = 10 * s.resolution_hz
    recs = np.stack([np.sin(2 * np.pi * f0 * t), np.sin(2 * np.pi * f0 * t + 2.0)])
    split = segment_ffts(recs, s)
    joined = segment_ffts(recs.reshape(1, -1), s)
    assert split.n_segments == 2 * 3 and split.record_index.tolist() == [0, 0, 0, 1, 1, 1]
    assert joined.n_segments == 7
    p_split = auto_spectrum(split, 0).values
    p_join = auto_spectrum(joined, 0).values
    off = np.arange(p_split.size) != 10
    assert p_split[off].max() < 1e-25 * p_split[10]
    assert p_join[off].max() > 1e-4 * p_join[10]


def _trial_variance(settings, shape, trials, seed, lines):
    """Variance over trials and lines of PSD / true PSD for unit white noise."""
    rng = np.random.default_rng(seed)
    vals = []
    n_eff = None
    for _ in range(trials):
        ffts = segment_ffts(rng.standard_normal(shape), settings)
        vals.append(auto_spectrum(ffts, 0).values[lines] / (2 / settings.fs))
        n_eff = ffts.n_effective
    vals = np.concatenate(vals)
    return vals.var(ddof=1), vals.size, n_eff


def test_variance_falls_as_one_over_n():
    """Uniform window, no overlap: lines and segments are independent, each averaged line is
    Gamma(n, 1/n) with variance 1/n. The sample variance from M values has relative std
    sqrt((2 + 6/n) / M) (excess kurtosis 6/n); the log-log slope is fitted with those weights."""
    s = SpectralSettings(fs=FS, nperseg=64, window="uniform", noverlap=0, detrend=None)
    lines = slice(1, 32)
    ns = np.array([1, 2, 4, 8, 16, 32])
    log_var, sd = [], []
    for i, n in enumerate(ns):
        var, m, n_eff = _trial_variance(s, (n, 64), 300, 100 + i, lines)
        assert n_eff == n
        rel_sd = math.sqrt((2 + 6 / n) / m)
        assert abs(var * n - 1) < 4 * rel_sd
        log_var.append(math.log(var))
        sd.append(rel_sd)
    wts = 1 / np.asarray(sd) ** 2
    x = np.log(ns)
    xm = np.sum(wts * x) / wts.sum()
    slope = np.sum(wts * (x - xm) * np.asarray(log_var)) / np.sum(wts * (x - xm) ** 2)
    slope_se = 1 / math.sqrt(np.sum(wts * (x - xm) ** 2))
    assert abs(slope + 1) < 4 * slope_se


@pytest.mark.parametrize("case", ["hann50", "exponential"])
def test_effective_number_of_averages(case):
    """The measured variance matches 1/n_effective, not 1/n_segments.

    Hann at 50 %: 32 segments in one record, n_eff = 32 / (1 + 2 (31/32) / 36) = 30.4 (5.4 % fewer).
    Exponential averaging, N = 8 over 64 segments: n_eff -> 2N - 1 = 15.
    Even lines only for Hann (neighbours' power correlation 4/9, next-but-one 1/36)."""
    if case == "hann50":
        s = SpectralSettings(fs=FS, nperseg=64, window="hann", noverlap=32, detrend=None)
        shape, lines, k = (64 + 31 * 32,), slice(2, 31, 2), 32
    else:
        s = SpectralSettings(fs=FS, nperseg=64, window="uniform", noverlap=0, detrend=None,
                             averaging="exponential", exp_averages=8)
        shape, lines, k = (64 * 64,), slice(1, 32), 64
    var, m, n_eff = _trial_variance(s, shape, 3000, 11, lines)
    if case == "hann50":
        assert n_eff == pytest.approx(32 / (1 + 2 * (31 / 32) / 36), rel=1e-12)
        corr = 1 + 2 / 36  # neighbours in the even-line subset
    else:
        assert n_eff == pytest.approx(15, rel=1e-3)
        corr = 1.0
    rel_sd = math.sqrt((2 + 6 / n_eff) / m * corr)
    assert abs(var * n_eff - 1) < 4 * rel_sd
    if case == "hann50":
        assert abs(var * k - 1) > 4 * rel_sd  # counting segments would be measurably wrong


def test_exponential_average_equals_recursion():
    """The closed-form weights reproduce the 35670A recursion
    A_k = A_{k-1} + (X_k - A_{k-1}) / min(k, N), computed by a slow, obviously correct loop."""
    rng = np.random.default_rng(3)
    s = SpectralSettings(fs=FS, nperseg=32, window="hann", noverlap=16, averaging="exponential",
                         exp_averages=5)
    x = rng.standard_normal((3, 200))
    ffts = segment_ffts({"a": x, "b": np.roll(x, 1, axis=1)}, s)
    a, b = ffts["a"], ffts["b"]
    acc_aa, acc_ab = 0.0, 0.0
    for k in range(ffts.n_segments):
        wk = 1 / min(k + 1, 5)
        acc_aa = acc_aa + wk * (np.abs(a[k]) ** 2 - acc_aa)
        acc_ab = acc_ab + wk * (np.conj(a[k]) * b[k] - acc_ab)
    np.testing.assert_allclose(auto_spectrum(ffts, "a").values, acc_aa, rtol=1e-12)
    np.testing.assert_allclose(cross_spectrum(ffts, "a", "b").values, acc_ab, rtol=1e-12)
    assert ffts.weights.sum() == pytest.approx(1.0)


def test_peak_hold_and_vector_average():
    """Peak hold is the max over segments; vector averaging of a segment-synchronous sine keeps
    the sine and divides the noise floor by the number of segments (E|mean X|^2 = E|X|^2 / K).
    The floor is a mean over M independent lines of exponential variables: rel. std 1/sqrt(M)."""
    rng = np.random.default_rng(5)
    k_seg, n = 64, 128
    base = dict(fs=FS, nperseg=n, window="uniform", noverlap=0, detrend=None)
    t = np.arange(k_seg * n) / FS
    sine_line = 16
    x = 2.0 * np.sin(2 * np.pi * sine_line * FS / n * t) + 0.1 * rng.standard_normal(t.size)
    rms = auto_spectrum(segment_ffts(x, SpectralSettings(**base)), 0)
    vec = auto_spectrum(segment_ffts(x, SpectralSettings(**base, averaging="vector")), 0)
    peak_ffts = segment_ffts(x, SpectralSettings(**base, averaging="peak"))
    peak = auto_spectrum(peak_ffts, 0)
    assert np.all(peak.values >= rms.values)
    np.testing.assert_allclose(peak.values, np.max(np.abs(peak_ffts[0]) ** 2, axis=0))
    assert peak.n_effective == 1.0
    floor = np.r_[1:sine_line, sine_line + 1:n // 2]
    ratio = vec.values[floor].mean() / rms.values[floor].mean() * k_seg
    assert abs(ratio - 1) < 5 / math.sqrt(floor.size)
    # The sine line reads its RMS. Vector-averaged noise there has power 2 sigma^2 / (n K) (uniform
    # window) against the sine's A^2 / 2, so the reading's relative std is
    # sqrt(noise / (2 * sine)) ~ 8e-4; bound 5 sigma.
    sine = SpectralSettings(**base, averaging="vector").window_info.enbw_hz * vec.values[sine_line]
    sd = math.sqrt(2 * 0.1**2 / (n * k_seg) / (2 * 2.0**2 / 2))
    assert abs(math.sqrt(sine) / (2 / math.sqrt(2)) - 1) < 5 * sd
    with pytest.raises(SettingsError, match="peak"):
        cross_spectrum(segment_ffts({"a": x, "b": x}, SpectralSettings(**base, averaging="peak")),
                       "a", "b")


def test_coherence_and_cross_spectrum_phase_sign():
    """y lagging x by d samples: G_xy = <conj(X) Y> has phase -360 f d / fs; coherence ~ 1."""
    rng = np.random.default_rng(9)
    d = 2
    u = rng.standard_normal(40 * 1000 + d)
    x, y = u[d:].reshape(40, -1), u[:-d].reshape(40, -1)
    ffts = segment_ffts({"x": x, "y": y}, SpectralSettings(fs=FS, nperseg=500))
    g = cross_spectrum(ffts, "x", "y")
    expected = -360 * g.freqs_hz * d / FS
    band = (g.freqs_hz > 1) & (g.freqs_hz < 20)
    dphi = (g.phase_deg - expected + 180) % 360 - 180
    assert np.all(np.abs(dphi[band]) < 2.0)
    assert np.all(coherence(ffts, "x", "y")[band] > 0.9)


def test_one_shot_and_channel_layouts():
    rng = np.random.default_rng(2)
    x = rng.standard_normal((2, 3, 1000))
    out = estimate_auto_spectra(x, settings=SpectralSettings(fs=FS, nperseg=100))
    assert set(out) == {0, 1}
    named = estimate_auto_spectra({"p": x[0], "q": x[1]}, settings=SpectralSettings(fs=FS,
                                                                                    nperseg=100))
    np.testing.assert_array_equal(named["q"].values, out[1].values)
    assert named["p"].magnitude_db.shape == (51,)
    sel = named["p"].select(10, 20)
    assert sel.freqs_hz.min() >= 10 and sel.freqs_hz.max() <= 20


@pytest.mark.parametrize("kwargs, match", [
    (dict(fs=0.0, nperseg=64), "fs = 0.0"),
    (dict(fs=-5, nperseg=64), "fs = -5"),
    (dict(fs=float("nan"), nperseg=64), "fs = nan"),
    (dict(fs=FS, nperseg=1), "nperseg = 1"),
    (dict(fs=FS, nperseg=64.0), "nperseg = 64.0"),
    (dict(fs=FS, nperseg=64, noverlap=-1), "noverlap = -1"),
    (dict(fs=FS, nperseg=64, noverlap=64), "noverlap = 64"),
    (dict(fs=FS, nperseg=64, overlap=-0.5), "overlap = -0.5"),
    (dict(fs=FS, nperseg=64, overlap=1.0), "overlap = 1.0"),
    (dict(fs=FS, nperseg=64, noverlap=3, overlap=0.5), "both given"),
    (dict(fs=FS, nperseg=64, window="hamming"), "window = 'hamming'.*uniform"),
    (dict(fs=FS, nperseg=64, averaging="median"), "averaging = 'median'.*rms"),
    (dict(fs=FS, nperseg=64, detrend="quadratic"), "detrend = 'quadratic'"),
    (dict(fs=FS, nperseg=64, exp_averages=0), "exp_averages = 0"),
    (dict(fs=FS, nperseg=64, force_fraction=1.5), "force_fraction = 1.5"),
    (dict(fs=FS, nperseg=64, exp_tau_s=-1.0), "exp_tau_s = -1.0"),
    (dict(fs=FS, nperseg=64, span_hz=60.0), "span_hz = 60.0"),
])
def test_bad_settings_raise_naming_the_value(kwargs, match):
    with pytest.raises(SettingsError, match=match):
        SpectralSettings(**kwargs)
    with pytest.raises(ValueError):  # still catchable as the built-in
        SpectralSettings(**kwargs)


def test_bad_data_raise():
    s = SpectralSettings(fs=FS, nperseg=256)
    with pytest.raises(SettingsError, match="nperseg = 256.*100 samples"):
        segment_ffts(np.zeros((3, 100)), s)
    with pytest.raises(ChannelDataError, match="'b' has shape"):
        segment_ffts({"a": np.zeros((2, 300)), "b": np.zeros((3, 300))}, s)
    bad = np.zeros((2, 300))
    bad[1, 7] = np.nan
    with pytest.raises(ChannelDataError, match="'a' holds non-finite"):
        segment_ffts({"a": bad}, s)
    ffts = segment_ffts({"a": np.zeros((2, 300))}, s)
    with pytest.raises(ChannelDataError, match="'z' is not present"):
        auto_spectrum(ffts, "z")
    with pytest.raises(SettingsError, match="scaling = 'power'"):
        auto_spectrum(ffts, "a", scaling="power")
