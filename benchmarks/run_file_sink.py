#!/usr/bin/env python3
"""The run file's cost in the paper's linear acquisition: the same run, in one warm process,
written by the HDF5 sink (rows through HDF5's write call), by a sink that assigns the rows the
ordinary h5py way (the path before), and to memory only; interleaved rounds, CPU medians, the
per-round ratio of the two sinks' own cost (each minus the memory run), and whether the two files
are equal byte for byte apart from their start time.

    .venv/bin/python benchmarks/run_file_sink.py --rounds 15
"""

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import h5py

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from daq.acquisition import acquire  # noqa: E402
from daq.hdf5 import Hdf5Sink  # noqa: E402
from daq.sinks import MemorySink  # noqa: E402
from rig.scene import load_scene  # noqa: E402


class AssigningSink(Hdf5Sink):
    """The rows assigned with ``ds[k] = value`` (h5py's general selection)."""

    def _put_row(self, ds, k, value):
        ds[k] = value


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=15)
    args = ap.parse_args(argv)
    sc = load_scene("ishizaki2009", ["acquisition.model=linear"])
    sinks = {"direct": lambda p: [Hdf5Sink(p)], "assigned": lambda p: [AssigningSink(p)],
             "memory": lambda p: [MemorySink()]}
    print(f"load average before: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as d:
        def run(kind, i):
            p = os.path.join(d, f"{kind}{i}.h5")
            t = time.process_time()
            acquire(sc, seed=2009, sinks=sinks[kind](p))
            return time.process_time() - t, p

        for k in sinks:
            run(k, -1)
        res = {k: [] for k in sinks}
        for i in range(args.rounds):
            for k in (list(sinks) if i % 2 == 0 else list(sinks)[::-1]):
                res[k].append(run(k, i))
        for k, v in res.items():
            print(f"{k}: CPU per run, median {statistics.median(x[0] for x in v):.3f} s")
        ratio = [(n[0] - m[0]) / (o[0] - m[0])
                 for n, o, m in zip(res["direct"], res["assigned"], res["memory"])]
        print(f"the sink's own CPU, direct / assigned, per round: median "
              f"{statistics.median(ratio):.2f} (quartiles "
              f"{statistics.quantiles(ratio, n=4)[0]:.2f}, {statistics.quantiles(ratio, n=4)[2]:.2f})")

        def start(p):
            with h5py.File(p, "r") as f:
                return f["entry"].attrs["start_time"].encode()

        a, b = res["direct"][0][1], res["assigned"][0][1]
        ba, bb = Path(a).read_bytes(), Path(b).read_bytes()
        print(f"files equal byte for byte apart from the start time: "
              f"{ba.replace(start(a), start(b)) == bb} ({len(ba)} bytes)")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
