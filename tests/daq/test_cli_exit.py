"""The ``daq`` console script (daq.cli.run): exit statuses and output survive its fast exit."""

import os
import subprocess
import sys

import pytest


def _daq(*args, env=None):
    return subprocess.run([sys.executable, "-m", "daq.cli", *args], capture_output=True,
                          text=True, env=env)


@pytest.mark.parametrize("full_exit", ["", "1"])
def test_output_and_exit_status_are_kept(full_exit):
    env = dict(os.environ, PENDULUM_DAQ_FULL_EXIT=full_exit)
    ok = _daq("--version", env=env)
    assert ok.returncode == 0 and "version 0." in ok.stdout
    bad = _daq("scene", "show", "no-such-scene", env=env)
    assert bad.returncode == 1 and "no-such-scene" in bad.stderr
    usage = _daq("no-such-command", env=env)
    assert usage.returncode == 2 and "No such command" in usage.stderr


def test_every_command_is_registered_when_run_as_a_module():
    out = _daq("check", "--help")  # the last command defined
    assert out.returncode == 0 and "Check the files PATHS" in out.stdout
    gone = _daq("bench", "--help")  # the benchmark runs from the source tree: benchmarks/run.py
    assert gone.returncode == 2 and "No such command" in gone.stderr
