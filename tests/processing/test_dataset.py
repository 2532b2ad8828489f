"""``daq dataset``: sweep files, runs on local processes and on Dask, resume, failures, manifest.

The sweeps are tiny (runs of 2 records of 10 s after 10 s of settling) so that the process
starts dominate. One 3-run sweep, made on 1 worker, 2 workers and a Dask cluster, is shared by
the tests that read it (identity, manifest) and is the starting point of the rerun test (a copy);
the tests of interruption and failure run their own.
"""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from daq.cli import main
from processing.dataset import check_run_file, load_sweep, parse_sweep, plan_runs, run_sweep
from processing.dataset.sweep import run_seed
from rig.errors import ConfigError

SET = 'set = ["acquisition.records=2", "acquisition.record_s=10", "acquisition.settle_s=10"]\n'
ANALYSIS = "[analysis]\nnperseg = 500\n"


def sweep_file(tmp_path: Path, body: str, name: str = "sweep.toml", seed: int = 5) -> Path:
    p = tmp_path / name
    p.write_text(f'seed = {seed}\nscene = "ishizaki2009"\n{SET}{body}\n{ANALYSIS}')
    return p


GRID3 = '[grid]\n"source.level_vrms" = { linspace = [0.05, 0.15], num = 3 }\n'


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def rows(out: Path) -> list[dict]:
    with open(out / "manifest.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def start_time(path: Path) -> bytes:
    with h5py.File(path, "r") as f:
        return f["entry"].attrs["start_time"].encode()


def same_apart_from_start_time(a: Path, b: Path) -> bool:
    ba, bb = a.read_bytes(), b.read_bytes()
    ta, tb = start_time(a), start_time(b)
    return ba.count(ta) == 1 and ba.replace(ta, tb) == bb


# -- the sweep file --------------------------------------------------------------------------

def test_grids_cross_or_zip_in_order_and_random_draws_do_not_depend_on_the_count(tmp_path):
    s = parse_sweep({"seed": 1, "scene": "ishizaki2009",
                     "grid": {"source.level_vrms": {"logspace": [0.01, 1.0], "num": 3},
                              "pendulum": {"q1": [300.0, 500.0]}}})
    assert s.n_runs == 6
    got = [(r.params["source.level_vrms"], r.params["pendulum.q1"]) for r in s.runs()]
    assert got == [(0.01, 300.0), (0.01, 500.0), (pytest.approx(0.1), 300.0),
                   (pytest.approx(0.1), 500.0), (1.0, 300.0), (1.0, 500.0)]
    z = parse_sweep({"seed": 1, "scene": "ishizaki2009", "grid": {
        "combine": "zip", "pendulum.q1": [300.0, 500.0], "pendulum.q2": [50.0, 60.0]}})
    assert [tuple(r.params.values()) for r in z.runs()] == [(300.0, 50.0), (500.0, 60.0)]

    def draws(count):
        return parse_sweep({"seed": 3, "scene": "ishizaki2009", "random": {
            "count": count, "pendulum.q2": {"loguniform": [50.0, 200.0]},
            "accelerometer.noise_mps2_rthz": {"normal": [1e-5, 1e-5], "bounds": [0.0, 2e-5]}}
        }).runs()
    few, many = draws(3), draws(50)
    assert [r.params for r in few] == [r.params for r in many[:3]]
    assert [r.seed for r in few] == [r.seed for r in many[:3]]
    q2 = np.array([r.params["pendulum.q2"] for r in many])
    noise = np.array([r.params["accelerometer.noise_mps2_rthz"] for r in many])
    assert q2.min() >= 50 and q2.max() <= 200 and noise.min() >= 0 and noise.max() <= 2e-5
    assert len(set(q2)) == 50


def test_run_seeds_are_the_seed_sequence_children_of_the_sweep_seed():
    children = np.random.SeedSequence(2026).spawn(5)
    for i, child in enumerate(children):
        assert run_seed(2026, i) == int(child.generate_state(1, np.uint64)[0] >> np.uint64(1))
    assert len({run_seed(2026, i) for i in range(100)}) == 100


@pytest.mark.parametrize("body, match", [
    ('[grid]\n"pendulum.q7" = [1.0]', r"grid\.pendulum\.q7: unknown key 'q7' of \[pendulum\]; "
                                      r"valid keys: .*q1"),
    ('[grid]\n"source.level_vrms" = { linspace = [0.1, 0.2] }',
     r"grid\.source\.level_vrms\.num = None is invalid: expected an integer >= 1"),
    ('[grid]\n"source.level_vrms" = []', r"grid\.source\.level_vrms = \[\] is invalid"),
    ('[grid]\n"stage.reaction" = [1.0]',
     r"grid\.stage\.reaction\[1\] = 1\.0 is invalid: expected true or false"),
    ('[random]\n"pendulum.q2" = { uniform = [200.0, 50.0] }',
     r"random\.pendulum\.q2\.uniform = \[200\.0, 50\.0\] is invalid: expected low < high"),
    ('[random]\ncount = 0', r"random\.count = 0 is invalid: expected an integer >= 1"),
    ('[keep]\nspectrum = true', r"unknown key keep\.spectrum = True; valid keys: raw, model, "),
    ('colour = "red"', r"unknown key colour = 'red' in the sweep file; valid keys: seed, "),
])
def test_a_bad_sweep_file_fails_before_any_run_naming_key_value_and_what_is_valid(
        tmp_path, body, match):
    path = sweep_file(tmp_path, body)
    with pytest.raises(ConfigError, match=match):
        load_sweep(path)
    out = tmp_path / "ds"
    res = invoke("dataset", path, "--out", out)
    assert res.exit_code == 1 and res.output.startswith("Error: ")
    assert "Traceback" not in res.output and len(res.output.strip().splitlines()) == 1
    assert not out.exists()


def test_bad_analysis_settings_and_a_bad_base_scene_fail_before_any_run(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('seed = 1\nscene = "no-such-preset"\n')
    with pytest.raises(ConfigError, match="scene = 'no-such-preset'.*not a preset"):
        load_sweep(p)
    p.write_text('seed = 1\nscene = "ishizaki2009"\n[analysis]\nwindow = "hamming"\n')
    with pytest.raises(ConfigError, match="analysis: window = 'hamming' is invalid: expected "
                                          "one of"):
        load_sweep(p)


def test_dry_run_prints_the_runs_time_and_disk_and_writes_nothing(tmp_path):
    path = sweep_file(tmp_path, GRID3 + '"pendulum.q1" = [300.0, -1.0]\n')
    out = tmp_path / "ds"
    res = invoke("dataset", path, "--out", out, "--dry-run", "--workers", "2")
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == ("sweep sweep: 6 runs (3 valid, 3 invalid parameter sets), seed 5, scene "
                        "ishizaki2009")
    assert lines[1].split() == ["run", "seed", "source.level_vrms", "pendulum.q1", "status"]
    assert lines[2].split()[:4] == ["0", str(run_seed(5, 0)), "0.05", "300"]
    assert "invalid: pendulum.q1 = -1.0 is invalid: expected > 0" in lines[3]
    assert lines[-2].startswith("estimated time: ") and " on 2 workers" in lines[-2]
    assert lines[-1].startswith("estimated disk: ")
    assert not out.exists()


def test_scheduler_without_dask_fails_with_a_clear_message(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    res = invoke("dataset", sweep_file(tmp_path, ""), "--out", tmp_path / "ds",
                 "--scheduler", "tcp://127.0.0.1:1")
    assert res.exit_code == 1
    assert res.output.strip() == ("Error: --scheduler needs Dask distributed, the optional extra "
                                  "of pendulum-daq: pip install 'pendulum-daq[dask]' (or "
                                  "'dask[distributed]')")


# -- runs: engines, identical files, the manifest --------------------------------------------

@pytest.fixture(scope="module")
def three_ways(tmp_path_factory):
    """The same 3-run sweep on 1 worker, 2 workers and a 2-worker Dask LocalCluster."""
    distributed = pytest.importorskip("distributed", reason="the dask extra is not installed")
    tmp = tmp_path_factory.mktemp("sweeps")
    path = sweep_file(tmp, GRID3)
    out = {}
    for name, args in (("one", ["--workers", "1"]), ("two", ["--workers", "2"])):
        out[name] = tmp / name
        res = invoke("dataset", path, "--out", out[name], *args)
        assert res.exit_code == 0, res.output
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0") as cluster:
        out["dask"] = tmp / "dask"
        res = invoke("dataset", path, "--out", out["dask"], "--scheduler",
                     cluster.scheduler_address)
        assert res.exit_code == 0, res.output
    return path, out


def test_one_two_workers_and_a_dask_cluster_give_identical_run_files(three_ways):
    _, out = three_ways
    for name in ("one", "two", "dask"):
        assert [r["status"] for r in rows(out[name])] == ["complete"] * 3
    for i in range(3):
        f = f"runs/run_{i:06d}.h5"
        assert same_apart_from_start_time(out["one"] / f, out["two"] / f)
        assert same_apart_from_start_time(out["one"] / f, out["dask"] / f)
    # ... and the runs differ from each other (the drive and the seed change)
    a, b = (out["one"] / f"runs/run_{i:06d}.h5" for i in (0, 1))
    assert a.read_bytes() != b.read_bytes()


def test_manifest_opens_in_xarray_and_its_stacked_arrays_equal_the_run_files(three_ways):
    xr = pytest.importorskip("xarray")
    _, out = three_ways
    d = out["two"]
    ds = xr.open_dataset(d / "manifest.h5", engine="h5netcdf")
    assert ds.sizes["run"] == 3 and ds.sizes["record"] == 2 and ds.sizes["time"] == 1000
    np.testing.assert_allclose(ds["source.level_vrms"].values, [0.05, 0.1, 0.15])
    assert list(ds.status.values) == ["complete"] * 3
    assert list(ds.seed.values) == [run_seed(5, i) for i in range(3)]
    table = rows(d)
    for i in range(3):
        with h5py.File(d / f"runs/run_{i:06d}.h5", "r") as f:
            e = f["entry"]
            assert ds.sha256.values[i] == table[i]["sha256"]
            assert int(e["dataset"].attrs["run_seed"]) == run_seed(5, i)
            for c in ("a", "x", "y"):
                codes = e["data"][c][()]
                volts = codes * e["data"][c].attrs["scale_factor"] + e["data"][c].attrs[
                    "add_offset"]
                np.testing.assert_array_equal(ds[c].values[i], volts)
            np.testing.assert_array_equal(ds.truth_theta_rad.values[i], e["truth/theta_rad"][()])
            for k in ("H_t_real", "Theta_2_imag", "coherence_y", "G_ax_real",
                      "expected_H_t_real"):
                np.testing.assert_array_equal(ds[k].values[i], e["analysis"][k][()])
            np.testing.assert_array_equal(ds.frequency.values, e["analysis/frequency"][()])
            for k, v in e["analysis/modal"].items():
                assert ds[k].values[i] == v[()]
    with h5py.File(d / "manifest.h5", "r") as f:  # the runs are linked whole
        np.testing.assert_array_equal(f["runs/run_000002/data/y"][()], f["y"][2])


# -- failures, resume, interruption ----------------------------------------------------------

def test_every_group_of_a_sweep_s_run_file_is_where_the_declared_layout_says(three_ways):
    """The run file's layout is declared once (daq.run_layout): every declared path is in a
    sweep's run file, and every group of its entry is declared."""
    from daq import run_layout as layout

    _, out = three_ways
    paths = [v for v in (getattr(layout, n) for n in layout.__all__)
             if isinstance(v, str) and v.split("/")[0] == layout.ENTRY]
    with h5py.File(out["one"] / "runs/run_000000.h5", "r") as f:
        assert [p for p in paths if p not in f] == []
        declared = {layout.name_of(p) for p in paths}
        assert sorted(set(f[layout.ENTRY]) - declared) == []


def test_the_plan_estimates_each_run_file_as_the_acquisition_s_preflight_does(three_ways):
    """One size estimate of a run file: the dry run's per run equals daq acquire's preflight
    for the same scene, and bounds the file written (nothing compressed is counted)."""
    from daq.hdf5 import read_run
    from daq.resources import estimate_needs

    path, out = three_ways
    for p in plan_runs(load_sweep(path)):
        f = out["one"] / "runs" / p.spec.name
        h = read_run(f).header
        needs = estimate_needs(records=h.plan.records, samples=h.plan.samples,
                               channels=len(h.channels), bodies=h.scene.chain.n,
                               truth=bool(h.truth))
        assert p.bytes_estimate == needs.file_bytes
        assert 0 < f.stat().st_size <= p.bytes_estimate


def test_an_invalid_parameter_set_is_recorded_and_the_sweep_goes_on(tmp_path):
    # run 1: the scene rejects q1 < 0 (found while planning); run 2: a single 10 s record gives
    # one average, which the analyzer refuses (found in the worker)
    path = tmp_path / "s.toml"
    path.write_text('seed = 9\nscene = "ishizaki2009"\nset = ["acquisition.record_s=10", '
                    '"acquisition.settle_s=10"]\n[grid]\ncombine = "zip"\n'
                    '"pendulum.q1" = [300.0, -2.0, 300.0]\n"acquisition.records" = [2, 2, 1]\n')
    out = tmp_path / "ds"
    res = invoke("dataset", path, "--out", out, "--workers", "1")
    assert res.exit_code == 4, res.output  # a partial sweep
    t = rows(out)
    assert [r["status"] for r in t] == ["complete", "failed", "failed"]
    assert t[1]["error"] == "pendulum.q1 = -2.0 is invalid: expected > 0"
    assert t[2]["error"].startswith("1 record x 1 FFT = 1 average")
    assert t[1]["file"] == t[2]["file"] == "" and t[0]["file"] == "run_000000.h5"
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["run_000000.h5"]
    assert "run 2 failed: 1 record x 1 FFT" in res.output
    assert check_run_file(out / "runs/run_000000.h5", sha256=t[0]["sha256"]).ok


def test_a_rerun_skips_finished_runs_redoes_damaged_ones_and_a_changed_sweep_needs_force(
        tmp_path, three_ways):
    # starts from a copy of the shared 3-run sweep made on 1 worker (no sweep of its own first)
    src_path, done = three_ways
    path = tmp_path / src_path.name
    shutil.copyfile(src_path, path)
    out = tmp_path / "ds"
    shutil.copytree(done["one"], out)
    first = {p.name: (p.stat().st_mtime_ns, p.stat().st_ino) for p in (out / "runs").iterdir()}
    res = invoke("dataset", path, "--out", out, "--workers", "1")
    assert res.exit_code == 0 and "3 of 3 runs complete (3 already there)" in res.output
    assert {p.name: (p.stat().st_mtime_ns, p.stat().st_ino)
            for p in (out / "runs").iterdir()} == first
    # runs 1 and 2 change (0.10, 0.15 -> 0.15, 0.25 V rms), run 0 keeps its 0.05
    path.write_text(path.read_text().replace("linspace = [0.05, 0.15]", "linspace = [0.05, 0.25]"))
    res = invoke("dataset", path, "--out", out, "--workers", "1")
    assert res.exit_code == 1
    assert "holds another version of this sweep; changed: grid: " in res.output
    assert '"args": [0.05, 0.15, 3]' in res.output and '"args": [0.05, 0.25, 3]' in res.output
    assert "pass --force to apply the changes" in res.output
    res = invoke("dataset", path, "--out", out, "--workers", "1", "--force")
    assert res.exit_code == 0, res.output
    assert "3 of 3 runs complete (1 already there)" in res.output
    now = {p.name: (p.stat().st_mtime_ns, p.stat().st_ino) for p in (out / "runs").iterdir()}
    assert now["run_000000.h5"] == first["run_000000.h5"]  # unchanged run: kept
    assert now["run_000002.h5"] != first["run_000002.h5"]  # changed run: redone
    with h5py.File(out / "runs/run_000002.h5", "r") as f:
        assert json.loads(f["entry/dataset"].attrs["parameters_json"]) == {
            "source.level_vrms": 0.25}
    # a damaged file (one flipped byte: its sha256 no longer agrees) is set aside and redone
    f = out / "runs/run_000000.h5"
    data = bytearray(f.read_bytes())
    data[len(data) // 2] ^= 0xFF
    f.write_bytes(bytes(data))
    res = invoke("dataset", path, "--out", out, "--workers", "1", "--force")
    assert res.exit_code == 0 and "3 of 3 runs complete (2 already there)" in res.output
    assert (out / "runs/run_000000.h5.invalid-0").read_bytes() == bytes(data)
    assert check_run_file(f, sha256=rows(out)[0]["sha256"]).ok


def _daq(*args) -> list[str]:
    return [sys.executable, "-m", "daq.cli", *map(str, args)]


def _wait_for(cond, timeout_s=120.0):
    t = time.monotonic()
    while not cond():
        assert time.monotonic() - t < timeout_s, "timed out"
        time.sleep(0.05)


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True)
    return [int(x) for x in out.stdout.split()]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")
    return stat.exists() and stat.read_text().split()[2] != "Z"


def test_sigkill_of_the_parent_then_the_same_command_completes_every_run_exactly_once(tmp_path):
    path = sweep_file(tmp_path, '[random]\ncount = 3\n"pendulum.q2" = { uniform = [80.0, 120.0] }')
    out = tmp_path / "ds"
    cmd = _daq("dataset", path, "--out", out, "--workers", "1")
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = out / "journal.jsonl"
    _wait_for(lambda: journal.exists() and len(journal.read_text().splitlines()) >= 1)
    workers = _children(p.pid)
    p.send_signal(signal.SIGKILL)
    p.wait()
    _wait_for(lambda: not any(_alive(w) for w in workers), 30)  # they die with the parent
    done_before = len(journal.read_text().splitlines())
    assert done_before < 3
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert f"3 of 3 runs complete ({done_before} already there)" in res.stdout
    t = rows(out)
    assert [int(r["run"]) for r in t] == list(range(3)) and {r["status"] for r in t} == {
        "complete"}
    names = sorted(p.name for p in (out / "runs").iterdir())
    assert names == [f"run_{i:06d}.h5" for i in range(3)]  # no partial or duplicate left
    for r in t:
        assert check_run_file(out / "runs" / r["file"], sha256=r["sha256"]).ok


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs Linux's /proc to see a zombie")
def test_a_killed_writer_s_partial_file_is_removed_even_before_its_zombie_is_reaped(tmp_path):
    """A worker killed with its sweep stays a zombie until its new parent reaps it (a
    container's init may do so late): it writes nothing more, so the next run of the command
    removes its temporary file; a live writer's stays."""
    import socket

    from processing.dataset.runner import _clean_partials

    z = subprocess.Popen([sys.executable, "-c", "pass"])
    _wait_for(lambda: Path(f"/proc/{z.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
              == "Z", 30)  # exited, not reaped
    host = socket.gethostname().replace(".", "-")
    runs = tmp_path / "runs"
    runs.mkdir()
    dead = runs / f".run_000001.h5.{host}.{z.pid}.0123abcd.partial.h5"
    live = runs / f".run_000002.h5.{host}.{os.getpid()}.0123abcd.partial.h5"
    dead.write_bytes(b"")
    live.write_bytes(b"")
    _clean_partials(runs)
    z.wait()
    assert not dead.exists() and live.exists()


def test_ctrl_c_stops_cleanly_keeping_finished_runs_and_the_manifest_says_what_is_missing(
        tmp_path):
    path = sweep_file(tmp_path, '[random]\ncount = 6\n"pendulum.q2" = { uniform = [80.0, 120.0] }')
    out = tmp_path / "ds"
    p = subprocess.Popen(_daq("dataset", path, "--out", out, "--workers", "1"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    journal = out / "journal.jsonl"
    _wait_for(lambda: journal.exists() and len(journal.read_text().splitlines()) >= 1)
    os.killpg(p.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole process group
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "Traceback" not in err
    t = rows(out)
    complete = [r for r in t if r["status"] == "complete"]
    assert 1 <= len(complete) < 6 and {r["status"] for r in t} <= {"complete", "missing"}
    assert f"interrupted (SIGINT): {len(complete)} of 6 runs complete, 0 failed, {6 - len(complete)} " \
           "missing" in err
    assert sorted(p.name for p in (out / "runs").iterdir()) == sorted(r["file"] for r in complete)
    for r in complete:
        assert check_run_file(out / "runs" / r["file"], sha256=r["sha256"]).ok


def test_a_worker_that_dies_is_retried_a_bounded_number_of_times_then_recorded_failed(tmp_path):
    """A watcher SIGKILLs every worker that starts writing run 1 (its temporary file names the
    worker's pid): run 1 is tried 1 + max_retries times, then failed; the others complete."""
    sweep = load_sweep(sweep_file(tmp_path, GRID3))
    out = tmp_path / "ds"
    killed, stop = [], threading.Event()

    def watch():
        while not stop.is_set():
            for p in (out / "runs").glob(".run_000001.h5.*.partial.h5") if (out / "runs").exists() \
                    else ():
                pid = int(p.name.split(".")[-4])
                if pid not in killed:
                    killed.append(pid)
                    os.kill(pid, signal.SIGKILL)
            time.sleep(0.01)

    w = threading.Thread(target=watch, daemon=True)
    w.start()
    try:
        result = run_sweep(sweep, out, workers=1, max_retries=1, planned=plan_runs(sweep))
    finally:
        stop.set()
        w.join()
    assert len(killed) == 2
    assert result.complete == 2 and result.failed == 1
    t = rows(out)
    assert [r["status"] for r in t] == ["complete", "failed", "complete"]
    assert t[1]["error"] == ("BrokenProcessPool: the worker running it died 2 times (killed or "
                             "out of memory)")
