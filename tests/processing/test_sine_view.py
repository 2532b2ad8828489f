"""``daq view`` of a stepped-sine run file: what the .rrd holds against the file (read with
h5py), with and without kept records, a file still being written, and the rendered layout.

One short sweep (3 points, the linear model, seconds of bench time) is written by the CLI in a
subprocess; every replay goes to an .rrd file read back with rerun's own reader. No test opens
a viewer window (the screenshot renders off screen, or is skipped with the reason).
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

lv = pytest.importorskip("processing.live_view")
from rerun.chunk import RrdReader  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
POINTS = 3
SWEEP = ["sine", "ishizaki2009", "--fmin", "2", "--fmax", "3", "--points", str(POINTS),
         "--level", "0.1", "--settle-s", "2", "--integrate-s", "2", "--integrate-cycles", "2",
         "--random-error", "0", "--set", "acquisition.model=linear", "-q"]


def daq(*args, timeout=240):
    """``python -m daq.cli ARGS`` in a subprocess, bounded; its CompletedProcess."""
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, RUST_LOG="off"))


@pytest.fixture(scope="module")
def sine_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sine_view")
    out = d / "s.h5"
    p = daq(*SWEEP, "--keep-records", "--out", out)
    assert p.returncode == 0, p.stderr
    return out


@pytest.fixture(scope="module")
def viewed(sine_file):
    """The sweep's file replayed once: (.rrd, the command's output)."""
    return view_rrd(sine_file)


def view_rrd(path: Path) -> tuple[Path, str]:
    rrd = path.with_suffix(".rrd")
    p = daq("view", path, "--rrd", rrd)
    assert p.returncode == 0, p.stderr
    return rrd, p.stdout


def rows(rrd, entity):
    """The temporal record batches of ``entity`` (concatenated in time order)."""
    batches = [ch.to_record_batch() for ch in
               RrdReader(str(rrd)).stream().filter(content=entity, is_static=False).to_chunks()
               if str(ch.entity_path) == entity]
    table = pa.Table.from_batches(batches) if batches else None
    if table is None:
        return None
    return table.sort_by("time")


def statuses(rrd) -> list[str]:
    t = rows(rrd, "/status")
    return [str(v[0]) for v in t.column("TextDocument:text").to_pylist()]


def test_bode_points_land_one_by_one_with_the_files_values(sine_file, viewed):
    rrd, out = viewed
    assert f"replayed {POINTS} points" in out and "with records" in out
    with h5py.File(sine_file, "r") as f:
        g = f["entry/sweep"]
        col = {k: g[k][()] for k in g}
    t_end = col["t0_s"] + col["settle_s"] + col["integrate_s"]
    for key, name in (("H_t", "h_t"), ("Theta_2", "theta_2")):
        for part in ("gain", "phase"):
            t = rows(rrd, f"/analyzer/{key}/points/{part}")
            assert t.num_rows == POINTS
            # one landing per point, at its end in the sweep's time, holding the points so far
            np.testing.assert_allclose(t.column("time").cast(pa.int64()).to_numpy() * 1e-9,
                                       t_end, atol=1e-9)
            sizes = pc.list_value_length(t.column("Points2D:positions")).to_numpy()
            assert list(sizes) == list(range(1, POINTS + 1))
            last = {c: np.asarray(t.column(c)[POINTS - 1].as_py())
                    for c in ("frequency_hz", "gain_db", "phase_deg")}
            # the file's own values, carried unchanged (float64)
            np.testing.assert_array_equal(last["frequency_hz"], col["frequency"])
            np.testing.assert_allclose(last["gain_db"], col[f"{name}_gain_db"], rtol=0,
                                       atol=1e-12)
            np.testing.assert_allclose(last["phase_deg"], col[f"{name}_phase_deg"], rtol=0,
                                       atol=1e-9)


def test_each_point_states_its_settling_bias_and_random_error(sine_file, viewed):
    rrd, _ = viewed
    with h5py.File(sine_file, "r") as f:
        g = f["entry/sweep"]
        ex = g["h_t_exact_real"][()] + 1j * g["h_t_exact_imag"][()]
        bias = ex + g["h_t_bias_real"][()] + 1j * g["h_t_bias_imag"][()]
        rel = g["h_t_rel_error"][()]
    texts = statuses(rrd)
    assert len(texts) == POINTS + 1  # one per landing, and the final state
    for k in range(POINTS):
        bias_db = 20 * np.log10(abs(bias[k] / ex[k]))
        assert f"Point {k + 1} of {POINTS}" in texts[k]
        assert f"{bias_db:+.4f}" in texts[k]  # the H_t column comes first in each row
        assert f"{20 / np.log(10) * rel[k]:.4f}" in texts[k]
    assert "(complete)" in texts[-1]
    t = rows(rrd, "/analyzer/H_t/points/gain")
    stated = np.asarray(t.column("settling_bias_db")[POINTS - 1].as_py())
    np.testing.assert_allclose(stated, 20 * np.log10(np.abs(bias / ex)), rtol=0, atol=1e-12)


def test_the_drawn_model_is_the_files_exact_steady_state_at_the_points(sine_file):
    """The curve is :func:`rig.bench.sampled_response` on the resolving grid; at
    the points it is the file's exact steady state to round-off (1e-9 relative: the modal
    form's round-off is far below that away from 0 Hz and the notches)."""
    from daq.sine_file import read_sine
    from rig.bench import sampled_response
    from rig.scene import scene_from_settings

    d = read_sine(sine_file)
    c = d["columns"]
    model = sampled_response(scene_from_settings(d["scene_settings"]))(c["frequency"])
    for name in ("h_t", "theta_2"):
        exact = c[f"{name}_exact_real"] + 1j * c[f"{name}_exact_imag"]
        np.testing.assert_allclose(getattr(model, name), exact, rtol=1e-9)


def test_kept_records_give_the_signals_of_each_point_in_engineering_units(sine_file, viewed):
    rrd, _ = viewed
    with h5py.File(sine_file, "r") as f:
        r = f["entry/records"]
        ds = r["codes_x"]
        volts = ds[()] * ds.attrs["scale_factor"] + ds.attrs["add_offset"]
        micro_m = volts / ds.attrs["volts_per_unit"] * 1e6  # x is drawn in micrometres
        first, samples = r["first_sample"][()], r["samples"][()]
    t = rows(rrd, "/signals")
    v = np.stack([np.asarray(x) for x in t.column("Scalars:scalars").to_pylist()])
    gaps = np.flatnonzero(np.isnan(v[:, 1]))
    assert gaps.size == POINTS  # one gap after each point: its line is not joined
    parts = np.split(v[:, 1], gaps + 1)[:POINTS]
    for k, part in enumerate(parts):
        shown = part[~np.isnan(part)]
        end = first[k] + samples[k]
        np.testing.assert_allclose(shown, micro_m[end - shown.size:end], rtol=1e-12)
    assert rows(rrd, "/bench/stage/pendulum").num_rows > POINTS  # the bench moves


def test_each_points_signals_end_where_its_point_lands_stepped_or_swept(sine_file, viewed,
                                                                        tmp_path):
    """The kept record ends with the point's window in both modes (stepped: settle + window;
    swept: the window alone), so its last sample is drawn one sample before the point lands."""
    swept = tmp_path / "swept.h5"
    p = daq("sine", "ishizaki2009", "--mode", "swept", "--fmin", "2", "--fmax", "3", "--points",
            str(POINTS), "--sweep-s", "400", "--level", "0.1", "--set", "acquisition.model=linear",
            "--keep-records", "--out", swept, "-q")
    assert p.returncode == 0, p.stderr
    for path, (rrd, out) in ((sine_file, viewed), (swept, view_rrd(swept))):
        mode = "swept" if path == swept else "stepped"
        assert f"points of the {mode} sine" in out
        with h5py.File(path, "r") as f:
            g = f["entry/sweep"]
            t_end = g["t0_s"][()] + g["settle_s"][()] + g["integrate_s"][()]
        t = rows(rrd, "/signals")
        times = t.column("time").cast(pa.int64()).to_numpy() * 1e-9
        v = np.stack([np.asarray(x) for x in t.column("Scalars:scalars").to_pylist()])
        gaps = np.flatnonzero(np.isnan(v[:, 0]))  # one after each point's samples
        assert gaps.size == POINTS
        last = times[gaps - 1]
        assert np.all(last < t_end) and np.all(last > t_end - 0.1), (mode, last, t_end)
        if mode == "swept":
            assert "sweep bias" in statuses(rrd)[-1]


def test_without_records_the_status_says_so_and_no_signals_are_drawn(sine_file, tmp_path):
    bare = tmp_path / "bare.h5"
    shutil.copy(sine_file, bare)
    with h5py.File(bare, "a") as f:
        del f["entry/records"]
    rrd, out = view_rrd(bare)
    assert "without records" in out
    assert rows(rrd, "/signals") is None
    assert rows(rrd, "/analyzer/Theta_2/points/gain").num_rows == POINTS
    assert all("records not kept" in s for s in statuses(rrd))


def test_a_file_still_being_written_shows_its_finished_points(sine_file, tmp_path):
    part = tmp_path / "partial.h5"
    shutil.copy(sine_file, part)
    with h5py.File(part, "a") as f:  # as a sweep leaves it after its second point
        f["entry/status"][()] = np.bytes_(b"acquiring")
        f["entry/points_complete"][()] = np.int64(2)
    rrd, out = view_rrd(part)
    assert "replayed 2 points" in out and "acquiring" in out
    assert rows(rrd, "/analyzer/H_t/points/gain").num_rows == 2
    assert "its finished points" in statuses(rrd)[-1]


def test_screenshot_of_a_sine_replay_renders_the_layout(sine_file, tmp_path):
    try:
        lv.screenshot_command(tmp_path / "x.rrd", tmp_path / "x.png")
    except lv.LiveViewError as exc:
        pytest.skip(f"the viewer cannot render here: {exc}")
    png = tmp_path / "sine.png"
    p = daq("view", sine_file, "--screenshot", png, "--size", "1280x720", timeout=300)
    if p.returncode != 0 and "could not render" in p.stderr + p.stdout:
        pytest.skip(f"the viewer cannot render here: {(p.stderr + p.stdout).strip()}")
    assert p.returncode == 0, p.stderr
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[:2] == (720, 1280)
    # not a blank window: the measured points (processing.live_view.drawing.MEASURED) and the
    # model curve (MODEL) are on screen (within 40 of their colour: anti-aliasing)
    img = img.astype(int)
    for colour in (lv.drawing.MEASURED, lv.drawing.MODEL):
        assert (np.abs(img - np.array(colour)).sum(-1) < 40).sum() > 20, colour
