#!/usr/bin/env python3
"""The paper's acquisition (30 x 100 s at 100 Hz from the 1 kHz bench, seed 2009, written to a run
file) in one warm process: the linear model, the nonlinear model with its default method and
with the earlier one (lawson4), interleaved, CPU and wall time.

    .venv/bin/python benchmarks/acquire.py                 # 7 rounds (~2 minutes)
    .venv/bin/python benchmarks/acquire.py --rounds 11 --configs linear,etdab
    .venv/bin/python benchmarks/acquire.py --rounds 5 --configs linear,etdab,etdab_per_sample
    .venv/bin/python benchmarks/acquire.py --rounds 7 --configs linear,linear@fresh,etdab,etdab@fresh

(``*_per_sample``: the same model without the fused chain, ``rig_bench(lifted=False)``.)

Every round runs each configuration once, in a rotating order (A B C, B C A, ...), after one
warm-up run each (numba's cache loaded, the filter design memoised). Printed per configuration:
the median and quartiles of CPU (``time.process_time``: every thread of the process) and wall
time, and the median of the per-round ratios to the first configuration with their quartiles
(a ratio within one round compares runs made under the same load). "Runs per minute on 2 cores"
is 2 x 60 s / median CPU: what two such processes side by side sustain if CPU-bound.

A configuration's name followed by ``@fresh`` (``--configs linear,linear@fresh``) runs it with
a scene of its own every run, as a sweep over drive levels does (the source's level times
1 + k 1e-6 for the k-th such run: the same model, the same work): it pays the scene's own
computations every run (the model choice with its linearisation-error prediction and the
expected responses, memoised per scene by :mod:`rig.scene_memo`), which repeated runs of one
scene pay once per process.
"""

import argparse
import functools
import itertools
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.interleave import interleaved, ratio_rows  # noqa: E402
from daq.acquisition import acquire  # noqa: E402
from daq.benches import rig_bench  # noqa: E402
from daq.hdf5 import Hdf5Sink  # noqa: E402
from rig.scene import load_scene  # noqa: E402

CONFIGS = {
    "linear": ("acquisition.model=linear", {}),
    "etdab": ("acquisition.model=nonlinear", {"method": "etdab"}),
    # etdab with the remainder at every step (the default's path before speed round 4's
    # rig.bench.model.remainder_every: every 5 steps on the paper's drive)
    "etdab_every1": ("acquisition.model=nonlinear", {"method": "etdab", "every": 1}),
    "lawson4": ("acquisition.model=nonlinear", {"method": "lawson4"}),
    # the unfused paths (rig_bench(lifted=False)): the bench's per-sample blocks, then daq's
    # anti-alias filter and decimation (the "before" of the fused chains)
    "linear_per_sample": ("acquisition.model=linear", {"lifted": False}),
    "etdab_per_sample": ("acquisition.model=nonlinear", {"method": "etdab", "lifted": False}),
}


_RUNS = itertools.count(1)


def one_run(name, out, extra=()):
    base, _, how = name.partition("@")
    if base not in CONFIGS or how not in ("", "fresh"):
        raise SystemExit(f"configuration {name!r}: expected one of {', '.join(CONFIGS)}, "
                         "optionally followed by @fresh")
    override, kw = CONFIGS[base]
    scene = load_scene("ishizaki2009", [override, *extra])
    if how == "fresh":  # a scene of its own (module docstring)
        level = scene.source.level_vrms * (1 + next(_RUNS) * 1e-6)
        scene = load_scene("ishizaki2009", [override, *extra, f"source.level_vrms={level!r}"])
    t, c = time.perf_counter(), time.process_time()
    summary = acquire(scene, seed=2009, sinks=[Hdf5Sink(out, force=True)],
                      bench=functools.partial(rig_bench, **kw))
    return time.perf_counter() - t, time.process_time() - c, summary


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--configs", default="linear,etdab,lawson4")
    ap.add_argument("--set", action="append", default=[], help="a scene override for every run")
    args = ap.parse_args(argv)
    names = args.configs.split(",")
    print(f"load average before: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "paper.h5"
        for n in names:
            w, c, s = one_run(n, out, args.set)
            info = s.model_info
            est = (info.error_estimate or {}).get("relative_rms_theta")
            print(f"warm-up {n}: model {info.model}, method {info.method[:60]}..., "
                  f"error estimate {est:.2g}; wall {w:.2f} s, CPU {c:.2f} s", flush=True)
        walls, cpus = interleaved(names, args.rounds, lambda n: one_run(n, out, args.set))
    print(f"\n{args.rounds} rounds, interleaved; medians [quartiles]")
    print("| configuration | CPU [s] | wall [s] | CPU / first | wall / first | runs/min on 2 "
          "cores |")
    print("|---|---|---|---|---|---|")
    print("\n".join(ratio_rows(names, cpus, walls)))
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
