#!/usr/bin/env python3
"""Set up the project's virtual environment and run its jobs, with nothing but Python 3.11 and pip.

    python3 tasks.py experiment   # the paper's experiment end to end
    python3 tasks.py test         # the test suite

The environment is ``.venv`` beside this file, created (and the package installed into it with its
test extras) on first use and refreshed when ``pyproject.toml`` changes.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PY = VENV / "bin" / "python"
STAMP = VENV / ".pendulum-daq-installed"


def run(*cmd, **kw) -> None:
    print("+", " ".join(str(c) for c in cmd), flush=True)
    subprocess.run([str(c) for c in cmd], check=True, cwd=ROOT, **kw)


def ensure_venv() -> None:
    want = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if STAMP.exists() and STAMP.read_text() == want and PY.exists():
        return
    if not PY.exists():
        try:
            run(sys.executable, "-m", "venv", VENV)
        except subprocess.CalledProcessError:
            # Debian's python3 without python3-venv has no ensurepip: make the venv bare and let
            # the system pip install into it.
            run(sys.executable, "-m", "venv", "--clear", "--without-pip", VENV)
    has_pip = subprocess.run([str(PY), "-m", "pip", "--version"], capture_output=True).returncode == 0
    pip = [PY, "-m", "pip"] if has_pip else [sys.executable, "-m", "pip", "--python", PY]
    run(*pip, "install", "--disable-pip-version-check", "-q", "-e", ".[test]")
    STAMP.write_text(want)


def main(argv: list[str]) -> int:
    jobs = {
        "experiment": [PY, "-m", "daq.cli", "model", "ishizaki2009", "--csv", "out/model.csv",
                       "--plot", "out/bode_model.png"],
        "test": [PY, "-m", "pytest", "-q"],
        "setup": None,
    }
    if len(argv) < 1 or argv[0] not in jobs:
        print(f"usage: python3 tasks.py {{{','.join(jobs)}}} [extra args]", file=sys.stderr)
        return 2
    ensure_venv()
    cmd = jobs[argv[0]]
    if cmd is None:
        return 0
    (ROOT / "out").mkdir(exist_ok=True)
    env = dict(os.environ, PYTHONHASHSEED="0")
    return subprocess.run([str(c) for c in cmd] + argv[1:], cwd=ROOT, env=env).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
