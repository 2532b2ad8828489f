"""The live view in rerun: what the .rrd holds against the run file, replay, isolation, failures.

No test opens a viewer window (except the screenshot test, which renders off screen) and none
serves gRPC: the stream goes to .rrd files, read back with rerun's own reader.
"""

import os
import socket
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from click.testing import CliRunner

from daq.acquisition import acquire
from daq.cli import main
from daq.hdf5 import Hdf5Sink, read_run
from daq.sinks import Sink
from rig.scene import load_scene

lv = pytest.importorskip("processing.live_view")
from rerun.chunk import RrdReader  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SEED = 11
OVERRIDES = ["acquisition.records=3", "acquisition.record_s=5", "acquisition.rate_hz=100",
             "acquisition.settle_s=5"]


#: What the signal plots multiply each unit by (processing.live_view.drawing.DISPLAY_UNITS)
DISPLAY = {"m/s^2": 1.0, "m": 1e6, "rad": 1e6}


def short_scene():
    return load_scene("ishizaki2009", OVERRIDES)


def live_sink(rrd, **kw):
    opts = dict(rrd=rrd)
    opts.update(kw)
    return lv.LiveView(lv.ViewerStream(lv.ViewerOptions(**opts)))


def column(rrd, entity, component):
    """(times [s], values) of ``entity``'s temporal ``component``, sorted by time; values are
    the flattened lists (one row per time)."""
    ts, vs, lens = [], [], []
    for ch in RrdReader(str(rrd)).stream().filter(content=entity, is_static=False).to_chunks():
        if str(ch.entity_path) != entity:
            continue
        rb = ch.to_record_batch()
        if component not in rb.schema.names:
            continue
        ts.append(rb.column("time").cast(pa.int64()).to_numpy())
        col = rb.column(component)
        flat = pc.list_flatten(col)
        # points per strip for strips (a list of lists), else values per row
        lens.append(pc.list_value_length(flat if pa.types.is_list(flat.type) else col)
                    .to_numpy())
        while pa.types.is_list(flat.type) or pa.types.is_fixed_size_list(flat.type):
            flat = pc.list_flatten(flat)
        vs.append(flat.to_numpy(zero_copy_only=False))
    t = np.concatenate(ts) * 1e-9
    return t, np.concatenate(vs), np.concatenate(lens)


def channel(rrd, entity, header, c):
    """(times [s], samples) of channel ``c`` in ``entity`` ("/signals" or "/volts": one series
    per channel, in the run's order)."""
    t, v, lens = column(rrd, entity, "Scalars:scalars")
    k = len(header.names)
    assert np.all(lens == k)
    return t, v.reshape(-1, k)[:, header.names.index(c)]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One short run written to HDF5 and .rrd at once."""
    d = tmp_path_factory.mktemp("live")
    out, rrd = d / "run.h5", d / "run.rrd"
    sink = live_sink(rrd)
    summary = acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(out), sink])
    assert summary.status == "complete" and sink.path == rrd
    return out, rrd


def test_rrd_holds_every_sample_of_the_run_file_in_engineering_units_and_volts(run):
    out, rrd = run
    rec = read_run(out)
    plan = rec.header.plan
    starts = rec.record_start_s()
    t_file = (starts[:, None] + rec.times_s()[None, :]).ravel()
    for c in rec.header.names:
        t, v = channel(rrd, "/signals", rec.header, c)
        assert v.size == rec.records * plan.samples
        np.testing.assert_allclose(t, t_file, rtol=0, atol=0.5e-9)  # rounded to whole ns
        factor = DISPLAY[rec.header.channel(c).unit]  # shown in um and urad
        np.testing.assert_array_equal(v, rec.values(c).ravel() * factor)
        _, volts = channel(rrd, "/volts", rec.header, c)
        np.testing.assert_array_equal(volts, rec.volts(c).ravel())


def test_rrd_draws_the_recorded_angles_at_30_to_60_frames_per_second(run):
    out, rrd = run
    rec = read_run(out)
    h = rec.header
    n = h.scene.chain.n
    t, pts, lens = column(rrd, "/bench/stage/pendulum", "LineStrips2D:strips")
    duration = rec.records * h.plan.record_s
    assert 30 <= t.size / duration <= 60
    step = int(round(np.median(np.diff(t)) * h.plan.rate_hz))
    # the frames are the samples whose index is a multiple of the step, theta drawn magnified
    theta = rec.truth["theta_rad"].reshape(-1, n)
    g = np.round(t * h.plan.rate_hz).astype(int) - h.plan.settle_samples
    assert np.all(g % step == g[0] % step)
    drawing = lv.BenchDrawing.from_scene(h.scene)
    joints = drawing.joints(theta[g])
    centre, face = drawing.mirror(theta[g], joints, half_mm=max(3.0, 0.12 * drawing.reach_mm))
    # per frame three strips: the bodies (n + 1 joints), the mirror's face, the laser beam
    assert np.all(lens.reshape(t.size, 3) == [n + 1, 2, 3])
    pts = pts.reshape(t.size, n + 6, 2)
    atol = 1e-4 * drawing.reach_mm  # float32
    np.testing.assert_allclose(pts[:, :n + 1], joints, rtol=0, atol=atol)
    np.testing.assert_allclose(pts[:, n + 1:n + 3], face, rtol=0, atol=atol)
    np.testing.assert_allclose(pts[:, n + 4], centre, rtol=0, atol=atol)  # the beam's bounce
    # the pivots, then the centres of mass
    _, marks, mlens = column(rrd, "/bench/stage/marks", "Points2D:positions")
    assert np.all(mlens == 2 * n)
    marks = marks.reshape(t.size, 2 * n, 2)
    np.testing.assert_allclose(marks[:, :n], joints[:, :-1], rtol=0, atol=atol)
    np.testing.assert_allclose(marks[:, n:], drawing.centres_of_mass(theta[g], joints), rtol=0,
                               atol=atol)
    # the spot on the PSD from the channels' volts, in mm (v up is image -y)
    _, spot, _ = column(rrd, "/psd/spot", "Points2D:positions")
    gain = h.scene.settings["psd"]["gain_vpm"]
    np.testing.assert_allclose(spot.reshape(-1, 2)[:, 0],
                               1e3 * rec.volts("x").ravel()[g] / gain, atol=1e-5)
    np.testing.assert_allclose(spot.reshape(-1, 2)[:, 1],
                               -1e3 * rec.volts("y").ravel()[g] / gain, atol=1e-5)


def test_analyzer_screen_and_status_are_updated_after_each_record(run):
    out, rrd = run
    rec = read_run(out)
    h = rec.header
    ends = rec.record_start_s() + h.plan.record_s
    for entity in ("/analyzer/H_t/measured", "/analyzer/Theta_2/measured",
                   "/analyzer/coherence/x", "/analyzer/coherence/y"):
        t, _, _ = column(rrd, entity, "LineStrips2D:strips")
        np.testing.assert_allclose(t, ends, atol=1e-9)
    t, _, _ = column(rrd, "/status", "TextDocument:text")
    assert t.size == rec.records + 2  # before the first record, after each, at the end
    statics = {str(ch.entity_path) for ch in RrdReader(str(rrd)).stream().to_chunks()
               if ch.is_static}
    for e in ("/analyzer/H_t/model", "/analyzer/H_t/expected", "/analyzer/Theta_2/model",
              "/analyzer/H_t/grid", "/analyzer/H_t/labels", "/psd/detector", "/bench/note"):
        assert e in statics


def test_status_says_record_k_of_n_counts_model_and_seed(run):
    _, rrd = run
    texts = [t for ch in RrdReader(str(rrd)).stream().filter(content="/status").to_chunks()
             for t in ch.to_record_batch().column("TextDocument:text").to_pylist()]
    last = " ".join(texts[-1]) if isinstance(texts[-1], list) else texts[-1]
    assert "Record 3 of 3" in last and "(complete)" in last
    assert f"**seed** {SEED}" in last and "**model** linear" in last and "**why** auto:" in last
    assert "**clipped / saturated samples** a 0 / 0, x 0 / 0, y 0 / 0" in last


def test_running_average_equals_the_analyzer_over_the_same_records(run):
    from processing.analyzer import AnalyzerSettings
    from processing.frf import frequency_response
    from processing.running_average import RunningAverage
    from processing.spectra import segment_ffts

    out, _ = run
    rec = read_run(out)
    avg = RunningAverage(rec.header)
    spectral = AnalyzerSettings().spectral(rec.header.plan.rate_hz, rec.header.plan.samples)
    for k in range(rec.records):
        est = avg.add({c: rec.codes[c][k] for c in rec.header.names})
        ffts = segment_ffts({c: rec.values(c)[:k + 1] for c in ("a", "x", "y")}, spectral)
        for got, out_ch, g2 in ((est.h_t, "x", est.coherence_x), (est.theta_2, "y",
                                                                  est.coherence_y)):
            ref = frequency_response(ffts, "a", out_ch)
            band = np.isin(ref.freqs_hz, est.freqs_hz)
            # the same sums in another order: equal to rounding (1e-12 of the value)
            np.testing.assert_allclose(got, ref.h[band], rtol=1e-12)
            if k:  # one average has coherence 1 by construction
                np.testing.assert_allclose(g2, ref.coherence[band], rtol=1e-10)
    assert est.records == rec.records


def test_live_run_and_replay_of_its_file_draw_the_same(run, tmp_path):
    out, rrd = run
    again = tmp_path / "replay.rrd"
    lv.replay(out, lv.ViewerStream(lv.ViewerOptions(rrd=again)))
    a, b = lv.recording_summary(rrd), lv.recording_summary(again)
    assert set(a) == set(b)
    for entity, comp in (("/signals", "Scalars:scalars"), ("/volts", "Scalars:scalars"),
                         ("/bench/stage", "Transform3D:translation"),
                         ("/bench/stage/pendulum", "LineStrips2D:strips"),
                         ("/bench/stage/marks", "Points2D:positions"),
                         ("/psd/spot", "Points2D:positions"),
                         ("/analyzer/Theta_2/measured", "LineStrips2D:strips")):
        ta, va, _ = column(rrd, entity, comp)
        tb, vb, _ = column(again, entity, comp)
        np.testing.assert_array_equal(ta, tb)
        np.testing.assert_array_equal(va, vb)


class _StopAfter(Sink):
    """Interrupts the run (like Ctrl-C) in the first block of record ``n``."""

    def __init__(self, n):
        self.n = n

    def block(self, block):
        if block.record == self.n:
            raise KeyboardInterrupt


def test_replay_of_an_interrupted_file_shows_only_its_finished_records(tmp_path):
    out, live, replayed = tmp_path / "run.h5", tmp_path / "live.rrd", tmp_path / "replay.rrd"
    with pytest.raises(KeyboardInterrupt):
        acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(out), live_sink(live), _StopAfter(2)])
    rec = read_run(out)
    assert rec.status == "interrupted" and rec.records == 2
    assert live.exists()  # the live recording is kept (renamed at the end) too
    v = lv.replay(out, lv.ViewerStream(lv.ViewerOptions(rrd=replayed)))
    assert v.footer.records_complete == 2
    t, x = channel(replayed, "/signals", rec.header, "x")
    assert x.size == 2 * rec.header.plan.samples
    np.testing.assert_array_equal(x, rec.values("x").ravel() * DISPLAY["m"])
    t, _, _ = column(replayed, "/analyzer/H_t/measured", "LineStrips2D:strips")
    assert t.size == 2
    texts = RrdReader(str(replayed)).stream().filter(content="/status").collect()
    assert texts is not None
    res = CliRunner().invoke(main, ["view", str(out), "--rrd", str(tmp_path / "cli.rrd")])
    assert res.exit_code == 0, res.output
    assert "replayed 2 of 3 records" in res.stdout and "(interrupted)" in res.stdout


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _without_start_time(path: Path, start: bytes) -> bytes:
    data = path.read_bytes()
    assert data.count(start) == 1
    return data.replace(start, b"")


def test_refused_viewer_warns_once_and_the_file_is_the_same_as_without_live_options(tmp_path):
    plain, live, rrd = tmp_path / "plain.h5", tmp_path / "live.h5", tmp_path / "live.rrd"
    acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(plain)])
    url = f"rerun+http://127.0.0.1:{_closed_port()}/proxy"
    with pytest.warns(lv.LiveViewWarning) as caught:
        summary = acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(live),
                                                                 live_sink(rrd, connect=url)])
    assert len(caught) == 1 and "connection refused" in str(caught[0].message)
    assert summary.status == "complete" and rrd.exists()
    a, b = read_run(plain).header.start_time.encode(), read_run(live).header.start_time.encode()
    assert _without_start_time(plain, a) == _without_start_time(live, b)


def test_missing_viewer_executable_warns_once_and_the_run_goes_on(tmp_path, monkeypatch):
    monkeypatch.setattr(lv.stream, "viewer_executable", lambda: None)
    with pytest.warns(lv.LiveViewWarning) as caught:
        summary = acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(tmp_path / "run.h5"),
                                 lv.LiveView(lv.ViewerStream(lv.ViewerOptions(spawn=True)))])
    assert len(caught) == 1 and "no rerun viewer executable" in str(caught[0].message)
    assert summary.status == "complete" and summary.records == 3


def test_a_failing_live_view_is_dropped_with_one_warning_and_the_file_is_complete(tmp_path):
    class Broken(lv.LiveView):
        def record(self, record):
            raise OSError("disk of the viewer full")

    sink = Broken(lv.ViewerStream(lv.ViewerOptions(rrd=tmp_path / "x.rrd")))
    with pytest.warns(RuntimeWarning, match="disk of the viewer full") as caught:
        summary = acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(tmp_path / "run.h5"), sink])
    assert len(caught) == 1
    assert summary.status == "complete" and read_run(tmp_path / "run.h5").records == 3


def _python(code: str, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, env=env, timeout=300)


def test_rerun_is_imported_only_when_a_live_option_is_used(tmp_path):
    args = ", ".join(repr(a) for a in ["--records", "2", "--duration", "5", "--rate", "100",
                                       "--set", "acquisition.settle_s=5", "--seed", "1", "-q"])
    code = f"""
import sys
from daq.cli import main
def run(*a):
    try:
        main(list(a), standalone_mode=False)
    except SystemExit:
        pass
    return "rerun" in sys.modules
r = [run("--help"), run("acquire", "--help"), run("view", "--help"),
     run("acquire", "--scene", "ishizaki2009", {args}, "--out", r"{tmp_path / 'a.h5'}"),
     run("analyze", r"{tmp_path / 'a.h5'}"),
     run("acquire", "--scene", "ishizaki2009", {args}, "--out", r"{tmp_path / 'b.h5'}",
         "--rrd", r"{tmp_path / 'b.rrd'}")]
print("RESULT", r)
# the live view spares the import of pandas (pyarrow's probe), and pyarrow still converts to
# pandas when asked
import importlib.util
import pyarrow as pa
before = "pandas" in sys.modules
kind = ("no pandas" if importlib.util.find_spec("pandas") is None
        else type(pa.table({{"v": [1.5]}}).to_pandas()).__name__)
print("PANDAS", before, kind)
"""
    p = _python(code)
    assert p.returncode == 0, p.stderr
    result = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    assert result == ["RESULT [False, False, False, False, False, True]"]
    pandas = [ln for ln in p.stdout.splitlines() if ln.startswith("PANDAS ")]
    assert pandas in (["PANDAS False DataFrame"], ["PANDAS False no pandas"])
    # and only the live view's package imports rerun
    users = [f.relative_to(ROOT).as_posix() for d in ("rig", "daq", "processing")
             for f in (ROOT / d).rglob("*.py")
             if "import rerun" in f.read_text() or "from rerun" in f.read_text()]
    assert users and all(u.startswith("processing/live_view/") for u in users), users


def test_a_headless_run_without_a_display_saves_the_recording(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out, rrd = tmp_path / "run.h5", tmp_path / "run.rrd"
    p = subprocess.run([sys.executable, "-m", "daq.cli", "acquire", "--scene", "ishizaki2009",
                        "--records", "1", "--duration", "5", "--set", "acquisition.settle_s=5",
                        "--seed", "3", "--out", str(out), "--rrd", str(rrd), "-q"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert p.stderr == "" and f"wrote {rrd} (rerun recording)" in p.stdout
    rec = read_run(out)
    t, a = channel(rrd, "/signals", rec.header, "a")
    np.testing.assert_array_equal(a, rec.values("a").ravel())


@pytest.mark.parametrize("args, message", [
    ([], "give --out RUN.h5 and/or a live option"),
    (["--out", "{d}/r.h5", "--speed", "2"], "--speed 2 needs --realtime"),
    (["--rrd", "{d}/old.rrd"], "exists"),
    (["--rrd", "{d}/r.rrd", "--realtime", "--speed", "0"], "speed = 0.0 is invalid"),
    (["--connect", "nonsense", "--out", "{d}/r.h5"], "viewer URL 'nonsense' is invalid"),
])
def test_bad_live_options_give_one_line_errors_and_write_nothing(tmp_path, args, message):
    (tmp_path / "old.rrd").write_bytes(b"keep")
    args = [a.format(d=tmp_path) for a in args]
    res = CliRunner().invoke(main, ["acquire", "--scene", "ishizaki2009", "--records", "1",
                                    *args])
    assert res.exit_code != 0
    assert message in res.output and "Traceback" not in res.output
    assert (tmp_path / "old.rrd").read_bytes() == b"keep"
    assert not (tmp_path / "r.h5").exists() and not (tmp_path / "r.rrd").exists()


def test_realtime_paces_blocks_to_the_wall_clock():
    from daq.pacing import Pacer

    now, slept = [100.0], []

    def sleep(s):
        slept.append(s)
        now[0] += s

    p = Pacer(2.0, clock=lambda: now[0], sleep=sleep)
    p.wait(300.0)  # the first instant is "now"
    p.wait(310.0)  # 10 simulated seconds at 2x: due 5 s later
    now[0] += 1.0  # the emulator took 1 s of its own
    p.wait(312.0)  # due at 106 s: no wait
    p.wait(320.0)  # due at 110 s
    assert slept == [5.0, 4.0] and now[0] == 110.0


def test_simulate_shows_free_motion_to_scale(tmp_path):
    rrd = tmp_path / "free.rrd"
    res = CliRunner().invoke(main, ["simulate", "double-rod", "--duration", "2", "--rrd",
                                    str(rrd), "--no-error-estimate"])
    assert res.exit_code == 0, res.output
    t, pts, lens = column(rrd, "/bench/stage/pendulum", "LineStrips2D:strips")
    # per frame the two rods (3 joints) and the mirror's face (2 points)
    assert np.all(lens.reshape(-1, 2) == [3, 2]) and 30 <= t.size / 2.0 <= 60
    joints = pts.reshape(t.size, 5, 2)[:, :3]
    _, _, per_row = column(rrd, "/signals/theta", "Scalars:scalars")
    assert np.all(per_row == 2)  # the two angles
    # to scale: the two 1 m rods are 1000 mm long in every frame
    np.testing.assert_allclose(np.hypot(*(joints[:, 1] - joints[:, 0]).T), 1000.0, rtol=1e-6)
    np.testing.assert_allclose(np.hypot(*(joints[:, 2] - joints[:, 1]).T), 1000.0, rtol=1e-6)


def blueprint_y_ranges(rrd) -> list[tuple[float, float]]:
    """The value-axis ranges the .rrd's blueprint sets on its views."""
    r = RrdReader(str(rrd))
    out = []
    for ch in r.stream(store=r.blueprints()[0]).to_chunks():
        rb = ch.to_record_batch()
        if "ScalarAxis:range" in rb.schema.names:
            out += [tuple(v[0]) for v in rb.column("ScalarAxis:range").to_pylist()]
    return out


def test_signal_plots_span_their_data_with_labelled_ticks_on_both_sides_of_zero(run):
    """Each signal plot (engineering units and volts) runs from -h to h, h from the channel's
    predicted spread: every sample of the run fits, and the plot's value labels (every power of
    ten, hidden when they crowd) number 3 to 7 with at least 0.4 of their step to the edges,
    never a "0" alone (what 5 x 10^k gave at 1280x720)."""
    from processing.live_view.drawing import HALF_HEIGHT_MANTISSAS, signal_ranges

    out, rrd = run
    rec = read_run(out)
    ranges = signal_ranges(rec.header)
    assert set(ranges) == set(rec.header.names)
    want = sorted((-h, h) for c in rec.header.names for h in ranges[c])
    np.testing.assert_allclose(sorted(blueprint_y_ranges(rrd)), want, rtol=1e-12)
    for c in rec.header.names:
        shown, volts = ranges[c]
        assert np.abs(rec.values(c)).max() * DISPLAY[rec.header.channel(c).unit] <= shown
        assert np.abs(rec.volts(c)).max() <= volts
        for h in (shown, volts):
            step = 10.0 ** np.floor(np.log10(h))
            labels = 2 * np.floor(h / step) + 1
            assert 3 <= labels <= 7 and h / step - np.floor(h / step) >= 0.4 - 1e-9, (c, h)
            assert round(h / step, 9) in HALF_HEIGHT_MANTISSAS


def test_the_live_views_expected_estimate_is_drawn_per_line_over_its_bin(run):
    """E[H1] on the analyzer screen: flat over each line's bin, vertical at its edges, never a
    slope between lines (a value no line reads)."""
    _, rrd = run
    for key in ("H_t", "Theta_2"):
        entity = f"/analyzer/{key}/expected"
        strips = []
        for ch in RrdReader(str(rrd)).stream().filter(content=entity,
                                                      is_static=True).to_chunks():
            if str(ch.entity_path) == entity:
                for row in ch.to_record_batch().column("LineStrips2D:strips").to_pylist():
                    strips += [np.asarray(s, float) for s in row]
        assert strips and sum(len(s) for s in strips) > 100
        for s in strips:
            d = np.diff(s, axis=0)
            assert np.all((d[:, 0] == 0) | (d[:, 1] == 0)), key


def test_screenshot_renders_the_layout_to_a_png(run, tmp_path):
    out, _ = run
    try:
        lv.screenshot_command(tmp_path / "x.rrd", tmp_path / "x.png")
    except lv.LiveViewError as exc:
        pytest.skip(f"the viewer cannot render here: {exc}")
    png = tmp_path / "layout.png"
    res = CliRunner().invoke(main, ["view", str(out), "--screenshot", str(png), "--size",
                                    "1280x720"])
    if res.exit_code != 0 and "could not render" in res.output:
        pytest.skip(f"the viewer cannot render here: {res.output.strip()}")
    assert res.exit_code == 0, res.output
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[0] >= 720 and img.shape[1] >= 1280
    # not a blank window: the signals' and the analyzer's colours are on screen
    colours = {tuple(c) for c in img.reshape(-1, 3)[::97]}
    assert len(colours) > 50


def test_viewer_going_away_mid_run_warns_once_and_the_run_goes_on(tmp_path):
    import rerun_cli

    exe = Path(rerun_cli.__file__).parent / "rerun"
    try:
        lv.screenshot_command(tmp_path / "x.rrd", tmp_path / "x.png")
    except lv.LiveViewError as exc:
        pytest.skip(f"no headless viewer here: {exc}")
    port = _closed_port()
    viewer = subprocess.Popen([str(exe), "--headless", "--bind", "127.0.0.1", "--port",
                               str(port), "--memory-limit", "200MiB"],
                              env=dict(os.environ, WGPU_BACKEND="vulkan", RUST_LOG="off"),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        if not lv.stream._listening("127.0.0.1", port, wait_s=30.0):
            pytest.skip("the headless viewer did not start here")

        class KillViewer(Sink):
            critical = False

            def record(self, record):
                if record.index == 0:
                    viewer.kill()
                    viewer.wait()

        url = f"rerun+http://127.0.0.1:{port}/proxy"
        rrd = tmp_path / "run.rrd"
        with pytest.warns(lv.LiveViewWarning) as caught:
            summary = acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(tmp_path / "run.h5"),
                                     live_sink(rrd, connect=url), KillViewer()])
        assert len(caught) == 1 and "lost the rerun viewer" in str(caught[0].message)
        assert summary.status == "complete"
        rec = read_run(tmp_path / "run.h5")
        _, a = channel(rrd, "/signals", rec.header, "a")  # the file kept everything
        np.testing.assert_array_equal(a, rec.values("a").ravel())
    finally:
        viewer.kill()
        viewer.wait()


def test_realtime_live_view_sends_the_run_paced_and_unchanged(tmp_path):
    from daq.pacing import Pacer

    now, slept = [0.0], []

    def sleep(s):
        slept.append(s)
        now[0] += s

    rrd = tmp_path / "paced.rrd"
    view = lv.LiveView(lv.ViewerStream(lv.ViewerOptions(rrd=rrd)),
                       pacer=Pacer(50.0, clock=lambda: now[0], sleep=sleep))
    from daq.pacing import PACED_BLOCK_S

    assert view.block_s == PACED_BLOCK_S  # paced: the run in short blocks
    assert lv.LiveView(lv.ViewerStream(lv.ViewerOptions(rrd=rrd))).block_s is None
    acquire(short_scene(), seed=SEED, sinks=[Hdf5Sink(tmp_path / "run.h5"), view])
    rec = read_run(tmp_path / "run.h5")
    # the records' 15 s, from the first sample to the last, at 50 x real time, in 0.1 s steps
    assert sum(slept) == pytest.approx(15.0 / 50.0, rel=1e-12)
    assert len(slept) == 150 and max(slept) == pytest.approx(0.1 / 50.0)
    _, a = channel(rrd, "/signals", rec.header, "a")
    np.testing.assert_array_equal(a, rec.values("a").ravel())
