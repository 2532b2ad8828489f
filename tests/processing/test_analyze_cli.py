"""``daq analyze`` (click's CliRunner) on short emulated runs (6 records of 20 s: 50 mHz lines).

What each test proves:

* one call writes the CSV with exactly the documented columns in engineering units (x gain at
  0.2 Hz within 0.5 dB of 20 log10(l1/g) = -50.6 dB and within 4 sigma of the exact model, phase
  within 20 deg of 180: the accelerometer's high-pass turns it by -14 deg there), the PNG, the
  Markdown report and an HDF5 spectra file that xarray opens with a frequency axis in Hz and
  units on every variable; the run file is not modified; the summary names the settings, the
  averages, the fitted modes next to the exact ones, the bias at the peaks and the rotation
  reading;
* 35670A-style ``--lines/--span`` off the file's grid make the model be recomputed exactly;
* nothing is overwritten without ``--force`` (checked before any work: no output at all
  appears), and ``--force`` replaces;
* bad inputs fail with exit status 1 or 2 and a message naming the value and what is valid;
* an interrupted run is analysed with its finished records, and says so;
* importing the analyzer imports neither scipy nor matplotlib, and ``daq analyze`` without
  ``--plot`` never imports matplotlib (a fresh interpreter, so nothing else loaded them).
"""

from __future__ import annotations

import csv
import hashlib
import math
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from daq.acquisition import AcquisitionInterrupted, acquire
from daq.cli import main
from daq.hdf5 import Hdf5Sink, read_run
from daq.sinks import Sink
from processing.analyzer import analyze
from processing.writers import CSV_COLUMNS
from rig.scene import load_scene

SHORT = ["acquisition.records=6", "acquisition.record_s=20.0", "acquisition.settle_s=60.0"]


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "run.h5"
    acquire(load_scene("ishizaki2009", SHORT), seed=4, sinks=[Hdf5Sink(path)])
    return path


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_analyze_writes_csv_plot_report_and_spectra(runner, run_file, tmp_path):
    import xarray as xr

    before = _digest(run_file)
    out = {k: tmp_path / f"out.{k}" for k in ("csv", "png", "md", "h5")}
    res = runner.invoke(main, ["analyze", str(run_file), "--csv", str(out["csv"]), "--plot",
                               str(out["png"]), "--report", str(out["md"]), "--spectra",
                               str(out["h5"])])
    assert res.exit_code == 0, res.output
    assert _digest(run_file) == before  # the run file is only read
    for text in (f"analysed {run_file}: ishizaki2009, seed 4, 6 of 6 records x 20 s at 100 Hz "
                 "(complete)",
                 "hann window, 2000-sample FFT (20 s, 50 mHz lines), overlap 0%, rms averaging, "
                 "H1: 6 averages", "from the run file (its grid is the FFT lines",
                 "mode 1: exact 0.82676 Hz, Q 100.0", "mode 2: exact 2.47939 Hz, Q 528.9",
                 "Theta_2 leakage-aware", "H_t direct", "bias ", "|Theta_2/Theta_1| 6-10 Hz:",
                 f"wrote {out['csv']}", f"wrote {out['h5']}"):
        assert text in res.output

    with open(out["csv"], newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == CSV_COLUMNS
    data = np.array(rows[1:], dtype=float)
    col = {c: data[:, i] for i, c in enumerate(CSV_COLUMNS)}
    assert col["frequency_hz"][0] == pytest.approx(0.1) and col["frequency_hz"][-1] == 10.0
    assert np.all((col["x_coherence"] >= 0) & (col["x_coherence"] <= 1))
    assert np.all((col["y_coherence"] >= 0) & (col["y_coherence"] <= 1))
    np.testing.assert_allclose(col["x_gain_db"],
                               20 * np.log10(np.hypot(col["x_re"], col["x_im"])), rtol=1e-12)
    np.testing.assert_allclose(col["y_phase_deg"],
                               np.degrees(np.arctan2(col["y_im"], col["y_re"])), atol=1e-9)
    j = int(np.argmin(np.abs(col["frequency_hz"] - 0.2)))
    head = read_run(run_file).header
    l1, g = head.scene.chain.length_m[0], head.scene.chain.g_mps2
    assert col["x_gain_db"][j] == pytest.approx(20 * math.log10(l1 / g), abs=0.5)  # -50.6 dB
    assert abs(abs(col["x_phase_deg"][j]) - 180.0) < 20.0
    assert col["y_gain_db"][j] == pytest.approx(20 * math.log10(1 / g), abs=1.0)  # -19.8 dB
    k = int(np.argmin(np.abs(head.response.freqs_hz - 0.2)))
    model = head.response.values["h_t"][k]
    eps = math.sqrt(1 - col["x_coherence"][j]) / math.sqrt(2 * 6 * col["x_coherence"][j])
    assert abs(col["x_re"][j] + 1j * col["x_im"][j] - model) < 4 * eps * abs(model)

    assert out["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = out["md"].read_text(encoding="utf-8")
    for heading in ("# Analysis of run.h5: ishizaki2009, seed 4", "## Run", "## Model",
                    "## Modal fit", "## Leakage bias and random error at the peaks",
                    "## Residual statistics", "## Rotation isolation", "## Reading"):
        assert heading in md

    with xr.open_dataset(out["h5"], group="spectra", engine="h5netcdf") as ds:
        assert ds["frequency"].attrs["units"] == "Hz"
        assert ds.sizes["frequency"] == 1001  # 0 .. 50 Hz at 50 mHz
        for name, unit in (("G_aa", "(m/s^2)^2/Hz"), ("G_xx", "(m)^2/Hz"),
                           ("G_ax_real", "(m/s^2)(m)/Hz"), ("H_t_real", "m/(m/s^2)"),
                           ("Theta_2_imag", "rad/(m/s^2)"), ("coherence_y", "1"),
                           ("model_H_t_real", "m/(m/s^2)"),
                           ("expected_Theta_2_real", "rad/(m/s^2)")):
            assert ds[name].dims == ("frequency",) and ds[name].attrs["units"] == unit
        assert ds.attrs["window"] == "hann" and ds.attrs["nperseg"] == 2000
        assert ds.attrs["n_averages"] == 6 and ds.attrs["settings_fmax_hz"] == 10.0
        h = ds["H_t_real"].values + 1j * ds["H_t_imag"].values
        gx = ds["G_ax_real"].values + 1j * ds["G_ax_imag"].values
        np.testing.assert_allclose(h[1:], gx[1:] / ds["G_aa"].values[1:], rtol=1e-12)
        sel = ds["frequency"].sel(frequency=0.2).values
        assert sel == pytest.approx(0.2)
        # the expected coherence beside the measured one: the same numbers the analysis holds
        budget = analyze(read_run(run_file)).coherence_budget
        for c in ("x", "y"):
            assert ds[f"expected_coherence_{c}"].attrs["units"] == "1"
            np.testing.assert_array_equal(ds[f"expected_coherence_{c}"].values,
                                          budget.expected[c])


def test_lines_and_span_off_the_files_grid_recompute_the_model(runner, run_file):
    res = runner.invoke(main, ["analyze", str(run_file), "--lines", "160", "--span", "10",
                               "--window", "uniform"])
    assert res.exit_code == 0, res.output
    assert "uniform window, 1600-sample FFT (16 s, 62.5 mHz lines)" in res.output
    assert "6 averages" in res.output
    assert "recomputed exactly at the FFT lines" in res.output


def test_nothing_is_overwritten_without_force(runner, run_file, tmp_path):
    csv_path, report = tmp_path / "frf.csv", tmp_path / "report.md"
    csv_path.write_text("keep me")
    res = runner.invoke(main, ["analyze", str(run_file), "--report", str(report), "--csv",
                               str(csv_path)])
    assert res.exit_code == 1
    assert f"output '{csv_path}' exists; pass --force to overwrite it" in res.output
    assert csv_path.read_text() == "keep me" and not report.exists()
    assert "analysed" not in res.output  # refused before any work
    res = runner.invoke(main, ["analyze", str(run_file), "--report", str(report), "--csv",
                               str(csv_path), "--force"])
    assert res.exit_code == 0, res.output
    assert csv_path.read_text().startswith(",".join(CSV_COLUMNS))
    assert report.read_text(encoding="utf-8").startswith("# Analysis of run.h5")


@pytest.mark.parametrize("args, code, message", [
    (["{missing}"], 2, "does not exist"),
    (["{text}"], 1, "is not a readable HDF5 file"),
    (["{other_h5}"], 1, "is not a pendulum-daq run file"),
    (["{run}", "--window", "blackman"], 2,
     "Invalid value for '--window': 'blackman' is not one of 'uniform', 'hann', 'flattop'"),
    (["{run}", "--averaging", "peak"], 1, "averaging = 'peak' is invalid for this analysis"),
    (["{run}", "--nperseg", "4000"], 1,
     "nperseg = 4000 (40 s), longer than a record (2000 samples = 20 s): expected 2 <= nperseg "
     "<= 2000"),
    (["{run}", "--lines", "800", "--span", "10"], 1,
     "lines = 800, span_hz = 10 give a time record of 8000 samples (80 s), longer than a record"),
    (["{run}", "--lines", "800"], 1, "lines = 800, span_hz = None: give both"),
    (["{run}", "--lines", "100", "--span", "10", "--nperseg", "1000"], 1,
     "nperseg = 1000 and lines = 100 both given"),
    (["{run}", "--overlap", "1"], 2, "Invalid value for '--overlap': 1.0 is not in the range "
                                     "0.0<=x<1.0"),
    (["{run}", "--spectra", "{run}", "--force"], 2, "is the run file being analysed"),
])
def test_bad_inputs_give_clear_errors(runner, run_file, tmp_path, args, code, message):
    import h5py

    text = tmp_path / "notes.txt"
    text.write_text("not hdf5")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1.0
    subs = {"missing": str(tmp_path / "missing.h5"), "text": str(text), "other_h5": str(other),
            "run": str(run_file)}
    before = _digest(run_file)
    res = runner.invoke(main, ["analyze", *(a.format(**subs) for a in args)])
    assert res.exit_code == code, res.output
    assert message in res.output
    assert "Traceback" not in res.output
    assert _digest(run_file) == before


def test_an_interrupted_run_is_analysed_with_its_finished_records(runner, tmp_path):
    out = tmp_path / "cut.h5"
    sc = load_scene("ishizaki2009", ["acquisition.records=5", "acquisition.record_s=20.0",
                                     "acquisition.settle_s=60.0"])

    class CtrlC(Sink):  # Ctrl-C as the fourth record's first samples arrive, whatever the
        def block(self, block):  # bench's block length
            if block.record == 3:
                raise KeyboardInterrupt

    with pytest.raises(AcquisitionInterrupted):
        acquire(sc, seed=2, sinks=[Hdf5Sink(out), CtrlC()])
    assert read_run(out).status == "interrupted"
    csv_path = tmp_path / "frf.csv"
    res = runner.invoke(main, ["analyze", str(out), "--csv", str(csv_path)])
    assert res.exit_code == 0, res.output
    assert "3 of 5 records x 20 s at 100 Hz (INCOMPLETE, status interrupted)" in res.output
    assert "note: INCOMPLETE run (status interrupted): analysed the 3 finished records of 5 " \
           "planned" in res.output
    assert "H1: 3 averages" in res.output
    assert csv_path.read_text().startswith(",".join(CSV_COLUMNS))


def test_the_analyzer_imports_scipy_and_matplotlib_only_when_needed(run_file):
    code = (
        "import sys\n"
        "import processing, processing.analyzer, processing.compare, processing.modal\n"
        "import processing.report, processing.frf, processing.spectra\n"
        "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'matplotlib'})\n"
        "from click.testing import CliRunner\n"
        "from daq.cli import main\n"
        f"res = CliRunner().invoke(main, ['analyze', {str(run_file)!r}])\n"
        "assert res.exit_code == 0, res.output\n"
        "print(heavy, 'matplotlib' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["[]", "False"]
