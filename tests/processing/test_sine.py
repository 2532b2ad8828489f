"""The stepped-sine measurement against the exact response: peak, notch, harmonics, the CLI,
its files and their readers."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import rig
from processing.sine_sweep import SineSettings, measure_sine

#: The accuracy settings (README, BENCHMARKS.md): auto resolution 2 dB / 20 deg, the mirror's
#: rotation held at 3e-4 rad by auto level (the paper's 0.1 V pushes the spot off the PSD at
#: the 0.83 Hz mode; 3e-4 rad keeps the sweep in the linear regime the error budget chooses),
#: at most 1 V, each window continued until the random error is 0.02 dB (1 sigma), the settle
#: from the poles (transient bound 1e-3 of each channel: a bias below ~0.02 dB)
ACCURACY = dict(auto_level=("y", 3e-4, 0.2), level_limit_vrms=1.0, points=50,
                auto_resolution=(2.0, 20.0), random_error_db=0.02, max_integrate_s=20000.0)
DB_TOL, DEG_TOL = 0.1, 0.5  # the issue's: 5 random errors of 0.02 dB (0.115 deg)


def _band(fmin, fmax, **kw):
    scene = rig.load_scene("ishizaki2009")
    return scene, measure_sine(scene, SineSettings(fmin_hz=fmin, fmax_hz=fmax,
                                                   **{**ACCURACY, **kw}), seed=2009)


@pytest.mark.parametrize("fmin, fmax, target, refined", [(2.40, 2.56, 2.4794, 4),
                                                          (4.55, 4.75, 4.6608, 1.6)],
                         ids=["peak", "notch"])
def test_sweep_matches_exact_response_at_peak_and_notch(fmin, fmax, target, refined):
    # the grid's step here is (fmax/fmin)^(1/49): ~3 mHz at the peak, ~4 mHz at the notch;
    # auto resolution refines it where the response changes fast
    scene, sweep = _band(fmin, fmax)
    assert sweep.model_info["model"] == "linear"  # chosen by the error budget
    f = sweep.column("frequency_hz")
    assert np.min(np.abs(f - target)) < 2.4e-3  # within the 2.48 Hz mode's half bandwidth
    for p in sweep.points:
        for name in ("h_t", "theta_2"):
            db, deg = p.gain_phase_error(name)
            assert abs(db) <= DB_TOL and abs(deg) <= DEG_TOL, (p.frequency_hz, name, db, deg)
            b_db, b_deg = p.bias_db_deg(name)
            assert abs(b_db) < 0.02 and abs(b_deg) < 0.12  # the settle rule's bound
            e_db, _ = p.error_db_deg(name)
            assert e_db <= 0.0201 or p.integrate_s >= 19000  # target met or window at its cap
        assert p.saturated.sum() == 0 and p.clipped.sum() == 0
        # auto level: the mirror's rotation within 20 % of 3e-4 rad, or the level at its cap
        y = abs(p.harmonics[2, 0])
        assert abs(y / 3e-4 - 1) <= 0.2 or p.level_vrms == pytest.approx(1.0), (p.frequency_hz, y)
    # auto resolution: steps below the grid's where the response turns fast (halved twice
    # at the Q ~ 300 peak, at least once in the notch, whose 2 dB takes ~4 mHz)
    grid_step = fmin * ((fmax / fmin) ** (1 / 49) - 1)
    assert np.min(np.diff(f)) < grid_step / refined
    assert np.all(np.diff(f) > 0)  # up, in order


def test_lever_predicts_the_2f_components():
    # near the 0.83 Hz mode at 0.1 V the mirror's rotation is ~4e-3 rad: the lever's
    # second-order terms (x: -D cos(phi) theta^2, y: -cos(2 phi)/(D cos(phi)) dx theta) are
    # above the noise; measured against predicted within 3 % (the lever's third-order
    # terms are ~theta^2 ~ 1e-5 of them) plus 4 random errors of the coefficient (each part's
    # sigma from the channel's residual noise)
    scene = rig.load_scene("ishizaki2009", ["acquisition.model=linear"])
    sweep = measure_sine(scene, SineSettings(fmin_hz=0.76, fmax_hz=0.78, points=2,
                                             level_vrms=0.1, integrate_s=300.0), seed=4)
    for p in sweep.points:
        for i, c in ((1, "x"), (2, "y")):
            measured, predicted = p.harmonics[i, 1], p.lever_2f[i - 1]
            sigma = p.coef_sd[i]
            assert abs(measured - predicted) < 0.03 * abs(predicted) + 4 * math.sqrt(2) * sigma
            assert abs(predicted) > 10 * sigma  # the comparison means something
        assert p.saturated.sum() == 0


def test_large_drive_shows_the_pendulums_odd_harmonics():
    # at 0.3 V near the 2.48 Hz mode the nonlinear model runs (the error budget says so) and
    # the third harmonic of the mirror's translation stands 10 x above the linear model's
    # (whose third harmonic is only the lever's geometry and noise)
    out = {}
    for model in ("linear", "nonlinear"):
        scene = rig.load_scene("ishizaki2009", [f"acquisition.model={model}"])
        sweep = measure_sine(scene, SineSettings(fmin_hz=2.40, fmax_hz=2.41, points=2,
                                                 level_vrms=0.3, settle_s=300.0,
                                                 integrate_s=40.0), seed=6)
        out[model] = np.array([abs(p.harmonics[1, 2]) for p in sweep.points])
    assert np.all(out["nonlinear"] > 10 * out["linear"]), out


def _daq(*args, cwd):
    return subprocess.run([sys.executable, "-m", "daq.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("args, words", [
    (["--auto-resolution", "2"], ["--auto-resolution", "'2'", "DB,DEG"]),
    (["--auto-level", "q,1,0.1"], ["--auto-level", "'q,1,0.1'", "channel a, x or y"]),
    (["--fmin", "10", "--fmax", "1"], ["fmin_hz = 10.0", "fmax_hz"]),
    (["--settle-s", "10", "--settle-cycles", "3"], ["--settle-cycles and --settle-s"]),
    (["--fmax", "60"], ["fmax_hz = 60.0", "half the output rate"]),
    (["--level", "2", "--level-limit", "1"], ["level_vrms = 2.0", "level_limit_vrms"]),
    (["--harmonics", "0"], ["harmonics = 0", "1..20"]),
    (["--level", "0.1", "--auto-level", "y,1e-3,0.1"], ["--level and --auto-level"]),
])
def test_cli_refuses_bad_options_in_one_line(tmp_path, args, words):
    r = _daq("sine", "ishizaki2009", "--out", "s.h5", *args, cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    line = r.stderr.strip()
    assert "\n" not in line and "Traceback" not in line and line.startswith("Error:"), line
    for w in words:
        assert w in line, line
    assert not (tmp_path / "s.h5").exists()


def test_cli_files_open_in_every_reader(tmp_path):
    import h5py
    import pyuff
    import xarray as xr

    r = _daq("sine", "ishizaki2009", "--fmin", "2.3", "--fmax", "2.6", "--points", "4",
             "--auto-level", "y,3e-4,0.2", "--out", "s.h5", "--csv", "s.csv", "--uff", "s.uff",
             "--report", "r.md", "--plot", "b.png", "--keep-records", "--random-error", "0", "-q",
             cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    ds = xr.open_dataset(tmp_path / "s.h5", group="entry/sweep", engine="h5netcdf")
    assert ds.sizes["point"] == 4 and ds.sizes["harmonic"] == 5
    assert ds["h_t_gain_db"].attrs["units"] == "dB"
    rec = xr.open_dataset(tmp_path / "s.h5", group="entry/records", engine="h5netcdf")
    assert int(rec["samples"].sum()) == rec.sizes["sample"]
    assert (tmp_path / "s.h5").read_bytes()[8] == 3  # superblock v3: the v110 bounds
    with h5py.File(tmp_path / "s.h5", "r") as f:
        assert all(f["entry/sweep"][k].fletcher32 for k in f["entry/sweep"]
                   if f["entry/sweep"][k].chunks)
        assert f["entry/status"][()] == b"complete"
    csv = np.genfromtxt(tmp_path / "s.csv", delimiter=",", names=True)
    assert np.allclose(csv["x_gain_db"], ds["h_t_gain_db"].values, rtol=0, atol=1e-12)
    sets = pyuff.UFF(str(tmp_path / "s.uff")).read_sets()
    assert [s["func_type"] for s in sets] == [4, 4]
    h = sets[0]["data"]
    assert np.allclose(h, csv["x_re"] + 1j * csv["x_im"], rtol=1e-10)  # ASCII: 12 digits
    # an uneven abscissa is an E13.5 field in ASCII UFF 58: 6 significant digits (5e-6)
    assert np.allclose(sets[0]["x"], csv["frequency_hz"], rtol=5e-6, atol=0)
    chk = _daq("check", "s.h5", "--json", cwd=tmp_path)
    assert chk.returncode == 0 and json.loads(chk.stdout)[0]["kind"] == "sine"
    ins = _daq("inspect", "s.h5", "--json", cwd=tmp_path)
    info = json.loads(ins.stdout)
    assert ins.returncode == 0 and info["points"] == 4 and info["records_kept"]
    assert "## Accuracy against the exact response" in (tmp_path / "r.md").read_text()


def test_cli_check_names_a_cut_sine_file(tmp_path):
    r = _daq("sine", "ishizaki2009", "--fmin", "1", "--fmax", "2", "--points", "2", "--out",
             "s.h5", "--random-error", "0", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = (tmp_path / "s.h5").read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[: len(data) * 2 // 3])
    chk = _daq("check", "cut.h5", cwd=tmp_path)
    assert chk.returncode == 1 and "truncated" in chk.stdout
    assert math.isfinite(len(data))


def test_sweep_down_runs_the_grid_in_reverse():
    scene = rig.load_scene("ishizaki2009", ["acquisition.model=linear"])
    sweep = measure_sine(scene, SineSettings(fmin_hz=1.0, fmax_hz=2.0, points=3, direction="down",
                                             level_vrms=0.05), seed=1)
    f = sweep.column("frequency_hz")
    assert f[0] == pytest.approx(2.0, rel=1e-3) and f[-1] == pytest.approx(1.0, rel=1e-3)
    assert np.all(np.diff(f) < 0)


def test_sine_file_is_readable_while_the_sweep_writes_it(tmp_path):
    # a SWMR reader opens the growing file after each point and finds at least
    # points_complete rows in every per-point dataset
    import h5py

    from daq.sine_file import SineFileSink

    file_sink = SineFileSink(tmp_path / "s.h5")
    seen = []

    class Follower:
        def start(self, info):
            pass

        def point(self, row, record):
            with h5py.File(file_sink.path, "r", swmr=True) as f:
                n = int(f["entry/points_complete"][()])
                rows = f["entry/sweep/h_t_gain_db"].shape[0]
                seen.append((n, rows, f["entry/status"][()]))

        def stop(self, status):
            pass

    scene = rig.load_scene("ishizaki2009", ["acquisition.model=linear"])
    measure_sine(scene, SineSettings(fmin_hz=1.0, fmax_hz=2.0, points=3, level_vrms=0.05),
                 seed=1, sinks=[file_sink, Follower()])
    assert [s[0] for s in seen] == [1, 2, 3] and all(r >= n for n, r, _ in seen)
    assert all(s[2] == b"acquiring" for s in seen)
    with h5py.File(tmp_path / "s.h5", "r") as f:
        assert f["entry/status"][()] == b"complete" and int(f["entry/points_complete"][()]) == 3


def test_interrupted_sweep_keeps_its_finished_points(tmp_path):
    from daq.sine_file import SineFileSink, read_sine

    class CtrlC:
        def start(self, info):
            self.n = 0

        def point(self, row, record):
            self.n += 1
            if self.n == 2:
                raise KeyboardInterrupt

        def stop(self, status):
            pass

    scene = rig.load_scene("ishizaki2009", ["acquisition.model=linear"])
    with pytest.raises(KeyboardInterrupt):
        measure_sine(scene, SineSettings(fmin_hz=1.0, fmax_hz=2.0, points=4, level_vrms=0.05),
                     seed=1, sinks=[SineFileSink(tmp_path / "s.h5"), CtrlC()])
    d = read_sine(tmp_path / "s.h5")
    assert d["status"] == "interrupted" and d["points"] == 2  # the file sink wrote both
    assert list(tmp_path.iterdir()) == [tmp_path / "s.h5"]  # no partial file left


@pytest.mark.parametrize("module, option, extra", [("matplotlib", "--plot", "plot"),
                                                    ("pyuff", "--uff", "uff")])
def test_missing_extra_is_named_before_the_sweep(tmp_path, module, option, extra):
    code = (f"import sys; sys.modules[{module!r}] = None\n"
            "from daq.cli import run\n"
            f"sys.argv = ['daq', 'sine', 'ishizaki2009', '--out', 's.h5', {option!r}, "
            f"'out.{'png' if extra == 'plot' else 'uff'}']\n"
            "run()\n")
    res = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert f"pip install 'pendulum-daq[{extra}]'" in res.stderr.strip().splitlines()[-1]
    assert not list(tmp_path.iterdir())  # nothing simulated, nothing written
