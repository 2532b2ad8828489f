#!/usr/bin/env python3
"""Paper experiments per minute on this machine's cores, measured, not derived: ``--procs``
processes side by side (default 2, one per core), each a warm process (one untimed warm-up run)
acquiring ``--runs`` paper runs (30 x 100 s, 330 s settling, to a run file, a seed per run) of one
model; the wall time from the moment every process is warm until the last one finishes.

    .venv/bin/python benchmarks/acquire_2cores.py --rounds 3 --runs 8

The models alternate within each round (linear, nonlinear; nonlinear, linear; ...). Printed per
model: runs per minute (procs x runs x 60 s / wall) per round, their median and range.

``--models linear,nonlinear,linear@fresh,nonlinear@fresh``: ``@fresh`` gives every timed run a
scene of its own (the source's level times 1 + k 1e-6, k different in every run of every
process), loaded inside the timed loop, as a sweep over drive levels runs: it pays the scene's
memoised computations (the model choice and its prediction, the expected responses) every run.
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

WORKER = r"""
import sys
sys.path.insert(0, {root!r})
from daq.acquisition import acquire
from daq.benches import rig_bench
from daq.hdf5 import Hdf5Sink
from rig.scene import load_scene
base = ["acquisition.model={model}"]
scene = load_scene("ishizaki2009", base)
out = {out!r}
acquire(scene, seed=1, sinks=[Hdf5Sink(out, force=True)], bench=rig_bench)
print("warm", flush=True)
sys.stdin.readline()  # the start signal
for i in range({runs}):
    if {fresh}:  # a scene of its own (module docstring)
        k = 1 + {proc} * 100000 + i
        scene = load_scene("ishizaki2009", base + [f"source.level_vrms={{0.1 * (1 + k * 1e-6)!r}}"])
    acquire(scene, seed=100 + i, sinks=[Hdf5Sink(out, force=True)], bench=rig_bench)
print("done", flush=True)
"""


def one_round(name: str, procs: int, runs: int, tmp: str) -> float:
    model, _, how = name.partition("@")
    if model not in ("linear", "nonlinear") or how not in ("", "fresh"):
        raise SystemExit(f"model {name!r}: expected linear or nonlinear, optionally @fresh")
    ps = []
    for p in range(procs):
        code = WORKER.format(root=str(ROOT), model=model, runs=runs, fresh=how == "fresh",
                             proc=p, out=os.path.join(tmp, f"{model}_{p}.h5"))
        ps.append(subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True))
    for p in ps:
        assert p.stdout.readline().strip() == "warm"
    t = time.perf_counter()
    for p in ps:
        p.stdin.write("go\n")
        p.stdin.flush()
    for p in ps:
        assert p.stdout.readline().strip() == "done"
    wall = time.perf_counter() - t
    for p in ps:
        p.wait()
    return procs * runs * 60.0 / wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--runs", type=int, default=8, help="timed runs per process")
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--models", default="linear,nonlinear",
                    help="comma-separated: linear, nonlinear, each optionally @fresh")
    args = ap.parse_args(argv)
    print("load average before:", os.getloadavg())
    models = args.models.split(",")
    per = {m: [] for m in models}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for m in (models if r % 2 == 0 else models[::-1]):
                per[m].append(one_round(m, args.procs, args.runs, tmp))
                print(f"round {r + 1} {m}: {per[m][-1]:.0f} runs/min", flush=True)
    print(f"\n{args.procs} processes x {args.runs} runs, {args.rounds} rounds; runs per minute")
    print("| model | median | range |\n|---|---|---|")
    for m in models:
        v = per[m]
        print(f"| {m} | {statistics.median(v):.0f} | {min(v):.0f} - {max(v):.0f} |")
    print("load average after:", os.getloadavg())


if __name__ == "__main__":
    main()
