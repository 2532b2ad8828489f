"""A stepped-sine run file (:mod:`daq.sine_file`) replayed into the live view: the measured
H_t and Theta_2 points landing one by one over the exact model, each point's difference from
the exact steady state beside its stated settling bias, and, when the file keeps its records
(``daq sine --keep-records``), the bench and the signals of every point.

Timeline: a point lands at its end in the sweep's simulated time (``t0_s + settle_s +
integrate_s`` [s], the time of the sweep's discarded points included). Entities:

- ``/analyzer/H_t``, ``/analyzer/Theta_2``: gain [dB] and phase [deg] panels on a drawn
  log-frequency axis (:mod:`processing.bode_canvas`); ``model`` is the exact whole-chain model
  (:meth:`rig.bench.SampledResponse.resolved`, on the resolving grid of
  :func:`rig.response_grid.resolving_grid`, so the sharp modes and the notches are drawn to
  0.1 dB); ``points/gain`` and ``points/phase`` hold every point so far (one row per landing)
  with the file's values beside each instance (``frequency_hz``, ``gain_db``, ``phase_deg``,
  ``settling_bias_db``, ``random_error_db``; rerun's selection panel shows them); ``latest``
  marks the newest point;
- ``/analyzer/difference``: measured - exact [dB] of both responses, and the stated settling
  bias [dB];
- ``/status``: the point, its measured, exact, settling bias and random error (1 sigma) in dB
  and degrees, the model that ran, and whether records were kept;
- with records: ``/signals`` (a, x, y in engineering units, the last :data:`SIGNAL_TAIL_S`
  seconds of each point's window) and the bench (:mod:`processing.live_view.drawing`): the
  stage and the bodies in the steady state of the exact linear model at the point's frequency,
  driven by the recorded a; the PSD spot from the recorded x and y. Without records the bench
  is drawn at rest.

A file still being written is read as it stands (its finished points), as ``daq view`` reads a
run file; its status says so. Public API: :func:`replay_sine`, :class:`SineReplay`,
:func:`sine_blueprint`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from processing import bode_canvas as bc
from processing.bench_geometry import MAGNIFICATION, MM, BenchDrawing, frame_indices, frame_step
from processing.live_view.blueprint import trailing_range
from processing.live_view.drawing import (ANALYZER_WIDTH, BODE_BOUNDS, CHANNEL_COLORS, MARKS,
                                          MEASURED, MODEL, PENDULUM, SIGNALS, analyzer_panels,
                                          bench_bounds, bench_layout, bode_strips,
                                          chain_frames, gain_db, log_bench_static,
                                          log_chain_style, log_panel_static, display_unit,
                                          legend_row)
from processing.live_view.stream import TIMELINE, ViewerStream
from processing.phase_display import phase_branch, wrap_to

__all__ = ["SineReplay", "replay_sine", "sine_blueprint"]

#: the signals of a point: its last seconds (at most the whole point) [s]; the signal plots
#: show as much, following the newest point
SIGNAL_TAIL_S = 10.0
LATEST = (255, 255, 255)
BIAS = (230, 230, 230)
RESPONSES = (("H_t", "h_t", "x"), ("Theta_2", "theta_2", "y"))
DIFF_BOUNDS = ((-bc.LABEL_MARGIN - 2.0, ANALYZER_WIDTH + 12.0), (-16.0, 44.0))


@dataclass(frozen=True)
class SineReplay:
    """What was replayed: ``points`` finished points of the file's ``status``, ``records_kept``,
    the ``.rrd`` written (or None), the sweep's ``mode`` ("stepped" or "swept")."""

    points: int
    status: str
    records_kept: bool
    path: Path | None
    mode: str = "stepped"


def _tail_samples(rate_hz: float) -> int:
    return max(2, int(round(SIGNAL_TAIL_S * rate_hz)))


def sine_blueprint(*, records: bool, units: dict, bench_bounds=None,
                   bias: str = "settling bias") -> rrb.Blueprint:
    """The layout of a sine replay: bench and status on the left, the signals in the middle
    (only with records; ``units`` channel -> engineering unit), the Bode panels and the
    difference from the exact response on the right; the time panel follows the newest data."""
    def bounds(b):
        return rrb.VisualBounds2D(x_range=b[0], y_range=b[1])

    names = {k: f"{k} = {c}/a: gain [dB re 1 {u}], phase [deg]"
             for (k, _, c), u in zip(RESPONSES, ("m/(m/s^2)", "rad/(m/s^2)"))}
    right = rrb.Vertical(
        rrb.Spatial2DView(origin="/analyzer/H_t", name=names["H_t"],
                          visual_bounds=bounds(BODE_BOUNDS)),
        rrb.Spatial2DView(origin="/analyzer/Theta_2", name=names["Theta_2"],
                          visual_bounds=bounds(BODE_BOUNDS)),
        rrb.Spatial2DView(origin="/analyzer/difference",
                          name=f"measured - exact steady state, and the stated {bias} [dB]",
                          visual_bounds=bounds(DIFF_BOUNDS)),
        row_shares=[3, 3, 1.4])
    left = rrb.Vertical(rrb.Spatial2DView(origin="/bench", name="bench (side view, mm)",
                                              visual_bounds=bench_bounds),
                        rrb.TextDocumentView(origin="/status", name="status"),
                        row_shares=[2, 3])
    cols, shares = [left], [1.1]
    if records:
        views = []
        for i, c in enumerate(("a", "x", "y")):
            shown = rr.SeriesLines.from_fields(visible_series=[j == i for j in range(3)])
            views.append(rrb.TimeSeriesView(
                origin=SIGNALS, name=f"{c} [{display_unit(units.get(c, ''))[1]}]",
                overrides={SIGNALS: shown}, plot_legend=rrb.PlotLegend(visible=False),
                time_ranges=trailing_range(SIGNAL_TAIL_S)))
        cols.append(rrb.Vertical(*views, name="signals (engineering units)"))
        shares.append(0.8)
    cols.append(right)
    shares.append(1.5 if records else 2.0)
    return rrb.Blueprint(rrb.Horizontal(*cols, column_shares=shares),
                         rrb.TimePanel(timeline=TIMELINE, play_state="following",
                                       state="collapsed"),
                         collapse_panels=True)


def _log_at(stream: ViewerStream, t_s: float, entity: str, *archetypes) -> None:
    """Log ``archetypes`` to ``entity`` at ``t_s`` [s] on the stream's worker thread."""
    def send():
        for rec in stream.recs:
            rec.set_time(TIMELINE, duration=float(t_s))
            rec.log(entity, *archetypes)
            rec.reset_time()

    stream.later(send)


def _phasor(y: np.ndarray, t: np.ndarray, f_hz: float) -> complex:
    """The complex amplitude P of ``y`` ~ c + Re(P e^{i 2 pi f t}) (least squares)."""
    w = 2 * math.pi * f_hz * t
    m = np.stack([np.ones_like(t), np.cos(w), np.sin(w)], axis=1)
    c = np.linalg.lstsq(m, y, rcond=None)[0]
    return complex(c[1], -c[2])


class _Replay:
    """The state of one replay (the module docstring)."""

    def __init__(self, path, stream: ViewerStream, magnification: float):
        from daq.sine_file import read_sine, read_sine_records, sine_info
        from rig.scene import scene_from_settings

        self.path, self.stream = Path(path), stream
        d = read_sine(path)
        d["seed"] = sine_info(path).get("seed", "-")
        self.d, self.c = d, d["columns"]
        self.scene = scene_from_settings(d["scene_settings"], origin=str(path))
        self.rate = float(self.scene.acquisition.rate_hz)
        self.n = d["points"]
        self.f = self.c["frequency"]
        self.records = read_sine_records(path, tail=lambda k: _tail_samples(self.rate))
        self.drawing = BenchDrawing.from_scene(self.scene, magnification)
        self.has_spot = self.drawing.psd_gain_vpm is not None
        self.t_end = self.c["t0_s"] + self.c["settle_s"] + self.c["integrate_s"]
        self.bias_name = "sweep bias" if self.d["mode"] == "swept" else "settling bias"
        self.h = {name: self.c[f"{name}_real"] + 1j * self.c[f"{name}_imag"]
                  for _, name, _ in RESPONSES}
        self.exact = {name: self.c[f"{name}_exact_real"] + 1j * self.c[f"{name}_exact_imag"]
                      for _, name, _ in RESPONSES}
        self.biased = {name: self.exact[name] + self.c[f"{name}_bias_real"]
                       + 1j * self.c[f"{name}_bias_imag"] for _, name, _ in RESPONSES}

    # -- static: bench, model, panels -------------------------------------------------------
    def start(self) -> None:
        from rig.bench import sampled_response

        st = self.d["settings"]
        fmin, fmax = float(st["fmin_hz"]), float(st["fmax_hz"])
        self.bench = sampled_response(self.scene)
        resolved = self.bench.resolved(fmin, fmax)
        self.model_f = resolved.freqs_hz
        self.model = {"H_t": resolved.h_t, "Theta_2": resolved.theta_2}
        measured_db = {k: gain_db(self.h[name]) for k, name, _ in RESPONSES}
        self.panels = analyzer_panels(self.model_f, {k: gain_db(v) for k, v in self.model.items()},
                                       measured_db,
                                       {k: phase_branch((self.model_f, v))
                                        for k, v in self.model.items()})
        for key, db in measured_db.items():  # every measured point inside its gain panel
            gain, phase = self.panels[key]
            finite = db[np.isfinite(db)]
            lo = min(gain.lo, 20.0 * math.floor((finite.min() - 5.0) / 20.0)) if finite.size \
                else gain.lo
            lo = max(lo, gain.hi - 200.0)
            step = 20.0 if gain.hi - lo <= 120.0 else 40.0
            lo = gain.hi - step * math.ceil((gain.hi - lo) / step)
            self.panels[key] = (replace(gain, lo=lo, ticks=bc.ticks(lo, gain.hi, step)), phase)
        upd = self.panels["H_t"][0].units_per_decade
        self.diff_db = {name: gain_db(self.h[name] / self.exact[name]) for _, name, _ in RESPONSES}
        self.bias_db = {name: gain_db(self.biased[name] / self.exact[name])
                        for _, name, _ in RESPONSES}
        sigma = {name: 20 / math.log(10) * self.c[f"{name}_rel_error"]
                 for _, name, _ in RESPONSES}
        spread = [np.abs(v) for v in self.diff_db.values()]
        spread += [np.abs(self.bias_db[k]) + 2 * sigma[k] for k in sigma]
        top = max([0.1] + [float(np.nanmax(v)) for v in spread if np.size(v)])
        step = 10 ** math.floor(math.log10(top * 1.15 / 2))
        lim = step * math.ceil(top * 1.15 / step)
        self.diff = bc.Panel(fmin, fmax, -lim, lim, (-lim, 0.0, lim), "dB", 0.0, 30.0, "", upd)
        units = self.records["units"] if self.records else {}
        s = self.stream
        s.open(sine_blueprint(records=self.records is not None, units=units, bias=self.bias_name,
                             bench_bounds=bench_bounds(self.drawing, True)))
        self._log_bench()
        self._log_analyzer()

    def _log_bench(self) -> None:
        s, d = self.stream, self.drawing
        log_bench_static(s, d, moving_stage=True, optics=self.has_spot)
        log_chain_style(s, len(d.lengths_mm))
        lines, strips, marks, centre = chain_frames(d, np.zeros((1, len(d.lengths_mm))))
        s.queue(PENDULUM, "strips", np.zeros(1), lines, strips)
        s.queue(MARKS, "points", np.zeros(1), marks)
        if self.records is not None:
            colors = [CHANNEL_COLORS[c] for c in ("a", "x", "y")]
            u = self.records["units"]
            s.static(SIGNALS, rr.SeriesLines(
                names=[f"{c} [{display_unit(u.get(c, ''))[1]}]" for c in ("a", "x", "y")],
                colors=colors, widths=[1.0] * 3))
        s.send_queued()

    def _log_analyzer(self) -> None:
        s = self.stream
        for key, _, _ in RESPONSES:
            gain, phase = self.panels[key]
            base = f"/analyzer/{key}"
            log_panel_static(s, base, (gain, phase))
            s.static(f"{base}/model", rr.LineStrips2D(
                bode_strips(gain, phase, self.model_f, self.model[key]), colors=MODEL,
                radii=0.35, draw_order=10.0))
            pos, colors, texts = legend_row([("exact model", MODEL),
                                             (f"{self.d['mode']} sine", MEASURED),
                                             ("latest point", LATEST)])
            s.static(f"{base}/legend", rr.Points2D(pos, radii=1.6, colors=colors, labels=texts,
                                                   show_labels=True))
        log_panel_static(s, "/analyzer/difference", (self.diff,))
        pos, colors, texts = legend_row([("H_t", CHANNEL_COLORS["x"]),
                                         ("Theta_2", CHANNEL_COLORS["y"]),
                                         (f"stated {self.bias_name}", BIAS)])
        s.static("/analyzer/difference/legend", rr.Points2D(pos, radii=1.6, colors=colors,
                                                            labels=texts, show_labels=True))
        # zero line of the difference panel
        y0 = float(self.diff.y(0.0))
        s.static("/analyzer/difference/zero", rr.LineStrips2D(
            [np.array([[0.0, y0], [self.diff.width, y0]])], colors=(120, 120, 120),
            radii=0.2))

    # -- per point ------------------------------------------------------------------------
    def point(self, k: int) -> None:
        t = float(self.t_end[k])
        if self.records is not None:
            self._signals(k)
        for key, name, c in RESPONSES:
            gain, phase = self.panels[key]
            f, h = self.f[: k + 1], self.h[name][: k + 1]
            g_db = gain_db(h)
            p_deg = np.degrees(np.angle(h))
            shown = wrap_to(p_deg, phase.lo)
            extra = {"frequency_hz": f, "settling_bias_db": self.bias_db[name][: k + 1],
                     "random_error_db": 20 / math.log(10) * self.c[f"{name}_rel_error"][: k + 1]}
            base = f"/analyzer/{key}"
            _log_at(self.stream, t, f"{base}/points/gain",
                    rr.Points2D(np.stack([gain.x(f), gain.y(g_db)], -1), colors=MEASURED,
                                radii=1.1, draw_order=20.0),
                    rr.AnyValues(gain_db=g_db, phase_deg=p_deg, **extra))
            _log_at(self.stream, t, f"{base}/points/phase",
                    rr.Points2D(np.stack([phase.x(f), phase.y(shown)], -1), colors=MEASURED,
                                radii=1.1, draw_order=20.0),
                    rr.AnyValues(gain_db=g_db, phase_deg=p_deg, **extra))
            last = [(gain.x(f[-1]), gain.y(g_db[-1])), (phase.x(f[-1]), phase.y(shown[-1]))]
            _log_at(self.stream, t, f"{base}/latest",
                    rr.Points2D(last, colors=LATEST, radii=1.5, draw_order=30.0))
            fk = self.f[: k + 1]
            x = self.diff.x(fk)
            _log_at(self.stream, t, f"/analyzer/difference/{name}",
                    rr.Points2D(np.stack([x, self.diff.y(self.diff_db[name][: k + 1])], -1),
                                colors=CHANNEL_COLORS[c], radii=1.2, draw_order=20.0))
            _log_at(self.stream, t, f"/analyzer/difference/bias_{name}",
                    rr.Points2D(np.stack([x, self.diff.y(self.bias_db[name][: k + 1])], -1),
                                colors=BIAS, radii=0.5, draw_order=30.0))
        self.stream.text_at(t, "/status", self._status(k, "replaying"))

    def _signals(self, k: int) -> None:
        rec, s, d = self.records, self.stream, self.drawing
        f = float(self.f[k])
        m = rec["samples"][k]
        volts = {c: rec["volts"][c][k] for c in ("a", "x", "y")}
        nw = volts["a"].size
        g0 = int(m - nw)
        # the record ends with the point's window (stepped: settle + window; swept: the window)
        t = self.t_end[k] - (m - g0 - np.arange(nw)) / self.rate
        eng = {c: volts[c] / rec["volts_per_unit"][c] for c in volts}
        values = np.stack([eng[c] * display_unit(rec["units"].get(c, ""))[0]
                           for c in ("a", "x", "y")], axis=1)
        # a gap after the point's samples: the next point's line does not join them
        s.queue(SIGNALS, "scalars", np.append(t, t[-1] + 0.5 / self.rate),
                np.vstack([values, np.full((1, 3), np.nan)]))
        # the bench: the exact linear model's steady state at f, driven by the recorded a
        idx = frame_indices(g0, nw, frame_step(self.rate))
        if idx.size:
            tf = t[idx]
            fields = self.bench(np.array([f]))
            a_eng = fields.a[0] / self.bench.volts_per_unit["a"]
            p = _phasor(eng["a"], t - t[0], f)
            rot = np.exp(2j * math.pi * f * (tf - t[0]))
            theta = np.real(np.outer(rot * p / a_eng, fields.theta[0]))
            stage = np.real(rot * p * fields.stage_accel[0] / a_eng) / -(2 * math.pi * f) ** 2
            tr = np.zeros((idx.size, 3))
            tr[:, 0] = d.stage_magnification * MM * stage
            s.queue("/bench/stage", "translation", tf, tr)
            lines, strips, marks, centre = chain_frames(d, theta)
            s.queue(MARKS, "points", tf, marks)
            if self.has_spot:
                spot = d.spot_mm(volts["x"][idx], volts["y"][idx])
                lay = bench_layout(d)
                laser, psd = np.array(lay["laser"]), np.array(lay["psd"])
                hit = psd + np.stack([np.zeros(idx.size), spot[:, 1] * d.magnification], -1)
                beam = np.stack([np.broadcast_to(laser, centre.shape), centre, hit], axis=1)
                lines, strips = np.concatenate([lines, beam], axis=1), (*strips, 3)
            s.queue(PENDULUM, "strips", tf, lines, strips)
        s.send_queued()

    def _status(self, k: int, state: str) -> str:
        c, sc = self.c, self.scene
        info = self.d["model_info"]
        n_all = self.n
        lines = [f"**Point {k + 1} of {n_all} ({state})**: {self.f[k]:.6g} Hz, "
                 f"level {c['level_vrms'][k]:.3g} V rms  ",
                 f"settle {c['settle_s'][k]:.4g} s, window {c['integrate_s'][k]:.4g} s "
                 f"({int(c['cycles'][k])} cycles); bench time so far "
                 f"{self.t_end[k] / 3600:.3g} h  ",
                 "",
                 "| dB, deg | H_t | Theta_2 |", "|---|---|---|"]
        cells = {"measured": [], "- exact": [], self.bias_name: [],
                 "random error (1 sigma)": []}
        for key, name, _ in RESPONSES:
            h, ex, bi = self.h[name][k], self.exact[name][k], self.biased[name][k]
            e = float(c[f"{name}_rel_error"][k])
            dd, bb = h / ex, bi / ex
            cells["measured"].append(f"{gain_db(h):.3f}, {math.degrees(np.angle(h)):.2f}")
            cells["- exact"].append(f"{gain_db(dd):+.4f}, {math.degrees(np.angle(dd)):+.3f}")
            cells[self.bias_name].append(f"{gain_db(bb):+.4f}, {math.degrees(np.angle(bb)):+.3f}")
            cells["random error (1 sigma)"].append(f"{20 / math.log(10) * e:.4f}, "
                                                   f"{math.degrees(e):.3f}")
        lines += [f"| {row} | {' | '.join(v)} |" for row, v in cells.items()]
        lines += ["",
                  f"**scene** {sc.name}, **seed** {self.d.get('seed', '-')}; **model** "
                  f"{info.get('model', '-')}  "]
        if self.records is None:
            lines.append("*records not kept (daq sine --keep-records stores them): no signals, "
                         "the bench at rest*")
        else:
            lines.append(f"*signals: the last seconds of each point's window; bench: the exact "
                         f"model's steady state driven by the recorded a, angles "
                         f"x{self.drawing.magnification:g}, stage travel "
                         f"x{self.drawing.stage_magnification:g}*")
        return "\n".join(lines)

    def stop(self) -> str:
        status = self.d["status"]
        if status == "acquiring":
            status = ("acquiring: its finished points (a sweep still running, or one stopped "
                      "without closing the file)")
        if self.n:
            self.stream.text_at(float(self.t_end[-1]), "/status",
                                self._status(self.n - 1, status))
        else:
            self.stream.text_at(0.0, "/status", f"**no finished point yet ({status})**")
        return status


def replay_sine(path, stream: ViewerStream, *, magnification: float = MAGNIFICATION
                ) -> SineReplay:
    """Replay the sine run file ``path`` (its finished points) into ``stream`` (not yet
    opened; closed at the end): the module docstring."""
    r = _Replay(path, stream, magnification)
    r.start()
    status = r.d["status"]
    try:
        for k in range(r.n):
            r.point(k)
    finally:
        try:
            status = r.stop()
        finally:
            out = stream.close()
    return SineReplay(points=r.n, status=status, records_kept=r.records is not None, path=out,
                      mode=r.d["mode"])
