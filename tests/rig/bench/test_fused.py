"""The linear acquisition lifted to the output rate and fused (rig.bench.fused): equal to the
per-sample path (rig.bench.advance, then the anti-alias filter and the decimation of
daq.antialias) within round-off on the paper's scene, a strongly driven scene that clips, a
near-degenerate design and a long chain; block-wise equal to one-shot; the same seed, the same
bytes. The nonlinear model's fused chain (per-sample bench, then the fused sensors and the
lifted filter) equals its per-sample path bit for bit up to the filter (the same arithmetic in
the same order) and within the same round-off bound after it, with the same block-wise and
same-seed checks.

The round-off bound. Both paths compute the same exact linear map; they differ only in the
order of the sums (Phi^q formed once against q products of Phi, the readings from the lifted
state, the filter's sections lifted to q samples). Each interval injects a rounding of a few
ulp of the state (~ nz eps |z| ~ 1e-15 relative for nz = 12) and the stable bench carries it
along its modes: over the amplitude time constant of the Q = 530 mode (68 s, 6,800 intervals)
as a random walk, ~1e-15 sqrt(6,800) ~ 1e-13 of the rms. The tests allow ``ROUND_OFF`` =
1e-11 of each series' rms for the largest difference, 100 times that estimate (measured:
1e-13 .. 1e-12).
"""

import math

import numpy as np
import pytest

from daq.acquisition import antialias_for
from daq.benches import interval_any
from daq.records import RecordPlan
from rig.bench import BenchSimulation
from rig.scene import load_scene

ROUND_OFF = 1e-11
TRUTH = ("stage_accel_mps2", "theta_rad", "mirror_x_m", "mirror_rot_rad", "source_v")
#: beta^2 = 0.997: a nearly singular mass matrix, a 316 Hz mode (tests/rig/solvers)
BETA2 = [f"pendulum.r1_m={0.999 * 9.80665 / (2 * math.pi * 2.4783) ** 2!r}", "pendulum.eps=1.001",
         f"pendulum.f2_hz={math.sqrt(0.999 * 9.80665 / 0.000846) / (2 * math.pi)!r}"]
SCENES = {
    "paper": ("ishizaki2009", [], 60.0),
    # 3 V: the spot leaves an 8 mm detector and the accelerometer passes a 0.5 m/s^2 range now and
    # then, so clipping and the flags are exercised
    "driven_clipping": ("ishizaki2009", ["source.level_vrms=3.0", "psd.size_m=0.008",
                                         "accelerometer.range_mps2=0.5"], 30.0),
    "near_degenerate": ("ishizaki2009", BETA2, 30.0),
    "chain_n20": ("rod-chain", ["pendulum.n=20", "initial.theta0_rad=0.02",
                                "pendulum.damping_nms=1e-3", "acquisition.records=1",
                                "acquisition.record_s=5", "acquisition.settle_s=0"], 10.0),
}


def _scene(name):
    base, over, _ = SCENES[name]
    return load_scene(base, ["acquisition.model=linear", *over])


def _per_sample(scene, seed, duration_s, block_s=10.0, **kw):
    """The reference: per-sample bench blocks, filtered and decimated like daq's loop (``kw``:
    the simulation's, e.g. ``method``); returns the kept series, the filter, the simulation."""
    acq = scene.acquisition
    aa = antialias_for(acq, RecordPlan.from_acquisition(acq))
    sim = BenchSimulation(scene, seed, **kw)
    st = aa.initial_state(3)
    out = {k: [] for k in ("a", "x", "y", *TRUTH, "sat_a", "sat_x")}
    carry = {"a": False, "x": False}
    for b in sim.blocks(block_s, duration_s):
        x = np.stack([b.volts[k] for k in "axy"])
        kept = aa.kept(st, x.shape[1])
        y, st = aa.step(st, x)
        for i, k in enumerate("axy"):
            out[k].append(y[i])
        for k in TRUTH:
            out[k].append(np.asarray(b.truth[k])[kept])
        for k, key in (("a", "a_overrange"), ("x", "psd_off_detector")):
            s, carry[k] = interval_any(b.truth[key], kept, carry[k])
            out["sat_" + k].append(s)
    return {k: np.concatenate(v) for k, v in out.items()}, aa, sim


def _lifted(scene, seed, duration_s, aa, block_s=10.0, **kw):
    """The fused chain's kept series (``BenchSimulation.decimated_blocks``) and the simulation."""
    sim = BenchSimulation(scene, seed, **kw)
    out = {k: [] for k in ("a", "x", "y", *TRUTH, "sat_a", "sat_x", "sat_y")}
    for b in sim.decimated_blocks(block_s, duration_s, aa.sos):
        for k in "axy":
            out[k].append(b.volts[k])
            out["sat_" + k].append(b.saturated[k])
        for k in TRUTH:
            out[k].append(b.truth[k])
    return {k: np.concatenate(v) for k, v in out.items()}, sim


@pytest.mark.parametrize("name", list(SCENES))
def test_the_lifted_chain_equals_the_per_sample_path_within_round_off(name):
    scene = _scene(name)
    dur = SCENES[name][2]
    ref, aa, _ = _per_sample(scene, 11, dur)
    new, sim = _lifted(scene, 11, dur, aa)
    for k, v in ref.items():
        assert new[k].shape == v.shape, k
        if k.startswith("sat_"):
            assert np.array_equal(new[k], v), k
            continue
        scale = np.sqrt(np.mean(v**2))
        assert np.max(np.abs(new[k] - v)) <= ROUND_OFF * scale, (k, np.max(np.abs(new[k] - v))
                                                                 / scale)
    if name == "driven_clipping":  # the flags were exercised, and agree
        assert 0 < ref["sat_x"].sum() < ref["sat_x"].size
        assert 0 < ref["sat_a"].sum() < ref["sat_a"].size
    # the noise streams end where the per-sample path leaves them
    ref_sim = BenchSimulation(scene, 11)
    for _ in ref_sim.blocks(10.0, dur):
        pass
    assert sim.state.rng_states == ref_sim.state.rng_states


def test_lifted_blocks_reproduce_a_one_shot_run_bit_for_bit():
    scene = _scene("driven_clipping")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    one, _ = _lifted(scene, 4, 6.0, aa, block_s=6.0)
    for block_s in (0.01, 0.37, 2.5):
        split, _ = _lifted(scene, 4, 6.0, aa, block_s=block_s)
        for k, v in one.items():
            assert np.array_equal(split[k], v), (block_s, k)


def test_the_fused_kernel_gives_the_same_bytes_whatever_intervals_it_takes_at_a_time(
        monkeypatch):
    import rig.bench.fused as rl

    scene = _scene("driven_clipping")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    one, _ = _lifted(scene, 4, 6.0, aa, block_s=6.0)  # 600 intervals: 3 chunks of 256
    assert rl.CHUNK_INTERVALS < 600
    for chunk in (1, 7, 600, 10**6):
        monkeypatch.setattr(rl, "CHUNK_INTERVALS", chunk)
        split, _ = _lifted(scene, 4, 6.0, aa, block_s=6.0)
        for k, v in one.items():
            assert np.array_equal(split[k], v), (chunk, k)


def test_the_lifted_chain_gives_the_same_bytes_for_the_same_seed_and_others_for_another():
    scene = _scene("paper")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    a, _ = _lifted(scene, 9, 5.0, aa)
    b, _ = _lifted(scene, 9, 5.0, aa)
    c, _ = _lifted(scene, 10, 5.0, aa)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["x"], c["x"])


def test_the_lifted_chain_refuses_a_nonlinear_model_unlifted_sections_and_a_mid_interval_start():
    from rig.errors import ConfigError
    from rig.bench.fused import advance_decimated, lift, start_decimated

    scene = load_scene("ishizaki2009", ["acquisition.model=nonlinear"])
    with pytest.raises(ConfigError, match="linear model"):
        lift(BenchSimulation(scene, 1).model, 10)
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    sim = BenchSimulation(_scene("paper"), 1)
    with pytest.raises(ConfigError, match=r"sections = ndarray of shape \(\d+, 6\) is invalid: "
                                          r"expected lift_sections\(sos, 10\)"):
        advance_decimated(sim.model, lift(sim.model, 10), sim.state, start_decimated(aa.sos), 10,
                          aa.sos)
    sim.next_block(3)
    with pytest.raises(ConfigError, match="kept instant"):
        next(sim.decimated_blocks(1.0, 2.0, aa.sos))


def test_the_model_info_probe_reuses_the_run_s_source_made_ahead_without_changing_anything():
    sc = load_scene("ishizaki2009", ["acquisition.model=linear", "acquisition.records=2",
                                     "acquisition.record_s=10", "acquisition.settle_s=10"])
    ahead = BenchSimulation(sc, 5, ahead=(10.0, 30.0))
    plain = BenchSimulation(sc, 5)
    assert ahead.model_info().error_estimate == plain.model_info().error_estimate
    aa = antialias_for(sc.acquisition, RecordPlan.from_acquisition(sc.acquisition))
    for a, b in zip(ahead.decimated_blocks(10.0, 30.0, aa.sos),
                    plain.decimated_blocks(10.0, 30.0, aa.sos)):
        assert all(np.array_equal(a.volts[k], b.volts[k]) for k in a.volts)


# -- the nonlinear model: per-sample bench, fused sensors, lifted filter ------------------------

#: the nonlinear scenes: the paper's, ten times its drive, and a clipping one, by the coupled
#: integrator (etdab, the default) and the pendulum on the exactly stepped stage (rk4, which
#: needs the stage without reaction)
NONLINEAR = {
    "paper": (["acquisition.model=nonlinear"], {}, 60.0),
    "driven_1v": (["acquisition.model=nonlinear", "source.level_vrms=1.0"], {}, 30.0),
    "driven_clipping": (["acquisition.model=nonlinear", *SCENES["driven_clipping"][1]], {},
                        30.0),
    "paper_rk4": (["acquisition.model=nonlinear", "stage.reaction=false"], {"method": "rk4"},
                  20.0),
    # no anti-alias sections: the kernel keeps every q-th sensor reading as it is
    "paper_unfiltered": (["acquisition.model=nonlinear", "acquisition.antialias=none"], {}, 20.0),
}


def _nl(name):
    over, kw, dur = NONLINEAR[name]
    return load_scene("ishizaki2009", over), kw, dur


@pytest.mark.parametrize("name", list(NONLINEAR))
def test_the_fused_nonlinear_chain_equals_the_per_sample_path_up_to_the_filter_s_round_off(
        name):
    # up to the filter the same arithmetic in the same order (rig.bench.fused.
    # advance_decimated_nonlinear): the truth, the flags, the bench and the noise streams are
    # the per-sample path's own; the kept volts come from the filter lifted to the interval
    # (its sums in another order): within ROUND_OFF of each series' rms, the bound of the lifted
    # bench (module docstring; measured here 7e-14 .. 1.5e-13: the elliptic sections' sharp
    # poles carry each interval's rounding for a while)
    scene, kw, dur = _nl(name)
    ref, aa, ref_sim = _per_sample(scene, 11, dur, **kw)
    new, sim = _lifted(scene, 11, dur, aa, **kw)
    assert sim.model.model == "nonlinear"
    for k, v in ref.items():
        assert new[k].dtype == v.dtype and new[k].shape == v.shape, k
        if k in "axy" and aa.sos.shape[0]:
            scale = np.sqrt(np.mean(v**2))
            err = np.max(np.abs(new[k] - v))
            assert err <= ROUND_OFF * scale, (k, err / scale)
        else:
            assert np.array_equal(new[k], v), (k, np.max(np.abs(new[k] - v)))
    assert np.array_equal(new["sat_y"], new["sat_x"])
    if name == "driven_clipping":  # the flags were exercised, and agree
        assert 0 < ref["sat_x"].sum() < ref["sat_x"].size
        assert 0 < ref["sat_a"].sum() < ref["sat_a"].size
    # the bench and the noise streams end where the per-sample path leaves them
    assert sim.state.rng_states == ref_sim.state.rng_states
    assert np.array_equal(sim.state.z, ref_sim.state.z)


def test_the_fused_nonlinear_kernel_gives_the_same_bytes_whatever_intervals_it_takes_at_a_time(
        monkeypatch):
    import rig.bench.fused as rl

    scene, kw, _ = _nl("driven_clipping")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    one, sim = _lifted(scene, 4, 6.0, aa, block_s=6.0, **kw)  # 600 intervals: 3 chunks of 256
    for chunk in (1, 7, 10**6):
        monkeypatch.setattr(rl, "CHUNK_INTERVALS", chunk)
        split, other = _lifted(scene, 4, 6.0, aa, block_s=6.0, **kw)
        for k, v in one.items():
            assert np.array_equal(split[k], v), (chunk, k)
        assert other.state.rng_states == sim.state.rng_states


def test_fused_nonlinear_blocks_reproduce_a_one_shot_run_bit_for_bit():
    scene, kw, _ = _nl("driven_clipping")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    one, _ = _lifted(scene, 4, 6.0, aa, block_s=6.0, **kw)
    for block_s in (0.01, 0.37, 2.5):
        split, _ = _lifted(scene, 4, 6.0, aa, block_s=block_s, **kw)
        for k, v in one.items():
            assert np.array_equal(split[k], v), (block_s, k)


def test_the_fused_nonlinear_chain_gives_the_same_bytes_for_the_same_seed_only():
    scene, kw, _ = _nl("driven_1v")
    aa = antialias_for(scene.acquisition, RecordPlan.from_acquisition(scene.acquisition))
    a, _ = _lifted(scene, 9, 5.0, aa, **kw)
    b, _ = _lifted(scene, 9, 5.0, aa, **kw)
    c, _ = _lifted(scene, 10, 5.0, aa, **kw)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["x"], c["x"])


def test_the_fused_nonlinear_chain_refuses_a_linear_model_an_odd_block_and_unlifted_sections():
    from rig.errors import ConfigError
    from rig.bench.fused import advance_decimated_nonlinear, start_decimated
    from rig.sosfilt import lift_sections

    lin = BenchSimulation(_scene("paper"), 1)
    aa = antialias_for(lin.model.scene.acquisition,
                       RecordPlan.from_acquisition(lin.model.scene.acquisition))
    with pytest.raises(ConfigError, match="nonlinear model"):
        advance_decimated_nonlinear(lin.model, lin.state, start_decimated(aa.sos), 10,
                                    lift_sections(aa.sos, 10))
    sim = BenchSimulation(_nl("paper")[0], 1)
    with pytest.raises(ConfigError, match="multiple of the decimation 10"):
        advance_decimated_nonlinear(sim.model, sim.state, start_decimated(aa.sos), 15,
                                    lift_sections(aa.sos, 10))
    with pytest.raises(ConfigError, match=r"sections = ndarray of shape \(\d+, 6\) is invalid: "
                                          r"expected lift_sections\(sos, 10\)"):
        advance_decimated_nonlinear(sim.model, sim.state, start_decimated(aa.sos), 10, aa.sos)
    sim.next_block(3)
    with pytest.raises(ConfigError, match="kept instant"):
        next(sim.decimated_blocks(1.0, 2.0, aa.sos))


def test_no_kernel_of_the_fused_chain_takes_more_than_15_arguments():
    # one tuple of parameters per system (the lifted bench, each sensor, the lifted filter,
    # the mirror's layout, the outputs) instead of their numbers one by one
    import inspect

    import rig.bench.fused
    import rig.devices.accelerometer
    import rig.devices.optical_lever
    import rig.sosfilt

    modules = (rig.bench.fused, rig.sosfilt, rig.devices.accelerometer,
               rig.devices.optical_lever)
    counts = {}
    for mod in modules:
        for name, obj in vars(mod).items():
            func = getattr(obj, "py_func", None)  # a lazy kernel or numba's dispatcher
            if func is not None and func.__module__ == mod.__name__:
                counts[f"{mod.__name__}.{name}"] = len(inspect.signature(func).parameters)
    assert {"rig.bench.fused._fused_chunk", "rig.bench.fused.nonlinear_fused_kernel",
            "rig.sosfilt.lifted_sections_pass",
            "rig.devices.optical_lever.lever_row"} <= set(counts)
    assert {k: v for k, v in counts.items() if v > 15} == {}
