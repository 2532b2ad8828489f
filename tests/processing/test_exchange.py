"""Runs and spectra leaving the project: engineering units in xarray and netCDF (daq.eu), UFF 58
time records and frequency responses read back by pyuff, and the README's h5py-only recipe.

Tolerances: the engineering-unit arrays are the analyzer's own (equal bit for bit); an
independent computation from the raw HDF5 attributes (code * scale_factor + add_offset, divided
by volts_per_unit) differs by at most one rounding of each of its two float operations (2 ulp
relative, 5e-16); ASCII UFF 58 keeps 12 significant digits (``%20.11e``: relative error <= 5e-12
of each real and imaginary part; we check 1e-11 of the largest magnitude, the parts being
compared one by one against the largest value of the set).
"""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import processing.analyzer
from daq.acquisition import acquire
from daq.cli import main
from daq.eu import to_xarray
from daq.hdf5 import Hdf5Sink, read_run
from processing.analyzer import AnalyzerSettings, analyze
from rig.scene import load_scene

SHORT = ["acquisition.records=3", "acquisition.record_s=20.0", "acquisition.settle_s=20.0"]
ASCII_RTOL = 1e-11


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("exchange") / "run.h5"
    acquire(load_scene("ishizaki2009", SHORT), seed=5, sinks=[Hdf5Sink(path)])
    return path


@pytest.fixture
def runner():
    return CliRunner()


def test_eu_arrays_are_the_ones_the_analyzer_transforms(run_file, monkeypatch):
    seen = {}
    real = processing.analyzer.segment_ffts

    def spy(data, *args, **kwargs):
        seen.update(data)
        return real(data, *args, **kwargs)

    monkeypatch.setattr(processing.analyzer, "segment_ffts", spy)
    rec = read_run(run_file)
    analyze(rec, AnalyzerSettings())
    ds = to_xarray(rec)
    assert set(seen) == {"a", "x", "y"}
    for c in "axy":
        np.testing.assert_array_equal(ds[c].values, seen[c])
    assert (ds.a.attrs["units"], ds.x.attrs["units"], ds.y.attrs["units"]) == ("m/s^2", "m", "rad")
    for v in ds.variables.values():
        assert "units" in v.attrs, v.name


def test_eu_equals_the_calibration_applied_from_the_raw_attributes(run_file):
    ds = to_xarray(read_run(run_file))
    with h5py.File(run_file, "r") as f:
        for c in "axy":
            d = f["entry/data"][c]
            eu = (d[()] * d.attrs["scale_factor"] + d.attrs["add_offset"]) / d.attrs["volts_per_unit"]
            np.testing.assert_allclose(ds[c].values, eu, rtol=5e-16, atol=0)
    volts = read_run(run_file).to_xarray(units="volts")
    assert volts.a.attrs["units"] == "V"
    np.testing.assert_array_equal(read_run(run_file).to_xarray()["y"].values, ds["y"].values)


def test_export_out_writes_an_eu_netcdf_that_xarray_opens(run_file, runner, tmp_path):
    import xarray as xr

    out = tmp_path / "eu.nc"
    res = runner.invoke(main, ["export", str(run_file), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert f"wrote {out}: 3 records of a, x, y in eu" in res.output
    ref = to_xarray(read_run(run_file))
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        for c in "axy":
            np.testing.assert_array_equal(ds[c].values, ref[c].values)
            assert ds[c].attrs["units"] == ref[c].attrs["units"]
        assert ds.time.attrs["units"] == "s" and ds.sizes == {"record": 3, "time": 2000}
    res = runner.invoke(main, ["export", str(run_file), "--out", str(out)])
    assert res.exit_code == 1 and "exists; pass --force" in res.output


@pytest.mark.parametrize("args, message", [
    ([], "nothing to export"),
    (["--out", "x.csv"], "a netCDF-4/HDF5 file is one of .nc, .h5, .hdf5"),
    (["--uff", "x.txt"], "a UFF file is one of .uff, .unv"),
])
def test_export_refuses_bad_outputs_with_one_line(run_file, runner, tmp_path, args, message):
    args = [str(tmp_path / a) if "." in a else a for a in args]
    res = runner.invoke(main, ["export", str(run_file), *args])
    assert res.exit_code in (1, 2) and message in res.output
    assert "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == []


def _close(got, want):
    scale = np.max(np.abs(want))
    assert np.max(np.abs(np.asarray(got) - want)) <= ASCII_RTOL * scale


def test_export_uff_writes_every_record_as_a_time_response_pyuff_reads(run_file, runner,
                                                                       tmp_path):
    import pyuff

    out = tmp_path / "time.uff"
    res = runner.invoke(main, ["export", str(run_file), "--uff", str(out)])
    assert res.exit_code == 0, res.output
    sets = pyuff.UFF(str(out)).read_sets()
    rec = read_run(run_file)
    assert len(sets) == 3 * 3
    expect = {"a": (1, 1, "m/s^2"), "x": (2, 1, "m"), "y": (2, -5, "rad")}
    for i, s in enumerate(sets):
        r, c = divmod(i, 3)
        name = "axy"[c]
        assert (s["type"], s["func_type"], s["load_case_id"]) == (58, 1, r + 1)
        assert (s["rsp_node"], s["rsp_dir"], s["ordinate_axis_units_lab"]) == expect[name]
        assert s["abscissa_axis_units_lab"] == "s" and s["id1"].startswith(f"{name}: ")
        np.testing.assert_allclose(s["x"], np.arange(2000) / 100.0, rtol=0, atol=1e-9)
        _close(s["data"], rec.values(name)[r])


def test_analyze_uff_writes_ht_theta2_and_coherence_that_pyuff_reads(run_file, runner,
                                                                     tmp_path):
    import pyuff

    out = tmp_path / "frf.uff"
    res = runner.invoke(main, ["analyze", str(run_file), "--uff", str(out)])
    assert res.exit_code == 0, res.output
    a = analyze(read_run(run_file), AnalyzerSettings())
    m = a.display
    sets = pyuff.UFF(str(out)).read_sets()
    assert [s["func_type"] for s in sets] == [4, 6, 4, 6]
    for s, want in zip(sets, (a.h_t.h[m], a.h_t.coherence[m], a.theta_2.h[m],
                              a.theta_2.coherence[m])):
        np.testing.assert_allclose(s["x"], a.freqs_hz[m], rtol=1e-9)
        _close(s["data"], want)
        assert (s["ref_node"], s["ref_dir"], s["ref_ent_name"]) == (1, 1, "stage")
        assert s["abscissa_axis_units_lab"] == "Hz"
    ht, th = sets[0], sets[2]
    assert (ht["rsp_node"], ht["rsp_dir"], ht["ordinate_axis_units_lab"],
            ht["orddenom_axis_units_lab"]) == (2, 1, "m", "m/s^2")
    assert (ht["ordinate_spec_data_type"], ht["orddenom_spec_data_type"]) == (8, 12)
    assert (th["rsp_node"], th["rsp_dir"], th["ordinate_axis_units_lab"]) == (2, -5, "rad")
    assert np.iscomplexobj(ht["data"]) and not np.iscomplexobj(sets[1]["data"])
    assert sets[1]["ordinate_axis_units_lab"] == "1"
    assert ht["id1"].startswith("H_t = W_ax/W_aa") and "seed 5" in ht["id2"]
    assert (ht["ordinate_axis_lab"], ht["orddenom_axis_lab"], ht["abscissa_axis_lab"]) == \
        ("mirror translation", "stage acceleration", "frequency")


def _readme_recipe() -> str:
    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    m = re.search(r"<!-- h5py-recipe -->\n```python\n(.*?)```", text, re.S)
    assert m, "README.md has no h5py-only recipe"
    return m.group(1)


def test_readmes_h5py_only_recipe_reads_the_run_and_spectra_files(run_file, runner, tmp_path):
    spectra = tmp_path / "spectra.h5"
    res = runner.invoke(main, ["analyze", str(run_file), "--spectra", str(spectra)])
    assert res.exit_code == 0, res.output
    code = _readme_recipe()
    assert "import daq" not in code and "processing" not in code and "rig" not in code
    ns = {}
    exec(compile(code.replace("run.h5", str(run_file)).replace("spectra.h5", str(spectra)),
                 "README recipe", "exec"), ns)
    rec = read_run(run_file)
    a = analyze(rec, AnalyzerSettings())
    for c in "axy":
        np.testing.assert_allclose(ns["eu"][c], rec.values(c), rtol=5e-16, atol=0)
    np.testing.assert_array_equal(ns["f"], a.freqs_hz)
    np.testing.assert_array_equal(ns["H_t"], a.h_t.h)
    np.testing.assert_array_equal(ns["coherence_x"], a.h_t.coherence)
