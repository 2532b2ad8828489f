#!/usr/bin/env python3
"""The work-precision benchmark as a script: the same code as ``daq bench`` (daq/bench_cmd.py,
rig/benchmark.py), with the same options.

    python benchmarks/run.py --quick                 # a few minutes
    python benchmarks/run.py --full --out out/bench  # the issue's durations (about half an hour)
    python benchmarks/run.py --quick --scene paper --scene chains

Writes OUT/bench.md, OUT/bench.json and OUT/bench_<scene>.png (default OUT: out/bench).
Run it with the project's environment (``.venv/bin/python benchmarks/run.py ...``).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from daq.bench_cmd import bench  # noqa: E402

if __name__ == "__main__":
    bench.main(args=sys.argv[1:], prog_name="benchmarks/run.py")
