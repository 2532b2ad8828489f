"""What a newcomer reads off the outputs is right: the model's CSV and figures show every
resonance and notch within 0.1 dB whatever --points says, a figure's format follows its
extension (an unknown one refused before any work), Theta_2's phase at +-180 deg is one band.
Real CLI in subprocesses, each bounded in time."""

import csv
import re
import time
from pathlib import Path

import numpy as np
import pytest

from cli_runs import daq, fast_run
from rig.describe import mirror_response
from rig.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
MAGIC = {".png": b"\x89PNG\r\n\x1a\n", ".pdf": b"%PDF-", ".svg": b"<?xml"}


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    return fast_run(tmp_path_factory.mktemp("run"))


def _columns(path):
    with open(path) as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    return {k: np.array([float(r[i]) for r in rows[1:]]) for i, k in enumerate(rows[0])}


def _true_extremum(channel, lo, hi, sign):
    """The largest (sign +1) or smallest (-1) gain [dB] of the exact model's channel over
    [lo, hi], by a grid of 2e6 points refined around its best point to 1e-9 Hz."""
    sc = load_scene("ishizaki2009")

    def gain(f):
        return 20 * np.log10(np.abs(getattr(mirror_response(sc, f), channel)))

    f = np.linspace(lo, hi, 2_000_001)
    for _ in range(4):
        g = gain(f)
        i = int(np.argmax(sign * g))
        step = f[1] - f[0]
        f = np.linspace(f[i] - 2 * step, f[i] + 2 * step, 2001)
    return float(sign * np.max(sign * gain(f)))


@pytest.mark.parametrize("points", [None, 10])
def test_model_csv_shows_the_peak_and_the_notch_within_a_tenth_of_a_db(tmp_path, points):
    extra = [] if points is None else ["--points", points]
    res = daq("model", "ishizaki2009", "--csv", "m.csv", *extra, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    c = _columns(tmp_path / "m.csv")
    f = c["frequency_hz"]
    base = 1000 if points is None else points
    assert f.size > base and np.all(np.diff(f) > 0) and f[0] == 0.1 and f[-1] == 10.0
    near_mode = (f > 2.4) & (f < 2.56)
    near_notch = (f > 4.5) & (f < 4.8)
    for col, ch in (("x_gain_db", "x"), ("y_gain_db", "y")):
        true_peak = _true_extremum(ch, 2.45, 2.51, +1)
        assert abs(c[col][near_mode].max() - true_peak) < 0.1, (col, true_peak)
    true_notch = _true_extremum("y", 4.6, 4.7, -1)
    assert abs(c["y_gain_db"][near_notch].min() - true_notch) < 0.1, true_notch
    assert f"{base} log-spaced" in res.stdout


def test_model_help_says_what_points_means(tmp_path):
    res = daq("model", "--help", cwd=tmp_path, timeout=60)
    text = " ".join(res.stdout.split())
    assert "base grid" in text and "within 0.1 dB" in text


@pytest.mark.parametrize("ext", [".png", ".pdf", ".svg"])
def test_model_plot_format_follows_the_extension(tmp_path, ext):
    res = daq("model", "ishizaki2009", "--plot", f"b{ext}", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / f"b{ext}").read_bytes().startswith(MAGIC[ext])


@pytest.mark.parametrize("name", ["b", "b.jpg", "b.txt"])
def test_an_unknown_figure_extension_is_refused_before_any_work(tmp_path, name):
    t0 = time.monotonic()
    res = daq("model", "ishizaki2009", "--csv", "m.csv", "--plot", name, cwd=tmp_path,
              timeout=60)
    assert res.returncode == 2
    assert ".png, .pdf, .svg" in res.stderr and "--plot" in res.stderr
    assert "Traceback" not in res.stderr
    assert list(tmp_path.iterdir()) == []  # not even the CSV
    assert time.monotonic() - t0 < 30


def test_analyze_plot_format_follows_the_extension(run_file, tmp_path):
    for ext in (".pdf", ".svg", ".png"):
        out = tmp_path / f"bode{ext}"
        res = daq("analyze", run_file, "--plot", out, cwd=tmp_path, timeout=300)
        assert res.returncode == 0, res.stderr
        assert out.read_bytes().startswith(MAGIC[ext]), ext
    res = daq("analyze", run_file, "--plot", tmp_path / "b.jpeg", "--csv", tmp_path / "f.csv",
              cwd=tmp_path, timeout=60)
    assert res.returncode == 2 and ".png, .pdf, .svg" in res.stderr
    assert not (tmp_path / "f.csv").exists()


def test_theta2_phase_is_drawn_on_one_branch_named_in_the_axis_label(run_file, tmp_path):
    """Theta_2 sits at +-180 deg between its 2.48 Hz mode and 4.66 Hz notch: the figure draws it
    on (-90, 270], where that stretch is one band (no model point within 45 deg of the cut
    there), and says so in the axis label."""
    from processing.phase_display import phase_branch, wrap_to

    res = daq("analyze", run_file, "--plot", "b.svg", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    svg = (tmp_path / "b.svg").read_text()
    assert svg.count("on (-90, 270]") >= 2  # both diagrams' phase axes (text kept as text)
    sc = load_scene("ishizaki2009")
    f = np.linspace(2.6, 4.5, 500)
    y = mirror_response(sc, f).y
    lo = phase_branch((f, y))
    p = wrap_to(np.degrees(np.angle(y)), lo)
    assert lo == -90.0 and np.all(np.abs(p - 180.0) < 45.0)
    # the branch depends on the response, not on how densely its steep parts are sampled
    from rig.describe import model_grid

    for points in (10, 1000, 20000):
        g = model_grid(sc, 0.1, 10.0, points)
        assert phase_branch((g, mirror_response(sc, g).y)) == -90.0, points


def test_analyze_at_0_hz_gives_no_high_pass_correction_and_says_why(run_file, tmp_path):
    res = daq("analyze", run_file, "--fmin", "0", "--report", "r.md", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    (line,) = [s for s in res.stdout.splitlines() if s.startswith("model:")]
    assert "no correction at 0 Hz: the high-pass passes nothing there" in line
    assert "dB" not in line and "nan" not in line.lower()
    report = (tmp_path / "r.md").read_text()
    assert "no correction at 0 Hz" in report and "nan" not in report.split("## Model")[1][:600]


def test_fmax_beyond_the_runs_band_is_refused_before_the_analysis(run_file, tmp_path):
    t0 = time.monotonic()
    res = daq("analyze", run_file, "--fmax", "50", "--csv", "f.csv", cwd=tmp_path, timeout=120)
    assert res.returncode == 2
    err = " ".join(res.stderr.split())
    assert "--fmax" in err and "passband ends at 40 Hz" in err and "give --fmax 40 or less" in err
    assert "Nyquist frequency of its 100 Hz rate is 50 Hz" in err
    assert not (tmp_path / "f.csv").exists()
    assert time.monotonic() - t0 < 60
    res = daq("analyze", run_file, "--fmax", "40", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr


def test_simulate_with_rrd_samples_and_estimates_as_without(tmp_path):
    common = ["simulate", "double-rod", "--duration", "3", "--method", "rk4"]
    plain = daq(*common, "--out", "a.csv", cwd=tmp_path, timeout=300)
    viewed = daq(*common, "--out", "b.csv", "--rrd", "b.rrd", cwd=tmp_path, timeout=300)
    assert plain.returncode == 0 and viewed.returncode == 0, plain.stderr + viewed.stderr

    def data(name):
        return [s for s in (tmp_path / name).read_text().splitlines() if not s.startswith("#")]

    def estimate(res):
        return [s for s in res.stdout.splitlines() if s.startswith("estimated max angle error")]

    assert data("a.csv") == data("b.csv") and len(data("a.csv")) == 1 + 4  # t = 0, 1, 2, 3 s
    assert estimate(plain) == estimate(viewed) and estimate(plain)
    assert "frames" in viewed.stdout and (tmp_path / "b.rrd").stat().st_size > 0


def test_view_screenshot_format_follows_the_extension(run_file, tmp_path):
    """A .jpg screenshot is JPEG (converted from the viewer's PNG); a .gif is refused before
    anything is replayed. The relative path is written where the user is (the viewer runs
    elsewhere)."""
    from processing.live_view import LiveViewError, screenshot_command

    res = daq("view", run_file, "--screenshot", "s.gif", cwd=tmp_path, timeout=60)
    assert res.returncode == 2 and ".png, .jpg, .jpeg" in res.stderr
    assert list(tmp_path.iterdir()) == []
    try:
        screenshot_command(tmp_path / "x.rrd", tmp_path / "x.png")
    except LiveViewError as exc:
        pytest.skip(f"the viewer cannot render here: {exc}")
    res = daq("view", run_file, "--screenshot", "s.jpg", cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "s.jpg").read_bytes()[:3] == b"\xff\xd8\xff"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.jpg"]  # no temporary left


def test_the_readme_scene_example_runs_as_asked_under_its_own_name(tmp_path):
    readme = (ROOT / "README.md").read_text()
    block = readme.split("```toml\nbase = ")[1].split("```")[0]
    (tmp_path / "mine.toml").write_text("base = " + block)
    res = daq("acquire", "mine.toml", "--seed", "1", "--out", "mine.h5", cwd=tmp_path,
              timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr  # within budget, nothing saturated
    assert "WARNING" not in res.stderr
    res = daq("inspect", "mine.h5", cwd=tmp_path)
    assert "scene: mine (mine.toml (base preset:ishizaki2009))" in res.stdout


def test_the_readme_names_only_what_exists(tmp_path):
    readme = (ROOT / "README.md").read_text()
    for path in set(re.findall(r"`(tests/[\w/]+\.py)`", readme)):
        assert (ROOT / path).is_file(), path
    (line,) = [s for s in readme.splitlines() if s.startswith("daq simulate") and "--method" in s]
    methods = line.split("--method ")[1].split("]")[0].split("|")
    for m in methods:  # every method listed runs on the fixed base
        res = daq("simulate", "double-rod", "--duration", "1", "--method", m, "--out",
                  f"{m}.csv", "--no-error-estimate", cwd=tmp_path, timeout=300)
        assert res.returncode == 0, (m, res.stderr)
