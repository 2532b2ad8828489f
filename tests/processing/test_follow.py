"""``daq analyze --follow``: a reader process follows a writer process (``daq acquire``) through
SWMR, printing the averaged estimate as records land, and stops when the run ends -- or when the
writer is killed."""

import re
import signal
import subprocess
import sys
import time

from processing.follow import follow_run

RUN = ["acquire", "--scene", "ishizaki2009", "--duration", "5", "--rate", "100", "--set",
       "acquisition.settle_s=5", "--set", "acquisition.model=linear", "--seed", "4", "-q"]


def _start(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_exists(path, proc, timeout=120):
    t0 = time.monotonic()
    while not path.exists():
        assert proc.poll() is None and time.monotonic() - t0 < timeout, proc.communicate()
        time.sleep(0.02)


def _updates(stdout):
    line = r"^average (\d+) of \d+(?:, \d+ s left)?: "
    return [int(m.group(1)) for m in re.finditer(line, stdout, re.M)]


def _first_line(proc, timeout):
    """What ``proc`` has written to stdout up to its first whole line, within ``timeout``
    seconds. Read from the pipe itself (as ``communicate`` later reads the rest), never
    through the text wrapper's buffer, so no output is lost between the two."""
    import os
    import selectors

    sel = selectors.DefaultSelector()
    sel.register(proc.stdout.fileno(), selectors.EVENT_READ)
    got, t0 = b"", time.monotonic()
    while b"\n" not in got:
        assert time.monotonic() - t0 < timeout, f"no whole line in {timeout} s: {got!r}"
        if sel.select(timeout=0.5):
            chunk = os.read(proc.stdout.fileno(), 4096)
            assert chunk, proc.communicate()  # the reader ended before a line
            got += chunk
    return got.decode()


def test_follow_prints_the_estimate_as_records_land_and_stops_when_the_run_ends(tmp_path):
    """The writer is paused (SIGSTOP) once its first record is in and resumed when the reader
    has printed its first estimate, so the reader sees the run part way whatever the host's
    speed."""
    out = tmp_path / "run.h5"
    writer = _start(*RUN, "--records", 300, "--out", out, cwd=tmp_path)
    try:
        _wait_exists(out, writer)
        t0 = time.monotonic()
        while _seen_records(out) < 1:
            assert writer.poll() is None and time.monotonic() - t0 < 120, writer.communicate()
            time.sleep(0.01)
        writer.send_signal(signal.SIGSTOP)
        assert _seen_records(out) < 300
        reader = _start("analyze", out, "--follow", cwd=tmp_path)
        head = _first_line(reader, 300)
    finally:
        writer.send_signal(signal.SIGCONT)
    w_out, w_err = writer.communicate(timeout=300)
    r_out, r_err = reader.communicate(timeout=300)
    r_out = head + r_out
    assert writer.returncode == 0, w_err
    assert reader.returncode == 0, r_err
    seen = _updates(r_out)
    assert len(seen) >= 2 and seen == sorted(set(seen)) and seen[-1] == 300, r_out
    last = r_out.splitlines()[len(seen) - 1]
    # the last update is the estimate of the whole run, and the full analysis follows it
    (whole,) = list(follow_run(out))
    assert last == whole.line()
    assert r_out.splitlines()[len(seen)].startswith(f"analysed {out}: ishizaki2009, seed 4, "
                                                    "300 of 300 records")


def test_follow_stops_when_the_writer_is_killed(tmp_path):
    out = tmp_path / "run.h5"
    writer = _start(*RUN, "--records", 5000, "--out", out, cwd=tmp_path)
    _wait_exists(out, writer)
    reader = _start("analyze", out, "--follow", cwd=tmp_path)
    t0 = time.monotonic()
    while not _seen_records(out) >= 3:
        assert time.monotonic() - t0 < 120
        time.sleep(0.05)
    writer.kill()
    writer.communicate()
    r_out, r_err = reader.communicate(timeout=120)
    assert reader.returncode == 0, r_err
    assert "INCOMPLETE run (status acquiring)" in r_out and "Traceback" not in r_err


def _seen_records(path):
    import h5py

    try:
        with h5py.File(path, "r", swmr=True) as f:
            return int(f["entry/records_complete"][()])
    except (OSError, KeyError):
        return 0


def test_time_left_comes_from_the_rate_records_have_landed_at():
    from processing.follow import _time_left

    assert _time_left([(10.0, 2)], 30) is None  # one landing: no rate yet
    assert _time_left([(10.0, 2), (14.0, 4)], 30) == 52.0  # 2 s a record, 26 to go
    assert _time_left([(10.0, 2), (14.0, 30)], 30) is None  # every record is in
