"""A run file replayed into the live view as the run showed it, and free motion
(:func:`rig.simulate.simulate`) shown on a fixed base."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from daq.records import Block, Footer, Record
from processing.bench_geometry import MAGNIFICATION, BenchDrawing
from processing.live_view.blueprint import trailing_range
from processing.live_view.drawing import MARKS, PENDULUM, chain_frames, log_chain_style
from processing.live_view.sink import LiveView
from processing.live_view.stream import TIMELINE, ViewerStream


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
        status = run.status
        if status == "acquiring":  # no footer yet: a writer at work, or one that was killed
            from daq.hdf5 import writer_alive

            status = ("acquiring (still being written)" if writer_alive(path) else
                      "acquiring (its writer stopped without closing it; a repair marks it "
                      "interrupted)")
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
                                            time_ranges=trailing_range(20.0)),
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
        log_chain_style(s, n, body=max(1.0, 0.008 * r), pivot=max(1.0, 0.01 * r),
                        com=max(1.0, 0.008 * r), mirror=max(1.0, 0.01 * r))
        s.static("/signals/theta", rr.SeriesLines(names=[f"theta_{j + 1}" for j in range(n)]))
        s.queue("/signals/theta", "scalars", t, theta)
        if traj.energy_j is not None:
            s.queue("/signals/energy", "scalars", t, np.asarray(traj.energy_j, float))
        lines, strips, marks, _ = chain_frames(d, theta)
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
