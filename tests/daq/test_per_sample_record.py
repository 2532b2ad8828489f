"""The run file says which parts of the chain run at every DAC sample, and why."""

import h5py

from daq.acquisition import acquire
from daq.hdf5 import Hdf5Sink, read_run
from rig.scene import load_scene

SHORT = ["acquisition.records=1", "acquisition.record_s=1", "acquisition.settle_s=1",
         "acquisition.model=linear"]


def test_run_file_records_what_runs_at_the_dac_rate_and_why(tmp_path):
    scene = load_scene("ishizaki2009", SHORT)
    path = tmp_path / "run.h5"
    acquire(scene, seed=3, sinks=[Hdf5Sink(path)])
    info = read_run(path).header.model_info.per_sample
    assert info["rate_hz"] == scene.settings["acquisition"]["simulation_rate_hz"]
    assert "optical lever" in info["what"] and "anti-alias" in info["what"]
    assert "second-order geometry" in info["why"]
    with h5py.File(path) as f:
        assert f["entry/model"].attrs["per_sample.rate_hz"] == info["rate_hz"]
