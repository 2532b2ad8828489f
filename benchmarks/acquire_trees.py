#!/usr/bin/env python3
"""The paper's linear acquisition in two source trees side by side: this tree against a baseline
(e.g. a worktree of the commit before a change), interleaved, CPU and wall time per run.

    git worktree add /tmp/base <commit>        # the code path before the change
    .venv/bin/python benchmarks/acquire_trees.py --baseline /tmp/base --pairs 4

Each pair runs ``benchmarks/acquire.py --rounds R --configs linear`` (one warm process: a warm-up
run, then R timed runs; their median) once in each tree, in alternating order (A B, B A, ...),
with this interpreter (the same numpy, numba, h5py). A process is the unit because the two trees'
modules share names. Printed: each tree's per-process medians, their median and quartiles, and
the median of the per-pair ratios this / baseline with their quartiles (a ratio within one pair
compares runs made under nearly the same load).

``--baseline-api 2026-12-01``: a baseline tree from before ``benchmarks/acquire.py`` (e.g.
c5c0225, the code path when issue 13 was filed: ``acquire(scene, seed=..., out=...)``, lawson4 for
the nonlinear model) runs the same measurement through :data:`OLD_API_WORKER` instead, the same
warm-up, timed runs and medians.

    git worktree add /tmp/start c5c0225
    .venv/bin/python benchmarks/acquire_trees.py --baseline /tmp/start --baseline-api 2026-12-01
"""

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.interleave import quart, tree_pairs  # noqa: E402

HERE = Path(__file__).resolve().parent.parent
# the paper's acquisition to a run file in a warm process through the API of 2026-12-01
# (daq.acquisition.acquire(scene, seed=..., out=..., force=...)); argv: rounds, overrides...
OLD_API_WORKER = r"""
import statistics, sys, tempfile, time
from pathlib import Path
from daq.acquisition import acquire
from rig.scene import load_scene
rounds, overrides = int(sys.argv[1]), sys.argv[2:]
with tempfile.TemporaryDirectory() as tmp:
    out = Path(tmp) / "paper.h5"
    def run():
        scene = load_scene("ishizaki2009", overrides)
        t, c = time.perf_counter(), time.process_time()
        acquire(scene, seed=2009, out=out, force=True)
        return time.process_time() - c, time.perf_counter() - t
    run()
    cpu, wall = zip(*[run() for _ in range(rounds)])
print(f"| linear | {statistics.median(cpu):.4f} [-] | {statistics.median(wall):.4f} [-] |")
"""
ROW = re.compile(r"^\| linear \| ([0-9.]+) \[[^]]*\] \| ([0-9.]+) ")


def one_process(tree: Path, rounds: int, extra: list[str], old_api: bool = False
                ) -> tuple[float, float]:
    """(median CPU, median wall) [s] per run of the paper acquisition in ``tree`` (the linear
    model unless ``extra`` sets another); ``old_api``: through :data:`OLD_API_WORKER`."""
    if old_api:
        cmd = [sys.executable, "-c", OLD_API_WORKER, str(rounds), *extra[1::2]]
    else:
        cmd = [sys.executable, str(tree / "benchmarks" / "acquire.py"), "--rounds", str(rounds),
               "--configs", "linear", *extra]
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=True)
    for line in out.stdout.splitlines():
        m = ROW.match(line)
        if m:
            return float(m.group(1)), float(m.group(2))
    raise RuntimeError(f"no result row in the output of {' '.join(cmd)}:\n{out.stdout}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", type=Path, required=True, help="the other source tree")
    ap.add_argument("--pairs", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=3, help="timed runs per process")
    ap.add_argument("--set", action="append", default=[], help="a scene override for every run")
    ap.add_argument("--baseline-api", choices=("current", "2026-12-01"), default="current",
                    help="2026-12-01: the baseline predates benchmarks/acquire.py")
    args = ap.parse_args(argv)
    extra = [a for s in args.set for a in ("--set", s)]
    trees = {"this": HERE, "baseline": args.baseline.resolve()}
    print(f"load average before: {os.getloadavg()}")
    res = tree_pairs(trees, args.pairs, lambda tree: one_process(tree, args.rounds, extra,
                                             old_api=args.baseline_api != "current"
                                             and tree == trees["baseline"]),
                     lambda p, k, r: print(f"pair {p}: {k} CPU {r[0]:.2f} s, wall {r[1]:.2f} s",
                                           flush=True))
    print(f"\n{args.pairs} pairs of processes ({args.rounds} timed runs each), interleaved; "
          "medians [quartiles]")
    print("| tree | CPU per run [s] | wall per run [s] | CPU / baseline | wall / baseline |")
    print("|---|---|---|---|---|")
    c0 = np.array([c for c, _ in res["baseline"]])
    w0 = np.array([w for _, w in res["baseline"]])
    for k in trees:
        c, w = np.array([c for c, _ in res[k]]), np.array([w for _, w in res[k]])
        qc, qw, rc, rw = quart(c), quart(w), quart(c / c0), quart(w / w0)
        print(f"| {k} ({trees[k]}) | {qc[1]:.2f} [{qc[0]:.2f}, {qc[2]:.2f}] | {qw[1]:.2f} "
              f"[{qw[0]:.2f}, {qw[2]:.2f}] | {rc[1]:.3f} [{rc[0]:.3f}, {rc[2]:.3f}] | "
              f"{rw[1]:.3f} [{rw[0]:.3f}, {rw[2]:.3f}] |")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
