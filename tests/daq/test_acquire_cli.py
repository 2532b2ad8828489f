"""``daq acquire`` and ``daq inspect`` (click's CliRunner), emulated rig, short records."""

import json
import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import daq.acquisition
from daq.acquisition import acquire
from daq.benches import FunctionBench
from daq.cli import main
from daq.hdf5 import Hdf5Sink, read_run
from daq.sinks import Sink
from rig.blocks import Calibration
from rig.scene import load_scene

SHORT = ["--scene", "ishizaki2009", "--records", "2", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5"]


@pytest.fixture
def runner():
    return CliRunner()


def test_acquire_writes_the_run_and_summarises_it(runner, tmp_path):
    out = tmp_path / "run.h5"
    res = runner.invoke(main, ["acquire", *SHORT, "--seed", "42", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert res.stdout.splitlines()[0].startswith(f"wrote {out} (")
    for text in ("2 records x 500 samples at 100 Hz (1000 samples per channel), channels a, x, y",
                 "seed: 42", "clipped samples: a 0, x 0, y 0",
                 "model: linear\n  method: exact discretisation",
                 "  error estimate: max_abs_theta_rad ",
                 "wall time: "):
        assert text in res.stdout
    assert "acquiring ishizaki2009" in res.stderr  # the progress bar is on stderr
    rec = read_run(out)
    assert rec.complete and rec.records == 2 and rec.header.seed == 42
    assert rec.header.plan.samples == 500 and rec.header.plan.settle_s == 5.0


def test_options_override_the_scene_and_same_seed_gives_same_data(runner, tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for out in (a, b):
        res = runner.invoke(main, ["acquire", "--scene", "ishizaki2009", "--set",
                                   "acquisition.records=9", "--records", "1", "--duration", "4",
                                   "--rate", "50", "--set", "acquisition.settle_s=2", "--seed",
                                   "7", "--out", str(out), "--quiet"])
        assert res.exit_code == 0, res.output
        assert res.stderr == ""
    ra, rb = read_run(a), read_run(b)
    assert (ra.records, ra.header.plan.rate_hz, ra.header.plan.samples) == (1, 50.0, 200)
    for k in ("a", "x", "y"):
        np.testing.assert_array_equal(ra.codes[k], rb.codes[k])
    # the files are identical apart from the start time
    ta, tb = ra.header.start_time.encode(), rb.header.start_time.encode()
    assert a.read_bytes().replace(ta, tb) == b.read_bytes()


def test_acquire_picks_and_reports_a_seed_when_none_is_given(runner, tmp_path):
    out = tmp_path / "run.h5"
    res = runner.invoke(main, ["acquire", *SHORT, "--records", "1", "--out", str(out), "-q"])
    assert res.exit_code == 0, res.output
    seed = int(res.stdout.split("seed: ")[1].split()[0])
    assert read_run(out).header.seed == seed


@pytest.mark.parametrize("args, message", [
    (["--records", "0"], "acquisition.records = 0 is invalid: expected an integer >= 1"),
    (["--rate", "300"], "acquisition.simulation_rate_hz = 1000 Hz is not an integer multiple "
                        "of it"),
    (["--rate", "2000"], "acquisition.rate_hz = 2000 Hz is invalid: it is above"),
    (["--duration", "0.005"], "acquisition.record_s = 0.005 s is invalid: expected a whole "
                              "number of samples"),
    (["--set", "acquisition.bogus=1"], "unknown key acquisition.bogus"),
    (["--seed", "-1"], "-1 is not in the range 0<=x<=9223372036854775807"),
])
def test_bad_inputs_give_clear_errors_and_write_nothing(runner, tmp_path, args, message):
    out = tmp_path / "run.h5"
    res = runner.invoke(main, ["acquire", *SHORT, "--seed", "1", "--out", str(out), *args])
    assert res.exit_code != 0
    assert message in res.output
    assert list(tmp_path.iterdir()) == []


def test_an_existing_file_is_kept_without_force_and_replaced_with_it(runner, tmp_path):
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    res = runner.invoke(main, ["acquire", *SHORT, "--seed", "1", "--out", str(out)])
    assert res.exit_code == 1
    assert "exists; pass --force to overwrite it" in res.output
    assert out.read_bytes() == b"precious"
    res = runner.invoke(main, ["acquire", *SHORT, "--seed", "1", "--out", str(out), "--force"])
    assert res.exit_code == 0, res.output
    assert read_run(out).complete
    res = runner.invoke(main, ["acquire", *SHORT, "--seed", "1", "--out",
                               str(tmp_path / "missing" / "run.h5")])
    assert res.exit_code == 1 and "does not exist" in res.output


def test_ctrl_c_keeps_the_finished_records_and_exits_130(runner, tmp_path, monkeypatch):
    cal = {k: Calibration("q", "m", 1.0) for k in "axy"}

    def sig(t, rng):
        if t[-1] >= 11.0:
            raise KeyboardInterrupt
        v = np.sin(t)
        return {"a": v, "x": v, "y": v}, {"source_v": v}

    monkeypatch.setattr(daq.acquisition, "rig_bench",
                        lambda sc, seed: FunctionBench(1000.0, sig, cal, block_samples=500))
    out = tmp_path / "run.h5"
    res = runner.invoke(main, ["acquire", *SHORT, "--records", "3", "--seed", "1", "--out",
                               str(out)])
    assert res.exit_code == 130, res.output
    assert f"interrupted (SIGINT) after 1 of 3 records; {out} holds them (status interrupted)" in res.stderr
    res = runner.invoke(main, ["inspect", str(out)])
    assert ("status: INCOMPLETE (interrupted), 1 of 3 records: SIGINT received (Ctrl-C)"
            in res.output)


def test_inspect_tells_what_a_file_holds(runner, tmp_path):
    out = tmp_path / "run.h5"
    assert runner.invoke(main, ["acquire", *SHORT, "--seed", "5", "--out", str(out)]).exit_code == 0
    res = runner.invoke(main, ["inspect", str(out)])
    assert res.exit_code == 0, res.output
    for text in ("pendulum-daq run 1.2, written by pendulum-daq 0.1.0",
                 "scene: ishizaki2009 (preset:ishizaki2009), seed 5, started ",
                 "status: complete, 2 of 2 records",
                 "sampling: 100 Hz (simulated at 1000 Hz, decimation 10), 500 samples per record",
                 "anti-alias: elliptic order 12, passband 40 Hz (0.01 dB ripple), >= 102.4 dB "
                 "from 50 Hz",
                 "  a: stage acceleration (accelerometer on the X stage) -- stage acceleration "
                 "x0'' [m/s^2], 1 V per m/s^2, +-1 V, 16 bit",
                 "clipped 0 samples in 0 of 2 records", "model: linear",
                 "ground truth: mirror_rot_rad, mirror_x_m, source_v, stage_accel_mps2, "
                 "theta_rad"):
        assert text in res.output
    info = json.loads(runner.invoke(main, ["inspect", str(out), "--json"]).output)
    assert info["status"] == "complete" and info["seed"] == 5
    assert info["clip_counts"] == {"a": [0, 0], "x": [0, 0], "y": [0, 0]}
    assert info["model_info"]["model"] == "linear"


def test_inspect_and_repair_a_file_whose_writer_died(runner, tmp_path):
    """A copy taken while the writer is in the middle of the run is what a killed writer leaves."""
    out, snap = tmp_path / "run.h5", tmp_path / "snapshot.h5"

    class Snapshot(Sink):
        def record(self, record):
            if record.index == 0:
                shutil.copyfile(out, snap)

    sc = load_scene("ishizaki2009", ["acquisition.records=2", "acquisition.record_s=2.0",
                                     "acquisition.settle_s=1.0"])
    acquire(sc, seed=1, sinks=[Hdf5Sink(out), Snapshot()])
    with pytest.raises(OSError):
        h5py.File(snap, "r")
    res = runner.invoke(main, ["inspect", str(snap)])
    assert res.exit_code == 0, res.output
    assert "status: INCOMPLETE (writer killed or still running), 1 of 2 records" in res.output
    assert "still marked open for writing" in res.output
    res = runner.invoke(main, ["inspect", str(snap), "--repair"])
    assert res.exit_code == 0, res.output
    assert f"cleared the open-for-writing mark of {snap}" in res.output
    assert "still marked open for writing" not in res.output
    with h5py.File(snap, "r") as f:
        assert f["entry/records_complete"][()] == 1


def test_inspect_refuses_what_is_not_a_run(runner, tmp_path):
    p = tmp_path / "x.h5"
    p.write_text("not hdf5")
    res = runner.invoke(main, ["inspect", str(p)])
    assert res.exit_code == 1 and "is not a readable HDF5 file" in res.output
