#!/usr/bin/env python3
"""Throughput of ``daq dataset``: paper experiments (30 x 100 s) per minute, side by side.

    python benchmarks/dataset_throughput.py [--runs 6] [--repeats 3] [--out DIR]

For the linear model (drive 0.1 V rms, the paper's) and a drive that needs the nonlinear one
(0.3 V rms), each repeat times, in a rotated order (interleaved, so that the host's load falls on
every configuration alike):

- ``loop``: the shell loop a user would write, ``for i in ...; do daq acquire ...; done`` (one
  process per run, acquisition only: no analysis);
- ``local-1``, ``local-2``: ``daq dataset`` with 1 and 2 local workers (acquisition *and*
  analysis of every run, manifest);
- ``dask-2``: ``daq dataset --scheduler`` on a running 2-worker ``LocalCluster`` (its start is
  not timed: it stands for an existing cluster);
- ``raw-2``: ``daq dataset`` with 2 local workers and ``[keep] analysis = false`` (the signals,
  truth and model only).

``--configs local-2,raw-2`` times only those (no cluster is started without ``dask-2``).

Every configuration makes ``--runs`` runs (different seeds) from a cold start of its command and
writes everything the runs keep (ground truth included, like ``daq acquire``). It prints, per
model and configuration, the median runs per minute over the repeats with the spread (min - max)
and the ratio of medians to the first configuration, and writes the raw times as JSON.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
LEVELS = {"linear": 0.1, "nonlinear": 0.3}


def sweep_text(level: float, runs: int, raw: bool = False) -> str:
    return (f'name = "throughput"\nseed = 11\nscene = "ishizaki2009"\n'
            f'set = ["source.level_vrms={level}"]\n[random]\ncount = {runs}\n'
            + ("[keep]\nanalysis = false\n" if raw else ""))


def time_loop(level: float, runs: int, work: Path) -> float:
    script = (f'for i in $(seq 1 {runs}); do "{PY}" -m daq.cli acquire --scene ishizaki2009 '
              f'--set source.level_vrms={level} --seed $i --out "{work}/run_$i.h5" -q '
              # a strong drive puts the spot off the PSD now and then: exit 3 without the flag
              '--allow-over-budget > /dev/null || exit 1; done')
    t = time.perf_counter()
    subprocess.run(["bash", "-c", script], check=True, cwd=ROOT)
    return time.perf_counter() - t


def time_sweep(path: Path, work: Path, args: list[str]) -> float:
    t = time.perf_counter()
    subprocess.run([PY, "-m", "daq.cli", "dataset", str(path), "--out", str(work / "ds"), *args],
                   check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench" / "dataset_throughput.json")
    ap.add_argument("--configs", default="loop,local-1,local-2,dask-2,raw-2")
    a = ap.parse_args()
    import contextlib

    configs = a.configs.split(",")
    times = {m: {c: [] for c in configs} for m in LEVELS}
    if "dask-2" in configs:
        from distributed import LocalCluster

        cluster_cm = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0")
    else:
        cluster_cm = contextlib.nullcontext()
    with cluster_cm as cluster:
        for r in range(a.repeats):
            for model, level in LEVELS.items():
                order = configs[r % len(configs):] + configs[:r % len(configs)]
                for c in order:
                    work = Path(tempfile.mkdtemp(prefix="dataset-bench-"))
                    try:
                        path = work / "sweep.toml"
                        path.write_text(sweep_text(level, a.runs, raw=c.startswith("raw")))
                        if c == "loop":
                            dt = time_loop(level, a.runs, work)
                        elif c == "dask-2":
                            dt = time_sweep(path, work, ["--scheduler",
                                                         cluster.scheduler_address])
                        else:
                            dt = time_sweep(path, work, ["--workers", c[-1]])
                    finally:
                        shutil.rmtree(work, ignore_errors=True)
                    times[model][c].append(dt)
                    print(f"repeat {r + 1} {model:9s} {c:8s} {dt:7.1f} s "
                          f"({a.runs / dt * 60:.1f} runs/min)", flush=True)
    print(f"\nratios are to {configs[0]}")
    print(f"\npaper experiments (30 x 100 s) per minute, {a.runs} runs per command, median "
          f"(min - max) of {a.repeats} interleaved repeats")
    print(f"| model | {' | '.join(configs)} |")
    print("|---|" + "---|" * len(configs))
    for model in LEVELS:
        rates = {c: [a.runs / t * 60 for t in times[model][c]] for c in configs}
        base = statistics.median(rates[configs[0]])
        cells = [f"{statistics.median(v):.1f} ({min(v):.1f} - {max(v):.1f}), "
                 f"x{statistics.median(v) / base:.2f}" for v in rates.values()]
        print(f"| {model} ({LEVELS[model]} V) | {' | '.join(cells)} |")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps({"runs": a.runs, "repeats": a.repeats, "levels": LEVELS,
                                 "seconds": times}, indent=1))
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
