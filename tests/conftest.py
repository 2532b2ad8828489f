"""Shared test setup: designed filters are cached in a per-session directory, never in the user's
cache (daq.antialias.design_cache_dir)."""

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

# rerun's viewer and SDK read their analytics setting from $XDG_CONFIG_HOME/rerun: the tests use a
# configuration of their own with analytics disabled (the user's is left alone).
_RERUN_CONFIG = tempfile.mkdtemp(prefix="pendulum-daq-test-config-")
atexit.register(shutil.rmtree, _RERUN_CONFIG, ignore_errors=True)
os.environ["XDG_CONFIG_HOME"] = _RERUN_CONFIG
_VIEWER = Path(sys.executable).parent / "rerun"
if _VIEWER.exists():
    subprocess.run([str(_VIEWER), "analytics", "disable"], capture_output=True, timeout=60)


@pytest.fixture(autouse=True, scope="session")
def _design_cache(tmp_path_factory):
    old = os.environ.get("PENDULUM_DAQ_CACHE")
    os.environ["PENDULUM_DAQ_CACHE"] = str(tmp_path_factory.mktemp("design-cache"))
    yield
    if old is None:
        os.environ.pop("PENDULUM_DAQ_CACHE", None)
    else:
        os.environ["PENDULUM_DAQ_CACHE"] = old


def pytest_sessionfinish(session, exitstatus):
    """Write the reliability tests' record (tests/faults.py) for the README's table."""
    from faults import write_report

    write_report()
