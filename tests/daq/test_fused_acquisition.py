"""The acquisition through the bench's fused chain (rig.bench.fused, the default) equals the
per-sample path (``rig_bench(lifted=False)``): a linear run (lifted) within round-off, a
nonlinear one (fused after its per-sample bench) bit for bit; the run file says which parts ran
per sample."""

import functools

import numpy as np
import pytest

from daq.acquisition import acquire
from daq.benches import rig_bench
from daq.sinks import MemorySink
from rig.scene import load_scene

SHORT = ["acquisition.records=2", "acquisition.record_s=4", "acquisition.settle_s=10"]
#: tests/rig/bench/test_fused.py: the largest difference of a series over its rms
ROUND_OFF = 1e-11


def _run(over, **kw):
    mem = MemorySink()
    acquire(load_scene("ishizaki2009", [*SHORT, *over]), seed=21, sinks=[mem],
            bench=functools.partial(rig_bench, **kw))
    return mem.recording


def test_a_lifted_run_equals_the_per_sample_run_within_round_off():
    new, old = _run(["acquisition.model=linear"]), _run(["acquisition.model=linear"],
                                                        lifted=False)
    for k, v in old.truth.items():
        v, w = np.asarray(v), np.asarray(new.truth[k])
        assert np.max(np.abs(w - v)) <= ROUND_OFF * np.sqrt(np.mean(v**2)), k
    for k, v in old.codes.items():
        # a code changes only where its sample lies within the round-off of a rounding edge
        d = np.abs(np.asarray(new.codes[k], np.int64) - np.asarray(v, np.int64))
        assert d.max() <= 1 and np.mean(d > 0) <= 1e-3, k
        assert np.array_equal(new.clipped[k], old.clipped[k]), k
        assert np.array_equal(new.saturated[k], old.saturated[k]), k
    assert "lifted" in new.header.model_info.per_sample
    assert "lifted" not in old.header.model_info.per_sample


def _same(new, old):
    for part in ("truth", "codes", "clipped", "saturated"):
        a, b = getattr(new, part), getattr(old, part)
        assert sorted(a) == sorted(b), part
        for k, v in b.items():
            assert np.asarray(a[k]).dtype == np.asarray(v).dtype, (part, k)
            assert np.array_equal(a[k], v), (part, k)


@pytest.mark.parametrize("over", [[], ["source.level_vrms=1.0"]], ids=["paper", "driven_1v"])
def test_a_fused_nonlinear_run_equals_the_per_sample_run_bit_for_bit(over):
    # the nonlinear bench runs per sample either way; after it the fused chain does the
    # per-sample path's own arithmetic in its order (rig.bench.fused.advance_decimated_nonlinear)
    over = ["acquisition.model=nonlinear", *over]
    new, old = _run(over), _run(over, lifted=False)
    _same(new, old)
    info, old_info = new.header.model_info.per_sample, old.header.model_info.per_sample
    assert "fused" in info and "lifted" not in info
    assert "fused" not in old_info and "lifted" not in old_info
    assert info["rate_hz"] == old_info["rate_hz"]


def test_inspect_says_what_runs_per_dac_sample_and_that_the_linear_bench_is_lifted(tmp_path):
    from click.testing import CliRunner

    from daq.cli import main

    out = tmp_path / "run.h5"
    res = CliRunner().invoke(main, ["acquire", "--scene", "ishizaki2009", "--seed", "5",
                                    "--out", str(out), *(a for s in SHORT for a in ("--set", s)),
                                    "--set", "acquisition.model=linear", "--allow-over-budget"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(main, ["inspect", str(out)])
    assert res.exit_code == 0, res.output
    method = next(line for line in res.output.splitlines() if line.startswith("  method: "))
    assert "lifted (rig.bench.fused): one exact step Phi^q per output sample" in method
    assert "one step per DAC sample" not in method
    assert "  per DAC sample (at 1000 Hz): the sensors' three linear readings" in res.output
    assert "  why: the bench from the DAC to the readings is linear" in res.output


@pytest.mark.parametrize("model", ["linear", "nonlinear"])
def test_the_model_probe_takes_its_source_from_the_run_not_a_second_generation(model,
                                                                              monkeypatch):
    import rig.bench.estimates as est

    calls = []
    real = est.generate
    monkeypatch.setattr(est, "generate", lambda *a, **k: calls.append(a) or real(*a, **k))
    rec = _run([f"acquisition.model={model}", "acquisition.settle_s=30"])
    assert calls == []  # the probe's 20 s came from the blocks made ahead
    assert rec.header.model_info.probe_s == 20.0
    assert np.isfinite(rec.header.model_info.error_estimate["relative_rms_theta"])


def test_a_paced_run_s_one_second_blocks_give_the_same_records_and_progress_each_second():
    # a paced sink asks for short blocks (Sink.block_s); the default bench runs in them
    from daq.pacing import PACED_BLOCK_S, Pacer, PacingSink

    now = [0.0]
    pacer = Pacer(1e6, clock=lambda: now[0], sleep=lambda s: now.__setitem__(0, now[0] + s))
    calls = []
    mem = MemorySink()
    acquire(load_scene("ishizaki2009", SHORT), seed=21, sinks=[mem, PacingSink(pacer)],
            progress=lambda done, total: calls.append(done))
    ref = _run([])
    for k in ref.codes:
        assert np.array_equal(mem.recording.codes[k], ref.codes[k]), k
    for k in ref.truth:
        assert np.array_equal(mem.recording.truth[k], ref.truth[k]), k
    np.testing.assert_allclose(calls, np.arange(1, 19) * PACED_BLOCK_S, rtol=1e-12)  # 10 + 2 x 4 s


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), True, "10"])
def test_a_bad_block_length_is_refused_naming_the_value(bad):
    from rig.errors import ConfigError

    with pytest.raises(ConfigError, match=r"block_s = .* is invalid: expected a bench block "
                                          r"length > 0 s"):
        rig_bench(load_scene("ishizaki2009", SHORT), 1, block_s=bad)
