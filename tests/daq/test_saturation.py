"""Sensor saturation (accelerometer over its range, laser spot off the PSD) is flagged per sample
-- set within the sample's decimation interval -- counted per record, stored, read back and
reported; files written before it existed read as never saturated."""

import h5py
import numpy as np
import pytest

from daq.acquisition import acquire
from daq.benches import interval_any
from daq.hdf5 import Hdf5Sink, read_run, run_info
from processing.analyzer import analyze
from rig.bench import BenchSimulation
from rig.scene import load_scene

SMALL = ["acquisition.records=2", "acquisition.record_s=10.0", "acquisition.settle_s=2.0",
         "psd.size_m=0.0015", "accelerometer.range_mps2=0.012"]


def _interval_any_reference(f: np.ndarray, q: int) -> np.ndarray:
    """Output j (simulation index j q) saw f anywhere in (j q - q, j q]."""
    m = -(-f.size // q)
    g = np.concatenate([np.zeros(q - 1, bool), f, np.zeros(m * q - f.size, bool)])
    return g[:m * q].reshape(m, q).any(axis=1)


@pytest.mark.parametrize("q", [2, 10])
def test_interval_flags_do_not_depend_on_how_the_run_is_split_into_blocks(q):
    rng = np.random.default_rng(q)
    f = rng.random(5003) < 0.02
    want = _interval_any_reference(f, q)
    for sizes in ([5003], [1, 9, 993, 4000], list(rng.integers(1, 40, 400))):
        out, carry, phase, pos = [], False, 0, 0
        for n in sizes:
            n = min(int(n), f.size - pos)
            if n <= 0:
                break
            got, carry = interval_any(f[pos:pos + n], slice(phase, n, q), carry)
            out.append(got)
            phase, pos = (phase - n) % q, pos + n
        got = np.concatenate(out)
        np.testing.assert_array_equal(got, want[:got.size])


def test_saturation_is_flagged_counted_stored_and_equal_to_the_benchs_own_flags(tmp_path):
    sc = load_scene("ishizaki2009", SMALL)
    out = tmp_path / "sat.h5"
    summary = acquire(sc, seed=3, sinks=[Hdf5Sink(out)])
    rec = read_run(out)
    plan = rec.header.plan
    q = round(plan.simulation_rate_hz / plan.rate_hz)
    truth = BenchSimulation(sc, seed=3).run(plan.simulation_samples / plan.simulation_rate_hz).truth
    n, s0 = plan.samples, plan.settle_samples
    for ch, key in (("a", "a_overrange"), ("x", "psd_off_detector"),
                    ("y", "psd_off_detector")):
        want = _interval_any_reference(np.asarray(truth[key], bool), q)
        for r in range(plan.records):
            np.testing.assert_array_equal(rec.saturated[ch][r], want[s0 + r * n:s0 + (r + 1) * n])
    counts = rec.saturation_counts()
    np.testing.assert_array_equal(counts, summary.saturation_counts)
    assert counts[:, 0].sum() > 0 and counts[:, 1].sum() > 0  # both sensors saturated here
    info = run_info(out)
    assert info["saturation_counts"] == {c: [int(v) for v in counts[:, i]]
                                         for i, c in enumerate(rec.header.names)}
    notes = [n for n in analyze(rec).notes if "sensor saturated" in n]
    totals = counts.sum(axis=0)
    assert notes and f"a {totals[0]}, x {totals[1]}, y {totals[2]}" in notes[0]


def test_the_default_experiment_never_saturates_and_an_older_file_reads_as_never(tmp_path):
    sc = load_scene("ishizaki2009", SMALL[:3])
    out = tmp_path / "ok.h5"
    summary = acquire(sc, seed=3, sinks=[Hdf5Sink(out)])
    assert summary.saturation_totals() == {"a": 0, "x": 0, "y": 0}
    with h5py.File(out, "r+") as f:  # what a file written before the saturation group looks like
        del f["entry/saturation"]
    rec = read_run(out)
    assert rec.saturated == {} and not rec.saturation_counts().any()
    assert run_info(out)["saturation_counts"] == {c: [0, 0] for c in ("a", "x", "y")}
