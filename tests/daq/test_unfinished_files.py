"""A run file still being written, and one whose writer was killed: ``daq view`` says which,
``daq check --repair`` marks a killed writer's file interrupted (its records kept), and a check
line says how many more problems or notes it has (all in --json). Real CLI in subprocesses,
each bounded in time."""

import json
import os
import signal
import subprocess
import sys
import time

import h5py

LONG = ["ishizaki2009", "--records", "5000", "--duration", "5", "--rate", "100",
        "--set", "acquisition.settle_s=5", "--set", "acquisition.model=linear", "--seed", "2",
        "-q", "--realtime", "--speed", "20"]


def daq(*args, cwd, timeout=180):
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


def _records(path) -> int:
    with h5py.File(path, "r", swmr=True) as f:
        return int(f["entry/records_complete"][()])


def _wait_for_records(path, proc, n=2, timeout=120):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        try:
            if _records(path) >= n:
                return
        except (OSError, KeyError):
            pass
        time.sleep(0.1)
    raise AssertionError("no records")


def test_view_check_and_repair_tell_a_live_writer_from_a_killed_one(tmp_path):
    out = tmp_path / "run.h5"
    writer = subprocess.Popen([sys.executable, "-m", "daq.cli", "acquire", *LONG, "--out", out],
                              cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    try:
        _wait_for_records(out, writer)
        res = daq("view", out, "--rrd", "live.rrd", cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        assert "(acquiring (still being written))" in res.stdout
        assert "writer stopped" not in res.stdout
        res = daq("check", out, "--repair", cwd=tmp_path)  # never while the writer lives
        assert "marked" not in res.stdout and "acquiring" in res.stdout
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.communicate(timeout=60)
    n = _records(out)
    res = daq("view", out, "--rrd", "dead.rrd", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "its writer stopped without closing it" in res.stdout

    res = daq("check", out, "--repair", cwd=tmp_path)
    assert f"marked {out} interrupted" in res.stdout and f"its {n} finished records kept" in (
        res.stdout)
    assert res.returncode == 0, res.stdout + res.stderr
    line = [s for s in res.stdout.splitlines() if s.startswith(f"{out}: ")][0]
    assert "OK run, interrupted" in line and f"{n} of 5000 records verify" in line
    res = daq("check", out, "--json", cwd=tmp_path)
    (d,) = json.loads(res.stdout)
    assert d["status"] == "interrupted" and d["records_valid"] == n
    with h5py.File(out, "r") as f:  # plainly openable, the records kept
        assert f["entry/status"][()].decode().strip("\x00 ") == "interrupted"
        assert f["entry/data/a"].shape[0] >= n
    res = daq("check", out, "--repair", cwd=tmp_path)  # a second repair changes nothing
    assert f"marked {out}" not in res.stdout and "OK run, interrupted" in res.stdout


def test_a_check_line_says_how_many_more_notes_and_where_they_are(tmp_path):
    res = daq("acquire", *LONG[:-3], "--records", "2", "--out", "run.h5", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    # cut the count: a file that is sound but shorter than planned, and holds extra rows
    with h5py.File(tmp_path / "run.h5", "r+") as f:
        f["entry/records_complete"][()] = 1
        f["entry/status"][()] = b"interrupted"
    res = daq("check", "run.h5", cwd=tmp_path)
    (d,) = json.loads(daq("check", "run.h5", "--json", cwd=tmp_path).stdout)
    extra = d["problems"] or d["notes"]
    assert len(extra) >= 2, d
    n = len(extra) - 1
    assert f"(and {n} more {'problem' if d['problems'] else 'note'}" in res.stdout
    assert "--json lists them all" in res.stdout
    assert "+1 more" not in res.stdout
    assert os.path.getsize(tmp_path / "run.h5") > 0
