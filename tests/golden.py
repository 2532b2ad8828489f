"""Golden run files: the arrays of short runs of the paper's experiment, stored in tests/data.

A golden run is the paper's scene (``ishizaki2009``, seed 2009) shortened to 10 s of settling and
3 records of 4 s, acquired to a run file and read back. Its arrays (ADC codes, clip and saturation
flags, ground truth, the stored model response) are kept in ``tests/data/golden_<name>.npz``; the
test compares a fresh run with them, so any change of output is visible.

    .venv/bin/python -m tests.golden            # rewrite every golden file (after a change of
                                                # output that is understood and bounded)
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data"
SEED = 2009
SHORT = ("acquisition.records=3", "acquisition.record_s=4", "acquisition.settle_s=10")
#: name -> (scene overrides, BenchSimulation keywords): the paper's drive with forced models, a
#: strongly driven one (the default method, etdab), and the same nonlinear runs by the coupled
#: bench's earlier path (lawson4)
RUNS = {
    "linear": (("acquisition.model=linear",), {}),
    "nonlinear": (("acquisition.model=nonlinear",), {}),
    "nonlinear_1v": (("acquisition.model=nonlinear", "source.level_vrms=1.0"), {}),
    "nonlinear_lawson4": (("acquisition.model=nonlinear",), {"method": "lawson4"}),
    "nonlinear_1v_lawson4": (("acquisition.model=nonlinear", "source.level_vrms=1.0"),
                             {"method": "lawson4"}),
}


def golden_scene(name: str):
    from rig.scene import load_scene

    return load_scene("ishizaki2009", list(SHORT) + list(RUNS[name][0]))


def run_arrays(name: str, **bench_kw) -> dict[str, np.ndarray]:
    """The arrays of a fresh golden run ``name``, through a run file (codes, clipped, saturated,
    truth, model). ``bench_kw`` (e.g. ``method``) go to :class:`rig.bench.BenchSimulation`,
    in place of the run's own."""
    import functools

    from daq.acquisition import acquire
    from daq.benches import rig_bench
    from daq.hdf5 import Hdf5Sink, read_run

    bench = functools.partial(rig_bench, **(bench_kw or RUNS[name][1]))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.h5"
        acquire(golden_scene(name), seed=SEED, sinks=[Hdf5Sink(path)], bench=bench)
        rec = read_run(path)
    out = {}
    for group in ("codes", "clipped", "saturated", "truth"):
        for k, v in getattr(rec, group).items():
            out[f"{group}/{k}"] = np.asarray(v)
    for k in ("h_t", "theta_2", "a", "x", "y"):
        out[f"model/{k}"] = np.asarray(rec.header.response.values[k])
    return out


def path_of(name: str) -> Path:
    return DATA / f"golden_{name}.npz"


def load(name: str) -> dict[str, np.ndarray]:
    with np.load(path_of(name)) as f:
        return {k: f[k] for k in f.files}


def write(name: str) -> Path:
    DATA.mkdir(exist_ok=True)
    p = path_of(name)
    np.savez_compressed(p, **run_arrays(name))
    return p


if __name__ == "__main__":
    for n in (sys.argv[1:] or RUNS):
        print(write(n))
