#!/usr/bin/env python3
"""The bench's and the pendulum's compiled kernels in two source trees side by side: this tree
against a baseline (e.g. a worktree of the commit before a change), interleaved, CPU time.

    git worktree add /tmp/base <commit>        # the code before the change
    .venv/bin/python benchmarks/kernel_trees.py --baseline /tmp/base --pairs 8

Timed in each process (CPU, ``time.process_time``; a warm-up call first, then ``--repeats``
calls and their median): the coupled bench's kernels alone
(``rig.bench.estimates.kernel_theta``) on the paper's drive (``ishizaki2009``, 0.1 V, seed 2009,
nonlinear) -- ``etdab`` over 300 s and ``lawson4`` over 60 s at 1 kHz; the model choice's
linearisation-error predictor (``predict_linearisation_error`` of the paper's scene, its
first-order kernel); and the pendulum solvers ``rk4`` and ``dop853`` through
``rig.simulate.simulate`` on a 6-body rod chain (their O(n) recursion), 20 s of seeded random
base input. Each pair runs one process in each tree, in alternating order, with this
interpreter; printed: each tree's median of the per-process medians and the median of the
per-pair ratios this / baseline with their range.
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.interleave import tree_pairs  # noqa: E402

HERE = Path(__file__).resolve().parent.parent

CHILD = r"""
import json, sys, time
import numpy as np
from rig import bench as rb
from rig.scene import load_scene
from rig.devices.source import generate, start_source
from rig.simulate import BaseInput, simulate
try:  # this tree's public names, else a baseline's from before they were made public
    from rig.bench.estimates import kernel_theta
    from rig.bench.run import spawn_streams
except ImportError:
    kernel_theta, spawn_streams = rb._kernel_theta, rb._spawn

reps = int(sys.argv[1])
sc = load_scene("ishizaki2009", ["acquisition.model=nonlinear"])
models = {"etdab": rb.build_model(sc, method="etdab"),
          "lawson4": rb.build_model(sc, method="lawson4")}
_, children = spawn_streams(2009)
src = models["etdab"].source
v, _ = generate(src, start_source(src, children[0]), 300_000)
chain = load_scene("rod-chain", ["pendulum.n=6"]).chain
base = BaseInput(0.5 * np.random.default_rng(2).standard_normal(2000), 0.01)
theta0 = tuple(np.linspace(0.8, -0.4, 6))


def cpu(fn):
    c = time.process_time()
    fn()
    return time.process_time() - c


cases = {
    "etdab kernel, 300 s": lambda: kernel_theta(models["etdab"], v, np.zeros(models["etdab"].n_states)),
    "lawson4 kernel, 60 s": lambda: kernel_theta(models["lawson4"], v[:60_000],
                                                  np.zeros(models["lawson4"].n_states)),
    "predictor (model choice)": lambda: rb.predict_linearisation_error(sc),
    "rk4, 6-body chain, 20 s": lambda: simulate(chain, 20.0, theta0=theta0, base=base, method="rk4"),
    "dop853, 6-body chain, 20 s": lambda: simulate(chain, 20.0, theta0=theta0, base=base,
                                                   method="dop853"),
}
for fn in cases.values():
    fn()  # warm-up: the kernels load from the cache (or compile)
res = {k: [] for k in cases}
for _ in range(reps):
    for k, fn in cases.items():
        res[k].append(cpu(fn))
print(json.dumps({k: float(np.median(x)) for k, x in res.items()}))
"""


def one_process(tree: Path, repeats: int) -> dict:
    """Per-case median CPU [s] of one process in ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", CHILD, str(repeats)], cwd=tree, env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", type=Path, required=True, help="the other source tree")
    ap.add_argument("--pairs", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per case and process")
    args = ap.parse_args(argv)
    trees = {"this": HERE, "baseline": args.baseline.resolve()}
    print(f"load average before: {os.getloadavg()}")
    res = tree_pairs(trees, args.pairs, lambda tree: one_process(tree, args.repeats))
    print(f"load average after: {os.getloadavg()}")
    print(f"\n{args.pairs} process pairs, each process the median of {args.repeats} calls per case"
          f" (CPU)\n")
    print("| case | baseline [ms] | this [ms] | ratio this / baseline, median (min - max) |")
    print("|---|---|---|---|")
    for case in res["this"][0]:
        b = np.array([r[case] for r in res["baseline"]])
        t = np.array([r[case] for r in res["this"]])
        q = t / b
        print(f"| {case} | {1e3 * np.median(b):.1f} | {1e3 * np.median(t):.1f} | "
              f"{np.median(q):.2f} ({q.min():.2f} - {q.max():.2f}) |")


if __name__ == "__main__":
    main()
