"""The acquisition's one route: a bench that decimates itself (the rig's fused chain) is used as
it is, any other is adapted once by the Decimator, which equals the anti-alias filter run over
the whole run in one piece, bit for bit, whatever the bench's block size."""

import numpy as np
import pytest

from daq.acquisition import antialias_for
from daq.antialias import AntiAliasFilter
from daq.benches import (DecimatingBench, Decimator, FunctionBench, StreamError, decimating,
                         rig_bench)
from daq.records import RecordPlan
from rig.blocks import Calibration, DecimatedBlock
from rig.scene import load_scene

FS = 1000.0
CAL = {"a": Calibration("stage acceleration x0''", "m/s^2", 0.1),
       "x": Calibration("mirror translation", "m", 2000.0)}


def _signals(t, rng):
    w = rng.standard_normal((len(t), 2))
    a = np.sin(2 * np.pi * 3.0 * t) + 0.3 * w[:, 0]
    x = 1e-3 * np.cos(2 * np.pi * 1.1 * t) + 1e-4 * w[:, 1]
    over = np.abs(a) > 1.2  # a saturation flag at the simulation rate
    return {"a": 0.1 * a, "x": 2000.0 * x}, {"accel": a, "mirror_x_m": x, "over": over}


def _function_bench(block_samples):
    b = FunctionBench(FS, _signals, CAL, seed=5, block_samples=block_samples)
    b.saturation_keys = {"a": "over"}
    return b


def test_the_rig_decimates_itself_and_a_bench_that_cannot_is_adapted_once():
    scene = load_scene("ishizaki2009", ["acquisition.records=1", "acquisition.record_s=2",
                                        "acquisition.settle_s=0"])
    fused = rig_bench(scene, 1)
    assert isinstance(fused, DecimatingBench) and decimating(fused) is fused
    per_sample = rig_bench(scene, 1, lifted=False)
    assert not isinstance(per_sample, DecimatingBench)
    adapted = decimating(per_sample)
    assert isinstance(adapted, Decimator) and decimating(adapted) is adapted
    assert isinstance(decimating(_function_bench(100)), Decimator)


@pytest.mark.parametrize("block_samples", [777, 1000, 10_000])
def test_the_decimator_equals_the_filter_over_the_whole_run_bit_for_bit(block_samples):
    n = 5_432  # not a whole number of blocks: the last one is cut
    aa = AntiAliasFilter.design(FS, 100.0)
    got = list(Decimator(_function_bench(block_samples), n).decimated_blocks(aa))
    assert all(isinstance(b, DecimatedBlock) for b in got)
    assert sum(b.samples for b in got) == n
    assert [b.t0_s for b in got] == [k * block_samples / FS for k in range(len(got))]
    # the reference: the bench's signals in one piece, filtered in one call
    t = np.arange(n) / FS
    volts, truth = _signals(t, np.random.default_rng(5))
    y, _ = aa.step(aa.initial_state(2), np.stack([volts["a"], volts["x"]]))
    for i, k in enumerate(("a", "x")):
        assert np.array_equal(np.concatenate([b.volts[k] for b in got]), y[i])
    assert np.array_equal(np.concatenate([b.truth["accel"] for b in got]), truth["accel"][::10])
    # the saturation flag: set within each kept instant's interval (since the previous one)
    sat = np.concatenate([b.saturated["a"] for b in got])
    want = [truth["over"][max(0, j - 9):j + 1].any() for j in range(0, n, 10)]
    assert np.array_equal(sat, want) and sat.any() and not sat.all()
    assert "x" not in got[0].saturated


def test_a_decimated_bench_block_without_a_channel_is_refused_naming_it():
    def signals(t, rng):
        volts, truth = _signals(t, rng)
        return {"a": volts["a"]}, truth

    aa = AntiAliasFilter.design(FS, 100.0)
    with pytest.raises(StreamError, match=r"bench block at t = 0 s has no volts for "
                                          r"channel\(s\) x"):
        next(Decimator(FunctionBench(FS, signals, CAL)).decimated_blocks(aa))


def test_the_rig_s_fused_blocks_are_those_of_its_decimation():
    scene = load_scene("ishizaki2009", ["acquisition.records=1", "acquisition.record_s=2",
                                        "acquisition.settle_s=0"])
    plan = RecordPlan.from_acquisition(scene.acquisition)
    aa = antialias_for(scene.acquisition, plan)
    blocks = list(rig_bench(scene, 1).decimated_blocks(aa))
    assert sum(b.samples for b in blocks) == plan.simulation_samples
    assert all(b.decimation == aa.decimation for b in blocks)
