"""The bench's sampled response in modal form (rig.bench.sampled) against the direct solve.

* ``sampled_response(scene)(f)`` equals ``expected_response(scene, f, sampled=True)`` field by
  field (the stage-1 curves included) within 1e-7 relative over 0 - 450 Hz: the modal form
  differs from the solve by round-off where the modal terms cancel (measured within 5e-9, 1e-8
  for the stage displacement, largest near 0 Hz and at the anti-resonances);
* the stage-1 curves are body 1's angle and its centre of mass's translation per unit of sensed
  stage acceleration, the same normalisation as H_t and Theta_2 (for the Ishizaki pendulum, whose
  mirror point lies on body 1's axis at G1's distance, ``h_g1 = h_t = l theta_1``); at 0 Hz
  through the accelerometer's high-pass they are NaN like H_t, and the pendulum's static
  deflection ``-1/g`` without it;
* a frequency outside [0, fs / 2) is refused with a message naming the valid range.
"""

from __future__ import annotations

import numpy as np
import pytest

from rig.bench import expected_response, sampled_response
from rig.errors import ConfigError
from rig.scene import load_scene

G = 9.80665
FIELDS = ("a", "x", "y", "stage_accel", "stage_disp", "mirror_x", "mirror_rot", "h_t", "theta_2",
          "h_t_pendulum", "theta_2_pendulum", "theta_1", "h_g1", "theta")


@pytest.fixture(scope="module")
def scene():
    return load_scene("ishizaki2009")


def test_modal_response_equals_the_direct_solve_within_round_off(scene):
    fast = sampled_response(scene)
    chain = scene.chain
    special = [float(v) for v in chain.modes()[0]]
    special += [float(v) for v in chain.antiresonances_hz(scene.mirror_weights())]
    special += [float(v) for v in chain.antiresonances_hz(np.eye(chain.n)[scene.mirror.body])]
    f = np.concatenate([np.arange(1, 400) * (100.0 / 131072), np.linspace(0.05, 49.9, 3000),
                        np.geomspace(0.05, 0.45 * fast.fs_hz, 12),
                        [v * (1 + d) for v in special for d in (-1e-3, 0.0, 1e-3)]])
    got = fast(f)
    ref = expected_response(scene, f, sampled=True)
    assert got.sampled and ref.sampled
    np.testing.assert_array_equal(got.freqs_hz, f)
    for k in FIELDS:
        b = np.asarray(getattr(ref, k))
        assert np.max(np.abs(getattr(got, k) - b) / np.abs(b)) < 1e-7, k


@pytest.mark.parametrize("sampled", [False, True])
def test_stage_one_curves_are_body_one_per_sensed_stage_acceleration(scene, sampled):
    f = np.geomspace(0.05, 20.0, 200)
    r = expected_response(scene, f, sampled=sampled)
    lever = scene.mirror_weights()[0]
    assert scene.mirror_weights()[1] == 0.0 and scene.chain.com_m[0] == lever
    np.testing.assert_allclose(r.theta_1 * lever, r.h_t, rtol=1e-12)
    np.testing.assert_allclose(r.h_g1, r.h_t, rtol=1e-12)
    np.testing.assert_allclose(r.theta_1 / r.theta_2, r.theta[:, 0] / r.theta[:, 1], rtol=1e-12)


def test_stage_one_curves_at_zero_hz_are_limits_like_the_ratios():
    with_hp = expected_response(load_scene("ishizaki2009"), [0.0], sampled=True)
    assert np.isnan(with_hp.theta_1[0]) and np.isnan(with_hp.h_t[0])
    flat = expected_response(load_scene("ishizaki2009", ["accelerometer.highpass_hz=0"]), [0.0],
                             sampled=True)
    assert flat.theta_1[0] == pytest.approx(-1.0 / G, rel=1e-9)
    assert flat.h_g1[0] == pytest.approx(flat.h_t[0], rel=1e-12)


def test_a_frequency_above_half_the_simulation_rate_is_refused(scene):
    fast = sampled_response(scene)
    with pytest.raises(ConfigError, match=r"freqs_hz must lie in \[0, "):
        fast([fast.fs_hz / 2])
