"""The run file: self-describing layout, xarray, round trip, reproducible bytes, and runs that end
early (KeyboardInterrupt, an exception, SIGKILL) leaving a valid file with every finished record."""

import json
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

import daq
from daq.acquisition import acquire
from daq.benches import FunctionBench
from daq.hdf5 import Hdf5Sink, open_run, read_run, run_info
from daq.repair import clear_write_flags
from daq.sinks import MemorySink
from rig.blocks import Calibration
from rig.errors import ConfigError
from rig.scene import load_scene, scene_from_settings

FS = 1000.0
CAL = {"a": Calibration("stage acceleration x0''", "m/s^2", 0.1),
       "x": Calibration("mirror translation", "m", 2000.0),
       "y": Calibration("mirror rotation", "rad", -200.0)}


def signals(t, rng):
    w = rng.standard_normal((len(t), 3))
    truth = {"stage_accel_mps2": 2 * np.sin(2 * np.pi * 1.3 * t) + 0.3 * w[:, 0],
             "theta_rad": np.stack([1e-3 * np.sin(t), 2e-3 * np.cos(t)], axis=1),
             "mirror_x_m": 1e-3 * np.sin(2 * np.pi * 2.1 * t) + 1e-6 * w[:, 1],
             "mirror_rot_rad": 5e-3 * np.cos(2 * np.pi * 0.7 * t) + 1e-6 * w[:, 2],
             "source_v": np.sin(2 * np.pi * 1.3 * t)}
    volts = {"a": 0.1 * truth["stage_accel_mps2"], "x": 2000.0 * truth["mirror_x_m"],
             "y": -200.0 * truth["mirror_rot_rad"] + 15 * (t > 1.7) * (t < 1.8)}  # clips
    return volts, truth


def bench(delay_s=0.0, fail_at_s=None, exc=KeyboardInterrupt):
    def sig(t, rng):
        if fail_at_s is not None and t[-1] >= fail_at_s:
            raise exc("stop here")
        if delay_s:
            time.sleep(delay_s)
        return signals(t, rng)

    def response(f):
        return {**{k: np.full(f.shape, c.volts_per_unit, complex) for k, c in CAL.items()},
                "H_t": -0.003 / (1 - (f / 2.48) ** 2 + 0.01j), "units": {"H_t": "m/(m/s^2)"}}

    return lambda scene, seed: FunctionBench(FS, sig, CAL, seed=seed, block_samples=500,
                                             response=response,
                                             info={"model": "linear", "method": "test",
                                                   "error_estimate": 1e-9})


def scene(records=3, record_s=2.0, settle_s=1.0, *more):
    return load_scene("ishizaki2009", [f"acquisition.records={records}",
                                       f"acquisition.record_s={record_s}",
                                       f"acquisition.settle_s={settle_s}", *more])


def write(path, sc=None, seed=3, **kw):
    mem = MemorySink()
    summary = acquire(sc or scene(), seed=seed,
                      sinks=[Hdf5Sink(path, force=kw.pop("force", False)), mem],
                      bench=kw.pop("bench", bench()), **kw)
    return summary, mem.recording


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("run") / "run.h5"
    summary, rec = write(path)
    return path, summary, rec


def test_layout_is_nexus_with_a_default_plot_chain_and_described_channels(run_file):
    path, summary, rec = run_file
    with h5py.File(path, "r") as f:
        assert f.attrs["NX_class"] == "NXroot" and f.attrs["default"] == "entry"
        assert f.attrs["file_format"] == "pendulum-daq run"
        e = f["entry"]
        assert e.attrs["NX_class"] == "NXentry" and e.attrs["default"] == "data"
        data = e["data"]
        assert data.attrs["NX_class"] == "NXdata" and data.attrs["signal"] == "a"
        assert list(data.attrs["auxiliary_signals"]) == ["x", "y"]
        for name in ("truth", "clipping", "model", "instrument", "scene"):
            assert "NX_class" in e[name].attrs
        assert e["instrument"].attrs["NX_class"] == "NXinstrument"
        # status and provenance
        assert e["status"][()].strip(b"\0 ") == b"complete"
        assert e["records_complete"][()] == e["records_planned"][()] == 3
        assert e.attrs["seed"] == 3
        assert e.attrs["software_version"] == "0.1.0" and e.attrs["file_format_version"] == "1.2"
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z", e.attrs["start_time"])
        m = e["model"]
        assert (m.attrs["model"], m.attrs["method"], m.attrs["error_estimate"]) == (
            "linear", "test", 1e-9)
        # raw channels: int16 codes, one record per chunk, compressed, calibration attributes
        y = data["y"]
        assert y.dtype == np.int16 and y.shape == (3, 200) and y.chunks == (1, 200)
        assert y.compression == "gzip" and y.shuffle
        assert y.attrs["scale_factor"] == 20.0 / 65536 and y.attrs["add_offset"] == 0.0
        assert y.attrs["units"] == "V" and y.attrs["engineering_unit"] == "rad"
        assert y.attrs["volts_per_unit"] == -200.0 and y.attrs["range_v"] == 10.0
        assert y.attrs["bits"] == 16
        assert [d.label or list(d.keys())[0] for d in y.dims] == ["record", "time"]
        np.testing.assert_array_equal(y[()], rec.codes["y"])
        # clip counts per record and channel
        counts = e["clipping/count"][()]
        np.testing.assert_array_equal(counts, summary.clip_counts)
        assert counts[:, 2].sum() > 0 and [s.decode() if isinstance(s, bytes) else s
                                           for s in e["clipping/channel"][()]] == ["a", "x", "y"]
        # the resolved scene rebuilds the scene
        settings = json.loads(e["scene/settings_json"][()])
        assert scene_from_settings(settings).settings == scene().settings
        # the exact response of the whole chain on the record's FFT grid
        fr = m["frequency"][()]
        assert m["frequency"].attrs["units"] == "Hz" and fr[0] == 0 and fr[-1] == 50.0
        h = m["a_real"][()] + 1j * m["a_imag"][()]
        np.testing.assert_array_equal(h, rec.header.response.values["a"])
        assert m["H_t_real"].attrs["units"] == "m/(m/s^2)"
        assert e["instrument/antialias"].attrs["order"] == 12


def test_xarray_opens_every_data_group_with_labelled_axes_and_units(run_file):
    import xarray as xr  # here, not at the top: the writer subprocess imports this module

    path, _, rec = run_file
    with xr.open_dataset(path, group="entry/data", engine="h5netcdf") as ds:
        assert ds["a"].dims == ("record", "time") and ds["a"].shape == (3, 200)
        assert ds["time"].attrs["units"] == "s" and ds["a"].attrs["units"] == "V"
        np.testing.assert_array_equal(ds["record"].values, [0, 1, 2])
        # CF packing: xarray decodes the codes to volts
        np.testing.assert_allclose(ds["x"].values, rec.volts("x"), rtol=0, atol=1e-15)
        np.testing.assert_allclose(ds["record_start"].values, [1.0, 3.0, 5.0])
    with xr.open_dataset(path, group="entry/truth", engine="h5netcdf") as ds:
        assert ds["theta_rad"].dims == ("record", "time", "body")
        assert ds["theta_rad"].attrs["units"] == "rad"
        np.testing.assert_array_equal(ds["body"].values, [1, 2])
        np.testing.assert_array_equal(ds["mirror_x_m"].values, rec.truth["mirror_x_m"])
    with xr.open_dataset(path, group="entry/clipping", engine="h5netcdf") as ds:
        assert ds["count"].dims == ("record", "channel")
        assert list(ds["channel"].values) == ["a", "x", "y"]
    with xr.open_dataset(path, group="entry/model", engine="h5netcdf") as ds:
        assert ds["frequency"].attrs["units"] == "Hz"
        assert ds["H_t_real"].dims == ("frequency",)


def test_read_run_returns_what_was_written(run_file):
    path, _, rec = run_file
    back = read_run(path)
    assert back.status == "complete" and back.records == 3
    assert back.header.names == ("a", "x", "y") and back.header.seed == 3
    assert back.header.channels == rec.header.channels
    np.testing.assert_array_equal(back.header.antialias.sos, rec.header.antialias.sos)
    for k in rec.codes:
        np.testing.assert_array_equal(back.codes[k], rec.codes[k])
        np.testing.assert_array_equal(back.clipped[k], rec.clipped[k])
    for k in rec.truth:
        np.testing.assert_array_equal(back.truth[k], rec.truth[k])
    for k, v in rec.header.response.values.items():
        np.testing.assert_array_equal(back.header.response.values[k], v)


def test_same_seed_gives_identical_files_apart_from_the_start_time(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    write(a)
    time.sleep(0.01)
    write(b)
    ta, tb = (run_info(p)["start_time"].encode() for p in (a, b))
    assert ta != tb
    ba, bb = a.read_bytes(), b.read_bytes()
    assert ba.count(ta) == 1 and len(ba) == len(bb)
    assert ba.replace(ta, tb) == bb


def test_keyboard_interrupt_leaves_a_valid_file_with_every_finished_record(tmp_path):
    import xarray as xr

    out = tmp_path / "run.h5"
    with pytest.raises(KeyboardInterrupt) as info:
        write(out, scene(records=6), bench=bench(fail_at_s=6.2))
    assert info.value.summary.records == 2 and info.value.summary.path == out
    with h5py.File(out, "r") as f:  # closed cleanly: any reader opens it
        assert f["entry/status"][()].strip(b"\0 ") == b"interrupted"
        assert f["entry/records_complete"][()] == 2 and f["entry/records_planned"][()] == 6
        assert f["entry/data/a"].shape == (2, 200)
    _, full = write(tmp_path / "full.h5", scene(records=6))
    back = read_run(out)
    assert back.status == "interrupted" and not back.complete
    np.testing.assert_array_equal(back.codes["a"], full.codes["a"][:2])
    with xr.open_dataset(out, group="entry/data", engine="h5netcdf") as ds:
        assert ds["y"].shape == (2, 200)


def test_a_failure_closes_the_file_marked_failed_and_reraises(tmp_path):
    out = tmp_path / "run.h5"
    with pytest.raises(RuntimeError, match="stop here"):
        write(out, bench=bench(fail_at_s=3.5, exc=RuntimeError))
    info = run_info(out)
    assert (info["status"], info["records_complete"]) == ("failed", 1)
    assert info["message"] == "stop here"


def test_existing_files_are_replaced_only_with_force_and_only_by_a_complete_run(tmp_path):
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    with pytest.raises(ConfigError, match="run.h5. exists$"):
        write(out)
    assert out.read_bytes() == b"precious"
    # interrupted with --force: the old file stays, the finished records are kept beside it
    with pytest.raises(KeyboardInterrupt) as info:
        write(out, force=True, bench=bench(fail_at_s=4.0))
    assert out.read_bytes() == b"precious"
    partial = info.value.summary.path
    assert partial.parent == tmp_path and partial.name.startswith("run.partial-")
    assert read_run(partial).records == 1
    partial.unlink()
    # interrupted before the first record: nothing is left behind
    with pytest.raises(KeyboardInterrupt):
        write(out, force=True, bench=bench(fail_at_s=1.0))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    # complete: replaced
    summary, _ = write(out, force=True)
    assert summary.path == out and read_run(out).records == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


WRITER = textwrap.dedent("""
    import sys
    sys.path[:0] = [{root!r}, {tests!r}]  # the project first: tests/rig/ is no package
    from test_hdf5 import bench, scene
    from daq.acquisition import acquire
    from daq.hdf5 import Hdf5Sink
    acquire(scene(200, 1.0, 0.5), seed=11, sinks=[Hdf5Sink(sys.argv[1])], bench=bench(delay_s=0.03))
""")


def test_a_killed_writer_leaves_a_readable_file_that_could_be_followed_while_it_grew(tmp_path):
    import xarray as xr

    script = tmp_path / "writer.py"
    here = Path(__file__).parent
    script.write_text(WRITER.format(root=str(Path(daq.__file__).parents[1]), tests=str(here)))
    out = tmp_path / "run.h5"
    proc = subprocess.Popen([sys.executable, str(script), str(out)], stderr=subprocess.PIPE)
    try:
        f, deadline = None, time.monotonic() + 60
        while f is None and time.monotonic() < deadline:  # until the writer is in SWMR mode
            try:
                f = h5py.File(out, "r", swmr=True)
            except (OSError, FileNotFoundError):
                assert proc.poll() is None, proc.stderr.read().decode()
                time.sleep(0.05)
        seen = []
        with f:
            n_ds, a = f["entry/records_complete"], f["entry/data/a"]
            while time.monotonic() < deadline:
                n_ds.refresh()
                n = int(n_ds[()])  # read the count first, then the data it vouches for
                a.refresh()
                if n and (not seen or n != seen[-1]):
                    assert a.shape[0] >= n
                    seen.append(n)
                    rows = a[:n]  # the finished records can be read while the file grows
                    assert rows.shape == (n, 100) and rows.any()
                if n >= 4:
                    break
                time.sleep(0.02)
        assert len(seen) >= 2 and seen == sorted(seen), seen
        with pytest.raises(ConfigError, match="still being written"):
            clear_write_flags(out)
    finally:
        proc.kill()  # SIGKILL: no chance to close anything
        proc.wait()
        proc.stderr.close()
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(out, "r")  # HDF5's own mark of an unclosed writer ...
    info = run_info(out)  # ... which SWMR readers (and ours) ignore
    assert info["status"] == "acquiring" and not info["complete"]
    assert info["writer_flag_set"] and info["records_complete"] >= 4
    got = read_run(out)
    n = got.records
    assert n == info["records_complete"]
    _, ref = write(tmp_path / "ref.h5", scene(n, 1.0, 0.5), seed=11)
    for k in ("a", "x", "y"):
        np.testing.assert_array_equal(got.codes[k], ref.codes[k])
    assert clear_write_flags(out) is True and clear_write_flags(out) is False
    with h5py.File(out, "r") as f:  # now any HDF5 reader opens it
        assert f["entry/records_complete"][()] == n
    with xr.open_dataset(out, group="entry/data", engine="h5netcdf") as ds:
        assert ds["a"].shape[0] >= n


def test_files_that_are_not_runs_are_refused_clearly(tmp_path):
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["x"] = 1
    with pytest.raises(ConfigError, match="is not a pendulum-daq run file"):
        run_info(p)
    q = tmp_path / "text.h5"
    q.write_text("hello")
    with pytest.raises(ConfigError, match="is not a readable HDF5 file"):
        read_run(q)
    with pytest.raises(ConfigError, match="does not exist"):
        with open_run(tmp_path / "missing.h5"):
            pass


def test_a_record_cut_short_by_an_error_is_dropped_from_the_file(tmp_path):
    from daq.records import Footer, Record

    _, rec = write(tmp_path / "ref.h5")
    sink = Hdf5Sink(tmp_path / "run.h5")
    sink.start(rec.header)

    def record(i, **truth):
        return Record(i, 0.0, {k: v[i] for k, v in rec.codes.items()},
                      {k: v[i] for k, v in rec.clipped.items()},
                      {k: truth.get(k, v[i]) for k, v in rec.truth.items()})

    sink.record(record(0))
    with pytest.raises(TypeError):  # the channels of record 1 are written, then its truth fails
        sink.record(record(1, theta_rad=np.zeros((7, 7))))
    sink.stop(Footer("failed", 1, np.zeros((1, 3), int), "TypeError"))
    back = read_run(tmp_path / "run.h5")
    assert back.status == "failed" and back.records == 1
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert {f["entry/data"][k].shape[0] for k in ("a", "x", "y", "record")} == {1}
        assert f["entry/truth/theta_rad"].shape == (1, 200, 2)


def test_rows_written_through_hdf5_directly_give_the_bytes_of_h5pys_own_assignment(tmp_path):
    """Hdf5Sink grows its datasets and writes each record's rows with HDF5's own calls (its
    fast path); a sink that resizes and assigns them the ordinary h5py way writes a file equal
    byte for byte (apart from the start time, which names the moment of the run)."""
    class AssigningSink(Hdf5Sink):
        def _extend(self, rows):
            for ds in self._grow:
                ds.resize(rows, axis=0)

        def _put_row(self, ds, k, value):
            ds[k] = value

    files = {}
    for name, cls in (("direct", Hdf5Sink), ("assigned", AssigningSink)):
        files[name] = tmp_path / f"{name}.h5"
        acquire(scene(), seed=3, sinks=[cls(files[name])], bench=bench())

    def start_time(p):
        with h5py.File(p, "r") as f:
            return f["entry"].attrs["start_time"].encode()

    a, b = (files[k].read_bytes() for k in ("direct", "assigned"))
    ta, tb = start_time(files["direct"]), start_time(files["assigned"])
    assert a.count(ta) == 1 and a.replace(ta, tb) == b


def test_a_sink_used_for_a_second_run_writes_the_file_a_fresh_one_writes(tmp_path):
    """What a sink keeps between records (its datasets' row shapes and memory spaces, keyed by
    HDF5 ids that a new file may reuse) is made anew by each start."""
    reused, fresh = Hdf5Sink(tmp_path / "reused.h5", force=True), tmp_path / "fresh.h5"
    acquire(scene(records=2), seed=5, sinks=[reused], bench=bench())
    acquire(scene(), seed=3, sinks=[reused], bench=bench())
    acquire(scene(), seed=3, sinks=[Hdf5Sink(fresh)], bench=bench())
    a, b = read_run(tmp_path / "reused.h5"), read_run(fresh)
    assert a.header.plan.records == b.header.plan.records == 3
    for k in b.codes:
        np.testing.assert_array_equal(a.codes[k], b.codes[k])
    for k in b.truth:
        np.testing.assert_array_equal(a.truth[k], b.truth[k])


def test_every_group_dataset_and_attribute_of_a_run_file_is_in_docs_run_file(tmp_path):
    """docs/run-file.md draws the layout; a real run of the bench (with truth) holds no group,
    dataset or attribute it does not name, except where the page says "..." (the model's
    information and the acquisition plan's attributes, the exact model's ``<name>_real`` and
    ``_imag`` pairs, named as patterns)."""
    OPEN_ENDED = ("entry/model", "entry/instrument/acquisition")
    doc = (Path(__file__).resolve().parents[2] / "docs" / "run-file.md").read_text()
    path = tmp_path / "run.h5"
    acquire(scene(1, 2.0, 1.0, "acquisition.truth=true"), seed=1, sinks=[Hdf5Sink(path)])
    names = set()

    def visit(name, obj):
        leaf = name.rsplit("/", 1)[-1]
        if not (name.startswith("entry/model/") and re.search(r"_(real|imag)$", leaf)):
            names.add(leaf)
        if not name.startswith(OPEN_ENDED):  # drawn as "@model @method ..." in the page
            names.update(k for k in obj.attrs if not k.startswith(("DIMENSION_", "REFERENCE_",
                                                                     "CLASS", "NAME", "_")))

    with h5py.File(path, "r") as f:
        f.visititems(visit)
        names.update(f.attrs)
    assert len(names) > 40
    missing = sorted(n for n in names if not re.search(rf"(?<![\w.]){re.escape(n)}(?!\w)", doc))
    assert not missing, f"in the run file but not in docs/run-file.md: {missing}"
