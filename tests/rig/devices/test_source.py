"""The analyzer's source (rig/devices/source.py): levels, spectra, periods, continuity across blocks.

Statistical tolerances: the rms of a Gaussian process of bandwidth B over T seconds has a relative
standard deviation of about 1 / (2 sqrt(B T)); a Welch PSD bin averaged over K segments has
1 / sqrt(K). Bounds are 5 standard deviations unless stated (the seeds are fixed, the bounds are
what an honest seed could produce).
"""

import math

import numpy as np
import pytest
import scipy.signal

from rig.errors import ConfigError
from rig.devices.source import SOURCE_TYPES, Source, generate, start_source

FS = 1000.0


def run(source, n, seed=1, blocks=None):
    st = start_source(source, seed)
    if blocks is None:
        v, st = generate(source, st, n)
        return v
    out = []
    for k in blocks:
        v, st = generate(source, st, k)
        out.append(v)
    return np.concatenate(out)


def welch(v, nperseg=2**14):
    # no detrending: removing each segment's mean would itself leak into the lowest bins
    return scipy.signal.welch(v, fs=FS, nperseg=nperseg, detrend=False)


def test_random_noise_has_the_set_rms_level():
    s = Source(type="random", level_vrms=0.1, fmin_hz=0.0, fmax_hz=12.5)
    t = 400.0
    v = run(s, int(t * FS))
    sd = 1 / (2 * math.sqrt(12.5 * t))  # ~0.7 %
    assert abs(np.sqrt(np.mean(v**2)) / 0.1 - 1) < 5 * sd
    assert abs(np.mean(v)) < 5 * 0.1 / math.sqrt(2 * 12.5 * t)  # mean of band-limited noise


def test_random_noise_is_stationary_from_the_first_sample():
    s = Source(type="random", level_vrms=0.2)
    v = run(s, 20_000)
    sd = 1 / (2 * math.sqrt(12.5 * 20.0))
    assert abs(np.sqrt(np.mean(v**2)) / 0.2 - 1) < 5 * sd


def test_random_noise_spectrum_is_flat_in_band_and_empty_outside():
    s = Source(type="random", level_vrms=0.1, fmin_hz=0.0, fmax_hz=12.5)
    v = run(s, 400_000)
    f, p = welch(v)  # 48 segments: 14 % per bin
    design = s.design_psd(f)
    inb = (f > 0.3) & (f < 12.2)
    ratio = p[inb] / design[inb]
    k = np.count_nonzero(inb)
    assert abs(np.mean(ratio) - 1) < 5 * 0.15 / math.sqrt(k / 4)  # neighbouring bins correlate
    lo, hi = ratio[: k // 2], ratio[k // 2:]
    assert abs(np.mean(lo) / np.mean(hi) - 1) < 0.1  # flat: no tilt across the band
    out = f > 13.5
    assert np.max(p[out]) < 1e-8 * np.mean(p[inb])  # -80 dB beyond the edge


def test_band_edges_of_the_fir_design():
    # the FIR itself: flat to 1e-3 dB inside, -6 dB at the nominal edge, < -80 dB 0.05 Hz beyond
    s = Source(type="random", fmin_hz=1.0, fmax_hz=5.0)
    nfft = 1 << 21
    h = np.abs(np.fft.rfft(s.taps, n=nfft))
    f = np.fft.rfftfreq(nfft, 1 / FS)
    ref = np.mean(h[(f > 2) & (f < 4)])
    db = 20 * np.log10(h / ref + 1e-300)
    inside = (f > 1.05) & (f < 4.95)
    assert np.max(np.abs(db[inside])) < 1e-3
    outside = (f < 0.95) | (f > 5.05)
    assert np.max(db[outside]) < -80
    # -6 dB (half amplitude) exactly at the nominal edges: the DTFT evaluated there
    k = np.arange(s.taps.size)
    for edge in (1.0, 5.0):
        he = abs(np.sum(s.taps * np.exp(-2j * np.pi * edge * k / FS)))
        assert abs(20 * np.log10(he / ref) - (-6.02)) < 0.02


def test_band_limited_noise_with_a_lower_edge_has_no_power_below_it():
    s = Source(type="random", level_vrms=0.05, fmin_hz=1.0, fmax_hz=5.0)
    v = run(s, 400_000)
    # Blackman-Harris (sidelobes < -92 dB beyond 4 bins = 0.06 Hz): the estimator does not leak
    f, p = scipy.signal.welch(v, fs=FS, nperseg=2**16, window="blackmanharris", detrend=False)
    inb = (f > 1.2) & (f < 4.8)
    assert np.max(p[(f < 0.8) | ((f > 5.2) & (f < 400))]) < 1e-8 * np.mean(p[inb])
    sd = 1 / (2 * math.sqrt(4.0 * 400.0))
    assert abs(np.sqrt(np.mean(v**2)) / 0.05 - 1) < 5 * sd


def test_pink_noise_falls_ten_db_per_decade():
    s = Source(type="pink", level_vrms=0.1, fmin_hz=0.0, fmax_hz=12.5)
    v = run(s, 400_000)
    f, p = welch(v, nperseg=2**15)
    sel = (f >= 0.2) & (f <= 10)
    slope, _ = np.polyfit(np.log10(f[sel]), np.log10(p[sel]), 1)
    # ~280 bins of 20 % scatter spread over 1.7 decades: slope error ~ 0.01
    assert abs(slope - (-1.0)) < 0.05
    sd = 1 / (2 * math.sqrt(0.5 * 400.0))  # pink: the power sits at low f, effective B ~ 0.5 Hz
    assert abs(np.sqrt(np.mean(v**2)) / 0.1 - 1) < 5 * sd
    # shelf: flat below fmax / 1000
    assert s.shelf_hz == pytest.approx(0.0125)
    np.testing.assert_allclose(s.design_psd([0.001, 0.0125]), s.design_psd([0.005, 0.005]))


def test_sine_has_the_set_frequency_amplitude_and_phase():
    s = Source(type="sine", level_vrms=0.3, frequency_hz=2.5)
    v = run(s, 100_000)
    k = np.arange(100_000)
    np.testing.assert_allclose(v, math.sqrt(2) * 0.3 * np.sin(2 * np.pi * 2.5 * k / FS), atol=1e-12)
    assert np.sqrt(np.mean(v**2)) == pytest.approx(0.3, rel=1e-9)  # 250 whole cycles
    spec = np.abs(np.fft.rfft(v))
    assert np.fft.rfftfreq(v.size, 1 / FS)[np.argmax(spec)] == pytest.approx(2.5)


def test_periodic_chirp_repeats_with_its_period_and_sweeps_the_band():
    s = Source(type="periodic-chirp", level_vrms=0.1, fmin_hz=0.5, fmax_hz=12.5, period_s=20.0)
    v = run(s, 60_000)
    np_ = 20_000
    np.testing.assert_array_equal(v[:np_], v[np_:2 * np_])
    np.testing.assert_array_equal(v[:np_], v[2 * np_:])
    assert np.sqrt(np.mean(v[:np_] ** 2)) == pytest.approx(0.1, rel=0.01)
    # the local frequency, 1 / (2 x the interval between zero crossings), rises linearly from
    # fmin to fmax (interpolated crossings: error ~ (2 pi f / fs)^2 ~ 1e-3 relative)
    x = v[:np_]
    k = np.flatnonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))
    tc = (k + x[k] / (x[k] - x[k + 1])) / FS
    assert abs(tc.size - 20.0 * (0.5 + 12.5)) <= 1  # P (fmin + fmax) crossings per period
    f_local = 0.5 / np.diff(tc)
    t_mid = 0.5 * (tc[1:] + tc[:-1])
    np.testing.assert_allclose(f_local, 0.5 + 12.0 * t_mid / 20.0, rtol=3e-3)
    # one period's power lies in the band, give or take the Fresnel spread of a finite sweep,
    # ~ sqrt(sweep rate) = sqrt(12 Hz / 20 s) = 0.8 Hz
    spec = np.abs(np.fft.rfft(v[:np_])) ** 2
    f = np.fft.rfftfreq(np_, 1 / FS)
    assert spec[f <= 12.5 + 0.8].sum() > 0.99 * spec.sum()
    assert spec[(f >= 0.5) & (f <= 12.5)].sum() > 0.95 * spec.sum()


def test_burst_random_is_on_for_its_fraction_of_each_period():
    s = Source(type="burst-random", level_vrms=0.1, period_s=10.0, burst_fraction=0.3)
    v = run(s, 100_000)
    per = v.reshape(10, 10_000)
    assert np.all(per[:, 3000:] == 0.0)
    assert np.all(per[:, :3000] != 0.0)
    on = per[:, :3000].ravel()
    sd = 1 / (2 * math.sqrt(12.5 * 30.0))
    assert abs(np.sqrt(np.mean(on**2)) / 0.1 - 1) < 5 * sd


@pytest.mark.parametrize("kind", SOURCE_TYPES)
def test_blockwise_equals_one_shot_bit_for_bit(kind):
    s = Source(type=kind, period_s=1.0)
    n = 1_000_000  # three frames: a pair, then the next pair's first
    sizes = [1, 999, 131_072, 0, 400_000, 7, 393_217, n - 1 - 999 - 131_072 - 400_000 - 7
             - 393_217]
    one = run(s, n, seed=5)
    blocks = run(s, n, seed=5, blocks=sizes)
    assert one.tobytes() == blocks.tobytes()


#: the noise's round-off against another exact evaluation of the same convolution, relative to
#: its rms: both are FFT convolutions of length ~2^19 - 2^21, whose error grows like
#: eps log2(N) (~4e-15); measured 3.3e-15 (frames in pairs against one real FFT each, the
#: paper's 3.33e6 samples) and 5.8e-15 against scipy's one FFT below; the bound leaves ~17
NOISE_ROUNDOFF = 1e-13


def test_noise_is_the_taps_convolved_with_the_generators_white_samples():
    # an independent evaluation: the seed's stream of white samples (the n_taps - 1 priming the
    # filter, then the rest) filtered by scipy in one FFT; five frames, so three pairs, both
    # halves of a pair and the history carried between pairs
    s = Source(type="random", level_vrms=1.0)
    n = 5 * (s.frame_len - s.n_taps + 1) - 123
    got = run(s, n, seed=9)
    w = np.random.Generator(np.random.PCG64(9)).standard_normal(s.n_taps - 1 + n)
    want = scipy.signal.fftconvolve(w, s.taps, mode="valid")
    assert want.shape == got.shape
    assert np.max(np.abs(got - want)) <= NOISE_ROUNDOFF * np.sqrt(np.mean(want**2))


def test_frames_in_pairs_equal_a_real_fft_per_frame_within_round_off(monkeypatch):
    import rig.devices.source as source

    s = Source(type="pink", level_vrms=1.0)
    n = 3 * (s.frame_len - s.n_taps + 1) + 5
    paired = run(s, n, seed=4)
    monkeypatch.setattr(source, "FRAMES_PER_FFT", 1)  # the path before
    single = run(s, n, seed=4)
    err = np.max(np.abs(paired - single)) / np.sqrt(np.mean(single**2))
    assert 0 < err <= NOISE_ROUNDOFF  # 0 would mean the pairs were not used


@pytest.mark.parametrize("kind", ["random", "pink", "burst-random"])
def test_same_seed_same_bytes_other_seed_other_noise(kind):
    s = Source(type=kind)
    a = run(s, 5000, seed=11)
    b = run(s, 5000, seed=11)
    c = run(s, 5000, seed=12)
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, c)


def test_the_state_does_not_share_the_generator():
    s = Source(type="random")
    st = start_source(s, 3)
    v1, st1 = generate(s, st, 100)
    v2, _ = generate(s, st, 100)  # same state again: same samples
    assert v1.tobytes() == v2.tobytes()
    assert st1.index == 100 and st.index == 0


@pytest.mark.parametrize("kwargs, match", [
    (dict(type="white"), r"source\.type = 'white' is invalid: expected one of random"),
    (dict(fmax_hz=600.0), r"source\.fmax_hz = 600\.0 is invalid: expected 0 < fmax_hz <= 500 Hz"),
    (dict(fmin_hz=12.5), r"source\.fmin_hz = 12\.5 is invalid: expected 0 <= fmin_hz < fmax_hz"),
    (dict(fmin_hz=-1.0), r"source\.fmin_hz = -1\.0 is invalid"),
    (dict(level_vrms=-0.1), r"source\.level_vrms = -0\.1 is invalid: expected a finite rms"),
    (dict(level_vrms=float("nan")), r"source\.level_vrms = nan is invalid"),
    (dict(frequency_hz=500.0), r"source\.frequency_hz = 500\.0 is invalid: expected 0 < "),
    (dict(period_s=0.0005), r"source\.period_s = 0\.0005 s is invalid: expected a whole number"),
    (dict(period_s=-1.0), r"source\.period_s = -1\.0 is invalid"),
    (dict(burst_fraction=0.0), r"source\.burst_fraction = 0\.0 is invalid: expected 0 < "),
    (dict(burst_fraction=1.5), r"source\.burst_fraction = 1\.5 is invalid"),
    (dict(fs_hz=0.0), r"acquisition\.simulation_rate_hz = 0\.0 is invalid"),
])
def test_bad_source_parameters_raise_config_error_naming_the_key(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        Source(**kwargs)


def test_bad_sample_count_raises():
    s = Source(type="sine")
    with pytest.raises(ConfigError, match="n = -1 is invalid"):
        generate(s, start_source(s, 0), -1)


@pytest.mark.parametrize("order", [1, 2, 4, 7])
def test_reconstruction_filter_is_scipys_butterworth_without_importing_scipy_signal(order):
    """The reconstruction filter's realisation is exactly scipy.signal.zpk2ss(*buttap(order))
    scaled by the corner, and its response equals butter(..., analog=True) to round-off
    (1e-15 of a gain <= 1)."""
    src = Source(reconstruction_hz=100.0, reconstruction_order=order)
    a, b, c = src.reconstruction_state_space()
    z, p, k = scipy.signal.buttap(order)
    ra, rb, rc, rd = scipy.signal.zpk2ss(z, p, k)
    wc = 2 * np.pi * 100.0
    np.testing.assert_array_equal(a, wc * ra)
    np.testing.assert_array_equal(b, wc * rb[:, 0])
    np.testing.assert_array_equal(c, rc[0])
    f = np.linspace(0.0, 500.0, 101)
    zz, pp, kk = scipy.signal.butter(order, wc, analog=True, output="zpk")
    ref = scipy.signal.freqs_zpk(zz, pp, kk, worN=2 * np.pi * f)[1]
    np.testing.assert_allclose(src.reconstruction_response(f), ref, rtol=0, atol=1e-15)
