"""The sensors' one-pass kernels, and the rows the bench's compiled chains run them by, give
the values of their per-sample definitions bit for bit."""

import math

import numpy as np
import pytest

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


@pytest.mark.parametrize("height", [True, False])
@pytest.mark.parametrize("noisy", [True, False])
@pytest.mark.parametrize("tilt_rad", [3e-6, 0.05])
def test_the_fused_sensor_rows_equal_the_sensors_sample_by_sample_bit_for_bit(tilt_rad, noisy,
                                                                              height):
    # the compiled chains' per-row sensors against the devices' own per-sample arithmetic: the
    # lever's vectorised small-angle spot where every tilt is below SMALL_ANGLE_RAD (3e-6 rad)
    # and the general one where one is not (0.05 rad), the mirror's height given (the
    # nonlinear bench's) or 0 (the linear one's), the noise added or not, clipped and flagged
    from rig.devices.accelerometer import AccelerometerRow, accelerometer_row
    from rig.devices.optical_lever import SMALL_ANGLE_RAD, LeverRow, lever_row, spot_kernel

    rng = np.random.default_rng(7)
    n = 301  # not a multiple of any vector width
    dx = rng.standard_normal(n) * 2e-3
    th = rng.standard_normal(n) * tilt_rad
    wx, wy, wa = (rng.standard_normal(n) * 1e-4 if noisy else np.zeros(0) for _ in range(3))
    dz = rng.standard_normal(n) * 1e-4 if height else np.zeros(n)
    assert (np.max(np.abs(th)) > SMALL_ANGLE_RAD) == (tilt_rad > SMALL_ANGLE_RAD)
    cphi, sphi, dist, gx, gy = math.cos(0.3), math.sin(0.3), 0.5, -250.0, 250.0
    u0, v0 = np.empty(n), np.empty(n)
    spot_kernel(dx, dz, th, cphi, sphi, dist, u0, v0)  # the exact spot, sample by sample
    spots = []
    for j in range(n):
        u, v = float(u0[j]), float(v0[j])
        if noisy:
            u, v = u + float(wx[j]), v + float(wy[j])
        spots.append((u, v))
    half = float(np.quantile(np.max(np.abs(spots), axis=1), 0.9))  # a tenth off the detector
    out_x, out_y, flag = np.empty(n), np.empty(n), np.empty(n, dtype=np.bool_)
    lever_row(dx, dz, th, wx, wy, LeverRow(cphi, sphi, dist, half, gx, gy, 1.0), out_x, out_y,
              flag)
    acc, acc_flag = np.empty(n), np.empty(n, dtype=np.bool_)
    r = rng.standard_normal(n) * 0.3
    accelerometer_row(r, wa, AccelerometerRow(10.0, 4.0, 1.0, 0.0), acc, acc_flag)
    for j, (u, v) in enumerate(spots):
        assert flag[j] == (abs(u) > half or abs(v) > half)
        assert out_x[j] == gx * min(max(u, -half), half)
        assert out_y[j] == gy * min(max(v, -half), half)
        a = 10.0 * float(r[j]) + (float(wa[j]) if noisy else 0.0)
        assert acc_flag[j] == (abs(a) > 4.0) and acc[j] == min(max(a, -4.0), 4.0)
    assert flag.any() and not flag.all() and acc_flag.any()  # both sides of the edge seen
