"""The daq command line (click's CliRunner): outputs, formats, refusals and error messages."""

import csv
import json

import numpy as np
import pytest
from click.testing import CliRunner

from daq.cli import main
from rig.describe import mirror_response
from rig.scene import load_scene


@pytest.fixture
def runner():
    return CliRunner()


def test_scene_list_names_every_preset(runner):
    res = runner.invoke(main, ["scene", "list"])
    assert res.exit_code == 0, res.output
    for name in ("ishizaki2009", "double-rod", "rod-chain"):
        assert name in res.output


def test_scene_show_json_has_si_parameters_design_and_frequencies(runner):
    res = runner.invoke(main, ["scene", "show", "ishizaki2009", "--json"])
    assert res.exit_code == 0, res.output
    s = json.loads(res.output)
    assert s["scene"]["chain"]["mass_kg"][0] == pytest.approx(0.05314, abs=1e-5)
    assert s["design"]["alpha"] == pytest.approx(0.0292, abs=5e-5)
    f = s["derived"]["natural_frequencies_hz"]
    assert f[0] == pytest.approx(0.83, abs=0.01) and f[1] == pytest.approx(2.48, abs=0.01)
    assert s["derived"]["modes"][1]["q"] == pytest.approx(530, rel=0.01)


def test_scene_show_applies_overrides_and_reports_bad_ones(runner):
    res = runner.invoke(main, ["scene", "show", "rod-chain", "--set", "pendulum.n=4", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["scene"]["chain"]["n"] == 4
    res = runner.invoke(main, ["scene", "show", "rod-chain", "--set", "pendulum.n=-3"])
    assert res.exit_code != 0
    assert "pendulum.n = -3 is invalid: expected 1 <= n <= 200" in res.output


def test_model_csv_has_the_documented_columns_and_equals_the_direct_solve(runner, tmp_path):
    out = tmp_path / "m.csv"
    res = runner.invoke(main, ["model", "ishizaki2009", "--csv", str(out), "--points", "50"])
    assert res.exit_code == 0, res.output
    with open(out) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg",
                       "y_re", "y_im", "y_gain_db", "y_phase_deg"]
    data = np.array(rows[1:], float)
    assert data.shape == (50, 9)
    np.testing.assert_allclose(data[[0, -1], 0], [0.1, 10.0], rtol=1e-12)
    resp = mirror_response(load_scene("ishizaki2009"), data[:, 0])
    np.testing.assert_array_equal(data[:, 1] + 1j * data[:, 2], resp.x)  # written with repr
    np.testing.assert_array_equal(data[:, 5] + 1j * data[:, 6], resp.y)
    # SPEC section 5: phase 180 deg at low frequency for both channels
    assert abs(abs(data[0, 4]) - 180) < 1 and abs(abs(data[0, 8]) - 180) < 1


def test_model_plot_writes_a_png(runner, tmp_path):
    out = tmp_path / "bode.png"
    res = runner.invoke(main, ["model", "ishizaki2009", "--plot", str(out), "--points", "200"])
    assert res.exit_code == 0, res.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_model_refuses_to_overwrite_without_force_and_keeps_the_file(runner, tmp_path):
    out = tmp_path / "m.csv"
    out.write_text("precious")
    res = runner.invoke(main, ["model", "ishizaki2009", "--csv", str(out)])
    assert res.exit_code != 0
    assert "exists; pass --force to overwrite it" in res.output
    assert out.read_text() == "precious"
    res = runner.invoke(main, ["model", "ishizaki2009", "--csv", str(out), "--force"])
    assert res.exit_code == 0, res.output
    assert out.read_text().startswith("frequency_hz")


@pytest.mark.parametrize("args, message", [
    (["--fmin", "0"], "fmin = 0.0 Hz is invalid: expected a finite frequency > 0"),
    (["--fmin", "5", "--fmax", "1"], "fmax = 1.0 Hz is invalid: expected a finite frequency > fmin"),
    (["--points", "1"], "1 is not in the range x>=2"),
])
def test_model_rejects_bad_frequency_grids(runner, tmp_path, args, message):
    res = runner.invoke(main, ["model", "ishizaki2009", "--csv", str(tmp_path / "m.csv"), *args])
    assert res.exit_code != 0
    assert message in res.output
    assert not (tmp_path / "m.csv").exists()


def test_model_output_in_a_missing_directory_is_refused(runner, tmp_path):
    res = runner.invoke(main, ["model", "ishizaki2009", "--csv", str(tmp_path / "no" / "m.csv")])
    assert res.exit_code != 0
    assert "does not exist" in res.output


def test_simulate_csv_has_the_documented_columns_a_sample_every_second_and_its_error(runner,
                                                                                     tmp_path):
    out = tmp_path / "t.csv"
    res = runner.invoke(main, ["simulate", "double-rod", "--duration", "3", "--method", "rk4",
                               "--dt", "0.001", "--out", str(out)])
    assert res.exit_code == 0, res.output
    lines = out.read_text().splitlines()
    meta = {l[2:].split(": ", 1)[0]: l[2:].split(": ", 1)[1] for l in lines if l.startswith("# ")}
    assert meta["method"] == "rk4"
    assert float(meta["max_error_estimate_rad"]) > 0
    assert "Richardson" in meta["error_method"]
    rows = [l for l in lines if not l.startswith("#")]
    assert rows[0] == "t,theta_1,theta_2,omega_1,omega_2,energy"
    data = np.array([r.split(",") for r in rows[1:]], float)
    np.testing.assert_array_equal(data[:, 0], [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(data[0, 1:3], [2.0, 2.5])  # the preset's initial angles
    # undamped, fixed base: energy conserved within the estimate's order of magnitude
    assert np.ptp(data[:, -1]) < 1e-6 * abs(data[0, -1])


def test_simulate_hdf5_opens_with_xarray_and_records_the_method(runner, tmp_path):
    xr = pytest.importorskip("xarray")
    out = tmp_path / "t.h5"
    res = runner.invoke(main, ["simulate", "ishizaki2009", "--duration", "2", "--theta0",
                               "0.05,0", "--out", str(out)])
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out, group="trajectory", engine="h5netcdf") as ds:
        assert ds["theta"].dims == ("t", "body")
        assert ds["theta"].attrs["units"] == "rad"
        assert ds.attrs["method"] == "dop853"
        assert float(ds["theta"][0, 0]) == 0.05


@pytest.mark.parametrize("args, message", [
    (["--duration", "0"], "duration_s = 0.0 is invalid"),
    (["--duration", "1", "--theta0", "0.1,x"], "is not a comma-separated list of numbers"),
    (["--duration", "1", "--theta0", "0.1,0.2,0.3"], "theta0"),
    (["--duration", "1", "--rtol", "1e-6", "--dt", "0.01"], "not both"),
    (["--duration", "1", "--method", "euler"], "'euler' is not one of"),
])
def test_simulate_rejects_bad_input_and_writes_nothing(runner, tmp_path, args, message):
    out = tmp_path / "t.csv"
    res = runner.invoke(main, ["simulate", "double-rod", *args, "--out", str(out)])
    assert res.exit_code != 0
    assert message in res.output
    assert not out.exists()


def test_simulate_refuses_an_unknown_extension_and_an_existing_file(runner, tmp_path):
    res = runner.invoke(main, ["simulate", "double-rod", "--duration", "1", "--out",
                               str(tmp_path / "t.txt")])
    assert res.exit_code != 0 and "unknown extension '.txt'" in res.output
    out = tmp_path / "t.csv"
    out.write_text("keep")
    res = runner.invoke(main, ["simulate", "double-rod", "--duration", "1", "--out", str(out)])
    assert res.exit_code != 0 and "exists; pass --force" in res.output
    assert out.read_text() == "keep"
