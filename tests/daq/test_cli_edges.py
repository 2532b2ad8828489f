"""The CLI at its edges, each case run as the real ``daq`` in a subprocess with a time bound:
signals and exit statuses of sweeps and exports, waits that must end (a follower, a Dask
scheduler or rerun viewer that never answers, a FIFO), the live view without a display, and
temporary files that never outlive the command that made them."""

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from faults import record_fault

ROOT = Path(__file__).resolve().parents[2]
SHORT = ["--scene", "ishizaki2009", "--records", "3", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5", "--seed", "3"]
SWEEP = ('seed = 5\nscene = "ishizaki2009"\nset = ["acquisition.records=2", '
         '"acquisition.record_s=10", "acquisition.settle_s=10"]\n{body}\n[analysis]\n'
         'nperseg = 500\n')


def _cmd(*args):
    return [sys.executable, "-m", "daq.cli", *map(str, args)]


def daq(*args, cwd, timeout=120, env=None):
    return subprocess.run(_cmd(*args), cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def start(*args, cwd, env=None):
    return subprocess.Popen(_cmd(*args), cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(cond, timeout_s=120.0):
    t = time.monotonic()
    while not cond():
        assert time.monotonic() - t < timeout_s, "timed out"
        time.sleep(0.02)


def no_display():
    return {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("edges")
    res = daq("acquire", *SHORT, "--out", d / "run.h5", "-q", cwd=d, timeout=300)
    assert res.returncode == 0, res.stderr
    return d / "run.h5"


@pytest.fixture(scope="module")
def long_run_file(tmp_path_factory):
    """The paper's 30 records of 100 s: an export of it takes seconds (room for a signal)."""
    d = tmp_path_factory.mktemp("long")
    res = daq("acquire", "ishizaki2009", "--seed", "4", "--out", d / "run.h5", "-q", cwd=d,
              timeout=600)
    assert res.returncode == 0, res.stderr
    return d / "run.h5"


@pytest.fixture
def silent_listener():
    """A TCP port that accepts connections into its backlog and never answers."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(8)
    try:
        yield s.getsockname()[1]
    finally:
        s.close()


def temporaries(d: Path) -> list[str]:
    return sorted(p.name for p in d.rglob(".*") if p.is_file() and p.name != ".lock")


# -- sweeps: signals and exit statuses ----------------------------------------------------------

@pytest.mark.parametrize("sig, group", [(signal.SIGTERM, False), (signal.SIGHUP, True)])
def test_sigterm_and_sighup_stop_a_sweep_with_128_plus_n_a_message_and_the_manifest(
        tmp_path, sig, group):
    """SIGTERM to the sweep (``kill PID``) and SIGHUP to its process group (a closed terminal):
    one line, exit 128 + N, the manifest written, no temporary file left."""
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body='[random]\ncount = 6\n"pendulum.q2" = '
                                      '{ uniform = [80.0, 120.0] }'))
    out = tmp_path / "ds"
    p = start("dataset", path, "--out", out, "--workers", "1", cwd=tmp_path)
    journal = out / "journal.jsonl"
    wait_for(lambda: journal.exists() and len(journal.read_text().splitlines()) >= 1)
    (os.killpg if group else os.kill)(p.pid, sig)
    _, err = p.communicate(timeout=120)
    name = signal.Signals(sig).name
    assert p.returncode == 128 + sig, err
    assert f"interrupted ({name}): " in err and "Traceback" not in err
    assert (out / "manifest.h5").exists() and (out / "manifest.csv").exists()
    assert temporaries(out / "runs") == []
    record_fault(f"{name} during daq dataset", records_lost=0,
                 outcome=f"'interrupted ({name}): N of M runs complete ...', exit {128 + sig}, "
                         "manifest written, no temporary file")


def test_a_sweep_whose_runs_failed_exits_4_with_a_line_saying_so(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body='[grid]\n"pendulum.q1" = [300.0, -2.0]'))
    res = daq("dataset", path, "--out", tmp_path / "ds", "--workers", "1", cwd=tmp_path)
    assert res.returncode == 4, res.stderr
    assert "partial sweep: 1 of 2 runs failed or missing" in res.stderr
    assert "run 1 failed: " in res.stdout


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_export_exits_128_plus_n_with_one_line_and_no_temporary_file(
        long_run_file, tmp_path, sig):
    """The signal arrives while the output is written (its temporary file exists)."""
    d = tmp_path
    p = start("export", long_run_file, "--uff", d / "out.uff", cwd=d)
    wait_for(lambda: temporaries(d) or p.poll() is not None, 120)
    if p.poll() is not None:
        pytest.skip("the export finished before it could be interrupted")
    os.killpg(p.pid, sig)
    _, err = p.communicate(timeout=60)
    name = signal.Signals(sig).name
    assert p.returncode == 128 + sig, err
    assert err.strip().splitlines() == [
        f"interrupted ({name}): daq export stopped; files it had finished are kept, none is "
        "left half-written"]
    assert temporaries(d) == [] and not (d / "out.uff").exists()
    record_fault(f"{name} during daq export / analyze outputs", records_lost=0,
                 outcome=f"'interrupted ({name}): daq export stopped ...', exit {128 + sig}, "
                         "no temporary or half-written file")


def test_a_dead_writer_s_temporary_file_is_removed_by_the_next_write_of_that_output(
        run_file, tmp_path):
    """A writer killed outright (SIGKILL: nothing of it runs) leaves its temporary file; the
    next command writing that output removes it, whatever its random part; a live writer's
    temporary file is left alone."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = socket.gethostname().replace(".", "-")
    stale = tmp_path / f".out.csv.{host}.{dead.pid}.k3j_x9q1.csv"
    live = tmp_path / f".out.csv.{host}.{os.getpid()}.ab12cd34.csv"
    stale.write_text("half")
    live.write_text("being written")
    res = daq("analyze", run_file, "--csv", tmp_path / "out.csv", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert not stale.exists() and live.exists() and (tmp_path / "out.csv").exists()
    record_fault("SIGKILL while an output is written", records_lost=0,
                 outcome="the next write of that output removes the dead writer's temporary "
                         "file; a live writer's stays")


# -- waits that end ------------------------------------------------------------------------------

def test_follow_of_a_truncated_file_no_writer_holds_fails_at_once(run_file, tmp_path):
    cut = tmp_path / "cut.h5"
    cut.write_bytes(run_file.read_bytes()[:50_000])
    os.utime(cut, (time.time() - 5, time.time() - 5))
    t = time.monotonic()
    res = daq("analyze", "--follow", cut, cwd=tmp_path, timeout=60)
    took = time.monotonic() - t
    assert res.returncode == 1 and "truncated" in res.stderr, res.stderr
    assert "no writer holds it" in res.stderr and took < 15
    record_fault("analyze --follow of a truncated file no writer holds", records_lost=0,
                 outcome="one line 'truncated ...; no writer holds it', exit 1, at once")


def test_follow_waits_for_a_run_file_that_does_not_exist_yet(tmp_path):
    out = tmp_path / "later.h5"
    f = start("analyze", "--follow", "--wait", "300", out, "--nperseg", "250",
              cwd=tmp_path)
    time.sleep(1.0)
    assert f.poll() is None  # still waiting
    res = daq("acquire", *SHORT, "--out", out, "-q", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    stdout, stderr = f.communicate(timeout=300)
    assert f.returncode == 0, stderr
    assert f"waiting up to 300 s for {out} to appear (--wait)" in stderr
    assert "average 3 of 3" in stdout


def test_follow_of_a_file_that_never_appears_ends_after_wait(tmp_path):
    t = time.monotonic()
    res = daq("analyze", "--follow", "--wait", "1", tmp_path / "never.h5", cwd=tmp_path,
              timeout=60)
    assert res.returncode == 1 and "did not appear within 1 s" in res.stderr, res.stderr
    assert time.monotonic() - t < 30


def test_check_and_follow_refuse_a_fifo_at_once(tmp_path):
    fifo = tmp_path / "pipe.h5"
    os.mkfifo(fifo)
    for args in (["check", "--repair", fifo], ["check", fifo], ["analyze", "--follow", fifo],
                 ["inspect", fifo]):
        res = daq(*args, cwd=tmp_path, timeout=30)
        assert res.returncode == 1, (args, res.stderr)
        assert "is a FIFO (named pipe), not a regular file" in res.stderr, res.stderr
    record_fault("a FIFO given as a run file (check --repair, analyze --follow, inspect)",
                 records_lost=0, outcome="one line 'is a FIFO (named pipe), not a regular "
                                         "file', exit 1, never a hang")


def test_a_dask_scheduler_that_never_answers_is_given_up_after_its_timeout(tmp_path,
                                                                           silent_listener):
    pytest.importorskip("distributed")
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body=""))
    t = time.monotonic()
    res = daq("dataset", path, "--out", tmp_path / "ds", "--scheduler",
              f"tcp://127.0.0.1:{silent_listener}", cwd=tmp_path, timeout=90)
    assert res.returncode == 1, res.stderr
    assert "no Dask scheduler answered there within 10 s" in res.stderr
    assert time.monotonic() - t < 60
    record_fault("a Dask scheduler or rerun viewer that accepts and never answers",
                 records_lost=0, outcome="one line 'no ... answered there within N s', exit 1; "
                                         "SIGTERM meanwhile: exit 143")


def test_sigterm_interrupts_the_wait_for_a_silent_dask_scheduler(tmp_path, silent_listener):
    pytest.importorskip("distributed")
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body=""))
    p = start("dataset", path, "--out", tmp_path / "ds", "--scheduler",
              f"tcp://127.0.0.1:{silent_listener}", cwd=tmp_path)
    time.sleep(3.0)  # past the imports, in the wait
    t = time.monotonic()
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 143, err
    assert time.monotonic() - t < 5 and "Traceback" not in err


@pytest.mark.parametrize("command", ["view", "acquire"])
def test_connect_to_a_viewer_that_never_answers_fails_before_any_work(
        run_file, tmp_path, silent_listener, command):
    url = f"rerun+http://127.0.0.1:{silent_listener}/proxy"
    args = (["view", run_file, "--connect", url] if command == "view" else
            ["acquire", *SHORT, "--connect", url, "--out", tmp_path / "r.h5"])
    t = time.monotonic()
    res = daq(*args, cwd=tmp_path, timeout=60)
    assert res.returncode == 1, res.stderr
    assert res.stderr.strip() == (f"Error: --connect {url}: no rerun viewer there (no answer "
                                  "within 3 s); start one (rerun --port PORT) or leave out "
                                  "--connect")
    assert time.monotonic() - t < 30 and not (tmp_path / "r.h5").exists()


def test_view_connect_to_a_dead_url_fails_with_a_sentence(run_file, tmp_path):
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    res = daq("view", run_file, "--connect", f"rerun+http://127.0.0.1:{port}/proxy",
              cwd=tmp_path, timeout=60)
    assert res.returncode == 1 and "no rerun viewer there (connection refused)" in res.stderr


# -- the live view without a display -------------------------------------------------------------

@pytest.mark.parametrize("args", [["view", "{run}"], ["acquire", *SHORT, "--live"],
                                  ["simulate", "double-rod", "--duration", "1", "--live"]])
def test_a_viewer_window_without_a_display_is_refused_at_once_saying_what_to_do(
        run_file, tmp_path, args):
    t = time.monotonic()
    res = daq(*[str(a).format(run=run_file) for a in args], cwd=tmp_path, env=no_display(),
              timeout=60)
    assert res.returncode == 1, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "there is no display here" in lines[0]
    assert "--rrd FILE.rrd" in lines[0] and "Warning" not in res.stderr
    assert time.monotonic() - t < 30
    record_fault("the live view without a display", records_lost=0,
                 outcome="refused at once, one line naming --rrd, --connect, --screenshot; "
                         "exit 1")


# -- resources: the live view's recording ---------------------------------------------------------

def test_an_rrd_that_cannot_fit_is_refused_before_the_run(tmp_path):
    t = time.monotonic()
    res = daq("acquire", "ishizaki2009", "--records", "100000000", "--rrd", tmp_path / "r.rrd",
              cwd=tmp_path, timeout=60)
    assert res.returncode == 1, res.stderr
    assert res.stderr.startswith(f"Error: --rrd {tmp_path / 'r.rrd'}: the recording could need "
                                 "up to ")
    assert "free: free some space" in res.stderr and time.monotonic() - t < 30
    assert list(tmp_path.iterdir()) == []
    record_fault("an --rrd larger than the disk", records_lost=0,
                 outcome="refused before the run: one line with the estimate and what is free, "
                         "exit 1")


def test_ctrl_c_with_only_an_rrd_says_the_recording_holds_the_finished_records(tmp_path):
    rrd = tmp_path / "view.rrd"
    p = start("acquire", "ishizaki2009", "--records", "3000", "--duration", "20",
              "--set", "acquisition.settle_s=5", "--seed", "1", "--rrd", rrd, "-q", cwd=tmp_path)
    wait_for(lambda: any(q.stat().st_size > 2_000_000 for q in tmp_path.glob(".view.rrd.*"))
             or p.poll() is not None, 120)
    assert p.poll() is None, p.communicate()
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert err.strip().endswith(f"records; {rrd} holds the live view of them (rerun "
                                "recording)"), err
    assert rrd.stat().st_size > 2_000_000 and temporaries(tmp_path) == []


# -- resources: sweeps -----------------------------------------------------------------------------

def test_a_grid_beyond_the_largest_sweep_is_refused_before_its_values_are_made(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(
        body='[grid]\n"pendulum.q1" = { linspace = [300.0, 800.0], num = 100000000 }'))
    t = time.monotonic()
    res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", cwd=tmp_path, timeout=60)
    assert res.returncode == 1
    assert res.stderr.strip() == ("Error: grid.pendulum.q1.num = 100000000 is invalid: a sweep "
                                  "has at most 100000 runs (split it into several sweeps)")
    assert time.monotonic() - t < 30


def test_a_cross_grid_beyond_the_largest_sweep_is_refused_at_once(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(
        body='[grid]\n"pendulum.q1" = { linspace = [300.0, 800.0], num = 1000 }\n'
             '"pendulum.q2" = { linspace = [80.0, 120.0], num = 1000 }'))
    t = time.monotonic()
    res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", cwd=tmp_path, timeout=60)
    assert res.returncode == 1 and "the sweep has 1000000 runs: expected at most 100000" in \
        res.stderr
    assert time.monotonic() - t < 30


def test_workers_beyond_the_cores_are_capped_with_a_warning_and_a_real_time_estimate(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body='[random]\ncount = 3\n"pendulum.q2" = '
                                      '{ uniform = [80.0, 120.0] }'))
    res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", "--workers", "1000",
              cwd=tmp_path, timeout=60)
    assert res.returncode == 0, res.stderr
    cores = len(os.sched_getaffinity(0))
    assert f"warning: --workers 1000 is more than the {cores} cores" in res.stderr
    est = [ln for ln in res.stdout.splitlines() if ln.startswith("estimated time: ")]
    assert est and not est[0].startswith("estimated time: 0 s") and " on 1000 " not in est[0]


def test_a_dask_cluster_is_capped_by_its_own_workers_memory_not_this_machines(tmp_path):
    """Two workers of two threads with 400 MB each hold one run each (300 MB a run): the dry
    run says so in one line and plans 2 runs in flight, not 4; a worker without a memory limit
    counts its threads (a remote cluster: this machine's cores and memory do not bound it)."""
    distributed = pytest.importorskip("distributed")
    from processing.dataset.engines import WORKER_BYTES, cluster_limit

    assert cluster_limit({"a": {"nthreads": 8, "memory_limit": 0},
                          "b": {"nthreads": 2, "memory_limit": 10 * WORKER_BYTES}}) == (10, "")
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body='[random]\ncount = 8\n"pendulum.q2" = '
                                      '{ uniform = [80.0, 120.0] }'))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=False,
                                  protocol="tcp", host="127.0.0.1", memory_limit="400MB",
                                  dashboard_address=None) as cluster:
        res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", "--scheduler",
                  cluster.scheduler_address, cwd=tmp_path, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stderr.strip() == (
        "warning: the Dask cluster has 4 worker threads but the memory limits of 2 of its 2 "
        "workers (0.4 GB and up) hold fewer runs than their threads (300 MB each): keeping 2 "
        "runs in flight")
    assert " on 2 workers " in res.stdout and not (tmp_path / "ds").exists()


def test_a_dry_run_checks_many_parameter_sets_and_reports_progress_as_it_goes(tmp_path):
    """The CLI's count; the progress callback's calls through the library (on a fast machine
    2000 checks end before the CLI's first one-second report, so that is not timed here)."""
    from processing.dataset import load_sweep, plan_runs

    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(
        body='[grid]\n"pendulum.q1" = { linspace = [300.0, 800.0], num = 2000 }'))
    res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", cwd=tmp_path, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "sweep s: 2000 runs (2000 valid" in res.stdout
    calls = []
    planned = plan_runs(load_sweep(path), progress=lambda k, n: calls.append((k, n)),
                        every_s=0.0)
    assert len(planned) == 2000 and all(p.error == "" for p in planned)
    assert [k for k, _ in calls] == list(range(2000)) and {n for _, n in calls} == {2000}


def test_a_dry_run_reports_every_invalid_parameter_set_as_each_scene_alone_would(tmp_path):
    """The plan checks what the runs share once (rig.scene.SceneMemo); each run's verdict and
    message are still those of its scene loaded on its own: invalid designs on the grid (J2 < 0
    at 20 and 30 Hz) and negative drive levels from a wide normal draw."""
    from processing.dataset import load_sweep, plan_runs
    from rig.errors import ConfigError
    from rig.scene import load_scene

    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(
        body='[grid]\n"pendulum.f2_hz" = [0.8268, 20.0, 5.0, 30.0]\n"stage.reaction" = '
             '[true, false]\n[random]\ncount = 25\n"source.level_vrms" = '
             '{ normal = [0.05, 0.1] }'))
    sweep = load_sweep(path)
    want = {}
    for spec in sweep.runs():
        try:
            load_scene(sweep.scene, spec.overrides)
            want[spec.index] = ""
        except ConfigError as exc:
            want[spec.index] = str(exc).splitlines()[0]
    bad = sum(bool(v) for v in want.values())
    assert 100 < bad < 200  # both kinds of invalid sets are there, and valid ones
    assert {p.spec.index: p.error for p in plan_runs(sweep)} == want
    res = daq("dataset", path, "--out", tmp_path / "ds", "--dry-run", cwd=tmp_path, timeout=120)
    assert res.returncode == 0, res.stderr
    assert f"sweep s: 200 runs ({200 - bad} valid, {bad} invalid parameter sets)" in res.stdout


def test_force_with_a_smaller_sweep_removes_the_run_files_it_does_not_list(tmp_path):
    path = tmp_path / "s.toml"
    out = tmp_path / "ds"
    path.write_text(SWEEP.format(body='[grid]\n"pendulum.q1" = [300.0, 400.0, 500.0]'))
    res = daq("dataset", path, "--out", out, "--workers", "1", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    path.write_text(SWEEP.format(body='[grid]\n"pendulum.q1" = [300.0, 400.0]'))
    res = daq("dataset", path, "--out", out, "--workers", "1", "--force", cwd=tmp_path,
              timeout=300)
    assert res.returncode == 0, res.stderr
    assert ("removed 1 run files of the earlier plan that this sweep does not list "
            "(run_000002.h5)") in res.stdout
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["run_000000.h5",
                                                                 "run_000001.h5"]


@pytest.fixture
def small_disk(tmp_path):
    """A real 6 MiB file system (tmpfs), unmounted afterwards."""
    import shutil

    d = tmp_path / "disk"
    d.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a small tmpfs needs root and mount(8) to test a full disk for real")
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=6m", "tmpfs", str(d)],
                         capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({res.stderr.strip()})")
    try:
        yield d
    finally:
        subprocess.run(["umount", "-l", str(d)], capture_output=True)


def test_a_full_disk_mid_sweep_gives_one_line_per_failed_run_and_no_temporary_file(
        small_disk, tmp_path):
    """The disk (6 MiB, room for the sweep's first runs) is filled by another file after the
    second run lands: no worker traceback, a line per failed run, no temporary file."""
    path = tmp_path / "s.toml"
    path.write_text(SWEEP.format(body='[random]\ncount = 12\n"pendulum.q2" = '
                                      '{ uniform = [80.0, 120.0] }'))
    out = small_disk / "ds"
    p = start("dataset", path, "--out", out, "--workers", "2", cwd=tmp_path)
    wait_for(lambda: (out / "runs" / "run_000001.h5").exists() or p.poll() is not None, 300)
    with open(small_disk / "filler", "wb", buffering=0) as fh:
        with pytest.raises(OSError):
            while True:
                fh.write(b"\0" * 65536)
    stdout, stderr = p.communicate(timeout=300)
    assert p.returncode == 4, stderr  # partly done, whether the runs or the journal failed
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr[-3000:]
    errors = [ln for ln in stderr.splitlines() if not ln.startswith("runs: ")]
    assert len(errors) == 1, errors
    assert ("disk is full" in errors[0] or "partial sweep" in errors[0]), errors
    failed = [ln for ln in stdout.splitlines() if ln.startswith("  run ") and " failed: " in ln]
    assert all(len(ln) < 600 for ln in failed)
    if (out / "manifest.csv").exists():  # a line per run the manifest calls failed
        import csv

        with open(out / "manifest.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert len(failed) == sum(r["status"] == "failed" for r in rows)
    assert temporaries(out) == []
    record_fault("disk full during daq dataset (a real tmpfs filled by another file)",
                 records_lost=0, outcome="a line per failed run and one saying the disk is "
                                         "full; finished runs kept, no temporary file, no "
                                         "worker traceback")


# -- long silences ----------------------------------------------------------------------------------

@pytest.mark.parametrize("args", [["scene", "show", "rod-chain"],
                                  ["acquire", "rod-chain", "--out", "r.h5"]])
def test_a_pendulum_of_1000_bodies_is_refused_at_once_saying_why(tmp_path, args):
    t = time.monotonic()
    res = daq(*args, "--set", "pendulum.n=1000", cwd=tmp_path, timeout=60)
    assert res.returncode == 1, res.stderr
    assert res.stderr.strip() == ("Error: pendulum.n = 1000 is invalid: expected 1 <= n <= 200 "
                                  "(the chain's modes are an O(n^3) eigenproblem solved when "
                                  "the scene loads: seconds at 200 bodies, minutes at 1000)")
    assert time.monotonic() - t < 30 and not (tmp_path / "r.h5").exists()


def test_a_cold_kernel_cache_is_announced_before_the_run(tmp_path):
    """With an empty numba cache the first line says the kernels are compiled, once; the run
    is stopped as soon as it is seen (the compilation itself takes a minute)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    p = start("acquire", *SHORT, "--out", tmp_path / "r.h5", cwd=tmp_path, env=env)
    try:
        first = p.stderr.readline()
    finally:
        os.killpg(p.pid, signal.SIGTERM)
        p.communicate(timeout=120)
    assert first.startswith("compiling the simulation kernels, once (about a minute; later runs "
                            f"load them from {tmp_path / 'cache'})"), first


# -- the live view's screenshot ------------------------------------------------------------------------

def test_a_screenshot_is_exactly_the_size_asked(run_file, tmp_path):
    pytest.importorskip("processing.live_view")
    from PIL import Image

    from processing.live_view import LiveViewError, screenshot_command

    try:
        screenshot_command(tmp_path / "x.rrd", tmp_path / "x.png")
    except LiveViewError as exc:
        pytest.skip(f"no headless viewer here: {exc}")
    png = tmp_path / "s.png"
    res = daq("view", run_file, "--screenshot", png, "--size", "1280x720", cwd=tmp_path,
              timeout=600)
    assert res.returncode == 0, res.stderr
    with Image.open(png) as im:
        assert im.size == (1280, 720) and im.format == "PNG"
    assert temporaries(tmp_path) == []
