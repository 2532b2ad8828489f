"""The real command line in a subprocess, and a small run file made with it, for the CLI tests
(imported by test modules: pytest puts this directory on sys.path)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: A short linear-model acquisition: 2 records of 10 s at 100 Hz after 5 s of settling.
FAST = ["--records", "2", "--duration", "10", "--rate", "100", "--seed", "1",
        "--set", "acquisition.settle_s=5", "--set", "acquisition.model=linear", "-q"]


def daq(*args, cwd, timeout=180):
    """``python -m daq.cli ARGS`` in ``cwd``, bounded by ``timeout`` [s]; its CompletedProcess."""
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


def fast_run(d: Path) -> Path:
    """``daq acquire ishizaki2009`` with :data:`FAST` into ``d/run.h5``; that path."""
    res = daq("acquire", "ishizaki2009", *FAST, "--out", "run.h5", cwd=d, timeout=300)
    assert res.returncode == 0, res.stderr
    return d / "run.h5"
