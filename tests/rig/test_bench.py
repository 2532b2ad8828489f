"""The whole bench (rig.bench): source -> coil -> stage -> pendulum -> sensors, in blocks."""

import math
import re

import numpy as np
import pytest

from rig.bench import (BenchSimulation, advance, build_model, calibrations, expected_response,
                       model_info, signal_to_noise, start)
from rig.blocks import AnalogBlock
from rig.errors import ConfigError, DivergenceError
from rig.scene import load_scene
from rig.devices.stage import Stage

QUIET = ["accelerometer.noise_mps2_rthz=0", "psd.noise_m_rthz=0"]
CHIRP = ["source.type=periodic-chirp", "source.period_s=10", "source.fmax_hz=20"]
FAST = ["pendulum.q1=5", "pendulum.q2=5"]  # transients gone in 150 s (to e^-40)


def ishizaki(*overrides):
    return load_scene("ishizaki2009", list(overrides))


def one_period_response(sim, key=None, volts=None, settle_s=150.0, period_s=10.0):
    sim.run(settle_s)
    b = sim.run(period_s)
    n = b.samples
    f = np.fft.rfftfreq(n, 1 / b.fs_hz)
    v = np.fft.rfft(b.truth["source_v"])
    return b, f, v


def test_blocks_over_a_duration_with_the_source_made_ahead_equal_sequential_blocks():
    """blocks(block_s, duration_s) makes the source's blocks ahead in another thread: the same
    bytes as next_block() one after the other, and nothing simulated beyond the duration."""
    sc = ishizaki()
    ahead = BenchSimulation(sc, seed=4)
    got = list(ahead.blocks(2.0, 7.0))
    seq = BenchSimulation(sc, seed=4)
    want = [seq.next_block(k) for k in (2000, 2000, 2000, 1000)]
    assert [b.samples for b in got] == [2000, 2000, 2000, 1000]
    for g, w in zip(got, want):
        for ch in ("a", "x", "y"):
            assert g.volts[ch].tobytes() == w.volts[ch].tobytes()
        for key, val in w.truth.items():
            assert np.asarray(g.truth[key]).tobytes() == np.asarray(val).tobytes(), key
    assert ahead.state.index == seq.state.index == 7000
    assert ahead.next_block(5).volts["x"].tobytes() == seq.next_block(5).volts["x"].tobytes()


@pytest.mark.parametrize("later", [(2.0, 7.0), (1.0, 3.0)])
def test_a_source_started_ahead_gives_the_same_blocks_whatever_blocks_asks_for(later):
    """ahead=(2 s, 7 s) starts the source during construction; blocks() with those arguments uses
    it, other arguments make their own: the same bytes as sequential next_block calls."""
    sc = ishizaki()
    sim = BenchSimulation(sc, seed=4, ahead=(2.0, 7.0))
    got = list(sim.blocks(*later))
    seq = BenchSimulation(sc, seed=4)
    sizes = [b.samples for b in got]
    want = [seq.next_block(k) for k in sizes]
    assert sum(sizes) == round(later[1] * 1000)
    for g, w in zip(got, want):
        for ch in ("a", "x", "y"):
            assert g.volts[ch].tobytes() == w.volts[ch].tobytes()
    assert sim.next_block(3).volts["a"].tobytes() == seq.next_block(3).volts["a"].tobytes()


def test_a_bad_ahead_plan_is_refused_naming_the_value():
    with pytest.raises(ConfigError, match="block_s = 0.0015 s is invalid"):
        BenchSimulation(ishizaki(), seed=4, ahead=(0.0015, 7.0))


def test_advance_refuses_a_source_block_that_does_not_start_at_its_state():
    sc = ishizaki()
    sim = BenchSimulation(sc, seed=4)
    from rig.devices.source import generate

    v, src = generate(sim.model.source, sim.state.source, 100)
    with pytest.raises(ValueError, match="source_block covers samples up to 100"):
        advance(sim.model, sim.state, 50, (v, src))


@pytest.mark.parametrize("model, reaction, method", [
    ("linear", "false", None), ("nonlinear", "false", "rk4"), ("nonlinear", "true", "lawson4"),
    ("nonlinear", "false", "lawson4")])
def test_blocks_reproduce_a_one_shot_run_bit_for_bit(model, reaction, method):
    sc = ishizaki(f"acquisition.model={model}", f"stage.reaction={reaction}")
    one = BenchSimulation(sc, seed=3, method=method).run(3.0)
    sim = BenchSimulation(sc, seed=3, method=method)
    parts = [sim.next_block(k) for k in (1, 999, 1700, 300)]
    for ch in ("a", "x", "y"):
        assert np.concatenate([p.volts[ch] for p in parts]).tobytes() == one.volts[ch].tobytes()
    for key, val in one.truth.items():
        joined = np.concatenate([p.truth[key] for p in parts])
        assert joined.tobytes() == val.tobytes(), key
    assert [p.t0_s for p in parts] == [0.0, 0.001, 1.0, 2.7]


def test_same_seed_gives_the_same_bytes_and_another_seed_other_noise():
    sc = ishizaki()
    a = BenchSimulation(sc, seed=11).run(2.0)
    b = BenchSimulation(sc, seed=11).run(2.0)
    c = BenchSimulation(sc, seed=12).run(2.0)
    for ch in "axy":
        assert a.volts[ch].tobytes() == b.volts[ch].tobytes()
        assert not np.array_equal(a.volts[ch], c.volts[ch])


def test_noise_floor_matches_the_stated_densities_and_streams_are_independent():
    sc = ishizaki("source.level_vrms=0")
    b = BenchSimulation(sc, seed=5).run(100.0)
    assert np.all(b.truth["stage_accel_mps2"] == 0) and np.all(b.truth["theta_rad"] == 0)
    n = b.samples
    tol = 5 / math.sqrt(2 * n)  # relative standard deviation of an rms from n samples, x 5
    acc, lever = build_model(sc).accelerometer, build_model(sc).lever
    assert np.std(b.volts["a"]) == pytest.approx(
        acc.sensitivity_vpmps2 * acc.noise_mps2_rthz * math.sqrt(500.0), rel=tol)
    for ch in "xy":
        assert np.std(b.volts[ch]) == pytest.approx(
            lever.gain_vpm * lever.noise_m_rthz * math.sqrt(500.0), rel=tol)
    c = np.corrcoef([b.volts["a"], b.volts["x"], b.volts["y"]])
    assert np.max(np.abs(c - np.eye(3))) < 5 / math.sqrt(n)


def test_channel_volts_are_the_sensor_models_applied_to_the_truth():
    sc = ishizaki(*QUIET)
    sim = BenchSimulation(sc, seed=1)
    sim.run(30.0)
    b = sim.run(5.0)
    m = sim.model
    # accelerometer: sign S times the high-passed acceleration, where q' = x0'' - w_c q
    np.testing.assert_array_equal(b.volts["a"], m.accelerometer.volts_per_mps2
                                  * b.truth["accel_sensed_mps2"])
    # PSD: sign G times the exact spot of the truth's mirror motion
    r = m.lever.measure(b.truth["mirror_x_m"], b.truth["mirror_rot_rad"], 1000.0, None, None,
                        mirror_z_m=b.truth["mirror_z_m"], noise=False)
    np.testing.assert_array_equal(b.volts["x"], r.x_v)
    np.testing.assert_array_equal(b.volts["y"], r.y_v)
    # linear model: the mirror motion is the linearised kinematics of the angles
    np.testing.assert_allclose(b.truth["mirror_x_m"], b.truth["theta_rad"] @ sc.mirror_weights(),
                               rtol=1e-15, atol=0)
    np.testing.assert_array_equal(b.truth["mirror_rot_rad"], b.truth["theta_rad"][:, 1])
    # and, through the linearised calibrations, within the optical lever's second-order terms
    cal = calibrations(sc)
    for ch, truth in (("x", "mirror_x_m"), ("y", "mirror_rot_rad")):
        lin = cal[ch].volts_per_unit * b.truth[truth]
        assert np.std(b.volts[ch] - lin) < 0.01 * np.std(lin)


@pytest.mark.parametrize("reaction", ["true", "false"])
def test_simulated_channels_match_the_exact_sampled_response(reaction):
    sc = ishizaki(*FAST, *CHIRP, *QUIET, "source.level_vrms=0.001", f"stage.reaction={reaction}")
    b, f, v = one_period_response(BenchSimulation(sc, seed=0))
    sel = (f > 0.05) & (f <= 20)
    r = expected_response(sc, f[sel], sampled=True)
    np.testing.assert_allclose(np.fft.rfft(b.volts["a"])[sel] / v[sel], r.a, rtol=1e-9)
    # x, y: exact optical-lever geometry; its second-order terms scale with the (tiny) level
    for ch in "xy":
        h = np.fft.rfft(b.volts[ch])[sel] / v[sel]
        want = getattr(r, ch)
        assert np.max(np.abs(h - want)) < 1e-4 * np.max(np.abs(want))


def test_sampled_response_is_the_continuous_one_plus_the_folded_dac_images():
    # y[k] = sum_m G(f + m fs) Z(f + m fs) V_d(f): the DAC hold Z = (1 - e^{-iwh}) / (iwh) makes
    # images at m fs +- f that sampling at the DAC instants folds back (terms ~ 1/m^2); with the
    # source's reconstruction filter off, the raw staircase drives the amplifier
    sc = ishizaki("source.reconstruction_hz=0")
    model = build_model(sc)
    f0 = np.array([0.3, 2.4794, 7.0])
    sampled = expected_response(sc, f0, sampled=True).stage_accel

    def poisson(big_m):
        ms = np.arange(-big_m, big_m + 1)
        out = []
        for f in f0:
            ff = f + ms * 1000.0
            w = 2 * np.pi * ff
            zoh = (1 - np.exp(-1j * w * 1e-3)) / (1j * w * 1e-3)
            g = model.stage.frequency_response(np.abs(ff), sc.chain).accel
            out.append(np.sum(np.where(ff >= 0, g, np.conj(g)) * zoh))
        return np.array(out)

    s1, s2 = poisson(1000), poisson(2000)
    assert np.all(np.abs(sampled - s2) <= 2 * np.abs(s2 - s1))  # the tail beyond 2000 images
    assert np.all(np.abs(s2 / sampled - 1) < 2e-5)
    cont = expected_response(sc, f0).stage_accel
    # the folded images are a DAC-rate artefact of sampling at 1 kHz (rig.bench.response)
    assert np.all(np.abs(sampled / cont - 1) < 0.05)


@pytest.mark.parametrize("sampled", [False, True])
@pytest.mark.parametrize("highpass", [True, False])
def test_the_ratios_at_0_hz_are_their_limits(sampled, highpass):
    """Stage acceleration and mirror motion both vanish at 0 Hz: the ratios take their limits
    there (the pendulum's static tilt -1/g per m/s^2), not a quotient of round-off; through an
    accelerometer with a high-pass the limit is unbounded (NaN)."""
    sc = ishizaki(*([] if highpass else ["accelerometer.highpass_hz=0"]))
    f = np.array([0.0, 1e-4, 1e-3])
    r = expected_response(sc, f, sampled=sampled)
    g = sc.chain.g_mps2
    assert r.theta_2_pendulum[0] == pytest.approx(-1.0 / g, rel=1e-12)
    for name in ("h_t_pendulum", "theta_2_pendulum") + (() if highpass else ("h_t", "theta_2")):
        v = getattr(r, name)
        # continuous in f: at 1e-3 Hz the ratios have moved by the damping's first-order term
        # (at most 1.2e-5 of the value here, theta_2's) and the sampled solve near z = 1 by
        # round-off ~1e-6 (growing as f falls); a quotient of round-off at 0 Hz is off by tens
        # of percent
        assert abs(v[2] / v[0] - 1) < 5e-5, (name, v)
    if highpass:
        assert np.all(np.isnan(r.h_t[:1])) and np.all(np.isnan(r.theta_2[:1]))
        assert abs(r.h_t[2]) > 10 * abs(r.h_t_pendulum[2])  # growing toward 0 Hz


def test_reconstruction_filter_removes_the_folded_dac_images():
    # 4th-order Butterworth at 100 Hz: the images near 1 kHz are attenuated by (100/990)^4 ~ 1e-4
    # on top of the hold's own ~f/fs, so sampled and continuous responses agree to ~1e-6 relative
    # where the unfiltered staircase left 1 % at 7 Hz and 4.8 % in the notch (test above)
    sc = ishizaki()
    f0 = np.array([0.3, 2.4794, 7.0, 10.0])
    sampled = expected_response(sc, f0, sampled=True)
    cont = expected_response(sc, f0)
    for name in ("stage_accel", "h_t", "theta_2"):
        rel = np.abs(getattr(sampled, name) / getattr(cont, name) - 1)
        assert np.all(rel < 2e-5), (name, rel)
    # common to a, x and y, the filter leaves the analyzer's ratios equal to the pendulum's
    np.testing.assert_allclose(cont.h_t_pendulum, cont.mirror_x / cont.stage_accel, rtol=1e-12)


def test_analyzer_readings_show_the_pendulum_and_the_accelerometer_corner():
    sc = ishizaki()
    g = sc.chain.g_mps2
    r = expected_response(sc, [0.001, 0.1, 1.0])
    l1 = sc.chain.length_m[0]
    # the pendulum alone: H_t -> -l/g, Theta_2 -> -1/g (phase 180 deg) at low frequency
    assert r.h_t_pendulum[0].real == pytest.approx(-l1 / g, rel=1e-4)
    assert r.theta_2_pendulum[0].real == pytest.approx(-1 / g, rel=1e-4)
    # the analyzer divides by the accelerometer's volts: its high-pass shows (+0.97 dB, -26.6 deg
    # at 0.1 Hz for the 0.05 Hz corner)
    hp = 1j * 0.1 / (1j * 0.1 + 0.05)
    assert r.h_t[1] / r.h_t_pendulum[1] == pytest.approx(1 / hp, rel=1e-12)
    assert r.theta_2[1] / r.theta_2_pendulum[1] == pytest.approx(1 / hp, rel=1e-12)
    # and the pendulum part is rig.describe's mirror response
    from rig.describe import mirror_response

    mr = mirror_response(sc, [0.1, 1.0])
    np.testing.assert_allclose(r.h_t_pendulum[1:], mr.x, rtol=1e-12)
    np.testing.assert_allclose(r.theta_2_pendulum[1:], mr.y, rtol=1e-12)
    # H_t does not care about the stage, nor about its reaction
    r2 = expected_response(ishizaki("stage.reaction=false", "stage.moving_mass_kg=7"), [0.1, 1.0])
    np.testing.assert_allclose(r2.h_t, r.h_t[1:], rtol=1e-12)


def test_calibrations_carry_the_sensor_signs():
    sc = ishizaki("accelerometer.sign=-1", "psd.sign_y=-1")
    cal = calibrations(sc)
    assert cal["a"].volts_per_unit == -1.0 and cal["a"].unit == "m/s^2"
    assert cal["x"].volts_per_unit == pytest.approx(1000.0) and cal["x"].unit == "m"
    assert cal["y"].volts_per_unit == pytest.approx(-1000 * 2 * 0.2 * math.cos(math.pi / 6))
    plain = BenchSimulation(ishizaki(*QUIET), seed=2).run(5.0)
    flipped = BenchSimulation(ishizaki(*QUIET, "accelerometer.sign=-1", "psd.sign_y=-1"),
                              seed=2).run(5.0)
    np.testing.assert_array_equal(flipped.volts["a"], -plain.volts["a"])
    np.testing.assert_array_equal(flipped.volts["y"], -plain.volts["y"])
    # the processing's job: undoing the calibration gives the same engineering units
    r1, r2 = expected_response(ishizaki(), [1.0]), expected_response(sc, [1.0])
    np.testing.assert_allclose(r2.h_t, r1.h_t, rtol=1e-14)
    np.testing.assert_allclose(r2.theta_2, r1.theta_2, rtol=1e-14)


def test_default_drive_keeps_the_pendulum_linear_and_the_spot_on_the_detector():
    sc = ishizaki()
    sim = BenchSimulation(sc, seed=7)
    sim.run(330.0)  # settle as in the paper (4.8 time constants of the Q1 = 530 mode)
    b = sim.run(300.0)
    th = b.truth["theta_rad"]
    assert np.max(np.abs(th)) < 0.05 and np.sqrt(np.mean(th[:, 0] ** 2)) < 0.01
    half = sim.model.lever.half_size_m
    assert not b.truth["psd_off_detector"].any()
    assert np.max(np.abs(b.truth["spot_v_m"])) < 0.75 * half
    assert np.max(np.abs(b.truth["spot_u_m"])) < 0.25 * half
    assert not b.truth["a_overrange"].any()
    x0 = b.truth["stage_disp_m"]
    assert np.sqrt(np.mean(x0**2)) < 3e-3 and np.max(np.abs(x0)) < 0.012
    lin = sim.model_info(probe_s=2.0).linearity
    assert lin["shift_over_half_bandwidth"] < 0.05


def test_signals_stay_well_above_the_sensor_noise_over_most_of_the_band():
    f = np.geomspace(0.1, 10.0, 401)
    snr = signal_to_noise(ishizaki(), f)
    assert np.min(snr["a"]) > 20  # 26 dB in the reaction's notch at 2.48 Hz, 45 dB elsewhere
    assert np.min(snr["x"]) > 20  # 21 dB at 10 Hz
    assert np.mean(snr["y"] > 20) > 0.75 and np.mean(snr["y"] > 10) > 0.95  # theta2's zero 4.68 Hz


def test_nonlinear_model_agrees_with_the_exact_linear_bench_within_its_error_estimate():
    # the prescribed-stage path (rig.solvers rk4 on the exact stage acceleration, linear
    # between sub-instants). A weak drive makes the nonlinearity (~theta^2 ~ 1e-8 relative)
    # negligible: what is left is the interpolation of the stage acceleration between
    # sub-instants, which the estimate measures (the raw DAC staircase, no reconstruction filter:
    # the acceleration has kinks to interpolate)
    over = ["stage.reaction=false", "source.level_vrms=0.01", "source.reconstruction_hz=0", *QUIET]
    lin = BenchSimulation(ishizaki(*over, "acquisition.model=linear"), seed=4).run(10.0)
    nl_scene = ishizaki(*over, "acquisition.model=nonlinear")
    errs = {}
    for m in (4, 8):
        sim = BenchSimulation(nl_scene, seed=4, method="rk4", oversample=m)
        nl = sim.run(10.0)
        diff = np.max(np.abs(nl.truth["theta_rad"] - lin.truth["theta_rad"]))
        info = sim.model_info(probe_s=10.0)
        est = info.error_estimate["max_abs_theta_rad"]
        assert 0.5 * est <= diff <= 1.5 * est
        assert info.error_estimate["integrator_max_abs_theta_rad"] < 1e-3 * est
        errs[m] = est
        np.testing.assert_allclose(nl.truth["stage_accel_mps2"], lin.truth["stage_accel_mps2"],
                                   rtol=1e-9, atol=1e-15)
    assert errs[4] / errs[8] == pytest.approx(4.0, rel=0.15)  # O((h / oversample)^2)


def test_prescribed_stage_methods_are_refused_with_the_stage_reaction():
    with pytest.raises(ConfigError, match=r"method = 'rk4' is not supported with "
                                          r"stage\.reaction = true: .* Use method 'lawson4'"):
        BenchSimulation(ishizaki("acquisition.model=nonlinear"), method="rk4")
    with pytest.raises(ConfigError, match=r"method = 'euler' is invalid: expected one of lawson4"):
        BenchSimulation(ishizaki("acquisition.model=nonlinear"), method="euler")


@pytest.mark.parametrize("bad", [0, -5, 2.5, True, "5"])
def test_a_bad_remainder_spacing_is_refused_naming_the_value(bad):
    with pytest.raises(ConfigError, match=rf"every = {re.escape(repr(bad))} is invalid: expected "
                                          r"an integer >= 1"):
        BenchSimulation(ishizaki("acquisition.model=nonlinear"), every=bad)


def test_linear_model_info_reports_round_off_and_the_predicted_linearisation_error():
    info = model_info(ishizaki("acquisition.model=linear"), probe_s=5.0)
    assert info.model == "linear" and "exact discretisation" in info.method
    est = info.error_estimate
    assert list(est)[0] == "max_abs_theta_rad"  # what `daq acquire` prints first
    assert est["discretisation_relative_rms_theta"] < 1e-10  # round-off
    # the model error dominates: the Q = 530 mode turns a 1e-5 frequency shift into ~0.5 %
    lin = est["linearisation_relative_rms_theta"]
    assert lin == info.selection["predicted_linear_error"] and 2e-3 < lin < 1e-2
    assert est["relative_rms_theta"] == pytest.approx(lin, rel=1e-6)
    assert info.states[:3] == ["coil_current_a", "stage_disp_m", "stage_vel_mps"]
    assert info.budget_met and info.selection["linear_meets_budget"]


# -- the coupled nonlinear bench (rig.solvers.coupled, method lawson4) ----------------------------

def test_coupled_nonlinear_bench_at_small_amplitude_is_the_exact_linear_bench():
    # 1 mV drive: theta ~ 6e-5 rad, the nonlinearity ~ Q theta^2 ~ 1e-6 relative; the Lawson
    # scheme propagates the linear part exactly, so nothing else separates the two
    over = [*QUIET, "source.level_vrms=0.001"]
    lin = BenchSimulation(ishizaki(*over, "acquisition.model=linear"), seed=6).run(20.0)
    nl = BenchSimulation(ishizaki(*over, "acquisition.model=nonlinear"), seed=6).run(20.0)
    for key in ("theta_rad", "stage_accel_mps2", "stage_disp_m", "coil_current_a"):
        a, b = lin.truth[key], nl.truth[key]
        assert np.sqrt(np.mean((a - b) ** 2)) < 1e-6 * np.sqrt(np.mean(a**2)), key
    for ch in "axy":
        assert np.max(np.abs(lin.volts[ch] - nl.volts[ch])) < 1e-5 * np.max(np.abs(lin.volts[ch]))


def test_coupled_bench_difference_from_linear_is_the_first_order_perturbation():
    # the same drive through both models: (nonlinear - linear) is, to O(e^2), the linear bench's
    # response to the nonlinear remainder along the linear trajectory (rig.bench.selection.
    # first_order_kernel on the full bench at the DAC rate, zero-order hold of V)
    from rig.bench.selection import first_order_kernel
    from rig.devices.source import generate, start_source

    over = [*QUIET, "source.level_vrms=0.1", "acquisition.model=nonlinear"]
    sim = BenchSimulation(ishizaki(*over), seed=8)
    nl = sim.run(60.0)
    lin = BenchSimulation(ishizaki(*over[:-1], "acquisition.model=linear"), seed=8).run(60.0)
    d = lin.truth["theta_rad"] - nl.truth["theta_rad"]
    measured = np.sqrt(np.mean(d**2, 0) / np.mean(nl.truth["theta_rad"] ** 2, 0))
    m = sim.model
    p = m.coupled
    phi, gam = m.phi, m.gamma
    bf = np.zeros((m.n_states, p.rows.size))
    bf[p.rows, np.arange(p.rows.size)] = 1.0
    from rig.linear import discretise

    _, gf0, gf1 = discretise(m.a, bf, 1e-3, "linear")
    v, _ = generate(m.source, start_source(m.source, np.random.SeedSequence(8).spawn(4)[0]),
                    60_000)
    np.testing.assert_array_equal(v, nl.truth["source_v"])
    sums, peaks = np.zeros((1, 3, 2)), np.zeros((2, 2))
    first_order_kernel(p.args(), phi, gam, np.zeros_like(gam), gf0, gf1, v,
                       np.zeros(m.n_states), np.zeros(m.n_states), 0, 1, sums, peaks)
    predicted = np.sqrt(sums[0, 1] / sums[0, 0])
    assert np.max(peaks[1]) < 0.1 * np.max(peaks[0])  # the first order holds all along
    assert 1e-4 < measured[0] < 1e-2  # a measurable nonlinearity
    np.testing.assert_allclose(measured, predicted, rtol=0.02)


@pytest.mark.parametrize("method, drift_bound", [
    ("lawson4", 1e-7),
    # etdab (the default): order 4 too, but its remainder is not small on a 1 rad swing, so its
    # error constant is larger (measured 8.5e-7 relative energy drift over 10 s)
    ("etdab", 2e-6)])
def test_free_stage_conserves_momentum_and_energy_within_the_estimate(method, drift_bound):
    # no spring, no guide damping, a (practically) disconnected coil, no drive, undamped chain:
    # the stage recoils as the double rod swings; horizontal momentum and total energy are
    # conserved by the equations, so their drift is the integrator's (Richardson at 2x steps)
    from rig.solvers.coupled import energy, horizontal_momentum

    over = ["source.level_vrms=0", "stage.stiffness_npm=0", "stage.damping_nspm=0",
            "stage.force_constant_npa=1e-9", "initial.theta0_rad=[1.0, -0.5]",
            "acquisition.model=nonlinear", "acquisition.settle_s=0", *QUIET]
    sc = load_scene("double-rod", over)
    runs = {}
    for sub in (1, 2):
        b = BenchSimulation(sc, seed=0, method=method, substeps=sub).run(10.0)
        t = b.truth
        runs[sub] = (horizontal_momentum(sc.chain, sc.stage,
                                         t["theta_rad"], t["omega_rad_s"], t["stage_vel_mps"]),
                     energy(sc.chain, sc.stage, t["theta_rad"],
                            t["omega_rad_s"], t["stage_disp_m"], t["stage_vel_mps"]),
                     t["stage_vel_mps"])
    p1, e1, v1 = runs[1]
    p2, e2, _ = runs[2]
    assert np.max(np.abs(v1)) > 0.3  # the stage really recoils (m = 2 kg on M = 2 kg)
    for q1, q2 in ((p1, p2), (e1, e2)):
        drift = np.max(np.abs(q1 - q1[0]))
        estimate = np.max(np.abs(q1 - q2)) * 16 / 15
        assert drift <= 1.5 * estimate + 1e-12 * np.max(np.abs(q1)), (drift, estimate)
    assert np.max(np.abs(e1 - e1[0])) < drift_bound * abs(e1[0])


def test_blocks_have_the_documented_contents():
    sim = BenchSimulation(ishizaki(), seed=0)
    blocks = list(sim.blocks(0.5, 1.2))
    assert [b.samples for b in blocks] == [500, 500, 200]
    b = blocks[1]
    assert isinstance(b, AnalogBlock) and b.t0_s == 0.5 and b.fs_hz == 1000.0
    assert set(b.volts) == {"a", "x", "y"}
    assert {"stage_accel_mps2", "theta_rad", "mirror_x_m", "mirror_rot_rad", "source_v",
            "stage_disp_m", "accel_sensed_mps2", "a_overrange", "psd_off_detector"} <= set(b.truth)
    assert b.truth["theta_rad"].shape == (500, 2)
    assert b.truth["psd_off_detector"].dtype == bool
    np.testing.assert_allclose(b.times_s(), 0.5 + np.arange(500) / 1000.0)
    with pytest.raises(ConfigError, match=r"block_s = 0\.0005 s is invalid: expected a whole "
                                          r"number \(>= 1\) of ADC samples"):
        next(sim.blocks(0.0005))


@pytest.mark.parametrize("override, match", [
    ("acquisition.simulation_rate_hz=1050", r"acquisition\.rate_hz = 100 Hz is invalid: "
                                            r"acquisition\.simulation_rate_hz = 1050 Hz is not "
                                            r"an integer multiple of it"),
    ("acquisition.simulation_rate_hz=-1", r"acquisition\.simulation_rate_hz = -1\.0 is invalid"),
    ("acquisition.rate_hz=0", r"acquisition\.rate_hz = 0\.0 is invalid"),
    ("psd.incidence_deg=90", r"psd\.incidence_deg = 90\.0 is invalid"),
    ("psd.distance_m=0", r"psd\.distance_m = 0\.0 is invalid"),
    ("stage.moving_mass_kg=-1", r"stage\.moving_mass_kg = -1\.0 is invalid"),
    ("accelerometer.highpass_hz=-1", r"accelerometer\.highpass_hz = -1\.0 is invalid"),
    ("source.fmax_hz=501", r"source\.fmax_hz = 501\.0 is invalid: expected 0 < fmax_hz <= 500"),
    ("source.type=square", r"source\.type = 'square' is invalid: expected one of random"),
])
def test_bad_bench_settings_raise_config_error_naming_the_key(override, match):
    with pytest.raises(ConfigError, match=match):
        BenchSimulation(ishizaki(override))


@pytest.mark.parametrize("model_name", ["linear", "nonlinear"])
@pytest.mark.parametrize("bad_value", [np.inf, np.nan])
def test_a_non_finite_state_raises_divergence_error_with_time_and_state(model_name, bad_value):
    model = build_model(ishizaki(f"acquisition.model={model_name}"))
    st = start(model, 0)
    _, st = advance(model, st, 100)
    z = np.array(st.z)
    z[3] = bad_value
    import dataclasses

    bad = dataclasses.replace(st, z=z)
    with pytest.raises(DivergenceError, match=r"non-finite state in the block starting at "
                                              r"t = 0\.1 s") as exc:
        advance(model, bad, 10)
    assert exc.value.time_s == pytest.approx(0.1)


def test_the_finite_check_passes_huge_finite_states_and_catches_one_bad_element():
    from rig.bench.run import _check_finite

    model = build_model(ishizaki())
    st = start(model, 0)
    huge = np.full((1000, 12), 1e308)  # finite, but their sum overflows to inf
    _check_finite(model, st, huge, huge[0], 0.0, 1000)
    for bad_value in (np.nan, np.inf, -np.inf):
        z_out = np.zeros((1000, 12))
        z_out[517, 7] = bad_value
        with pytest.raises(DivergenceError, match="non-finite state"):
            _check_finite(model, st, z_out, z_out[0], 0.0, 1000)
    with pytest.raises(DivergenceError, match="non-finite state"):
        _check_finite(model, st, np.zeros((3, 12)), np.array([0.0, np.nan]), 0.0, 3)


@pytest.mark.parametrize("scale", [1e-6, 1e-2, 0.5])
def test_mirror_kinematics_equal_numpy_geometry(scale):
    # the compiled kernel against the numpy expression it replaced: the same bytes with one
    # term in the sum (the mirror on the second body), round-off (the sum's order) with more
    from rig.bench.run import mirror_kinematics_kernel

    rng = np.random.default_rng(11)
    theta = rng.standard_normal((50_000, 12))[:, 3:7] * scale  # a strided view, as in z_out
    lengths = np.array([0.12, 0.07, 0.05, 0.03])
    for j in range(4):
        for s in (0.0, 0.013):
            x_np = np.sin(theta[:, :j]) @ lengths[:j]
            z_np = (1 - np.cos(theta[:, :j])) @ lengths[:j]
            if s != 0.0:
                x_np = x_np + s * np.sin(theta[:, j])
                z_np = z_np + s * (1 - np.cos(theta[:, j]))
            n = theta.shape[0]
            x, z, rot = np.empty(n), np.empty(n), np.empty(n)
            mirror_kinematics_kernel(theta, lengths, j, s, x, z, rot)
            assert rot.tobytes() == theta[:, j].tobytes()
            if j <= 1 and np.array_equal(np.sin(theta), np.vectorize(math.sin)(theta)) and \
                    np.array_equal(np.cos(theta), np.vectorize(math.cos)(theta)):
                assert x.tobytes() == x_np.tobytes() and z.tobytes() == z_np.tobytes()
            # a sum of j + 1 positive-weighted terms: relative rounding <= (j + 1) eps
            tol = (j + 2) * np.finfo(float).eps
            np.testing.assert_allclose(x, x_np, rtol=0, atol=tol * np.max(np.abs(x_np) + 1e-300))
            np.testing.assert_allclose(z, z_np, rtol=0, atol=tol * np.max(np.abs(z_np) + 1e-300))


def test_every_name_the_repository_takes_from_rig_bench_is_in_the_package():
    # rig.bench is a package of rooms (model, run, simulation, response, selection, estimates);
    # its __init__ re-exports what the packages, tests and benchmarks import from it, by
    # `from rig.bench import X` or as attributes of `from rig import bench as rb`
    import ast
    from pathlib import Path

    import rig.bench

    root = Path(__file__).resolve().parents[2]
    wanted = set()
    for folder in ("rig", "daq", "processing", "tests", "benchmarks"):
        for path in (root / folder).rglob("*.py"):
            tree = ast.parse(path.read_text("utf-8"))
            aliases = set()
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and node.module == "rig.bench":
                    wanted.update((a.name, str(path)) for a in node.names)
                elif isinstance(node, ast.ImportFrom) and node.module == "rig":
                    aliases.update(a.asname or a.name for a in node.names if a.name == "bench")
            for node in ast.walk(tree):
                if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                        and node.value.id in aliases):
                    wanted.add((node.attr, str(path)))
    assert len({name for name, _ in wanted}) >= 10  # 14 names when written: the scan works
    missing = sorted((name, where) for name, where in wanted if not hasattr(rig.bench, name))
    assert missing == []
