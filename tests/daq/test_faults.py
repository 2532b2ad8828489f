"""Faults survived by ``daq acquire``, each injected into the real CLI in a subprocess: SIGINT,
SIGTERM and SIGHUP end the run cleanly (a message, a valid file marked interrupted); SIGKILL
leaves every finished record readable and ``daq inspect --repair`` makes the file plainly
openable; a full disk (a real one: a small tmpfs) ends the run with one line naming the partial
file and what it holds; the preflight refuses a run that cannot fit, before simulating. In every
case the finished records are bit-identical to a run of as many records with the same seed."""

import json
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from daq.check import check_file
from daq.hdf5 import read_run
from faults import record_fault
from tmpfs import mounted

LONG = ["--scene", "ishizaki2009", "--duration", "5", "--rate", "100",
        "--set", "acquisition.settle_s=5", "--set", "acquisition.model=linear", "--seed", "4"]


def _start(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def daq(*args, cwd, timeout=120):
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for_records(path, n, proc, timeout=120):
    """Wait until the writer has committed ``n`` records (read as a SWMR follower)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        if path.exists():
            try:
                with h5py.File(path, "r", swmr=True) as f:
                    if f["entry/records_complete"][()] >= n:
                        return
            except (OSError, KeyError):
                pass  # not created yet
        time.sleep(0.05)
    raise AssertionError("the writer did not get there")


def _same_as_a_fresh_run(path, tmp_path):
    """The records of ``path`` equal those of a run of as many records with the same seed."""
    got = read_run(path)
    ref = tmp_path / "reference.h5"
    res = daq("acquire", *LONG, "--records", got.records, "--out", ref, "-q", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    want = read_run(ref)
    for c in ("a", "x", "y"):
        np.testing.assert_array_equal(got.codes[c], want.codes[c])
    for k in want.truth:
        np.testing.assert_array_equal(got.truth[k], want.truth[k])
    return got.records


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_ends_acquire_cleanly_with_every_finished_record(tmp_path, sig):
    out = tmp_path / "run.h5"
    proc = _start("acquire", *LONG, "--records", 3000, "--out", out, "-q", cwd=tmp_path)
    _wait_for_records(out, 2, proc)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    name = signal.Signals(sig).name
    assert proc.returncode == 128 + sig, stderr
    fc = check_file(out)
    n = fc.records_valid
    assert stderr.strip() == (f"interrupted ({name}) after {n} of 3000 records; {out} holds them "
                              "(status interrupted)")
    assert fc.ok and fc.status == "interrupted" and fc.records_complete == n >= 2
    with h5py.File(out, "r") as f:  # closed: any reader opens it
        assert f["entry/message"][()].strip(b"\0 ").decode() == (
            "SIGINT received (Ctrl-C)" if sig == signal.SIGINT else f"{name} received")
    assert _same_as_a_fresh_run(out, tmp_path) == n
    record_fault(f"{name} during daq acquire", records_lost=0,
                 outcome=f"'interrupted ({name}) after N of M records; FILE holds them', exit "
                         f"{128 + sig}, file closed, status interrupted")


def test_sigkill_leaves_every_finished_record_and_repair_makes_the_file_plainly_openable(
        tmp_path):
    out = tmp_path / "run.h5"
    proc = _start("acquire", *LONG, "--records", 3000, "--out", out, "-q", cwd=tmp_path)
    _wait_for_records(out, 2, proc)
    proc.kill()
    proc.communicate(timeout=60)
    fc = check_file(out)
    assert fc.ok and fc.status == "acquiring" and fc.records_valid >= 2
    assert any("marked open for writing" in n for n in fc.notes)
    res = daq("check", out, cwd=tmp_path)
    assert res.returncode == 0 and "OK run, acquiring" in res.stdout
    with pytest.raises(OSError):
        h5py.File(out, "r")  # HDF5's mark of an unclosed writer
    copy = tmp_path / "copy.h5"
    shutil.copy(out, copy)
    res = daq("inspect", out, "--repair", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(f"cleared the open-for-writing mark of {out}")
    res = daq("check", "--repair", copy, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines()[0] == f"cleared the open-for-writing mark of {copy}"
    assert f"marked {copy} interrupted" in res.stdout and "OK run, interrupted" in res.stdout
    for p in (out, copy):
        with h5py.File(p, "r") as f:
            assert f["entry/records_complete"][()] == fc.records_valid
            assert f["entry/status"][()].decode().strip("\x00 ") == "interrupted"
    if shutil.which("h5dump"):
        assert subprocess.run(["h5dump", "-H", str(out)], capture_output=True).returncode == 0
    assert _same_as_a_fresh_run(out, tmp_path) == fc.records_valid
    record_fault("SIGKILL during daq acquire", records_lost=0,
                 outcome="every finished record readable (SWMR); check: OK acquiring; "
                         "check --repair / inspect --repair: plainly openable, marked "
                         "interrupted, records kept")


def test_a_corrupt_file_left_by_a_killed_writer_is_named_without_a_hang(tmp_path):
    """A file still marked open for writing is read as SWMR, whose reader retries bad metadata
    with doubling sleeps (days for HDF5's default 100 attempts): bytes flipped in its metadata
    are named within seconds."""
    out = tmp_path / "run.h5"
    proc = _start("acquire", *LONG, "--records", 3000, "--out", out, "-q", cwd=tmp_path)
    _wait_for_records(out, 2, proc)
    proc.kill()
    proc.communicate(timeout=60)
    src = out.read_bytes()
    damaged = []
    for i, at in enumerate(np.random.default_rng(3).integers(48, 4096, 16)):
        data = bytearray(src)
        data[at] ^= 0xFF
        damaged.append(tmp_path / f"d{i}.h5")
        damaged[-1].write_bytes(bytes(data))
    t = time.perf_counter()
    res = daq("check", "--json", *damaged, cwd=tmp_path, timeout=120)
    assert time.perf_counter() - t < 60
    got = json.loads(res.stdout)
    assert len(got) == 16 and any(not g["ok"] for g in got)
    whole = read_run(out)
    for g in got:  # a file called sound holds the same records
        if g["ok"]:
            np.testing.assert_array_equal(read_run(g["path"]).codes["a"], whole.codes["a"])
    record_fault("metadata bytes flipped in a killed writer's file (16 places)", records_lost=0,
                 outcome="each named corrupt, or read with the same records; all 16 in one "
                         "daq check under 60 s, never a hang")


@pytest.fixture
def small_disk(tmp_path):
    """A real 48 MiB file system (tmpfs), unmounted afterwards."""
    with mounted(tmp_path / "disk", "48m",
                 why=": the full disk is tested on a real small file system only") as d:
        yield d


def test_a_full_disk_ends_the_run_with_one_line_naming_the_partial_file(small_disk, tmp_path):
    """The disk (a 48 MiB tmpfs, room for the run when it starts) is filled by another file
    while the run writes: the write that fails is reported, the records before it are kept."""
    out = small_disk / "run.h5"
    proc = _start("acquire", *LONG, "--records", 1500, "--out", out, "-q", cwd=tmp_path)
    _wait_for_records(out, 2, proc)
    with open(small_disk / "filler", "wb", buffering=0) as fh:
        with pytest.raises(OSError):
            while True:
                fh.write(b"\0" * 65536)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    fc = check_file(out)
    n = fc.records_valid
    assert lines[0].startswith(f"Error: disk full after {n} of 1500 records: {out} holds {n} "
                               "finished records of 1500, each verified (status ")
    assert fc.ok and fc.status in ("failed", "acquiring") and n >= 2, repr(fc)
    (small_disk / "filler").unlink()
    if not fc.notes or "marked open" not in " ".join(fc.notes):
        with h5py.File(out, "r"):
            pass
    else:
        assert daq("inspect", out, "--repair", cwd=tmp_path).returncode == 0
    assert _same_as_a_fresh_run(out, tmp_path) == n
    record_fault("disk full during daq acquire (a real tmpfs filled by another file)",
                 records_lost=0, outcome="one line: 'disk full after N of M records: FILE "
                                         "holds N finished records ...', exit 1")


@pytest.mark.parametrize("args, message", [
    (["--records", "1", "--duration", "1e8"], "acquisition.record_s = 1e+08 s at 100 Hz gives "
                                              "records of 10000000000 samples, which need about"),
    (["--records", "100000000", "--duration", "100"], "the run file could need up to 60 TB "
                                                      "(100000000 records of 10000 samples) but"),
])
def test_the_preflight_refuses_a_run_that_cannot_fit_before_simulating(tmp_path, args, message):
    t = time.perf_counter()
    res = daq("acquire", "--scene", "ishizaki2009", *args, "--seed", "1", "--out",
              tmp_path / "run.h5", cwd=tmp_path)
    assert time.perf_counter() - t < 30  # no simulation of 1e8 s (a minute a year) started
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert res.stderr.startswith(f"Error: {message}") and len(res.stderr.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
    record_fault("run larger than the disk or the memory", records_lost=0,
                 outcome="refused before simulating: one line with the estimate and what is "
                         "free, exit 1")
