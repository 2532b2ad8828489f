"""The sensors' one-pass kernels give the values of their two-step definitions bit for bit."""

import numpy as np

from rig.devices.accelerometer import Accelerometer
from rig.devices.optical_lever import OpticalLever


def _walk(seed, n, scale):
    return scale * np.cumsum(np.random.default_rng(seed).standard_normal(n)) / np.sqrt(n)


def test_accelerometer_sense_and_output_equals_sensed_then_output():
    acc = Accelerometer(range_mps2=0.5)  # some samples clip
    a = 0.3 * np.random.default_rng(1).standard_normal(5000)
    zq = np.stack([_walk(2, 5000, 0.5), _walk(3, 5000, 0.5)], axis=1)
    q = zq[:, 1]  # a strided column, as the bench passes it
    s, v, over = acc.sense_and_output(a, q, 1000.0, np.random.default_rng(4))
    s_ref = acc.sensed(a, q)
    v_ref, over_ref = acc.output(s_ref, 1000.0, np.random.default_rng(4))
    assert over.any() and not over.all()
    assert np.array_equal(s, s_ref) and np.array_equal(v, v_ref)
    assert np.array_equal(over, over_ref)


def test_optical_lever_measure_equals_exact_spot_then_noise_and_clipping():
    lever = OpticalLever(size_m=0.004)  # some samples leave the detector
    n = 5000
    dx, dz, th = _walk(5, n, 2e-3), _walk(6, n, 1e-4), _walk(7, n, 2e-2)
    r = lever.measure(dx, th, 1000.0, np.random.default_rng(8), np.random.default_rng(9),
                      mirror_z_m=dz)
    u, v = lever.spot_m(dx, th, dz)
    sd = lever.noise_rms_m(1000.0)
    un = u + sd * np.random.default_rng(8).standard_normal(n)
    vn = v + sd * np.random.default_rng(9).standard_normal(n)
    h = lever.half_size_m
    off = (np.abs(un) > h) | (np.abs(vn) > h)
    assert off.any() and not off.all()
    assert np.array_equal(r.spot_u_m, u) and np.array_equal(r.spot_v_m, v)
    assert np.array_equal(r.off_detector, off)
    assert np.array_equal(r.x_v, lever.gain_vpm * np.clip(un, -h, h))
    assert np.array_equal(r.y_v, lever.gain_vpm * np.clip(vn, -h, h))
