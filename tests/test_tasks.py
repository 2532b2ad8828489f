"""``python3 tasks.py``: what a fresh clone's first command says while it installs."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_first_install_is_announced_and_a_failed_one_ends_in_a_sentence(tmp_path):
    """A copy of tasks.py beside a package pip cannot build (its build backend does not exist):
    the line saying what is installed comes first, pip's own messages follow, and the job ends
    with one line saying what failed and what to do, not a traceback of tasks.py."""
    (tmp_path / "tasks.py").write_bytes((ROOT / "tasks.py").read_bytes())
    (tmp_path / "pyproject.toml").write_text('[build-system]\nrequires = []\n'
                                             'build-backend = "no_such_backend"\n')
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(tmp_path / ".venv")],
                   check=True, timeout=120)
    res = subprocess.run([sys.executable, "tasks.py", "experiment"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 1
    assert res.stdout.splitlines()[0] == ("installing pendulum-daq and its dependencies into "
                                          ".venv (once, a few minutes)")
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("pip could not install pendulum-daq into .venv (exit status ")
    assert last.endswith("its messages are above); fix that and run this again")
    assert 'tasks.py", line' not in res.stderr
    assert "installed in" not in res.stdout and not (tmp_path / "out").exists()
