#!/usr/bin/env python3
"""The linearisation-error predictor (:func:`rig.bench.selection.predict_linearisation_error`,
which :func:`rig.bench.select_model` runs once per scene: every run of a sweep over drive levels
pays it) on the paper's scene, CPU per prediction, each made for a scene of its own (the level
times 1 + k 1e-6); with ``--baseline TREE`` the same in another checkout (e.g. a ``git worktree``
of an earlier commit), in alternating processes, with the per-pair ratio and the largest relative
difference of the two trees' predictions.

    .venv/bin/python benchmarks/predictor.py
    git worktree add /tmp/before <rev>; .venv/bin/python benchmarks/predictor.py --baseline /tmp/before
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.interleave import tree_pairs  # noqa: E402

_CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from rig.bench.selection import predict_linearisation_error
from rig.scene import load_scene
predict_linearisation_error(load_scene("ishizaki2009"))  # compiled code loaded
cpu = []
for k in range(int(sys.argv[2])):
    sc = load_scene("ishizaki2009", [f"source.level_vrms={0.1 * (1 + 1e-6 * (k + 1))!r}"])
    t = time.process_time()
    r = predict_linearisation_error(sc)
    cpu.append(time.process_time() - t)
print(json.dumps({"cpu": float(np.median(cpu)), "relative_rms_theta": r["relative_rms_theta"],
                  "upper": r["upper"]}))
"""


def measure(tree: Path, n: int) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(tree), str(n)], check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", type=Path, help="another checkout to compare with")
    ap.add_argument("--pairs", type=int, default=5, help="processes per tree (alternating)")
    ap.add_argument("--predictions", type=int, default=9, help="fresh scenes per process")
    args = ap.parse_args(argv)
    if args.baseline is None:
        got = {"this": [measure(ROOT, args.predictions) for _ in range(args.pairs)]}
    else:
        got = tree_pairs({"this": ROOT, "baseline": args.baseline.resolve()}, args.pairs,
                         lambda tree: measure(tree, args.predictions))
    for k, runs in got.items():
        cpu = [r["cpu"] for r in runs]
        name = "this tree" if k == "this" else k
        print(f"{name}: CPU per prediction, median of {args.pairs} processes (each the median of "
              f"{args.predictions}): {statistics.median(cpu) * 1e3:.1f} ms "
              f"[{min(cpu) * 1e3:.1f}, {max(cpu) * 1e3:.1f}]")
    if "baseline" in got:
        ratio = [a["cpu"] / b["cpu"] for a, b in zip(got["this"], got["baseline"])]
        a, b = got["this"][-1], got["baseline"][-1]
        diff = max(abs(x - y) / abs(y) for x, y in zip(a["relative_rms_theta"],
                                                        b["relative_rms_theta"]))
        print(f"this tree / baseline per pair: median {statistics.median(ratio):.3f} "
              f"[{min(ratio):.3f}, {max(ratio):.3f}]; predictions within {diff:.1g} (relative)")


if __name__ == "__main__":
    main()
