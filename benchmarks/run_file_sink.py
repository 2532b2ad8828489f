#!/usr/bin/env python3
"""The run file's cost in the paper's linear acquisition: the same run, in one warm process,
written by the HDF5 sink (datasets grown and rows written through HDF5's own calls), by a sink
that resizes and assigns them the ordinary h5py way (the path before), and to memory only;
interleaved rounds, CPU medians, the per-round ratio of the two sinks' own cost (each minus the
memory run), and whether the two files are equal byte for byte apart from their start time.

    .venv/bin/python benchmarks/run_file_sink.py --rounds 15
    .venv/bin/python benchmarks/run_file_sink.py --replay 21

``--replay N``: the sinks alone, without the acquisition's noise around them: the paper's run
acquired once to memory, then its header and 30 records written N times by each sink
(interleaved), CPU per file (start, records, stop), medians and quartiles; a third sink,
``resized``, writes the rows through HDF5 but grows the datasets with h5py's ``resize`` (the
path of speed round 5); a fourth, ``gzip4``, is the sink with gzip level 4 (its default before
speed round 8), with both files' sizes.
"""

import argparse
import functools
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
    """The datasets grown with h5py's ``resize`` and the rows assigned with ``ds[k] = value``
    (h5py's general selection)."""

    def _extend(self, rows):
        for ds in self._grow:
            ds.resize(rows, axis=0)

    def _put_row(self, ds, k, value):
        ds[k] = value


class ResizingSink(Hdf5Sink):
    """The rows through HDF5's write call, the datasets grown with h5py's ``resize`` (the path
    of speed round 5)."""

    _extend = AssigningSink._extend


def replay(n):
    """The sinks alone on the paper's recorded run (module docstring)."""
    sc = load_scene("ishizaki2009", ["acquisition.model=linear"])
    mem = MemorySink()
    acquire(sc, seed=2009, sinks=[mem])
    h, recs, footer = mem.header, mem._records, mem.footer
    kinds = {"direct": Hdf5Sink, "resized": ResizingSink, "assigned": AssigningSink,
             "gzip4": functools.partial(Hdf5Sink, compression_level=4)}
    res = {k: [] for k in kinds}
    with tempfile.TemporaryDirectory() as d:
        for i in range(n + 1):
            for k in (list(kinds) if i % 2 == 0 else list(kinds)[::-1]):
                p = os.path.join(d, f"{k}.h5")
                t = time.process_time()
                s = kinds[k](p, force=True)
                s.start(h)
                for r in recs:
                    s.record(r)
                s.stop(footer)
                if i:  # the first round warms up
                    res[k].append(time.process_time() - t)
        same = len({Path(d, f"{k}.h5").read_bytes() for k in kinds if k != "gzip4"}) == 1
        sizes = {k: Path(d, f"{k}.h5").stat().st_size for k in ("direct", "gzip4")}
    for k, v in res.items():
        q = statistics.quantiles(v, n=4)
        print(f"{k}: CPU per file {statistics.median(v) * 1e3:.1f} ms [{q[0] * 1e3:.1f}, "
              f"{q[2] * 1e3:.1f}]")
    for other in ("resized", "assigned", "gzip4"):
        ratio = [a / b for a, b in zip(res["direct"], res[other])]
        print(f"direct / {other} per round: median {statistics.median(ratio):.3f}")
    print(f"files equal byte for byte: {same} (the same header: the same start time; gzip4 "
          f"aside)")
    print(f"file size: gzip level 1 (the sink's) {sizes['direct']:,} B, level 4 (before speed "
          f"round 8) {sizes['gzip4']:,} B: {sizes['direct'] / sizes['gzip4'] - 1:+.2%}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--replay", type=int, default=0, help="rounds of the sinks alone (0: skip)")
    args = ap.parse_args(argv)
    if args.replay:
        print(f"load average before: {os.getloadavg()}")
        replay(args.replay)
        print(f"load average after: {os.getloadavg()}")
        return
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
