"""The anti-alias filter and decimation: documented attenuation above Nyquist (measured with sines),
passband ripple, the analytic response, block-wise == one-shot, and rate validation."""

import numpy as np
import pytest

from daq.adc import ADC
from daq.antialias import AntiAliasFilter, default_attenuation_db
from rig.acquisition_settings import decimation_factor
from rig.errors import ConfigError

FS, RATE = 1000.0, 100.0


def _run(filt, x, block=None):
    """Filter + decimate (channels, samples) at once or in blocks of the given sizes."""
    state = filt.initial_state(x.shape[0])
    if block is None:
        y, _ = filt.step(state, x)
        return y
    out, pos, sizes = [], 0, iter(block)
    while pos < x.shape[1]:
        n = next(sizes)
        y, state = filt.step(state, x[:, pos:pos + n])
        out.append(y)
        pos += n
    return np.concatenate(out, axis=1)


def _complex_amplitude(y, f_hz, rate_hz, skip):
    """Least-squares A with y[j] ~ Re(A exp(2 pi i f t_j)), t_j = j / rate (after ``skip``)."""
    t = np.arange(len(y)) / rate_hz
    t, y = t[skip:], y[skip:]
    basis = np.stack([np.cos(2 * np.pi * f_hz * t), -np.sin(2 * np.pi * f_hz * t)], axis=1)
    (re, im), *_ = np.linalg.lstsq(basis, y, rcond=1e-9)
    return re + 1j * im


def test_default_design_is_the_documented_one():
    f = AntiAliasFilter.design(FS, RATE)
    assert (f.kind, f.order, f.decimation) == ("elliptic", 12, 10)
    assert (f.passband_hz, f.stopband_hz, f.ripple_db) == (40.0, 50.0, 0.01)
    assert f.attenuation_db == pytest.approx(102.35, abs=0.01) == default_attenuation_db(16)
    assert f.group_delay_s(0.0)[0] == pytest.approx(0.0276, abs=2e-4)
    assert not f.sos.flags.writeable


@pytest.mark.parametrize("fs, rate", [(1000.0, 100.0), (200.0, 100.0), (10000.0, 100.0),
                                      (1000.0, 10.0)])
def test_analytic_response_meets_the_design_on_a_dense_grid(fs, rate):
    f = AntiAliasFilter.design(fs, rate)
    stop = np.linspace(rate / 2, fs / 2, 200001)
    assert 20 * np.log10(np.abs(f.response(stop)).max()) <= -f.attenuation_db + 1e-6
    gain_db = 20 * np.log10(np.abs(f.response(np.linspace(0, 0.4 * rate, 20001))))
    assert gain_db.max() <= 1e-9 and gain_db.min() >= -f.ripple_db - 1e-9


@pytest.mark.parametrize("f_hz", [50.0, 50.3, 51.0, 55.0, 60.0, 73.3, 100.0, 150.0, 250.0, 333.3,
                                  499.0])
def test_sines_at_and_above_nyquist_alias_at_most_at_the_documented_level(f_hz):
    """Measured: a unit sine beyond Nyquist comes out of the decimator at its alias frequency with
    amplitude |H(f)| <= 10^(-attenuation/20) (after the filter's start-up transient)."""
    filt = AntiAliasFilter.design(FS, RATE)
    t = np.arange(int(20 * FS)) / FS
    y = _run(filt, np.sin(2 * np.pi * f_hz * t + 0.3)[None])[0]
    amp = abs(_complex_amplitude(y, f_hz, RATE, skip=int(10 * RATE)))
    bound = 10 ** (-filt.attenuation_db / 20)
    assert amp <= bound * 1.001
    h = abs(filt.response(f_hz))
    if f_hz % (RATE / 2) == 0:  # aliases onto DC or Nyquist: only one quadrature is visible
        assert amp <= h * 1.001
    else:
        assert amp == pytest.approx(h, rel=1e-3)


def test_without_the_filter_the_same_sine_aliases_at_full_amplitude():
    filt = AntiAliasFilter.design(FS, RATE, kind="none")
    t = np.arange(int(5 * FS)) / FS
    y = _run(filt, np.sin(2 * np.pi * 60.0 * t)[None])[0]
    assert abs(_complex_amplitude(y, 40.0, RATE, skip=0)) == pytest.approx(1.0, rel=1e-9)


def test_a_full_scale_sine_above_nyquist_leaves_no_adc_code():
    """Documented: attenuation 20 log10(2^(bits+1)) makes a full-scale alias <= LSB/4: no code."""
    filt, adc = AntiAliasFilter.design(FS, RATE, bits=16), ADC(1.0, 16)
    t = np.arange(int(20 * FS)) / FS
    for f_hz in (50.0, 61.7, 120.0, 480.0):
        y = _run(filt, 0.9999 * np.sin(2 * np.pi * f_hz * t)[None])[0]
        codes, clipped = adc.digitize(y[int(10 * RATE):])
        assert not codes.any() and not clipped.any()


@pytest.mark.parametrize("f_hz", [0.1, 1.0, 2.48, 10.0, 25.0, 39.9])
def test_passband_sines_come_out_scaled_by_the_analytic_response(f_hz):
    """Gain and phase equal H(f) (so decimation adds no delay), within the 0.01 dB ripple."""
    filt = AntiAliasFilter.design(FS, RATE)
    t = np.arange(int(40 * FS)) / FS
    y = _run(filt, np.cos(2 * np.pi * f_hz * t + 0.7)[None])[0]
    a = _complex_amplitude(y, f_hz, RATE, skip=int(20 * RATE)) / np.exp(0.7j)
    h = filt.response(f_hz)
    assert abs(a - h) < 1e-9
    assert -0.01 - 1e-9 <= 20 * np.log10(abs(a)) <= 1e-9


@pytest.mark.parametrize("kind", ["elliptic", "none"])
def test_blockwise_filtering_equals_one_shot_bit_for_bit(kind):
    rng = np.random.default_rng(3)
    filt = AntiAliasFilter.design(FS, RATE, kind=kind)
    x = rng.standard_normal((3, 12345))
    one = _run(filt, x)
    sizes = list(rng.integers(1, 700, size=200)) + [1, 1, 9, 10, 11, 10_000]
    blocks = _run(filt, x, block=sizes)
    assert one.shape == (3, 1235)
    np.testing.assert_array_equal(blocks, one)
    if kind == "none":
        np.testing.assert_array_equal(one, x[:, ::10])


@pytest.mark.parametrize("fs, rate, message", [
    (1000.0, 2000.0, "rate_hz = 2000 Hz is invalid: it is above simulation_rate_hz = 1000 Hz"),
    (1000.0, 300.0, "not an integer multiple of it (ratio 3.33333)"),
    (1000.0, 1000.0, "it equals simulation_rate_hz"),
    (1000.0, 0.0, "rate_hz = 0.0 is invalid: expected a finite rate > 0 Hz"),
    (float("nan"), 100.0, "simulation_rate_hz = nan is invalid"),
])
def test_rates_that_do_not_decimate_are_refused(fs, rate, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        decimation_factor(fs, rate)
    with pytest.raises(ConfigError):
        AntiAliasFilter.design(fs, rate)


@pytest.mark.parametrize("kw, message", [
    ({"passband": 0.5}, "antialias_passband = 0.5 is invalid"),
    ({"ripple_db": 0.0}, "antialias_ripple_db = 0.0 is invalid"),
    ({"attenuation_db": 5.0}, "antialias_attenuation_db = 5.0 is invalid"),
    ({"kind": "bessel"}, "antialias = 'bessel' is invalid: expected one of elliptic, none"),
])
def test_bad_designs_are_refused(kw, message):
    with pytest.raises(ConfigError, match=message):
        AntiAliasFilter.design(FS, RATE, **kw)


def test_compiled_filter_equals_scipy_sosfilt_bit_for_bit():
    """The filter runs in compiled code (no scipy.signal import at run time) with scipy's
    arithmetic: the same samples and final state, bit for bit, on 3 channels of noise."""
    from scipy import signal

    filt = AntiAliasFilter.design(FS, RATE)
    x = np.random.default_rng(5).standard_normal((3, 20_001))
    state = filt.initial_state(3)
    y, after = filt.step(state, x)
    ref, zf = signal.sosfilt(np.array(filt.sos), x, axis=-1, zi=state.zi)
    assert y.tobytes() == np.ascontiguousarray(ref[:, ::10]).tobytes()
    assert after.zi.tobytes() == zf.tobytes()


def test_design_is_read_back_from_the_cache_bit_for_bit_without_scipy_signal(tmp_path):
    """A second process reads the design from the cache: the same sections, bit for bit, and
    scipy.signal never imported."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, PENDULUM_DAQ_CACHE=str(tmp_path))
    code = ("import sys, json; from daq.antialias import AntiAliasFilter as A; "
            "f = A.design(1000.0, 100.0); "
            "print(json.dumps([f.order, f.sos.tolist(), 'scipy.signal' in sys.modules]))")
    runs = [json.loads(subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                      capture_output=True, text=True).stdout) for _ in range(2)]
    assert len(list(tmp_path.glob("antialias-*.json"))) == 1
    assert runs[0][:2] == runs[1][:2]
    assert runs[0][2] is True and runs[1][2] is False  # designed, then read back
    from scipy import signal

    order, wn = signal.ellipord(40.0, 50.0, 0.01, default_attenuation_db(16), fs=FS)
    fresh = signal.ellip(order, 0.01, default_attenuation_db(16), wn, output="sos", fs=FS)
    assert runs[1][0] == order and np.array(runs[1][1]).tobytes() == fresh.tobytes()


def test_a_corrupt_design_cache_entry_is_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("PENDULUM_DAQ_CACHE", str(tmp_path))
    good = AntiAliasFilter.design(FS, RATE)
    (entry,) = tmp_path.glob("antialias-*.json")
    for junk in ("{not json", '{"key": {}, "order": 3, "sos": [[1, 2]]}', ""):
        entry.write_text(junk)
        again = AntiAliasFilter.design(FS, RATE)
        assert (again.order, again.sos.tobytes()) == (good.order, good.sos.tobytes())
    assert entry.read_text().startswith('{"key"')  # rewritten
