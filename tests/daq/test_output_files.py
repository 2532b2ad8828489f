"""Output files: they take the user's umask (also those written under a temporary name), a run
file must have an HDF5 extension, a --force replacement refuses while another process holds the
target, and ``daq simulate --method`` offers every integrator. Real CLI in subprocesses."""

import os
import signal
import stat
import subprocess
import sys
import time

import h5py
import pytest

SHORT = ["--scene", "ishizaki2009", "--records", "2", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5", "--seed", "1", "-q"]
LONG = ["--scene", "ishizaki2009", "--records", "5000", "--duration", "5", "--rate", "100",
        "--set", "acquisition.settle_s=5", "--set", "acquisition.model=linear", "--seed", "2",
        "-q"]


def _child(umask):
    def setup():
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.umask(umask)
    return setup


def daq(*args, cwd, umask=0o022, timeout=120):
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=_child(umask))


def _mode(p):
    return stat.S_IMODE(os.stat(p).st_mode)


def test_every_output_takes_the_umask(tmp_path):
    for args in (["acquire", *SHORT, "--out", "run.h5"],
                 ["acquire", *SHORT, "--out", "run.h5", "--force"],  # replaced via a partial
                 ["model", "ishizaki2009", "--csv", "m.csv", "--plot", "m.png"],
                 ["analyze", "run.h5", "--csv", "f.csv", "--report", "r.md", "--spectra",
                  "s.h5"],
                 ["simulate", "double-rod", "--duration", "1", "--method", "rk4", "--dt", "0.01",
                  "--out", "t.h5"]):
        res = daq(*args, cwd=tmp_path, umask=0o027)
        assert res.returncode == 0, res.stderr
    for name in ("run.h5", "m.csv", "m.png", "f.csv", "r.md", "s.h5", "t.h5"):
        assert _mode(tmp_path / name) == 0o640, name


def test_a_run_file_needs_an_hdf5_extension(tmp_path):
    res = daq("acquire", *SHORT, "--out", "x.csv", cwd=tmp_path)
    assert res.returncode == 1 and res.stderr.strip() == (
        "Error: run file 'x.csv': unknown extension '.csv'; a run file is HDF5: expected .h5, "
        ".hdf5, .nxs")
    assert list(tmp_path.iterdir()) == []


def _start(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_child(0o022))


def _wait_for_records(path, proc, n=2, timeout=120):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        try:
            with h5py.File(path, "r", swmr=True) as f:
                if f["entry/records_complete"][()] >= n:
                    return
        except (OSError, KeyError):
            pass
        time.sleep(0.05)
    raise AssertionError("no records")


@pytest.mark.parametrize("first_forces", [False, True])
def test_a_force_replacement_refuses_while_another_run_holds_the_target(tmp_path, first_forces):
    out = tmp_path / "run.h5"
    if first_forces:  # the first run is itself replacing an existing file
        assert daq("acquire", *SHORT, "--out", out, cwd=tmp_path).returncode == 0
    first = _start("acquire", *LONG, "--out", out, *(["--force"] if first_forces else []),
                   cwd=tmp_path)
    try:
        partial = None
        if first_forces:
            t0 = time.monotonic()
            while partial is None and time.monotonic() - t0 < 120:
                partial = next(iter(tmp_path.glob("run.partial-*.h5")), None)
                time.sleep(0.05)
        _wait_for_records(partial or out, first)
        res = daq("acquire", *SHORT, "--out", out, "--force", cwd=tmp_path)
        assert res.returncode == 1, res.stderr
        assert res.stderr.strip() == (f"Error: output {str(out)!r} is held by another process (a "
                                      "run writing or replacing it); wait for it to end or "
                                      "choose another path")
        assert first.poll() is None  # the first run goes on
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=60)
    assert first.returncode == 130


def test_simulate_offers_every_integrator(tmp_path):
    res = daq("simulate", "double-rod", "--duration", "1", "--method", "etd3", "--dt", "0.01",
              "--out", "e.csv", cwd=tmp_path)
    assert res.returncode == 0 and "method etd3" in res.stdout, res.stderr
    res = daq("simulate", "double-rod", "--duration", "1", "--method", "etd3m", "--dt", "0.01",
              "--out", "m.csv", cwd=tmp_path)
    assert res.returncode == 2 and "use --method etd3" in res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "m.csv").exists()
    help_text = daq("simulate", "--help", cwd=tmp_path).stdout
    for m in ("dop853", "rk4", "gauss4", "midpoint", "etd3", "etd3m", "linear"):
        assert m in help_text
