"""The acquisition stream with a synthetic bench (sines + seeded noise, real data): determinism,
continuous records, the chain from truth to codes, the model response, validation, sinks."""

import numpy as np
import pytest
from scipy import signal

from daq.acquisition import AcquisitionInterrupted, acquire
from daq.benches import FunctionBench, StreamError
from daq.antialias import AntiAliasFilter
from daq.hdf5 import Hdf5Sink
from daq.sinks import MemorySink, Sink
from rig.blocks import Calibration
from rig.errors import ConfigError
from rig.scene import load_scene

FS = 1000.0
CAL = {"a": Calibration("stage acceleration x0''", "m/s^2", 0.1),
       "x": Calibration("mirror translation", "m", 2000.0),
       "y": Calibration("mirror rotation", "rad", -200.0)}  # a PSD mounted upside down


def truth_of(t, rng, noise=0.2):
    """Ground truth at instants t: sines plus white noise (which reaches up to fs/2)."""
    w = rng.standard_normal((len(t), 2))  # per sample: the stream does not depend on blocks
    acc = 2.0 * np.sin(2 * np.pi * 1.3 * t) + noise * w[:, 0]
    return {"stage_accel_mps2": acc,
            "theta_rad": np.stack([1e-3 * np.sin(2 * np.pi * 0.7 * t),
                                   2e-3 * np.cos(2 * np.pi * 0.7 * t)], axis=1),
            "mirror_x_m": 1e-3 * np.sin(2 * np.pi * 2.1 * t + 0.4) + 1e-6 * w[:, 1],
            "mirror_rot_rad": 5e-3 * np.cos(2 * np.pi * 0.7 * t),
            "source_v": 0.2 * acc}


def sensors(truth):
    """The synthetic bench's sensor chain: pure gains."""
    return {"a": CAL["a"].volts_per_unit * truth["stage_accel_mps2"],
            "x": CAL["x"].volts_per_unit * truth["mirror_x_m"],
            "y": CAL["y"].volts_per_unit * truth["mirror_rot_rad"]}


def bench(noise=0.2, block_samples=777, fail_at_s=None, exc=KeyboardInterrupt):
    def signals(t, rng):
        if fail_at_s is not None and t[-1] >= fail_at_s:
            raise exc("stop")
        tr = truth_of(t, rng, noise)
        return sensors(tr), tr

    def response(f):
        return {k: np.full(f.shape, c.volts_per_unit, complex) for k, c in CAL.items()}

    return lambda scene, seed: FunctionBench(FS, signals, CAL, seed=seed,
                                             block_samples=block_samples, response=response)


def scene(*overrides, records=3, record_s=2.0, settle_s=1.0):
    return load_scene("ishizaki2009", [f"acquisition.records={records}",
                                       f"acquisition.record_s={record_s}",
                                       f"acquisition.settle_s={settle_s}", *overrides])


def run(sc, seed=1, **kw):
    mem = MemorySink()
    summary = acquire(sc, seed=seed, sinks=[mem, *kw.pop("sinks", [])],
                      bench=kw.pop("bench", bench()), **kw)
    return summary, mem.recording


def test_same_seed_gives_identical_data_bit_for_bit_and_another_seed_does_not():
    sc = scene()
    _, r1 = run(sc, seed=7)
    _, r2 = run(sc, seed=7, bench=bench(block_samples=1234))  # block size does not matter
    _, r3 = run(sc, seed=8)
    for k in ("a", "x", "y"):
        np.testing.assert_array_equal(r1.codes[k], r2.codes[k])
    for k in r1.truth:
        np.testing.assert_array_equal(r1.truth[k], r2.truth[k])
    assert not np.array_equal(r1.codes["a"], r3.codes["a"])


def test_records_are_back_to_back_pieces_of_one_continuous_run():
    """Three 2 s records equal one 6 s record of the same run, sample for sample: the last sample
    of record k and the first of record k+1 are consecutive samples of one signal."""
    _, short = run(scene(records=3, record_s=2.0))
    _, long = run(scene(records=1, record_s=6.0))
    for k in ("a", "x", "y"):
        np.testing.assert_array_equal(short.codes[k].reshape(-1), long.codes[k][0])
    np.testing.assert_array_equal(short.truth["theta_rad"].reshape(-1, 2),
                                  long.truth["theta_rad"][0])
    np.testing.assert_array_equal(short.record_start_s(), [1.0, 3.0, 5.0])
    assert short.times_s()[-1] == pytest.approx(1.99)


def test_truth_is_sampled_at_the_channel_instants_after_settling():
    sc = scene(settle_s=1.5)
    _, rec = run(sc, bench=bench(noise=0.0))
    t = np.arange(150, 150 + 600) * 10 / FS  # output sample j is simulation sample 10 j
    np.testing.assert_allclose(rec.record_start_s()[:, None] + rec.times_s()[None, :],
                               t.reshape(3, 200), rtol=1e-15)
    expected = truth_of(t, np.random.default_rng(0), noise=0.0)
    np.testing.assert_array_equal(rec.truth["mirror_rot_rad"].reshape(-1),
                                  expected["mirror_rot_rad"])
    assert rec.truth["theta_rad"].shape == (3, 200, 2)


def test_channels_equal_the_sensor_chain_and_filter_applied_to_the_truth_within_lsb_2():
    """Recompute the chain in one shot from the truth at the simulation rate (a reference built
    from scipy directly): sensor gains -> anti-alias sos -> every 10th sample -> ADC."""
    sc = scene(records=2, record_s=3.0, settle_s=2.0)
    _, rec = run(sc, seed=5)
    n_sim = int(8.0 * FS)
    truth = truth_of(np.arange(n_sim) / FS, np.random.default_rng(5))
    volts = sensors(truth)
    aa = rec.header.antialias
    for c in rec.header.channels:
        ref = signal.sosfilt(np.array(aa.sos), volts[c.name])[::10][200:].reshape(2, 300)
        err = rec.volts(c.name) - ref
        assert np.abs(err).max() <= c.adc.lsb_v / 2 * (1 + 1e-9)
        # in engineering units the calibration (and the PSD's sign) is undone
        np.testing.assert_allclose(rec.values(c.name), ref / c.volts_per_unit, rtol=0,
                                   atol=c.adc.lsb_v / 2 / abs(c.volts_per_unit) * (1 + 1e-9))


def test_stored_model_response_is_the_whole_chain_and_matches_the_measured_one():
    """A sine on an FFT line: channel / truth at that line equals the stored response (sensor gain
    x anti-alias H(f)) within the quantisation noise."""
    sc = scene(records=1, record_s=10.0, settle_s=5.0)
    _, rec = run(sc, bench=bench(noise=0.0))
    resp = rec.header.response
    f = resp.freqs_hz
    assert f[0] == 0 and f[-1] == 50.0 and len(f) == 501
    h_aa = AntiAliasFilter.design(FS, 100.0).response(f)
    np.testing.assert_allclose(resp.values["a"], 0.1 * h_aa, rtol=1e-15)
    np.testing.assert_array_equal(resp.values["antialias"], h_aa)
    k = 13  # 1.3 Hz
    measured = np.fft.rfft(rec.volts("a")[0])[k] / np.fft.rfft(rec.truth["stage_accel_mps2"][0])[k]
    assert abs(measured / resp.values["a"][k] - 1) < 2e-5


def test_clip_counts_are_counted_per_record_and_channel():
    sc = scene("acquisition.range_a_v=0.15")  # a = 0.2 sin(...) V: clips
    summary, rec = run(sc, bench=bench(noise=0.0))
    counts = rec.clip_counts()
    assert counts.shape == (3, 3) and counts[:, 0].min() > 0 and not counts[:, 1:].any()
    np.testing.assert_array_equal(summary.clip_counts, counts)
    assert summary.clip_totals() == {"a": int(counts[:, 0].sum()), "x": 0, "y": 0}
    clipped = rec.clipped["a"]
    assert np.all(np.abs(rec.codes["a"][clipped].astype(int)) >= 32767)


class Collect(Sink):
    def __init__(self):
        self.events = []

    def start(self, header):
        self.events.append(("start", header))

    def block(self, block):
        self.events.append(("block", block))

    def record(self, record):
        self.events.append(("record", record))

    def stop(self, footer):
        self.events.append(("stop", footer))


def test_stream_is_header_blocks_records_footer_and_blocks_never_straddle_records():
    col = Collect()
    summary, rec = run(scene(), sinks=[col])
    kinds = [e[0] for e in col.events]
    assert kinds[0] == "start" and kinds[-1] == "stop" and kinds.count("record") == 3
    blocks = [e[1] for e in col.events if e[0] == "block"]
    for r in range(3):
        mine = [b for b in blocks if b.record == r]
        assert mine[0].start == 0 and sum(b.samples for b in mine) == 200
        np.testing.assert_array_equal(np.concatenate([b.codes["x"] for b in mine]),
                                      rec.codes["x"][r])
    footer = col.events[-1][1]
    assert (footer.status, footer.records_complete) == ("complete", 3)
    assert summary.status == "complete" and summary.samples == 600


def test_progress_reports_simulated_time_up_to_the_total():
    calls = []
    run(scene(), progress=lambda done, total: calls.append((done, total)))
    done = [c[0] for c in calls]
    assert done == sorted(done) and calls[-1] == (7.0, 7.0)


def test_keyboard_interrupt_keeps_the_finished_records():
    mem = MemorySink()
    with pytest.raises(KeyboardInterrupt) as info:
        acquire(scene(records=5), seed=1, sinks=[mem], bench=bench(fail_at_s=6.5))
    assert isinstance(info.value, AcquisitionInterrupted)
    s = info.value.summary
    assert (s.status, s.records, s.records_planned) == ("interrupted", 2, 5)
    assert mem.footer.status == "interrupted" and mem.recording.records == 2
    _, full = run(scene(records=5))
    np.testing.assert_array_equal(mem.recording.codes["a"], full.codes["a"][:2])


def test_a_failing_live_sink_warns_and_the_run_goes_on():
    class Broken(Sink):
        critical = False

        def block(self, block):
            raise OSError("viewer went away")

    with pytest.warns(RuntimeWarning, match="sink Broken failed in block.*viewer went away"):
        summary, rec = run(scene(), sinks=[Broken()])
    assert summary.status == "complete" and rec.records == 3


def test_a_failing_file_sink_stops_the_run_and_every_sink_hears_of_it():
    class Full(Sink):
        def record(self, record):
            if record.index == 1:
                raise OSError("disk full")

    mem = MemorySink()
    with pytest.raises(OSError, match="disk full"):
        acquire(scene(), seed=1, sinks=[mem, Full()], bench=bench())
    assert mem.footer.status == "failed" and "disk full" in mem.footer.message
    assert mem.recording.records == 2  # the memory sink got record 1 before the file failed


def test_non_finite_volts_stop_the_run_naming_channel_and_time():
    def signals(t, rng):
        tr = truth_of(t, rng)
        v = sensors(tr)
        v["x"] = np.where(t >= 2.5, np.nan, v["x"])
        return v, tr

    with pytest.raises(StreamError, match=r"non-finite volts on channel\(s\) x at t = 2.5 s"):
        acquire(scene(), seed=1, bench=lambda sc, seed: FunctionBench(FS, signals, CAL))


def test_a_bench_with_gaps_is_refused():
    class Gappy(FunctionBench):
        def blocks(self):
            for i, b in enumerate(super().blocks()):
                yield b if i != 2 else type(b)(b.t0_s + 0.5, b.fs_hz, b.volts, b.truth)

    with pytest.raises(StreamError, match="blocks must be consecutive"):
        acquire(scene(), seed=1,
                bench=lambda sc, seed: Gappy(FS, lambda t, r: (sensors(truth_of(t, r)),
                                                               truth_of(t, r)), CAL))


def _never(scene, seed):
    raise AssertionError("the bench must not be built for an invalid run")


@pytest.mark.parametrize("overrides, message", [
    (["acquisition.records=0"], "acquisition.records = 0 is invalid: expected an integer >= 1"),
    (["acquisition.records=-3"], "acquisition.records = -3 is invalid"),
    (["acquisition.rate_hz=2000.0"], "acquisition.rate_hz = 2000 Hz is invalid: it is above "
                                     "acquisition.simulation_rate_hz = 1000 Hz"),
    (["acquisition.rate_hz=300.0"], "acquisition.simulation_rate_hz = 1000 Hz is not an integer "
                                    "multiple of it"),
    (["acquisition.rate_hz=1000.0"], "it equals acquisition.simulation_rate_hz"),
    (["acquisition.record_s=1.005"], "acquisition.record_s = 1.005 s is invalid: expected a whole "
                                     "number of samples at rate_hz = 100 Hz"),
    (["acquisition.record_s=0.0"], "acquisition.record_s = 0.0 s is invalid"),
    (["acquisition.settle_s=-1.0"], "acquisition.settle_s = -1.0 s is invalid"),
    (["acquisition.settle_s=0.333"], "acquisition.settle_s = 0.333 s is invalid"),
    (["acquisition.adc_bits=40"], "adc_bits = 40 is invalid"),
    (["acquisition.antialias_passband=0.6"], "antialias_passband = 0.6 is invalid"),
])
def test_bad_settings_are_refused_before_any_work_and_nothing_is_destroyed(tmp_path, overrides,
                                                                           message):
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        acquire(scene(*overrides), seed=1, sinks=[Hdf5Sink(out, force=True)], bench=_never)
    assert out.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_bad_outputs_and_seeds_are_refused_before_any_work(tmp_path):
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    with pytest.raises(ConfigError, match="exists"):
        acquire(scene(), seed=1, sinks=[Hdf5Sink(out)], bench=_never)
    with pytest.raises(ConfigError, match="does not exist"):
        acquire(scene(), seed=1, sinks=[Hdf5Sink(tmp_path / "no" / "run.h5")], bench=_never)
    with pytest.raises(ConfigError, match="is a directory"):
        acquire(scene(), seed=1, sinks=[Hdf5Sink(tmp_path, force=True)], bench=_never)
    for seed in (-1, 2 ** 63, 1.5, True):
        with pytest.raises(ConfigError, match=r"seed = .* is invalid: expected an integer"):
            acquire(scene(), seed=seed, bench=_never)
    assert out.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_a_bench_at_another_rate_is_refused():
    with pytest.raises(ConfigError, match="the bench runs at 2000 Hz but acquisition"):
        acquire(scene(), seed=1, bench=lambda sc, seed: FunctionBench(2000.0, None, CAL))


# -- the emulated rig (rig.bench) behind acquire's default bench ------------------------------

def rig_scene(*overrides, records=2, record_s=5.0, settle_s=5.0):
    return load_scene("ishizaki2009", [f"acquisition.records={records}",
                                       f"acquisition.record_s={record_s}",
                                       f"acquisition.settle_s={settle_s}", *overrides])


def test_rig_runs_are_reproducible_and_records_join_continuously():
    """Same seed, same bits; three 5 s records are one 15 s record cut in three (the bench is
    never restarted, and its block size -- 5 s or 10 s here -- does not matter)."""
    mem = [MemorySink() for _ in range(3)]
    acquire(rig_scene(records=3), seed=4, sinks=[mem[0]])
    acquire(rig_scene(records=3), seed=4, sinks=[mem[1]])
    acquire(rig_scene(records=1, record_s=15.0), seed=4, sinks=[mem[2]])
    a, b, one = (m.recording for m in mem)
    for k in ("a", "x", "y"):
        np.testing.assert_array_equal(a.codes[k], b.codes[k])
        np.testing.assert_array_equal(a.codes[k].reshape(-1), one.codes[k][0])
    np.testing.assert_array_equal(a.truth["theta_rad"].reshape(-1, 2), one.truth["theta_rad"][0])
    assert a.header.model_info.model == "linear" and a.header.model_info.error_estimate


def test_rig_channels_are_the_sensor_chain_of_the_truth_within_half_an_lsb():
    """Sensor noise off: the recorded volts equal accelerometer and PSD applied to the bench's
    truth at the simulation rate, then the anti-alias filter and decimation, within LSB/2."""
    from rig.bench import BenchSimulation

    sc = rig_scene("accelerometer.noise_mps2_rthz=0.0", "psd.noise_m_rthz=0.0")
    mem = MemorySink()
    acquire(sc, seed=2, sinks=[mem])
    rec = mem.recording
    sim = BenchSimulation(sc, 2)
    full = sim.run(15.0)  # one shot at 1 kHz: settle 5 s + 2 x 5 s
    tr, st = full.truth, sc.settings
    lever_h = st["psd"]["size_m"] / 2
    expected = {
        "a": st["accelerometer"]["sign"] * st["accelerometer"]["sensitivity_vpmps2"]
        * tr["accel_sensed_mps2"],
        "x": st["psd"]["sign_x"] * st["psd"]["gain_vpm"] * np.clip(tr["spot_u_m"], -lever_h,
                                                                   lever_h),
        "y": st["psd"]["sign_y"] * st["psd"]["gain_vpm"] * np.clip(tr["spot_v_m"], -lever_h,
                                                                   lever_h),
    }
    sos = np.array(rec.header.antialias.sos)
    for c in rec.header.channels:
        ref = signal.sosfilt(sos, expected[c.name])[::10][500:].reshape(2, 500)
        err = np.abs(rec.volts(c.name) - ref)
        assert err.max() <= c.adc.lsb_v / 2 + 1e-12 * c.range_v, c.name
    # the truth in the file is the bench's truth at the sample instants, up to the lifted
    # chain's round-off (1e-11 of the rms, tests/rig/bench/test_fused.py)
    want = tr["mirror_x_m"][::10][500:]
    assert np.max(np.abs(rec.truth["mirror_x_m"].reshape(-1) - want)) <= 1e-11 * np.sqrt(
        np.mean(want**2))


def test_rig_model_response_is_the_exact_chain_at_a_sine_line():
    """A 2 Hz sine source on an FFT line, transients settled (low Q for a short test): each
    channel over the source at that line equals the stored response (bench x anti-alias).

    Bound: the quantisation error e_j (|e_j| <= LSB/2) of a sine periodic in the record is
    coherent, so at the line |sum e_j exp(-i w t_j)| <= N LSB/2 against N A/2 for the signal
    (amplitude A): relative error <= LSB / A (~4e-3 for a, 3e-4 for x, y here)."""
    sc = rig_scene("source.type=sine", "source.frequency_hz=2.0", "pendulum.q1=5.0",
                   "pendulum.q2=5.0", "accelerometer.noise_mps2_rthz=0.0",
                   "psd.noise_m_rthz=0.0", records=1, record_s=10.0, settle_s=60.0)
    mem = MemorySink()
    acquire(sc, seed=0, sinks=[mem])
    rec = mem.recording
    resp = rec.header.response
    k = 20  # 2 Hz on the 0.1 Hz grid
    assert resp.freqs_hz[k] == pytest.approx(2.0)
    src = np.fft.rfft(rec.truth["source_v"][0])[k]
    amp_src = np.sqrt(2) * sc.settings["source"]["level_vrms"]
    lines, bound = {}, {}
    for c in rec.header.channels:
        lines[c.name] = np.fft.rfft(rec.volts(c.name)[0])[k]
        model = resp.values[c.name][k]
        bound[c.name] = c.adc.lsb_v / (abs(model) * amp_src)
        assert abs(lines[c.name] / src / model - 1) <= bound[c.name], c.name
    cal = {c.name: c.volts_per_unit for c in rec.header.channels}
    h_t = (lines["x"] / cal["x"]) / (lines["a"] / cal["a"])
    assert abs(h_t / resp.values["h_t"][k] - 1) <= 1.01 * (bound["x"] + bound["a"])
    assert resp.units["h_t"] == "m/(m/s^2)"
