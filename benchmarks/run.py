#!/usr/bin/env python3
"""The work-precision benchmark (benchmarks/work_precision.py computes, benchmarks/report.py
renders), run from the source tree (it is not part of the installed package).

    python benchmarks/run.py --quick                 # a few minutes
    python benchmarks/run.py --full --out out/bench  # the issue's durations (about half an hour)
    python benchmarks/run.py --quick --scene paper --scene chains

Writes OUT/bench.md, OUT/bench.json and OUT/bench_<scene>.png (default OUT: out/bench).
Run it with the project's environment (``.venv/bin/python benchmarks/run.py ...``).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.report import bench  # noqa: E402

if __name__ == "__main__":
    bench.main(args=sys.argv[1:], prog_name="benchmarks/run.py")
