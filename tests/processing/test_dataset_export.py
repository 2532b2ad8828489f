"""A finished sweep leaves the project as flat shards that other tools load unchanged, and a sweep
can keep only the signals (no analysis).

One raw-only sweep of 5 short runs (truth kept) is made once; the exports are read back with the
tools their users have: pyarrow, pandas and Hugging Face ``datasets`` for Parquet, numpy for npz.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from daq.hdf5 import read_run
from processing.dataset import check_run_file, load_sweep, parse_sweep, run_sweep
from processing.dataset.export import ExportSettings, assign_splits, export_dataset
from rig.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
LEVELS = [0.02, 0.05, 0.1, 0.15, 0.2]
SWEEP = f"""
name = "raw_only"
seed = 11
scene = "ishizaki2009"
set = ["acquisition.records=2", "acquisition.record_s=5"]
[grid]
"source.level_vrms" = {LEVELS}
[keep]
truth = true
analysis = false
"""


@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory):
    base = tmp_path_factory.mktemp("raw_only")
    (base / "sweep.toml").write_text(SWEEP)
    result = run_sweep(load_sweep(base / "sweep.toml"), base / "ds", workers=1)
    assert result.complete == len(LEVELS), result.results
    return base / "ds"


def _daq(*args, cwd):
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_raw_only_runs_are_complete_files_without_an_analysis(dataset_dir):
    for f in sorted((dataset_dir / "runs").glob("run_*.h5")):
        chk = check_run_file(f)
        assert chk.ok, chk.problems
        with h5py.File(f, "r") as h:
            assert "analysis" not in h["entry"]
            assert int(h["entry/dataset"].attrs["analysis"]) == 0
    import xarray as xr

    ds = xr.open_dataset(dataset_dir / "manifest.h5", engine="h5netcdf")
    assert ds.sizes["run"] == len(LEVELS) and "a" in ds and "H_t_real" not in ds
    assert (ds.status.values == "complete").all()


def test_default_keep_table_and_plans_are_unchanged_by_the_raw_only_key():
    base = 'seed = 3\nscene = "ishizaki2009"\n[grid]\n"pendulum.q1" = [300.0, 500.0]\n'
    plain = parse_sweep(__import__("tomllib").loads(base))
    explicit = parse_sweep(__import__("tomllib").loads(base + "[keep]\nanalysis = true\n"))
    assert "analysis" not in plain.keep
    assert [r.spec_hash for r in plain.runs()] == [r.spec_hash for r in explicit.runs()]
    raw = parse_sweep(__import__("tomllib").loads(base + "[keep]\nanalysis = false\n"))
    assert raw.keep["analysis"] is False and not raw.keep["frf"]
    assert raw.runs()[0].spec_hash != plain.runs()[0].spec_hash


def test_an_analysis_output_kept_without_the_analysis_is_refused_naming_both():
    text = 'seed = 3\nscene = "ishizaki2009"\n[keep]\nanalysis = false\nfrf = true\n'
    with pytest.raises(ConfigError, match=r"keep\.frf = true .* keep\.analysis = false"):
        parse_sweep(__import__("tomllib").loads(text))


def test_parquet_rows_equal_the_run_files_values_and_load_in_pyarrow_pandas_and_datasets(
        dataset_dir, tmp_path):
    import pyarrow.parquet as pq

    out = tmp_path / "ex"
    res = export_dataset(dataset_dir, out, ExportSettings(window_s=1.0, hop_s=0.5, truth=True,
                                                          drive=True))
    table = pq.read_table(out / "data")  # every shard of every split
    df = table.to_pandas()
    # 5 runs x 2 records x windows of 100 samples every 50 in 500: 9 per record
    assert len(df) == len(LEVELS) * 2 * 9 == sum(res.rows.values())
    assert table.schema.field("a").metadata == {b"unit": b"m/s^2"}
    assert table.schema.field("truth_mirror_rot").metadata == {b"unit": b"rad"}
    assert table.schema.field("drive").metadata == {b"unit": b"V"}
    row = df[(df.run == 3) & (df.record == 1) & (df.start_s == 2.0)].iloc[0]
    rec = read_run(dataset_dir / "runs" / "run_000003.h5")
    np.testing.assert_array_equal(np.asarray(row["x"]), rec.values("x")[1, 200:300])
    with h5py.File(dataset_dir / "runs" / "run_000003.h5", "r") as h:
        np.testing.assert_array_equal(np.asarray(row["drive"]),
                                      h["entry/truth/source_v"][1, 200:300])
    assert row["source.level_vrms"] == LEVELS[3] and row["seed"] == rec.header.seed

    from datasets import load_dataset

    hf = load_dataset("parquet", data_dir=str(out))
    assert {k: hf[k].num_rows for k in hf} == {k: v for k, v in res.rows.items() if v}
    first = hf["train"][0]
    assert len(first["y"]) == 100 and first["split"] == "train"


def test_splits_are_by_run_deterministic_and_byte_identical_when_made_again(dataset_dir,
                                                                           tmp_path):
    s = ExportSettings(split=(("train", 0.6), ("val", 0.2), ("test", 0.2)))
    a = export_dataset(dataset_dir, tmp_path / "a", s)
    b = export_dataset(dataset_dir, tmp_path / "b", s)
    runs = [set(v) for v in a.runs.values()]
    assert sum(len(r) for r in runs) == len(LEVELS) and set.union(*runs) == set(range(5))
    assert [len(a.runs[k]) for k in ("train", "val", "test")] == [3, 1, 1]
    for name, files in a.shards.items():
        for fa, fb in zip(files, b.shards[name]):
            assert fa.read_bytes() == fb.read_bytes()
    import pyarrow.parquet as pq

    for name, files in a.shards.items():
        df = pq.read_table(files[0]).to_pandas()
        assert set(df.run) == set(a.runs[name]) and (df.split == name).all()


def test_split_by_a_parameter_keeps_each_value_in_one_split():
    split = (("train", 0.5), ("test", 0.5))
    by_value = assign_splits([0.1, 0.2, 0.1, 0.3, 0.2, 0.4], split, seed=5)
    assert sorted(by_value) == [0.1, 0.2, 0.3, 0.4]
    assert sorted(by_value.values()) == ["test", "test", "train", "train"]
    assert assign_splits([0.4, 0.3, 0.2, 0.1], split, seed=5) == by_value  # order-free


def test_npz_shards_hold_the_same_rows_with_their_units(dataset_dir, tmp_path):
    res = export_dataset(dataset_dir, tmp_path / "npz", ExportSettings(format="npz"))
    rows = 0
    for name, files in res.shards.items():
        for f in files:
            z = np.load(f)
            assert z["a"].shape[1:] == (500,) and (z["split"] == name).all()
            assert json.loads(str(z["units_json"]))["y"] == "rad"
            rows += z["a"].shape[0]
            r = int(z["run"][0])
            rec = read_run(dataset_dir / "runs" / f"run_{r:06d}.h5")
            np.testing.assert_array_equal(z["a"][0], rec.values("a")[int(z["record"][0])])
    assert rows == len(LEVELS) * 2


@pytest.mark.parametrize("args, words", [
    (["--window-s", "0.123"], "window_s = 0.123 s is invalid: it must be a whole number of "
                              "samples at 100 Hz"),
    (["--split", "train=0.5,test=0.4"], "the fractions must be >= 0 and sum to 1"),
    (["--split-by", "pendulum.q9"], "split_by = 'pendulum.q9' is not a varied parameter of "
                                    "this dataset; valid: source.level_vrms"),
    (["--window-s", "10"], "longer than a record (5 s)"),
])
def test_bad_export_options_are_refused_in_one_sentence_before_writing(dataset_dir, tmp_path,
                                                                        args, words):
    out = tmp_path / "bad"
    p = _daq("dataset", "export", dataset_dir, "--out", out, *args, cwd=tmp_path)
    assert p.returncode == 1, p.stderr
    assert words in p.stderr and "Traceback" not in p.stderr
    assert not out.exists() or not any(out.rglob("*.parquet"))


def test_the_cli_export_prints_each_split_and_writes_a_card(dataset_dir, tmp_path):
    p = _daq("dataset", "export", dataset_dir, "--out", tmp_path / "cli", "--split",
             "train=0.8,test=0.2", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "train: " in p.stdout and "test: " in p.stdout
    card = (tmp_path / "cli" / "README.md").read_text()
    assert card.startswith("---\nconfigs:") and "| x | m |" in card
    assert "daq dataset export" in card and "--split train=0.8,test=0.2" in card


# -- the Zarr v3 index: virtual references read in place by xarray.open_zarr ------------------

def test_zarr_index_reads_the_run_files_values_in_place_through_xarray_open_zarr(dataset_dir):
    import xarray as xr

    from processing.dataset.zarr_index import INDEX, open_zarr_index, write_zarr_index

    index = write_zarr_index(dataset_dir, force=True)
    codes = open_zarr_index(dataset_dir, decode=False)
    assert codes.sizes["run"] == len(LEVELS)
    np.testing.assert_array_equal(codes["source.level_vrms"].values, LEVELS)
    for r in (0, 4):
        with h5py.File(dataset_dir / "runs" / f"run_{r:06d}.h5", "r") as h:
            for c in ("a", "x", "y"):  # the stored int16 codes, through gzip and fletcher32
                np.testing.assert_array_equal(codes[c].sel(run=r).values, h[f"entry/data/{c}"])
            np.testing.assert_array_equal(codes["truth_mirror_x_m"].sel(run=r).values,
                                          h["entry/truth/mirror_x_m"])
            np.testing.assert_array_equal(codes["model_h_t_real"].sel(run=r).values,
                                          h["entry/model/h_t_real"])
    # decoded like the manifest: volts through the codes' scale_factor
    volts = open_zarr_index(dataset_dir)
    man = xr.open_dataset(dataset_dir / "manifest.h5", engine="h5netcdf")
    np.testing.assert_array_equal(volts["y"].values, man["y"].values)
    # nothing copied: the repository holds references, not the chunks
    data_bytes = sum(f.stat().st_size for f in (dataset_dir / "runs").glob("*.h5"))
    index_bytes = sum(f.stat().st_size for f in index.rglob("*") if f.is_file())
    assert index_bytes < 0.1 * data_bytes, (index_bytes, data_bytes)
    assert index.name == INDEX


def test_zarr_index_names_the_files_where_readers_will_find_them(dataset_dir, tmp_path):
    import shutil

    from processing.dataset.zarr_index import open_zarr_index, write_zarr_index

    elsewhere = tmp_path / "served" / "runs"
    shutil.copytree(dataset_dir / "runs", elsewhere)
    url = f"file://{elsewhere}/"
    write_zarr_index(dataset_dir, chunks_url=url, force=True)
    moved = open_zarr_index(dataset_dir, chunks_url=url, decode=False)
    with h5py.File(elsewhere / "run_000002.h5", "r") as h:
        np.testing.assert_array_equal(moved["a"].sel(run=2).values, h["entry/data/a"])
    write_zarr_index(dataset_dir, force=True)  # back to the default for the other tests


def test_zarr_index_cli_refuses_to_replace_an_index_and_a_url_without_a_folder(dataset_dir,
                                                                              tmp_path):
    from processing.dataset.zarr_index import write_zarr_index

    write_zarr_index(dataset_dir, force=True)
    p = _daq("dataset", "index", dataset_dir, cwd=tmp_path)
    assert p.returncode == 1 and "index.icechunk exists" in p.stderr, p.stderr
    p = _daq("dataset", "index", dataset_dir, "--force", "--chunks-url", "s3://bucket/runs",
             cwd=tmp_path)
    assert p.returncode == 1 and "must end with '/'" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr
