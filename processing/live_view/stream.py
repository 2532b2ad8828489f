"""The rerun recording going to its sinks (a spawned viewer, a running viewer, an ``.rrd``
file), the sends in order on a worker thread, and the columnar sends themselves."""

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
import pyarrow as pa
import rerun as rr
from rerun.components import LineStrip2DBatch

from rig.output_files import check_writable, remove_stale_temps, temp_beside
from processing.viewer_url import DEFAULT_PORT, viewer_silence
from processing.viewer_url import host_port as _host_port


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
MEMORY_LIMIT = "2GiB"


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
            self._part = None  # made when the file sink opens (rig.output_files.temp_beside)
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
            why = viewer_silence(self.options.connect)
            if why is None:
                url = self.options.connect
            else:
                self._warn(f"no rerun viewer at {self.options.connect} ({why})")
        if self.rrd is not None:
            remove_stale_temps(self.rrd)
            self._part = temp_beside(self.rrd, ".part.rrd")
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
            if self._part is not None and self._part.exists():
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
