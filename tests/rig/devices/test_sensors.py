"""Sensors: the accelerometer (rig/devices/accelerometer.py) and the optical lever + PSD (rig/devices/optical_lever.py)."""

import math

import numpy as np
import pytest
import scipy.signal

from rig.devices.accelerometer import Accelerometer
from rig.errors import ConfigError
from rig.devices.optical_lever import SMALL_ANGLE_RAD, OpticalLever, _cos_sin

FS = 1000.0


# -- accelerometer ---------------------------------------------------------------------------

def test_accelerometer_response_shows_the_charge_amplifier_corner():
    acc = Accelerometer(sensitivity_vpmps2=1.0, highpass_hz=0.05)
    h = acc.frequency_response([0.05, 0.1, 1.0, 100.0])
    # first-order high-pass: -3.01 dB and +45 deg at the corner, -0.97 dB and +26.57 deg at 0.1 Hz
    np.testing.assert_allclose(20 * np.log10(np.abs(h)),
                               [-3.0103, -0.9691, -0.01084, -1.1e-6], atol=1e-4)
    np.testing.assert_allclose(np.degrees(np.angle(h)),
                               [45.0, math.degrees(math.atan(0.5)), math.degrees(math.atan(0.05)),
                                math.degrees(math.atan(5e-4))], rtol=1e-12)
    flat = Accelerometer(highpass_hz=0.0)  # servo type: flat to DC
    np.testing.assert_allclose(flat.frequency_response([0.0, 0.01, 10.0]), 1.0)
    assert flat.n_states == 0 and acc.n_states == 1


def test_accelerometer_measure_equals_the_first_order_hold_model_to_roundoff():
    # independent reference: scipy's lsim, which interpolates its input linearly between samples
    acc = Accelerometer(sensitivity_vpmps2=0.5, highpass_hz=0.2, noise_mps2_rthz=0.0, sign=-1)
    rng = np.random.default_rng(0)
    a = np.cumsum(rng.standard_normal(20_000)) * 1e-3  # a wandering, broadband acceleration
    t = np.arange(a.size) / FS
    wc = 2 * np.pi * 0.2
    sysc = scipy.signal.StateSpace([[-wc]], [[1.0]], [[-0.5 * wc]], [[0.5]])
    _, want, _ = scipy.signal.lsim(sysc, a, t, X0=[0.0], interp=True)
    got, _, over = acc.measure(a, FS, None, None, noise=False)
    np.testing.assert_allclose(got, -want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    assert not over.any()


def test_accelerometer_sine_steady_state_matches_its_transfer_function():
    acc = Accelerometer(highpass_hz=0.05, noise_mps2_rthz=0.0)
    f0 = 0.3
    t = np.arange(200_000) / FS  # 200 s: the 3.2 s transient is down to e^-63
    a = 0.01 * np.sin(2 * np.pi * f0 * t)
    v, _, _ = acc.measure(a, FS, None, None, noise=False)
    tail = slice(100_000, None)  # 30 whole periods
    ref = np.exp(2j * np.pi * f0 * t[tail])
    got = 2 * np.mean(v[tail] * np.conj(ref)) / 0.01  # complex amplitude ratio ~ H / i
    want = acc.frequency_response([f0])[0] / 1j
    # linear interpolation of a sine between samples: relative error (w h)^2 / 12 ~ 3e-7
    assert abs(got / want - 1) < 1e-6


def test_accelerometer_blocks_reproduce_one_shot_bit_for_bit():
    acc = Accelerometer()
    a = np.sin(np.arange(10_000) * 0.01) * 1e-2
    one, st_one, _ = acc.measure(a, FS, None, np.random.default_rng(1))
    rng = np.random.default_rng(1)
    parts, st = [], None
    for sl in (slice(0, 1), slice(1, 4000), slice(4000, 10_000)):
        v, st, _ = acc.measure(a[sl], FS, st, rng)
        parts.append(v)
    assert np.concatenate(parts).tobytes() == one.tobytes()
    assert st.q == st_one.q


def test_accelerometer_saturates_at_its_range_and_flags_it():
    acc = Accelerometer(sensitivity_vpmps2=0.1, highpass_hz=0.0, range_mps2=5.0,
                        noise_mps2_rthz=0.0, sign=-1)
    a = np.array([0.0, 4.9, 5.1, -7.0, 100.0])
    v, _, over = acc.measure(a, FS, None, None, noise=False)
    np.testing.assert_allclose(v, [0.0, -0.49, -0.5, 0.5, -0.5])
    np.testing.assert_array_equal(over, [False, False, True, True, True])


def test_accelerometer_noise_has_the_stated_density():
    acc = Accelerometer(sensitivity_vpmps2=2.0, noise_mps2_rthz=1e-4, highpass_hz=0.0)
    v, _, _ = acc.measure(np.zeros(200_000), FS, None, np.random.default_rng(4))
    want_rms = 2.0 * 1e-4 * math.sqrt(FS / 2)
    assert np.std(v) == pytest.approx(want_rms, rel=5 / math.sqrt(2 * 200_000))
    f, p = scipy.signal.welch(v, fs=FS, nperseg=4096)
    # one-sided density (2.0 * 1e-4)^2 V^2/Hz, flat: 97 segments, 10 % per bin, averaged
    assert np.mean(p[1:-1]) == pytest.approx((2.0 * 1e-4) ** 2, rel=0.02)


def test_accelerometer_calibration_carries_the_polarity():
    for sign in (1, -1):
        acc = Accelerometer(sensitivity_vpmps2=0.7, sign=sign)
        cal = acc.calibration()
        assert cal.volts_per_unit == 0.7 * sign and cal.unit == "m/s^2"
        assert acc.frequency_response([1e3])[0].real == pytest.approx(0.7 * sign, rel=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    (dict(sensitivity_vpmps2=0.0), r"accelerometer\.sensitivity_vpmps2 = 0\.0 is invalid: expected"
                                   r" a finite number > 0"),
    (dict(sensitivity_vpmps2=-1.0), r"accelerometer\.sensitivity_vpmps2 = -1\.0 is invalid"),
    (dict(highpass_hz=-0.1), r"accelerometer\.highpass_hz = -0\.1 is invalid: expected a finite "
                             r"number >= 0 Hz"),
    (dict(noise_mps2_rthz=float("nan")), r"accelerometer\.noise_mps2_rthz = nan is invalid"),
    (dict(range_mps2=0.0), r"accelerometer\.range_mps2 = 0\.0 is invalid"),
    (dict(sign=2), r"accelerometer\.sign = 2 is invalid: expected \+1 or -1"),
])
def test_bad_accelerometer_parameters_raise_config_error_naming_the_key(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        Accelerometer(**kwargs)


# -- optical lever and PSD -------------------------------------------------------------------

def reflect_reference(phi, dist, dx, dz, th):
    """Independent 3-D ray trace (vectors, one sample at a time)."""
    d = np.array([-math.cos(phi), -math.sin(phi), 0.0])  # incoming direction
    r0 = np.array([math.cos(phi), -math.sin(phi), 0.0])  # reflected at rest
    n = np.array([math.cos(th), 0.0, math.sin(th)])  # mirror normal (body rotated by th about y)
    p = np.array([dx, 0.0, dz])  # a point of the mirror plane
    t = np.dot(n, p) / np.dot(n, d)  # the beam (through the origin) meets the plane at t d
    q = t * d
    r = d - 2 * np.dot(d, n) * n
    centre = dist * r0  # the detector: plane normal to r0 through D r0
    s = np.dot(centre - q, r0) / np.dot(r, r0)
    hit = q + s * r - centre
    e_u = np.cross(np.array([0.0, 0.0, 1.0]), r0)  # horizontal, normal to the beam
    e_u *= np.sign(e_u[0])  # the sense in which the mirror's +x moves the spot
    return float(np.dot(hit, e_u)), float(hit[2])


def test_spot_position_matches_an_independent_ray_trace():
    lever = OpticalLever(incidence_deg=37.0, distance_m=0.3)
    rng = np.random.default_rng(2)
    dx = rng.uniform(-2e-3, 2e-3, 50)
    dz = rng.uniform(-1e-3, 1e-3, 50)
    th = rng.uniform(-0.2, 0.2, 50)
    u, v = lever.spot_m(dx, th, dz)
    ref = np.array([reflect_reference(math.radians(37.0), 0.3, *args) for args in zip(dx, dz, th)])
    np.testing.assert_allclose(u, ref[:, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(v, ref[:, 1], rtol=0, atol=1e-15)


def test_small_angle_cos_sin_equal_libm_at_a_mirrors_tilts():
    # below 1e-4 rad the polynomial part's rounding is ~1e-8 ulp of the value, so only a
    # near-tie that close could round the other way (expected < 1e-3 of the 200,000 here)
    rng = np.random.default_rng(5)
    mag = 10.0 ** rng.uniform(-14, -4, 200_000)
    th = np.concatenate([mag * rng.choice([-1.0, 1.0], mag.size), [0.0, -0.0, 0.3, -2.0]])
    got = np.array([_cos_sin(t) for t in th])
    want = np.array([(math.cos(t), math.sin(t)) for t in th])
    assert np.array_equal(got, want)


def test_small_angle_cos_sin_near_the_threshold_differ_from_libm_by_one_ulp_at_near_ties():
    # up to SMALL_ANGLE_RAD the rounding of the polynomial part (below 2^-53 th^2 of cos's
    # ulp, 2^-53 th^2 / 2 of sin's, a few roundings) can break a near-tie the other way: at
    # most one value in 1 / th^2, and then libm's neighbour
    rng = np.random.default_rng(6)
    th = rng.uniform(SMALL_ANGLE_RAD / 4, SMALL_ANGLE_RAD, 200_000) * rng.choice([-1.0, 1.0],
                                                                                 200_000)
    got = np.array([_cos_sin(t) for t in th])
    want = np.array([(math.cos(t), math.sin(t)) for t in th])
    bound = float(np.sum(th * th))  # ~29 here
    for k in range(2):
        off = got[:, k] != want[:, k]
        assert np.count_nonzero(off) <= bound
        np.testing.assert_array_equal(np.nextafter(want[off, k], got[off, k]), got[off, k])


def test_linearised_lever_moves_the_spot_by_2_sin_phi_dx_and_2_d_cos_phi_theta():
    lever = OpticalLever(incidence_deg=30.0, distance_m=0.2)
    # translation only: exactly 2 sin(phi) dx (a plane mirror translated along its normal)
    u, v = lever.spot_m(np.array([1e-4, -3e-3]), np.zeros(2))
    np.testing.assert_allclose(u, 2 * 0.5 * np.array([1e-4, -3e-3]), rtol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-18)
    # rotation only: v = D cos(phi) sin(2 theta) (s = D at dx = 0), u = -D sin(2 phi) sin^2 theta
    th = np.array([1e-4, 2e-3, -0.05])
    u, v = lever.spot_m(np.zeros(3), th)
    c = math.cos(math.radians(30))
    s_ = (0.2) / (c * (c * np.cos(2 * th)) + 0.25)  # s = D / (r0 . r)
    np.testing.assert_allclose(v, s_ * c * np.sin(2 * th), rtol=1e-13)
    np.testing.assert_allclose(v, 2 * 0.2 * c * th, rtol=(2 * 0.05) ** 2)  # linear to O(theta^2)
    assert lever.spot_per_rotation_m == pytest.approx(2 * 0.2 * c)
    # a vertical mirror displacement at theta = 0 slides within the mirror plane: no effect
    u, v = lever.spot_m(0.0, 0.0, 1e-3)
    assert u == 0.0 and v == 0.0


def test_psd_volts_equal_the_calibrations_times_small_motions():
    lever = OpticalLever(incidence_deg=30.0, distance_m=0.2, gain_vpm=1000.0, sign_x=-1)
    cal = lever.calibrations()
    assert cal["x"].volts_per_unit == pytest.approx(-1000.0 * 2 * 0.5)
    assert cal["y"].volts_per_unit == pytest.approx(1000.0 * 2 * 0.2 * math.cos(math.radians(30)))
    dx = np.array([1e-6, -2e-6])
    th = np.array([-1e-6, 3e-6])
    r = lever.measure(dx, th, FS, None, None, noise=False)
    # second-order terms are ~ theta dx / D and theta^2 (relative 1e-5 here)
    np.testing.assert_allclose(r.x_v, cal["x"].volts_per_unit * dx, rtol=1e-4)
    np.testing.assert_allclose(r.y_v, cal["y"].volts_per_unit * th, rtol=1e-4)
    # and exactly sign * gain * the exact spot
    u, v = lever.spot_m(dx, th)
    np.testing.assert_array_equal(r.x_v, -1000.0 * u)
    np.testing.assert_array_equal(r.y_v, 1000.0 * v)


def test_spot_leaving_the_detector_clips_the_output_at_the_edge_and_is_flagged():
    lever = OpticalLever(incidence_deg=30.0, distance_m=0.2, size_m=0.01, gain_vpm=1000.0,
                         sign_y=-1)
    dx = np.array([0.0, 4.9e-3, 5.1e-3, -1.0, 0.0, 0.0])
    th = np.array([0.0, 0.0, 0.0, 0.0, 0.02, -0.1])  # v = 0.346 theta: 6.9 mm, -34.6 mm
    r = lever.measure(dx, th, FS, None, None, noise=False)
    np.testing.assert_array_equal(r.off_detector, [False, False, True, True, True, True])
    assert np.all(np.abs(r.x_v) <= 5.0) and np.all(np.abs(r.y_v) <= 5.0)
    np.testing.assert_allclose(r.x_v[2:4], [5.0, -5.0])
    np.testing.assert_allclose(r.y_v[4:], [-5.0, 5.0])
    c = math.cos(math.radians(30))
    s_ = 0.2 / (c * c * math.cos(0.04) + 0.25)  # D / (r0 . r)
    assert r.spot_v_m[4] == pytest.approx(s_ * c * math.sin(0.04), rel=1e-13)


def test_psd_noise_has_the_stated_density_on_each_axis():
    lever = OpticalLever(noise_m_rthz=1e-7, gain_vpm=500.0)
    z = np.zeros(200_000)
    r = lever.measure(z, z, FS, np.random.default_rng(1), np.random.default_rng(2))
    want = 500.0 * 1e-7 * math.sqrt(FS / 2)
    for v in (r.x_v, r.y_v):
        assert np.std(v) == pytest.approx(want, rel=5 / math.sqrt(2 * 200_000))
    assert abs(np.corrcoef(r.x_v, r.y_v)[0, 1]) < 5 / math.sqrt(200_000)  # independent axes


def test_psd_has_a_flat_frequency_response():
    lever = OpticalLever()
    h = lever.frequency_response([0.0, 0.1, 10.0, 499.0])
    for k, cal in lever.calibrations().items():
        np.testing.assert_array_equal(h[k], cal.volts_per_unit)


@pytest.mark.parametrize("kwargs, match", [
    (dict(incidence_deg=90.0), r"psd\.incidence_deg = 90\.0 is invalid: expected 0 < "
                               r"incidence_deg < 90 deg"),
    (dict(incidence_deg=120.0), r"psd\.incidence_deg = 120\.0 is invalid"),
    (dict(incidence_deg=0.0), r"psd\.incidence_deg = 0\.0 is invalid: .*would not move the spot"),
    (dict(distance_m=0.0), r"psd\.distance_m = 0\.0 is invalid: expected a finite number > 0 m"),
    (dict(distance_m=-0.1), r"psd\.distance_m = -0\.1 is invalid"),
    (dict(size_m=-0.01), r"psd\.size_m = -0\.01 is invalid"),
    (dict(gain_vpm=0.0), r"psd\.gain_vpm = 0\.0 is invalid"),
    (dict(noise_m_rthz=-1e-9), r"psd\.noise_m_rthz = -1e-09 is invalid"),
    (dict(sign_x=0), r"psd\.sign_x = 0 is invalid: expected \+1 or -1"),
])
def test_bad_psd_parameters_raise_config_error_naming_the_key(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        OpticalLever(**kwargs)
