#!/usr/bin/env python3
"""The tolerance Monte Carlo of ``daq design``: designs evaluated per minute on one core, the
batched exact model (rig.design.tolerance.monte_carlo: N pendulums at once) against a plain loop
over the same draws (rig.design.tolerance.evaluate_loop: one rig.chain.Chain per sample, its
direct solve, pencil eigenvalues and anti-resonance problem), interleaved in one run.

    .venv/bin/python benchmarks/design_mc.py                  # ~1 minute
    .venv/bin/python benchmarks/design_mc.py --samples 20000 --loop 500 --rounds 7

Each round times (CPU, time.process_time) the batched Monte Carlo of ``--samples`` designs and
the loop over the first ``--loop`` of them, alternating which goes first; prints medians and
quartiles of designs per minute and the per-round ratio, and checks that the two agree on those
samples (largest difference per output). BLAS and OpenMP are held to one thread.
"""

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.interleave import quart  # noqa: E402
from rig.design import design, parse_targets  # noqa: E402
from rig.design.tolerance import evaluate_loop, monte_carlo, parse_tolerances  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", default=str(ROOT / "examples/design/suppression_targets.toml"))
    ap.add_argument("--tolerances", default=str(ROOT / "examples/design/tolerances.toml"))
    ap.add_argument("--samples", type=int, default=10000)
    ap.add_argument("--loop", type=int, default=400, help="samples of the plain loop per round")
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args(argv)
    d = design(parse_targets(Path(a.targets).read_text(), source=a.targets))
    tol = parse_tolerances(Path(a.tolerances).read_text())
    per_min = {"batched": [], "loop": []}
    for r in range(a.rounds):
        order = ("batched", "loop") if r % 2 == 0 else ("loop", "batched")
        for name in order:
            if name == "batched":
                t0 = time.process_time()
                mc = monte_carlo(d, tol, samples=a.samples, seed=r)
                dt = time.process_time() - t0
                per_min[name].append(60 * a.samples / dt)
            else:
                draws = monte_carlo(d, tol, samples=a.loop, seed=r).samples
                t0 = time.process_time()
                ref = evaluate_loop(d, draws)
                dt = time.process_time() - t0
                per_min[name].append(60 * a.loop / dt)
        first = {k: v[: a.loop] for k, v in mc.samples.items()}
        loop = evaluate_loop(d, first)
        diff = {k: float(np.nanmax(np.abs(loop[k] - mc.outputs[k][: a.loop]))) for k in loop}
    print(f"design {a.targets}, tolerances {a.tolerances}, {a.rounds} rounds, one thread")
    for name, v in per_min.items():
        q = quart(np.array(v))
        print(f"  {name:8s} designs/minute (CPU): median {q[1]:,.0f} [{q[0]:,.0f}, {q[2]:,.0f}]")
    ratio = np.array(per_min["batched"]) / np.array(per_min["loop"])
    q = quart(ratio)
    print(f"  batched / loop per round: median {q[1]:.1f} [{q[0]:.1f}, {q[2]:.1f}]")
    print("  largest |batched - loop| on the last round's first samples: "
          + ", ".join(f"{k} {v:.2g}" for k, v in diff.items()))
    del ref


if __name__ == "__main__":
    main()
