"""The ADC: code range and storage type, round-to-nearest within LSB/2, exact clip counts."""

import numpy as np
import pytest

from daq.adc import ADC
from rig.errors import ConfigError


@pytest.mark.parametrize("bits, dtype", [(8, np.int8), (12, np.int16), (16, np.int16),
                                         (24, np.int32), (32, np.int32)])
def test_code_range_lsb_and_storage_type(bits, dtype):
    adc = ADC(10.0, bits)
    assert adc.lsb_v == 20.0 / 2 ** bits
    assert (adc.code_min, adc.code_max) == (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    assert adc.dtype == np.dtype(dtype)
    codes, _ = adc.digitize(np.array([-10.0, 10.0]))
    assert codes.dtype == dtype and codes.tolist() == [adc.code_min, adc.code_max]


def test_sixteen_bit_lsb_of_ten_volts():
    assert ADC(10.0).lsb_v == pytest.approx(305.17578125e-6, rel=0, abs=0)


@pytest.mark.parametrize("bits", [4, 12, 16, 24])
def test_quantisation_error_is_at_most_half_an_lsb(bits):
    adc = ADC(2.5, bits)
    rng = np.random.default_rng(bits)
    v = rng.uniform(-2.5, 2.5 - adc.lsb_v, 200_000)
    # the worst cases: exactly half-way between two codes
    halfway = (np.arange(adc.code_min, adc.code_max) + 0.5)[::max(1, 2 ** bits // 100)]
    v = np.concatenate([v, halfway * adc.lsb_v])
    codes, clipped = adc.digitize(v)
    assert not clipped.any()
    err = adc.volts(codes) - v
    assert np.abs(err).max() <= adc.lsb_v / 2 * (1 + 1e-12)
    # round to nearest: the error is uniform on [-LSB/2, LSB/2], rms LSB/sqrt(12)
    assert err[:200_000].std() == pytest.approx(adc.lsb_v / np.sqrt(12), rel=0.01)


def test_volts_are_code_times_lsb():
    adc = ADC(1.0, 16)
    codes = np.array([-32768, -1, 0, 1, 32767], dtype=np.int16)
    np.testing.assert_array_equal(adc.volts(codes), codes * (2.0 / 65536))


def test_clipping_is_flagged_and_counted_exactly():
    adc = ADC(1.0, 8)  # lsb 1/128 V; codes -128 .. 127
    lsb = adc.lsb_v
    v = np.array([0.0, 0.5,
                  127.49 * lsb,   # rounds to 127: in range
                  127.51 * lsb,   # rounds to 128: clipped
                  -128.49 * lsb,  # rounds to -128: in range
                  -128.51 * lsb,  # rounds to -129: clipped
                  1.0, -1.0 - lsb, 5.0, -7.0, 1e9])
    codes, clipped = adc.digitize(v)
    assert clipped.tolist() == [False, False, False, True, False, True, True, True, True, True,
                                True]
    assert int(clipped.sum()) == 7
    assert codes[clipped].tolist() == [127, -128, 127, -128, 127, -128, 127]


def test_clip_count_of_an_overdriven_sine_matches_the_threshold_crossings():
    adc = ADC(1.0, 16)
    t = np.arange(100_000) / 100_000
    v = 1.5 * np.sin(2 * np.pi * 7 * t)
    codes, clipped = adc.digitize(v)
    r = np.rint(v / adc.lsb_v)
    expected = np.count_nonzero((r > adc.code_max) | (r < adc.code_min))
    assert clipped.sum() == expected > 0
    assert codes.max() == adc.code_max and codes.min() == adc.code_min


@pytest.mark.parametrize("kw, message", [
    ({"range_v": 0.0}, r"ADC range = 0.0 V is invalid: expected a finite number > 0"),
    ({"range_v": float("inf")}, r"ADC range = inf V is invalid"),
    ({"range_v": 1.0, "bits": 1}, r"adc_bits = 1 is invalid: expected an integer 2 .. 32"),
    ({"range_v": 1.0, "bits": 33}, r"adc_bits = 33 is invalid"),
    ({"range_v": 1.0, "bits": 16.0}, r"adc_bits = 16.0 is invalid"),
])
def test_bad_adc_parameters_are_refused(kw, message):
    with pytest.raises(ConfigError, match=message):
        ADC(**kw)
