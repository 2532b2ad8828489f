#!/usr/bin/env python3
"""CPU per run: a shell-style loop of ``daq acquire`` against ``daq dataset --workers 1``.

    python benchmarks/dataset_cpu.py

Linear paper runs (30 x 100 s), 4 per command, two interleaved pairs. Prints the CPU time of the
whole command per run (children included, ``getrusage``) and, for the sweep, each run's own CPU
in its worker (``journal.jsonl``). CPU time is less sensitive than wall time to a shared host.
"""

from __future__ import annotations

import json
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
N = 4


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(kind: str, work: Path, warm: list) -> None:
    quiet = dict(check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if kind == "loop":
        for i in range(N):
            subprocess.run([PY, "-m", "daq.cli", "acquire", "--scene", "ishizaki2009", "--seed",
                            str(i), "--out", str(work / f"r{i}.h5"), "-q"], **quiet)
        return
    (work / "s.toml").write_text(f'seed = 1\nscene = "ishizaki2009"\n[random]\ncount = {N}\n')
    subprocess.run([PY, "-m", "daq.cli", "dataset", str(work / "s.toml"), "--out",
                    str(work / "ds"), "--workers", "1"], **quiet)
    warm += [json.loads(line)["cpu_s"] for line in open(work / "ds" / "journal.jsonl")]


def main() -> int:
    out = {"loop": [], "sweep": [], "warm": []}
    for rep in range(2):
        for kind in (("loop", "sweep") if rep == 0 else ("sweep", "loop")):
            work = Path(tempfile.mkdtemp(prefix="dataset-cpu-"))
            try:
                c0, t0 = children_cpu(), time.perf_counter()
                run(kind, work, out["warm"])
                c, t = children_cpu() - c0, time.perf_counter() - t0
            finally:
                shutil.rmtree(work, ignore_errors=True)
            out[kind].append((c / N, t / N))
            print(f"{kind}: CPU {c / N:.2f} s/run, wall {t / N:.2f} s/run", flush=True)
    print("warm runs' own CPU (acquire + analyse + write), s:",
          [round(x, 2) for x in out["warm"]], "median", round(statistics.median(out["warm"]), 2))
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
