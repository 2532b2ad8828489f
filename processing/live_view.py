"""The live view in rerun: watch the bench while it runs, replay a run file, show free motion.

This is the only module that imports rerun (``rerun-sdk`` 0.41), and nothing imports it unless a
live option is used. It consumes the acquisition stream (:class:`daq.sinks.Sink`) like a
plot consumes an analysis, which is why it lives in ``processing``: the analyzer's screen needs
the running average (:mod:`processing.running_average`), and ``daq`` must not import
``processing`` (the CLI composes them).

What is shown (:func:`acquisition_blueprint` lays it out)
--------------------------------------------------------
- ``/bench``: the bench in a 2D side view [mm], sizes to scale, motions magnified (the factor is
  written in the view): the stage moving on its rail (``/bench/stage``, a translation), and on
  it ``pendulum`` (line strips: the bodies, the mirror's face, the laser beam) and ``marks``
  (points: the pivots, the centres of mass), each styled instance by instance; the laser and the
  PSD (:mod:`processing.bench_geometry`); about 33 frames per simulated second;
- ``/psd``: the 12 mm detector to scale with the spot and its last 2 s as a trail;
- ``/signals``: the channels a, x, y in engineering units (m/s^2, m, rad), one series each, in a
  20 s window that follows the run, one view per channel showing its series; ``/volts``: the
  same samples as ADC volts (a tab);
- ``/analyzer``: after every record, the running averaged H_t and Theta_2 (gain [dB] and phase
  [deg]) over the exact model stored in the run and the expected estimate E[H1], and the
  coherences, on a drawn log-frequency axis (:mod:`processing.bode_canvas`);
- ``/status``: record k of N, clipped and saturated samples, the model in use and why, the seed.

Cost: each entity costs a send and a time column per record, whatever it holds, hence few
entities (the channels as one entity per unit system, the moving parts as two). With a viewer
the columns go out once per block and entity; with only a file, the blocks of a record are held
and drawn at its end, as one (one send per record and entity); the analyzer curves once per
record. The sends run on a worker thread beside the acquisition. ``BENCHMARKS.md`` has the
figures.

Sinks: a spawned viewer (``spawn``, with an explicit memory limit), a running viewer
(``connect``), an ``.rrd`` file (``rrd``), any combination. A viewer that cannot be spawned,
refuses the connection or goes away gives one warning (:class:`LiveViewWarning`) and the run goes
on: the file sink, if any, keeps everything. ``.rrd`` files are written under a temporary name
and renamed when the stream ends (also when interrupted); an existing file is replaced only with
``force``.
"""

from __future__ import annotations

import os
import queue
import shutil
import socket
import subprocess
import sys
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# rerun's native log lines would repeat what the single warning below says
os.environ.setdefault("RUST_LOG", "off")

import pyarrow as pa  # noqa: E402
import rerun as rr  # noqa: E402
import rerun.blueprint as rrb  # noqa: E402
from rerun.components import LineStrip2DBatch  # noqa: E402

from daq.sinks import Sink  # noqa: E402
from rig._io import check_writable  # noqa: E402
from daq.records import Block, Footer, Record  # noqa: E402
from processing import bode_canvas as bc  # noqa: E402
from processing.bench_geometry import (FRAMES_PER_S, MAGNIFICATION, MM, BenchDrawing,  # noqa
                                       StagePosition, frame_indices, frame_step)
from processing.running_average import RunningAverage  # noqa: E402
from processing.spectra import ProcessingError, SettingsError  # noqa: E402
from processing.viewer_url import DEFAULT_PORT, host_port as _host_port  # noqa: E402



class _PandasHidden:
    """A meta-path finder under which ``import pandas`` fails (see :func:`_no_pandas_probe`)."""

    def find_spec(self, name, path=None, target=None):
        if name == "pandas" or name.startswith("pandas."):
            raise ModuleNotFoundError(f"{name} is not imported by the live view", name=name)
        return None


def _no_pandas_probe() -> None:
    """Spare the process pyarrow's import of pandas (0.4-0.6 s of CPU) when pandas is installed.

    On its first conversion pyarrow imports pandas only to ask whether the input is a pandas
    object (its "soft" probe); while nothing has imported pandas, nothing can be one. The probe
    is answered here, once, with pandas hidden: pyarrow records "no pandas" for its soft checks.
    Its pandas conversions (``to_pandas``, ...) still import pandas when called, and from then on
    pyarrow treats pandas objects as usual. Nothing changes if pandas is already imported."""
    if "pandas" in sys.modules:
        return
    finder = _PandasHidden()
    sys.meta_path.insert(0, finder)
    try:
        pa.array([0], pa.int8())
    finally:
        sys.meta_path.remove(finder)


_no_pandas_probe()

TIMELINE = "time"
#: The channels in engineering units and in ADC volts: one entity each, one series per channel
SIGNALS, VOLTS = "/signals", "/volts"
MEMORY_LIMIT = "2GiB"
SIGNAL_WINDOW_S = 20.0
TRAIL_S = 2.0
CHANNEL_COLORS = {"a": (230, 159, 0), "x": (86, 180, 233), "y": (0, 158, 115)}
MEASURED, MODEL, EXPECTED = (255, 200, 60), (90, 160, 255), (200, 120, 255)


class LiveViewWarning(RuntimeWarning):
    """A viewer could not be reached or went away; the run goes on without it."""


class LiveViewError(RuntimeError):
    """The live view cannot do what was asked (e.g. no screenshot possible here)."""


@dataclass(frozen=True)
class ViewerOptions:
    """Where the stream goes.

    Attributes
    ----------
    spawn : start a viewer (``rerun`` beside this Python, or on PATH) and stream to it.
    connect : URL of a running viewer, e.g. ``rerun+http://127.0.0.1:9876/proxy``.
    rrd : save the stream to this ``.rrd`` file.
    force : replace an existing ``rrd``.
    memory_limit : the spawned viewer's memory limit (rerun syntax, e.g. "2GiB").
    port : the spawned viewer's port (on 127.0.0.1).
    """

    spawn: bool = False
    connect: str | None = None
    rrd: Path | None = None
    force: bool = False
    memory_limit: str = MEMORY_LIMIT
    port: int = DEFAULT_PORT

    @property
    def any(self) -> bool:
        return bool(self.spawn or self.connect or self.rrd)


def viewer_executable() -> str | None:
    """The ``rerun`` viewer installed with rerun-sdk (beside this Python), else on PATH."""
    here = Path(sys.executable).parent / "rerun"
    return str(here) if here.exists() else shutil.which("rerun")


def _listening(host: str, port: int, wait_s: float = 0.0) -> bool:
    end = time.monotonic() + wait_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=0.5):
                return True
        except OSError:
            if time.monotonic() >= end:
                return False
            time.sleep(0.1)


class ViewerStream:
    """A rerun recording going to the sinks of :class:`ViewerOptions`: one recording stream
    per sink (the file's and the viewer's), so a viewer can be dropped while the file goes on.
    Warns instead of failing when a viewer is missing or lost (:class:`LiveViewWarning`, once
    per viewer)."""

    def __init__(self, options: ViewerOptions, *, application_id: str = "pendulum-daq",
                 recording_id: str | None = None):
        import uuid

        self.options = options
        self.rrd = None if options.rrd is None else Path(options.rrd)
        if self.rrd is not None:
            check_writable(self.rrd, force=options.force)
            self._part = self.rrd.with_name(self.rrd.name + ".part")
        self.url = None
        if options.connect:
            _host_port(options.connect)  # validates before anything runs
        self._app = application_id
        self._id = recording_id or str(uuid.uuid4())
        self._file = self._viewer = None
        self.recs = []
        self.viewer_lost = False
        self._closed = False
        self._jobs, self._worker, self._error = queue.Queue(), None, None

    def _stream(self):
        return rr.RecordingStream(self._app, recording_id=self._id, send_properties=False)

    def open(self, blueprint) -> None:
        """Attach the sinks and send the blueprint."""
        url = None
        if self.options.spawn:
            url = self._spawn()
        elif self.options.connect:
            host, port = _host_port(self.options.connect)
            if _listening(host, port):
                url = self.options.connect
            else:
                self._warn(f"no rerun viewer at {self.options.connect} (connection refused)")
        if self.rrd is not None:
            self._file = self._stream()
            self._file.set_sinks(rr.FileSink(str(self._part)), default_blueprint=blueprint)
            self.recs.append(self._file)
        if url is not None:
            self._viewer = self._stream()
            self._viewer.set_sinks(rr.GrpcSink(url), default_blueprint=blueprint)
            self.recs.append(self._viewer)
        self.url = url

    def _spawn(self) -> str | None:
        exe = viewer_executable()
        if exe is None:
            self._warn("no rerun viewer executable found (pip install rerun-sdk installs one)")
            return None
        port = self.options.port
        if not _listening("127.0.0.1", port):  # else reuse the viewer already there
            # started here, not by rr.spawn, to bind its server to this machine only (rerun's
            # default is every interface)
            cmd = [exe, "--port", str(port), "--bind", "127.0.0.1", "--memory-limit",
                   self.options.memory_limit, "--hide-welcome-screen", "--expect-data-soon"]
            try:
                subprocess.Popen(cmd, env=dict(os.environ, RERUN_APP_ONLY="true"),
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL, start_new_session=True)
            except OSError as exc:  # the viewer cannot be started
                self._warn(f"the rerun viewer could not be started: {exc}")
                return None
        if not _listening("127.0.0.1", port, wait_s=10.0):
            self._warn("the rerun viewer did not start (no display? see 'rerun --help'; "
                       "--rrd FILE saves the stream instead)")
            return None
        return f"rerun+http://127.0.0.1:{port}/proxy"

    def _warn(self, what: str) -> None:
        warnings.warn(f"live view: {what}; the run goes on without the viewer",
                      LiveViewWarning, stacklevel=3)

    def _drop_viewer(self, why) -> None:
        self.viewer_lost = True
        self._warn(f"lost the rerun viewer at {self.url} ({why})")
        if self._viewer in self.recs:
            self.recs.remove(self._viewer)

    # the sends run in order on one worker thread, beside the acquisition -------------------
    def later(self, fn, *args) -> None:
        """Run ``fn(*args)`` on the worker thread, after everything submitted before (a failure
        is raised by the next :meth:`drain`, :meth:`check` or :meth:`close`)."""
        self._submit(fn, *args)

    def _submit(self, fn, *args) -> None:
        if self._worker is None:
            self._worker = threading.Thread(target=self._work, name="live-view", daemon=True)
            self._worker.start()
        self._jobs.put((fn, args))

    def _work(self) -> None:
        while True:
            fn, args = self._jobs.get()
            try:
                if self._error is None:
                    fn(*args)
            except BaseException as exc:  # handed to the acquisition's thread by drain()
                self._error = exc
            finally:
                self._jobs.task_done()

    def drain(self) -> None:
        """Wait until everything submitted is sent; re-raise a failure of the sends."""
        if self._worker is not None:
            self._jobs.join()
        if self._error is not None:
            exc, self._error = self._error, None
            raise exc

    def check(self) -> None:
        """Flush to the viewer (once per record); if it went away, warn once and go on with the
        file alone."""
        if self._viewer is None or self.viewer_lost:
            return
        self.drain()
        try:
            self._viewer.flush(timeout_sec=10.0)
            if not _listening(*_host_port(self.url)):
                raise ConnectionError("it no longer accepts connections")
        except Exception as exc:
            self._drop_viewer(exc)

    def close(self) -> Path | None:
        """Flush, write the file's footer and rename it into place; return its path."""
        if self._closed:
            return self.rrd
        self._closed = True
        try:
            self.drain()
        finally:
            self._close()
        return self.rrd if self.rrd is not None and self.rrd.exists() else None

    def _close(self) -> None:
        self.check()
        if self._viewer is not None and not self.viewer_lost:
            try:
                self._viewer.disconnect()
            except Exception as exc:
                self._drop_viewer(exc)
        if self._file is not None:
            self._file.disconnect()
            if self._part.exists():
                os.replace(self._part, self.rrd)

    # columnar sends -----------------------------------------------------------------------
    @property
    def batch_records(self) -> bool:
        """True when only a file listens: columns are then gathered over a record and sent
        once per record and entity (fewer, larger sends); with a viewer, once per block."""
        return self.url is None or self.viewer_lost

    def _columns(self, entity: str, t_s: np.ndarray, columns) -> None:
        """Send ``columns`` at times ``t_s`` [s] (rounded to the timeline's whole ns)."""
        if np.size(t_s):
            ns = np.round(np.asarray(t_s, float) * 1e9).astype("timedelta64[ns]")
            for rec in self.recs:
                rec.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, duration=ns)],
                                 columns=columns)

    def queue(self, entity: str, kind: str, t_s: np.ndarray, data: np.ndarray,
              strips: tuple = ()) -> None:
        """Gather columns of ``entity`` for :meth:`send_queued`. ``kind``: "scalars" ((N,) or
        (N, k)), "translation" ((N, 3)), "strips" ((N, k, 2): per row, line strips of
        ``strips`` points each, ``sum(strips) == k``) or "points" ((N, k, 2): k points per
        row)."""
        if not np.size(t_s):
            return
        q = self.__dict__.setdefault("_queue", {})
        q.setdefault((entity, kind, tuple(strips)), []).append((np.asarray(t_s, float),
                                                                np.asarray(data)))

    def send_queued(self) -> None:
        """One ``send_columns`` per gathered entity (on the worker thread)."""
        q = self.__dict__.pop("_queue", {})
        if q:
            self._submit(self._send_queued, q)

    def _send_queued(self, q: dict) -> None:
        for (entity, kind, strips), parts in q.items():
            t = np.concatenate([p[0] for p in parts])
            d = np.concatenate([p[1] for p in parts])
            if kind == "scalars":
                cols = rr.Scalars.columns(scalars=d)
            elif kind == "translation":
                cols = rr.Transform3D.columns(translation=d)
            elif kind == "strips":
                cols = rr.LineStrips2D.columns(strips=_strip_array(d, strips)).partition(
                    np.full(t.size, len(strips), np.int32))
            else:
                k = d.shape[1]
                cols = rr.Points2D.columns(positions=np.ascontiguousarray(
                    d.reshape(-1, 2))).partition(np.full(t.size, k, np.int32))
            self._columns(entity, t, cols)

    def strips_at(self, t_s: float, entity: str, strips: list) -> None:
        """One row of line strips at ``t_s`` (its style is logged statically)."""
        self._submit(self._strips_at, t_s, entity, strips)

    def _strips_at(self, t_s, entity, strips) -> None:
        if not strips:
            strips = [np.full((2, 2), np.nan)]
        points = np.concatenate(strips)[None]
        self._columns(entity, np.array([t_s]), rr.LineStrips2D.columns(
            strips=_strip_array(points, tuple(len(p) for p in strips))).partition(
            [len(strips)]))

    def text_at(self, t_s: float, entity: str, markdown: str) -> None:
        self._submit(lambda: self._columns(entity, np.array([t_s]), rr.TextDocument.columns(
            text=[markdown], media_type=["text/markdown"])))

    def static(self, entity: str, archetype) -> None:
        self._submit(self._static, entity, archetype)

    def _static(self, entity: str, archetype) -> None:
        for rec in self.recs:
            rec.log(entity, archetype, static=True)


def _strip_array(d: np.ndarray, strips: tuple) -> pa.Array:
    """Rows of ``d`` (N, k, 2) as N x len(strips) line strips, of ``strips`` points each, row
    after row; built in Arrow directly (rerun's own conversion loops over the strips in
    Python); float32, as rerun stores them."""
    n, k = d.shape[:2]
    typ = LineStrip2DBatch._ARROW_DATATYPE
    points = pa.FixedSizeListArray.from_arrays(
        pa.array(np.ascontiguousarray(d, np.float32).reshape(-1)), type=typ.value_type)
    starts = (k * np.arange(n, dtype=np.int32)[:, None]
              + np.concatenate([[0], np.cumsum(strips[:-1])]).astype(np.int32)).ravel()
    offsets = np.append(starts, np.int32(n * k)).astype(np.int32)
    return pa.ListArray.from_arrays(pa.array(offsets), points, type=typ)


# -- what is drawn ---------------------------------------------------------------------------

_FRAME_COLOR = (150, 150, 150)
_BODY_COLORS = [(255, 170, 40), (255, 90, 40), (230, 60, 120), (160, 90, 230)]


def _bench_layout(d: BenchDrawing) -> dict:
    """Static positions of the stage frame, rail, laser and PSD in the side view [mm]."""
    reach = d.reach_mm
    w = max(40.0, 0.6 * reach)
    floor = reach + 0.25 * reach + 10.0
    return {"reach": reach, "half_width": w, "floor": floor,
            "laser": (w * 0.95, d.reach_mm * 0.25), "psd": (w * 0.95, d.reach_mm * 0.75)}


def _log_bench_static(s: ViewerStream, d: BenchDrawing, *, moving_stage: bool,
                      optics: bool) -> None:
    lay = _bench_layout(d)
    w, floor = lay["half_width"], lay["floor"]
    top = -0.15 * lay["reach"] - 5.0
    frame = [np.array([[-w, floor], [-w, top], [w, top], [w, floor]]),  # posts and top beam
             np.array([[-0.2 * w, top], [0, 0], [0.2 * w, top]]),  # hanger to the top pivot
             np.array([[-w - 8, floor], [w + 8, floor], [w + 8, floor + 6], [-w - 8, floor + 6],
                       [-w - 8, floor]])]  # the stage's table
    s.static("/bench/stage/frame", rr.LineStrips2D(frame, colors=_FRAME_COLOR, radii=0.6))
    rail_y = floor + 9
    span = w * (2.6 if moving_stage else 1.3)
    s.static("/bench/rail", rr.LineStrips2D([np.array([[-span, rail_y], [span, rail_y]])],
                                            colors=(90, 90, 90), radii=1.0))
    if optics:
        lx, ly = lay["laser"]
        px, py = lay["psd"]
        s.static("/bench/stage/optics", rr.Boxes2D(
            centers=[(lx, ly), (px, py)], half_sizes=[(4, 3), (2, d.psd_half_mm or 6)],
            colors=[(220, 50, 50), (120, 200, 120)], labels=["laser", "PSD"],
            show_labels=True))
    note = (f"side view, sizes to scale; angles x{d.magnification:g}, stage travel "
            f"x{d.stage_magnification:g}" if moving_stage else "side view, to scale")
    s.static("/bench/note", rr.Points2D([(0.0, top - 0.12 * lay["reach"] - 4)], radii=0.0,
                                        labels=[note], show_labels=True,
                                        colors=(220, 220, 220)))
    bar = 10.0 if lay["reach"] < 300 else 10 ** np.floor(np.log10(lay["reach"] / 2))
    y = floor - 0.15 * lay["reach"]
    s.static("/bench/scale", rr.LineStrips2D([np.array([[-0.9 * w, y], [-0.9 * w + bar, y]])],
                                             colors=(220, 220, 220), radii=0.8,
                                             labels=[f"{bar:g} mm"], show_labels=True))


def _bench_bounds(d: BenchDrawing, moving_stage: bool) -> rrb.VisualBounds2D:
    lay = _bench_layout(d)
    w, r = lay["half_width"] * (1.7 if moving_stage else 1.2), lay["reach"]
    return rrb.VisualBounds2D(x_range=(-w, w), y_range=(-0.45 * r - 15, lay["floor"] + 30))


# the moving parts go out as two entities, whatever the number of bodies (each entity costs a
# send and a time column per record): ``pendulum``, line strips [the bodies, the mirror's face,
# (the laser beam)]; ``marks``, points [the pivots, the centres of mass]. Their colours and
# radii are logged once, instance by instance (:func:`_log_chain_style`).
PENDULUM, MARKS = "/bench/stage/pendulum", "/bench/stage/marks"
_PIVOT_COLOR, _COM_COLOR = (255, 255, 255), (255, 90, 40)
_MIRROR_COLOR, _BEAM_COLOR = (190, 230, 255), (255, 60, 60)


def _chain_frames(d: BenchDrawing, theta: np.ndarray):
    """The pendulum at frames of the angles ``theta`` (frames, n) [rad], drawn [mm]: the line
    strips (frames, n + 3, 2) of the bodies (n + 1 joints) and the mirror's face (2 points),
    their lengths (n + 1, 2), the marks (frames, 2 n, 2): n pivots then n centres of mass, and
    the mirror's centres (frames, 2)."""
    joints = d.joints(theta)
    centre, face = d.mirror(theta, joints, half_mm=max(3.0, 0.12 * d.reach_mm))
    lines = np.concatenate([joints, face], axis=1)
    marks = np.concatenate([joints[:, :-1], d.centres_of_mass(theta, joints)], axis=1)
    return lines, (joints.shape[1], 2), marks, centre


def _log_chain_style(s: ViewerStream, n: int, *, body: float = 1.2, pivot: float = 1.4,
                     com: float = 1.0, mirror: float = 1.5, beam: float = 0.4) -> None:
    """Colours and radii [mm] of the strips of :data:`PENDULUM` and the points of
    :data:`MARKS`, per instance (the order of :func:`_chain_frames`)."""
    s.static(PENDULUM, rr.LineStrips2D.from_fields(
        colors=[_BODY_COLORS[0], _MIRROR_COLOR, _BEAM_COLOR], radii=[body, mirror, beam]))
    s.static(MARKS, rr.Points2D.from_fields(colors=[_PIVOT_COLOR] * n + [_COM_COLOR] * n,
                                            radii=[pivot] * n + [com] * n))


def _analyzer_panels(freqs, model_db, expected_db):
    """The panels of H_t / Theta_2 (gain, phase) and coherence on a common frequency range."""
    fmin, fmax = float(freqs[0]), float(freqs[-1])
    out = {}
    for key in ("H_t", "Theta_2"):
        lo, hi = bc.db_range(model_db[key], expected_db.get(key, []), step=20.0)
        lo = max(lo, hi - 120.0)  # an anti-resonance's notch need not set the scale
        gain = bc.Panel(fmin, fmax, lo, hi, bc.ticks(lo, hi, 20.0), "dB", 0.0, 62.0, "")
        phase = bc.Panel(fmin, fmax, -180.0, 180.0, bc.ticks(-180, 180, 180), "deg", 74.0,
                         36.0, "")
        out[key] = (gain, phase)
    out["coherence"] = (bc.Panel(fmin, fmax, 0.0, 1.0, bc.ticks(0, 1, 0.5), "", 0.0, 30.0,
                                 ""),)
    return out


def _db(h) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return 20.0 * np.log10(np.abs(h))


def _deg(h) -> np.ndarray:
    return np.degrees(np.angle(h))


def _log_panel_static(s: ViewerStream, entity: str, panels) -> None:
    grid, pos, text = [], [], []
    for i, p in enumerate(panels):
        grid += p.grid()
        q, t = p.labels(decades=i == len(panels) - 1)
        pos += list(q)
        text += t
        if p.title:
            pos.append((0.0, p.top - 4.0))
            text.append(p.title)
    s.static(f"{entity}/grid", rr.LineStrips2D(grid, colors=(70, 70, 70), radii=0.12))
    s.static(f"{entity}/labels", rr.Points2D(pos, radii=0.0, labels=text, show_labels=True,
                                             colors=(200, 200, 200)))


def _bode_strips(gain: bc.Panel, phase: bc.Panel, f, h) -> list:
    return gain.curve(f, _db(h)) + phase.curve(f, _deg(h), wrap=360.0)


class LiveView(Sink):
    """The acquisition stream into rerun (module docstring). A non-critical sink: if it fails,
    the acquisition warns, drops it and goes on.

    Parameters
    ----------
    stream : ViewerStream (not yet opened: :meth:`start` opens it with the blueprint).
    magnification : factor on displacements and angles in the bench drawing.
    pacer : optional :class:`daq.pacing.Pacer`: each block is sent in frames paced to the wall
        clock (``--realtime``).
    settings : processing.analyzer.AnalyzerSettings of the running average (default: the
        paper's analyzer).
    """

    critical = False

    def __init__(self, stream: ViewerStream, *, magnification: float = MAGNIFICATION,
                 pacer=None, settings=None):
        self.stream, self.pacer, self.settings = stream, pacer, settings
        self.magnification = magnification
        self.footer = None
        # blocks held to be drawn at their record's end (only a file listens, no pacing): then
        # the worker thread queues and sends the columns; otherwise this thread does, block by
        # block (``_queued_here``: something is queued here); never both at once
        self._pending = []
        self._queued_here = False

    # -- start: static parts, model curves ------------------------------------------------
    def start(self, header) -> None:
        self.header = header
        plan = header.plan
        self.rate = plan.rate_hz
        self.names = header.names
        self.drawing = BenchDrawing.from_scene(header.scene, self.magnification)
        self.step = frame_step(self.rate)
        truth = {t.name for t in header.truth}
        self.has_angles = "theta_rad" in truth
        self.stage = StagePosition(self.rate) if "stage_accel_mps2" in truth else None
        self.has_spot = ({"x", "y"} <= set(self.names)
                         and self.drawing.psd_gain_vpm is not None)
        self._clip = np.zeros(len(self.names), int)
        self._sat = np.zeros(len(self.names), int)
        try:
            self.average = RunningAverage(header, self.settings)
        except SettingsError:  # not a run with a, x and y: no analyzer screen
            self.average = None
        self.panels = None
        if self.average is not None:
            self._prepare_analyzer()
        self.stream.open(acquisition_blueprint(self))
        s = self.stream
        chans = [header.channel(c) for c in self.names]
        colors = [CHANNEL_COLORS.get(c, (200, 200, 200)) for c in self.names]
        s.static(SIGNALS, rr.SeriesLines(
            names=[f"{ch.name}: {ch.quantity} [{ch.unit}]" for ch in chans], colors=colors,
            widths=[1.0] * len(chans)))
        s.static(VOLTS, rr.SeriesLines(
            names=[f"{ch.name} [V] (ADC +-{ch.range_v:g} V)" for ch in chans], colors=colors,
            widths=[1.0] * len(chans)))
        _log_bench_static(s, self.drawing, moving_stage=True, optics=self.has_spot)
        _log_chain_style(s, len(self.drawing.lengths_mm))
        if self.has_spot:
            h = self.drawing.psd_half_mm
            s.static("/psd/detector", rr.Boxes2D(half_sizes=[(h, h)], centers=[(0, 0)],
                                                 colors=(120, 200, 120), radii=0.05,
                                                 labels=[f"PSD {2 * h:g} mm x {2 * h:g} mm, "
                                                         "to scale"], show_labels=True))
            s.static("/psd/axes", rr.LineStrips2D(
                [np.array([[-h, 0], [h, 0]]), np.array([[0, -h], [0, h]])],
                colors=(60, 90, 60), radii=0.02))
            s.static("/psd/spot", rr.Points2D.from_fields(colors=(255, 60, 60), radii=0.12))
        if self.panels is not None:
            self._log_analyzer_static()
        self._status(records=0, state="acquiring")

    def _prepare_analyzer(self) -> None:
        from processing.analyzer import model_at_lines
        from processing.leakage import expected_estimate

        avg = self.average
        f = avg.freqs_hz
        model = model_at_lines(self.header, f)
        self.model = {"H_t": model.h_t, "Theta_2": model.theta_2}
        self.expected = {}
        try:
            e = expected_estimate(self.header, avg.spectral, fmin_hz=avg.settings.fmin_hz,
                                  fmax_hz=avg.settings.fmax_hz)
            idx = np.searchsorted(e.freqs_hz, f)
            self.expected = {"H_t": e.h_t[idx], "Theta_2": e.theta_2[idx]}
        except ProcessingError:  # no E[H1] for this source (e.g. a sine): the model alone
            pass
        self.panels = _analyzer_panels(f, {k: _db(v) for k, v in self.model.items()},
                                       {k: _db(v) for k, v in self.expected.items()})

    def _log_analyzer_static(self) -> None:
        s, f = self.stream, self.average.freqs_hz
        for key in ("H_t", "Theta_2"):
            gain, phase = self.panels[key]
            base = f"/analyzer/{key}"
            _log_panel_static(s, base, (gain, phase))
            s.static(f"{base}/model", rr.LineStrips2D(_bode_strips(gain, phase, f,
                                                                   self.model[key]),
                                                      colors=MODEL, radii=0.15,
                                                      draw_order=30.0))
            legend = [("exact model (whole chain)", MODEL), ("measured, averaged", MEASURED)]
            if key in self.expected:
                s.static(f"{base}/expected", rr.LineStrips2D(
                    _bode_strips(gain, phase, f, self.expected[key]), colors=EXPECTED,
                    radii=0.2, draw_order=20.0))
                legend.insert(1, ("E[H1]: expected estimate", EXPECTED))
            s.static(f"{base}/legend", rr.Points2D(
                [(gain.width + 24.0, 8.0 + 10.0 * i) for i in range(len(legend))],
                radii=0.8, colors=[c for _, c in legend], labels=[t for t, _ in legend],
                show_labels=True))
        for key in ("H_t", "Theta_2"):
            s.static(f"/analyzer/{key}/measured", rr.LineStrips2D.from_fields(
                colors=MEASURED, radii=0.45, draw_order=10.0))
        for c in ("x", "y"):
            s.static(f"/analyzer/coherence/{c}", rr.LineStrips2D.from_fields(
                colors=CHANNEL_COLORS[c], radii=0.25))
        (coh,) = self.panels["coherence"]
        _log_panel_static(s, "/analyzer/coherence", (coh,))
        s.static("/analyzer/coherence/legend", rr.Points2D(
            [(coh.width + 24.0, 6.0), (coh.width + 24.0, 16.0)],
            radii=0.8,
            colors=[CHANNEL_COLORS["x"], CHANNEL_COLORS["y"]],
            labels=["x (H_t)", "y (Theta_2)"], show_labels=True))

    # -- blocks: signals and geometry ---------------------------------------------------
    def block(self, block: Block) -> None:
        n = block.samples
        if self.pacer is None and self.stream.batch_records:
            self._pending.append(block)  # drawn at the record's end, the blocks as one
            return
        self._queued_here = True
        if self.pacer is None:
            self._send(block, 0, n)
            return
        g0 = int(round(block.t0_s * self.rate))
        if not self.pacer.started:
            self.pacer.wait(block.t0_s)
        chunk = max(1, int(round(self.rate / 10)))  # 0.1 s of samples per paced send
        for i in range(0, n, chunk):
            j = min(n, i + chunk)
            self.pacer.wait((g0 + j) / self.rate)
            self._send(block, i, j)

    def _send(self, block: Block, i: int, j: int) -> None:
        s, rate = self.stream, self.rate
        g0 = int(round(block.t0_s * rate)) + i
        t = (g0 + np.arange(j - i)) / rate
        volts, values = {}, []
        for c in self.names:
            ch = self.header.channel(c)
            volts[c] = ch.adc.volts(np.asarray(block.codes[c][i:j]))
            values.append(volts[c] / ch.volts_per_unit)
        s.queue(SIGNALS, "scalars", t, np.stack(values, axis=1))
        s.queue(VOLTS, "scalars", t, np.stack(list(volts.values()), axis=1))
        idx = frame_indices(g0, j - i, self.step)
        tf = t[idx]
        d = self.drawing
        if self.stage is not None:  # integrated over every sample, drawn at the frames
            xs = self.stage(np.asarray(block.truth["stage_accel_mps2"][i:j]))[idx]
            tr = np.zeros((idx.size, 3))
            tr[:, 0] = d.stage_magnification * MM * xs
            s.queue("/bench/stage", "translation", tf, tr)
        lines = None
        if self.has_angles and idx.size:
            theta = np.asarray(block.truth["theta_rad"][i:j])[idx]
            lines, strips, marks, centre = _chain_frames(d, theta.reshape(idx.size, -1))
            s.queue(MARKS, "points", tf, marks)
        if self.has_spot and idx.size:
            spot = d.spot_mm(volts["x"][idx], volts["y"][idx])
            s.queue("/psd/spot", "points", tf, spot[:, None, :])
            if lines is not None:
                lay = _bench_layout(d)
                laser, psd = np.array(lay["laser"]), np.array(lay["psd"])
                # the reflected beam's end on the PSD icon moves with the spot (magnified)
                hit = psd + np.stack([np.zeros(idx.size), spot[:, 1] * d.magnification], -1)
                beam = np.stack([np.broadcast_to(laser, centre.shape), centre, hit], axis=1)
                lines, strips = np.concatenate([lines, beam], axis=1), (*strips, 3)
        if lines is not None:
            s.queue(PENDULUM, "strips", tf, lines, strips)
        if not s.batch_records:
            s.send_queued()

    def _send_pending(self, pending: list, record: Record | None = None) -> None:
        """Draw the blocks held since the last record as one block: the record's own arrays when
        they are all of it (the same frames and stage positions as block by block:
        :func:`processing.bench_geometry.frame_indices`, StagePosition)."""
        if not pending:
            return
        if record is not None and pending[0].start == 0:
            b = Block(record=record.index, start=0, t0_s=record.t0_s, codes=record.codes,
                      clipped=record.clipped, truth=record.truth, saturated=record.saturated)
        else:
            b = _joined(pending)
        self._send(b, 0, b.samples)
        self.stream.send_queued()

    # -- records: the analyzer screen and status ---------------------------------------------
    def record(self, record: Record) -> None:
        """The record's drawing (with only a file), running average and status are made on the
        stream's worker thread, beside the acquisition, in order."""
        pending, self._pending = self._pending, []
        self._send_queued_here()
        self.stream.later(self._record, pending, record)
        self.stream.check()

    def _send_queued_here(self) -> None:
        if self._queued_here:
            self.stream.send_queued()
            self._queued_here = False

    def _record(self, pending: list, record: Record) -> None:
        self._send_pending(pending, record)
        t_end = (record.t0_s + self.header.plan.record_s)
        self._sat = self._sat + np.array([record.saturation_counts()[c] for c in self.names])
        self._clip = self._clip + np.array([record.clip_counts()[c] for c in self.names])
        if self.average is not None:
            est = self.average.add(record.codes)
            s, f = self.stream, est.freqs_hz
            for key, h in (("H_t", est.h_t), ("Theta_2", est.theta_2)):
                gain, phase = self.panels[key]
                s.strips_at(t_end, f"/analyzer/{key}/measured", _bode_strips(gain, phase, f, h))
            (coh,) = self.panels["coherence"]
            for c, g2 in (("x", est.coherence_x), ("y", est.coherence_y)):
                s.strips_at(t_end, f"/analyzer/coherence/{c}", coh.curve(f, g2))
        self._status(records=record.index + 1, state="acquiring", t_s=t_end)

    def stop(self, footer: Footer) -> None:
        self.footer = footer
        pending, self._pending = self._pending, []
        try:
            self._send_queued_here()
            self.stream.later(self._send_pending, pending)  # an unfinished record's blocks
            self.stream.later(lambda: self._status(records=footer.records_complete,
                                                   state=footer.status, message=footer.message))
        finally:
            self.path = self.stream.close()

    def _status(self, *, records: int, state: str, t_s: float | None = None,
                message: str = "") -> None:
        h = self.header
        info = h.model_info
        clip, sat = self._clip, self._sat
        lines = [
            f"## Record {records} of {h.plan.records}  ({state}"
            + (f": {message}" if message else "") + ")",
            "",
            f"**scene** {h.scene.name}, **seed** {h.seed}  ",
            f"**sampling** {h.plan.rate_hz:g} Hz, records of {h.plan.record_s:g} s after "
            f"{h.plan.settle_s:g} s of settling",
            "",
            "| channel | clipped samples | sensor saturated |",
            "|---|---|---|",
            *[f"| {c} | {int(clip[i])} | {int(sat[i])} |" for i, c in enumerate(self.names)],
            "",
            f"**model** {info.get('model', '-')}, estimated error "
            f"{_error_text(info.get('error_estimate', '-'))}  ",
            f"**why** {info.get('reason', '-')}",
            "",
            f"bench: sizes to scale, angles x{self.drawing.magnification:g}, stage travel "
            f"x{self.drawing.stage_magnification:g} (the true acceleration integrated twice "
            "above 5 mHz); PSD to scale",
        ]
        if t_s is None:
            t_s = h.plan.settle_s if records == 0 else (
                h.plan.record_start_s(max(0, records - 1)) + h.plan.record_s)
        self.stream.text_at(t_s, "/status", "\n".join(lines))


def _joined(blocks: list) -> Block:
    """Consecutive blocks of one record as one block."""
    if len(blocks) == 1:
        return blocks[0]
    b = blocks[0]

    def cat(name):
        return {k: np.concatenate([getattr(x, name)[k] for x in blocks])
                for k in getattr(b, name)}

    return Block(record=b.record, start=b.start, t0_s=b.t0_s, codes=cat("codes"),
                 clipped=cat("clipped"), truth=cat("truth"), saturated=cat("saturated"))


def _error_text(v) -> str:
    """The headline of a model's error estimate (the relative RMS error of the angles)."""
    if isinstance(v, dict) and "relative_rms_theta" in v:
        return f"{v['relative_rms_theta']:.2g} (relative RMS of the angles)"
    return _plain(v)


def _plain(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_plain(x)}" for k, x in v.items())
    return str(v)


# -- blueprints ------------------------------------------------------------------------------

def _following(seconds: float) -> rrb.VisibleTimeRange:
    return rrb.VisibleTimeRange(TIMELINE,
                                start=rrb.TimeRangeBoundary.cursor_relative(seconds=-seconds),
                                end=rrb.TimeRangeBoundary.cursor_relative())


def _series(entity: str, names, header) -> list:
    """One view per channel of ``entity`` (one series per channel): that channel's series shown,
    the others hidden; the view's title names it (no legend: it would list the hidden ones)."""
    views = []
    for i, c in enumerate(names):
        ch = header.channel(c)
        title = (f"{c} [V] (ADC +-{ch.range_v:g} V)" if entity == VOLTS
                 else f"{c}: {ch.quantity} [{ch.unit}]")
        shown = rr.SeriesLines.from_fields(visible_series=[j == i for j in range(len(names))])
        views.append(rrb.TimeSeriesView(origin=entity, name=title, overrides={entity: shown},
                                        plot_legend=rrb.PlotLegend(visible=False),
                                        time_ranges=_following(SIGNAL_WINDOW_S)))
    return views


def acquisition_blueprint(view: LiveView) -> rrb.Blueprint:
    """The layout of a run (module docstring): bench, PSD and status on the left, the signals
    in the middle, the analyzer on the right; the time panel follows the newest data."""
    h = view.header
    left = [rrb.Spatial2DView(origin="/bench", name="bench (side view, mm)",
                              visual_bounds=_bench_bounds(view.drawing, True))]
    if view.has_spot:
        hh = view.drawing.psd_half_mm * 1.25
        left.append(rrb.Spatial2DView(origin="/psd", name=f"PSD spot (last {TRAIL_S:g} s)",
                                      visual_bounds=rrb.VisualBounds2D(
                                          x_range=(-hh, hh), y_range=(-hh, 1.35 * hh)),
                                      time_ranges=_following(TRAIL_S)))
    left.append(rrb.TextDocumentView(origin="/status", name="status"))
    middle = rrb.Tabs(rrb.Vertical(*_series(SIGNALS, view.names, h),
                                   name="signals (engineering units)"),
                      rrb.Vertical(*_series(VOLTS, view.names, h), name="ADC volts"),
                      active_tab=0)
    cols = [rrb.Vertical(*left, row_shares=[3, 2, 2][:len(left)]), middle]
    shares = [1.0, 1.0]
    if view.panels is not None:
        w = view.panels["coherence"][0].width
        bounds = rrb.VisualBounds2D(x_range=(-16, w + 50), y_range=(-4, 124))
        key_units = {"H_t": "m/(m/s^2)", "Theta_2": "rad/(m/s^2)"}
        names = {k: f"analyzer: {k} = {'x' if k == 'H_t' else 'y'}/a averaged after each record:"
                    f" gain [dB re 1 {u}], phase [deg]" for k, u in key_units.items()}
        cols.append(rrb.Vertical(
            rrb.Spatial2DView(origin="/analyzer/H_t", name=names["H_t"], visual_bounds=bounds),
            rrb.Spatial2DView(origin="/analyzer/Theta_2", name=names["Theta_2"],
                              visual_bounds=bounds),
            rrb.Spatial2DView(origin="/analyzer/coherence",
                              name="coherence gamma^2 of x (H_t) and y (Theta_2)",
                              visual_bounds=rrb.VisualBounds2D(x_range=(-16, w + 50),
                                                               y_range=(-4, 40))),
            row_shares=[3, 3, 1.3]))
        shares.append(1.5)
    return rrb.Blueprint(rrb.Horizontal(*cols, column_shares=shares),
                         rrb.TimePanel(timeline=TIMELINE, play_state="following",
                                       state="collapsed"),
                         collapse_panels=True)


# -- replay ------------------------------------------------------------------------------

def replay(path, stream: ViewerStream, *, magnification: float = MAGNIFICATION,
           settings=None) -> LiveView:
    """Replay a run file (finished or interrupted: its finished records) into ``stream``, as
    the live run showed it; the stream is closed at the end."""
    from daq.hdf5 import read_run

    run = read_run(path)
    h = run.header
    view = LiveView(stream, magnification=magnification, settings=settings)
    view.start(h)
    try:
        for r in range(run.records):
            t0 = h.plan.record_start_s(r)
            codes = {c: run.codes[c][r] for c in h.names}
            clipped = {c: run.clipped[c][r] for c in h.names}
            sat = {c: run.saturated[c][r] for c in run.saturated}
            truth = {k: run.truth[k][r] for k in run.truth}
            view.block(Block(record=r, start=0, t0_s=t0, codes=codes, clipped=clipped,
                             truth=truth, saturated=sat))
            view.record(Record(index=r, t0_s=t0, codes=codes, clipped=clipped, truth=truth,
                               saturated=sat))
    finally:
        status = run.status if run.status != "acquiring" else "acquiring (writer stopped)"
        view.stop(Footer(status=status, records_complete=run.records,
                         clip_counts=run.clip_counts()))
    return view


# -- free motion -------------------------------------------------------------------------

def show_trajectory(traj, scene, stream: ViewerStream) -> Path | None:
    """Free motion (:func:`rig.simulate.simulate`) into ``stream``: the pendulum to scale on a
    fixed base, its angles and energy over time; the stream is closed at the end."""
    d = BenchDrawing.from_scene(scene, 1.0)
    n = len(d.lengths_mm)
    t = np.asarray(traj.t_s, float)
    theta = np.asarray(traj.theta_rad, float).reshape(t.size, n)
    r = d.reach_mm
    bp = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial2DView(origin="/bench", name="pendulum (side view, mm)",
                                           visual_bounds=rrb.VisualBounds2D(
                                               x_range=(-1.25 * r, 1.25 * r),
                                               y_range=(-1.25 * r, 1.25 * r))),
                         rrb.TextDocumentView(origin="/status", name="status"),
                         row_shares=[4, 1]),
            rrb.Vertical(rrb.TimeSeriesView(origin="/signals/theta", name="angles [rad]",
                                            time_ranges=_following(20.0)),
                         rrb.TimeSeriesView(origin="/signals/energy", name="energy [J]")),
            column_shares=[1, 1]),
        rrb.TimePanel(timeline=TIMELINE, play_state="following", state="collapsed"),
        collapse_panels=True)
    stream.open(bp)
    s = stream
    try:
        s.static("/bench/pivot", rr.Points2D([(0, 0)], radii=max(1.0, 0.01 * r),
                                             colors=(255, 255, 255)))
        s.static("/bench/note", rr.Points2D([(-1.2 * r, -1.15 * r)], radii=0.0,
                                            labels=["side view, to scale; free motion on a "
                                                    "fixed base"], show_labels=True))
        _log_chain_style(s, n, body=max(1.0, 0.008 * r), pivot=max(1.0, 0.01 * r),
                         com=max(1.0, 0.008 * r), mirror=max(1.0, 0.01 * r))
        s.static("/signals/theta", rr.SeriesLines(names=[f"theta_{j + 1}" for j in range(n)]))
        s.queue("/signals/theta", "scalars", t, theta)
        if traj.energy_j is not None:
            s.queue("/signals/energy", "scalars", t, np.asarray(traj.energy_j, float))
        lines, strips, marks, _ = _chain_frames(d, theta)
        s.queue(PENDULUM, "strips", t, lines, strips)
        s.queue(MARKS, "points", t, marks)
        s.send_queued()
        est = getattr(traj, "max_error_rad", None)
        s.static("/status", rr.TextDocument(
            f"**{scene.name}**: free motion, {n} bodies, {t[-1] - t[0]:g} s, method "
            f"{traj.method}" + (f", estimated max angle error {est:.3g} rad" if est else ""),
            media_type="text/markdown"))
    finally:
        path = stream.close()
    return path


# -- screenshots --------------------------------------------------------------------------

def screenshot_command(rrd: Path, png: Path, size: str = "1600x900") -> tuple[list, dict]:
    """The command rendering ``rrd`` into ``png`` without a display, and its environment:
    ``rerun --headless`` on Vulkan (Mesa's software rasteriser works), else ``xvfb-run``.
    Raises LiveViewError when neither is available."""
    exe = viewer_executable()
    if exe is None:
        raise LiveViewError("no rerun viewer executable (pip install rerun-sdk)")
    env = dict(os.environ, WGPU_BACKEND="vulkan", RUST_LOG="error")
    cmd = [exe, str(rrd), "--screenshot-to", str(png), "--window-size", size]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return cmd, env
    if not _has_vulkan():
        raise LiveViewError("no Vulkan driver to render with (Debian: apt-get install xvfb "
                            "xauth mesa-vulkan-drivers libvulkan1)")
    xvfb = shutil.which("xvfb-run")
    if xvfb is not None:
        return [xvfb, "-a", "-s", f"-screen 0 {size}x24", *cmd], env
    return [exe, "--headless", *cmd[1:]], env


def _has_vulkan() -> bool:
    for d in ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"):
        if Path(d).is_dir() and any(Path(d).glob("*.json")):
            return True
    return False


def screenshot(rrd, png, *, size: str = "1600x900", force: bool = False,
               timeout_s: float = 300.0) -> Path:
    """Render the layout of ``rrd`` (at its end) into ``png`` without a window (see
    :func:`screenshot_command`)."""
    png = Path(png)
    check_writable(png, force=force)
    tmp = png.with_name(png.name + ".part.png")
    cmd, env = screenshot_command(Path(rrd), tmp, size)
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise LiveViewError(f"the viewer did not render within {timeout_s:g} s") from None
    if p.returncode != 0 or not tmp.exists():
        tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
        tmp.unlink(missing_ok=True)
        raise LiveViewError(f"the viewer could not render a screenshot (exit {p.returncode}): "
                            + " | ".join(tail))
    os.replace(tmp, png)
    return png


def recording_summary(rrd) -> dict:
    """Entities of an ``.rrd`` file and their rows (for checks and tests)."""
    from rerun.chunk import RrdReader

    rows: dict = {}
    for ch in RrdReader(str(rrd)).stream().to_chunks():
        rows[str(ch.entity_path)] = rows.get(str(ch.entity_path), 0) + ch.num_rows
    return rows


__all__ = ["ViewerOptions", "ViewerStream", "LiveView", "LiveViewWarning", "LiveViewError",
           "acquisition_blueprint", "replay", "show_trajectory", "screenshot",
           "screenshot_command", "recording_summary", "viewer_executable"]
