"""The acquisition stream into rerun (:class:`LiveView`, a non-critical
:class:`daq.sinks.Sink`): the static parts and the model curves at the start, the signals and
the bench's geometry block by block, the running average and the status after every record."""

from __future__ import annotations

import numpy as np
import rerun as rr

from daq.records import Block, Footer, Record
from daq.sinks import Sink
from processing.bench_geometry import (MAGNIFICATION, MM, BenchDrawing, StagePosition,
                                       frame_indices, frame_step)
from processing.errors import ProcessingError, SettingsError
from processing.line_steps import line_steps
from processing.live_view.blueprint import acquisition_blueprint
from processing.live_view.drawing import (CHANNEL_COLORS, EXPECTED, MARKS, MEASURED, MODEL,
                                          PENDULUM, SIGNALS, VOLTS, analyzer_panels, bench_layout,
                                          bode_strips, chain_frames, display_unit, gain_db,
                                          legend_row, log_bench_static, log_chain_style,
                                          log_panel_static)
from processing.live_view.stream import ViewerStream
from processing.running_average import RunningAverage


class LiveView(Sink):
    """The acquisition stream into rerun (the package docstring). A non-critical sink: if it fails,
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
        if pacer is not None:  # paced: the run in the pacer's short blocks (Sink.block_s)
            self.block_s = pacer.block_s
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
            names=[f"{ch.name}: {ch.quantity} [{display_unit(ch.unit)[1]}]" for ch in chans],
            colors=colors,
            widths=[1.0] * len(chans)))
        s.static(VOLTS, rr.SeriesLines(
            names=[f"{ch.name} [V] (ADC +-{ch.range_v:g} V)" for ch in chans], colors=colors,
            widths=[1.0] * len(chans)))
        log_bench_static(s, self.drawing, moving_stage=True, optics=self.has_spot)
        log_chain_style(s, len(self.drawing.lengths_mm))
        if self.has_spot:
            h = self.drawing.psd_half_mm
            s.static("/psd/detector", rr.Boxes2D(half_sizes=[(h, h)], centers=[(0, 0)],
                                                 colors=(120, 200, 120), radii=0.05,
                                                 labels=[f"PSD {2 * h:g} x {2 * h:g} mm"],
                                                 show_labels=True))
            s.static("/psd/axes", rr.LineStrips2D(
                [np.array([[-h, 0], [h, 0]]), np.array([[0, -h], [0, h]])],
                colors=(60, 90, 60), radii=0.02))
            s.static("/psd/spot", rr.Points2D.from_fields(colors=(255, 60, 60), radii=0.12))
        if self.panels is not None:
            self._log_analyzer_static()
        self._status(records=0, state="acquiring")

    def _prepare_analyzer(self) -> None:
        from processing.leakage import expected_estimate
        from processing.phase_display import phase_branch
        from rig.bench.sampled import sampled_response

        avg = self.average
        f = avg.freqs_hz
        lines = f[f > 0]
        bench = sampled_response(self.header.scene)  # one evaluator for the model and E[H1]
        # the model on a grid that shows its modes and notches (not only at the lines)
        curves = bench.resolved(float(lines[0]), float(f[-1]))
        self.model_f = curves.freqs_hz
        self.model = {"H_t": curves.h_t, "Theta_2": curves.theta_2}
        self.expected = {}
        try:
            e = expected_estimate(self.header, avg.spectral, fmin_hz=avg.settings.fmin_hz,
                                  fmax_hz=avg.settings.fmax_hz, bench=bench)
            idx = np.searchsorted(e.freqs_hz, f)
            self.expected = {"H_t": e.h_t[idx], "Theta_2": e.theta_2[idx]}
        except ProcessingError:  # no E[H1] for this source (e.g. a sine): the model alone
            pass
        self.panels = analyzer_panels(f, {k: gain_db(v) for k, v in self.model.items()},
                                      {k: gain_db(v) for k, v in self.expected.items()},
                                      {k: phase_branch((self.model_f, v))
                                       for k, v in self.model.items()})

    def _log_analyzer_static(self) -> None:
        s, f = self.stream, self.average.freqs_hz
        for key in ("H_t", "Theta_2"):
            gain, phase = self.panels[key]
            base = f"/analyzer/{key}"
            log_panel_static(s, base, (gain, phase))
            # three curves that agree where the run does: drawn as nested bands, the measured
            # widest (bottom), E[H1] inside it, the model a thin line on top
            s.static(f"{base}/model", rr.LineStrips2D(bode_strips(gain, phase, self.model_f,
                                                                  self.model[key]),
                                                      colors=MODEL, radii=0.35,
                                                      draw_order=30.0))
            legend = [("model (exact)", MODEL), ("measured (average)", MEASURED)]
            if key in self.expected:
                s.static(f"{base}/expected", rr.LineStrips2D(  # per line, over its bin
                    bode_strips(gain, phase, *line_steps(f, self.expected[key])),
                    colors=EXPECTED,
                    radii=0.8, draw_order=20.0))
                legend.insert(1, ("E[H1] (expected)", EXPECTED))
            pos, colors, texts = legend_row(legend)
            s.static(f"{base}/legend", rr.Points2D(pos, radii=1.6, colors=colors, labels=texts,
                                                   show_labels=True))
        for key in ("H_t", "Theta_2"):
            s.static(f"/analyzer/{key}/measured", rr.LineStrips2D.from_fields(
                colors=MEASURED, radii=1.4, draw_order=10.0))
        for c in ("x", "y"):
            s.static(f"/analyzer/coherence/{c}", rr.LineStrips2D.from_fields(
                colors=CHANNEL_COLORS[c], radii=0.6))
        (coh,) = self.panels["coherence"]
        log_panel_static(s, "/analyzer/coherence", (coh,))
        pos, colors, texts = legend_row([("x (H_t)", CHANNEL_COLORS["x"]),
                                         ("y (Theta_2)", CHANNEL_COLORS["y"])])
        s.static("/analyzer/coherence/legend", rr.Points2D(pos, radii=1.6, colors=colors,
                                                           labels=texts, show_labels=True))

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
            values.append((volts[c] / ch.volts_per_unit) * display_unit(ch.unit)[0])
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
            lines, strips, marks, centre = chain_frames(d, theta.reshape(idx.size, -1))
            s.queue(MARKS, "points", tf, marks)
        if self.has_spot and idx.size:
            spot = d.spot_mm(volts["x"][idx], volts["y"][idx])
            s.queue("/psd/spot", "points", tf, spot[:, None, :])
            if lines is not None:
                lay = bench_layout(d)
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
                s.strips_at(t_end, f"/analyzer/{key}/measured", bode_strips(gain, phase, f, h))
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
        budget = info.error_budget
        lines = [
            f"**Record {records} of {h.plan.records} ({state}"
            + (f": {message}" if message else "") + ")**  ",
            f"**scene** {h.scene.name}, **seed** {h.seed}; {h.plan.rate_hz:g} Hz, records of "
            f"{h.plan.record_s:g} s after {h.plan.settle_s:g} s of settling  ",
            "**clipped / saturated samples** " + ", ".join(
                f"{c} {int(clip[i])} / {int(sat[i])}" for i, c in enumerate(self.names)) + "  ",
            f"**model** {info.model or '-'}, estimated error "
            f"{_error_text('-' if info.error_estimate is None else info.error_estimate)}"
            + (f", budget {_plain(budget)}" if budget is not None else "") + "  ",
            f"**why** {_why(info.reason or '-')}  ",
            f"*bench: sizes to scale, angles x{self.drawing.magnification:g}, stage travel "
            f"x{self.drawing.stage_magnification:g}; PSD to scale*",
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


def _why(reason: str) -> str:
    """A model choice's reason in short: its kind and its conclusion ("auto: the exact linear
    model ... is the cheapest that meets it"); the whole reason is in ``daq inspect``."""
    parts = str(reason).split(": ")
    return f"{parts[0]}: {parts[-1]}" if len(parts) > 2 else str(reason)


def _plain(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_plain(x)}" for k, x in v.items())
    return str(v)
