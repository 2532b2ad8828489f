"""No traceback reaches a CLI user: every failure is ``Error: <one line>`` and exit status 1
(``--debug`` keeps the traceback); a run that is not what was asked (over its error budget,
saturated) ends with a WARNING and exit status 3 unless ``--allow-over-budget``. Real CLI in
subprocesses."""

import os
import signal
import subprocess
import sys

import pytest

from faults import record_fault, record_inputs
from tmpfs import mounted

SHORT = ["--scene", "ishizaki2009", "--records", "2", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5", "--seed", "1"]


def daq(*args, cwd, timeout=120):
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _one_error_line(res, *, contains):
    assert res.returncode == 1, res.stdout + res.stderr
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), res.stderr
    assert contains in lines[0], lines[0]


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("errors")
    assert daq("acquire", *SHORT, "--out", "run.h5", "-q", cwd=d).returncode == 0
    return d / "run.h5"


CASES = [
    (["scene", "show", "{junk}"], "is not a TOML text file (byte 2 is not UTF-8)"),
    (["model", "ishizaki2009", "--set", "pendulum.r1_m=1e9"], "a rigid body needs J1 >= 0"),
    (["model", "ishizaki2009", "--set", "pendulum.eps=-5"], "pendulum.eps = -5.0 is invalid"),
    (["acquire", "--scene", "ishizaki2009", "--records", "1", "--duration", "1e8", "--out",
      "x.h5"], "which need about 12 TB of memory"),
    (["analyze", "{run}", "--lines", "800", "--span", "10"], "longer than a record"),
    (["inspect", "{junk}"], "is not a readable HDF5 file"),
]


def test_lines_too_coarse_for_a_fit_are_noted_not_a_failure(run_file, tmp_path):
    """One 0.5 Hz line per band: the analysis is made, the fits it cannot make are named."""
    res = daq("analyze", run_file, "--span", "0.5", "--lines", "1", cwd=tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "Traceback" not in res.stderr
    assert "H_t direct fit not made: 0 lines in (1.5, 4.0) Hz for 8 real parameters" in res.stdout


@pytest.mark.parametrize("args, contains", CASES)
def test_a_failure_is_one_line_and_exit_status_1(run_file, tmp_path, args, contains):
    junk = tmp_path / "junk.toml"
    junk.write_bytes(b"\x00\x01\xff\xfe binary junk")
    res = daq(*(a.format(junk=junk, run=run_file) for a in args), cwd=tmp_path)
    _one_error_line(res, contains=contains)
    record_inputs("bad command lines (CLI cases)", 1)


@pytest.fixture
def full_disk(tmp_path):
    """A real 4 MiB tmpfs, filled to the last byte by another file."""
    with mounted(tmp_path / "disk", "4m") as d:
        (d / "old.csv").write_text("an earlier output\n")
        with open(d / "filler", "wb", buffering=0) as fh:
            try:
                while True:
                    fh.write(b"\0" * 4096)
            except OSError:
                pass
        yield d


def test_a_full_disk_is_one_line_for_model_and_analyze_and_loses_nothing(run_file, full_disk,
                                                                          tmp_path):
    before = set(os.listdir(full_disk))
    for args in (["model", "ishizaki2009", "--csv", full_disk / "m.csv"],
                 ["model", "ishizaki2009", "--csv", full_disk / "old.csv", "--force"],
                 ["analyze", run_file, "--spectra", full_disk / "s.h5"]):
        res = daq(*args, cwd=tmp_path)
        _one_error_line(res, contains="disk full")
        assert set(os.listdir(full_disk)) == before  # no partial output left behind
        assert (full_disk / "old.csv").read_text() == "an earlier output\n"
    res = daq("--debug", "model", "ishizaki2009", "--csv", full_disk / "m.csv", cwd=tmp_path)
    assert res.returncode == 1 and "Traceback" in res.stderr  # --debug keeps it
    assert set(os.listdir(full_disk)) == before
    record_fault("disk full during daq model / daq analyze outputs", records_lost=0,
                 outcome="one line 'disk full ...', exit 1; no partial output, earlier file "
                         "kept")


def test_a_run_not_as_asked_warns_and_exits_3_unless_allowed(tmp_path):
    args = [*SHORT, "--set", "source.level_vrms=2", "--set", "acquisition.model=linear", "-q"]
    res = daq("acquire", *args, "--out", "a.h5", cwd=tmp_path)
    assert res.returncode == 3, res.stderr
    warnings = [s for s in res.stderr.splitlines() if s.startswith("WARNING: ")]
    assert warnings[0].startswith("WARNING: the run's estimated error ")
    assert "exceeds its error budget 0.01 (acquisition.error_budget)" in warnings[0]
    assert any("beyond its sensor's range, more than 0.1 %" in w for w in warnings)
    assert res.stdout.startswith("wrote a.h5")  # the file is written all the same
    res = daq("acquire", *args, "--out", "b.h5", "--allow-over-budget", cwd=tmp_path)
    assert res.returncode == 0 and "WARNING: the run's estimated error" in res.stderr
    res = daq("acquire", *SHORT, "-q", "--out", "c.h5", cwd=tmp_path)
    assert res.returncode == 0 and "WARNING" not in res.stderr
