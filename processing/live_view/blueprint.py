"""The layout of the live view (rerun blueprints): bench, PSD and status on the left, the
signals in the middle, the analyzer on the right; the time panel follows the newest data."""

from __future__ import annotations

import rerun as rr
import rerun.blueprint as rrb

from processing.live_view.drawing import (BODE_BOUNDS, COHERENCE_BOUNDS, SIGNALS, VOLTS,
                                           bench_bounds, display_unit, signal_ranges)
from processing.live_view.stream import TIMELINE

SIGNAL_WINDOW_S = 20.0
TRAIL_S = 2.0


def trailing_range(seconds: float) -> rrb.VisibleTimeRange:
    """A view's visible time range: the last ``seconds`` up to the time cursor."""
    return rrb.VisibleTimeRange(TIMELINE,
                                start=rrb.TimeRangeBoundary.cursor_relative(seconds=-seconds),
                                end=rrb.TimeRangeBoundary.cursor_relative())


def _series(entity: str, names, header, ranges) -> list:
    """One view per channel of ``entity`` (one series per channel): that channel's series shown,
    the others hidden; the view's title names it (no legend: it would list the hidden ones); its
    value axis from -h to h, h from ``ranges`` (:func:`~processing.live_view.drawing.
    signal_ranges`; a channel without one fits its data)."""
    views = []
    for i, c in enumerate(names):
        ch = header.channel(c)
        title = (f"{c} [V] (ADC +-{ch.range_v:g} V)" if entity == VOLTS
                 else f"{c} [{display_unit(ch.unit)[1]}]: {ch.quantity}")
        shown = rr.SeriesLines.from_fields(visible_series=[j == i for j in range(len(names))])
        axis = None
        if c in ranges:
            h = ranges[c][1 if entity == VOLTS else 0]
            axis = rrb.ScalarAxis(range=(-h, h), zoom_lock=False)
        views.append(rrb.TimeSeriesView(origin=entity, name=title, overrides={entity: shown},
                                        plot_legend=rrb.PlotLegend(visible=False),
                                        axis_y=axis, time_ranges=trailing_range(SIGNAL_WINDOW_S)))
    return views


def acquisition_blueprint(view) -> rrb.Blueprint:
    """The layout of a run (the package docstring) for a started ``view``
    (:class:`~processing.live_view.sink.LiveView`): bench, PSD and status on the left, the
    signals in the middle, the analyzer on the right; the time panel follows the newest data."""
    h = view.header
    left = [rrb.Spatial2DView(origin="/bench", name="bench (side view, mm)",
                              visual_bounds=bench_bounds(view.drawing, True))]
    if view.has_spot:
        hh = view.drawing.psd_half_mm * 1.25
        left.append(rrb.Spatial2DView(origin="/psd", name=f"PSD spot (last {TRAIL_S:g} s)",
                                      visual_bounds=rrb.VisualBounds2D(
                                          x_range=(-hh, hh), y_range=(-hh, 1.7 * hh)),
                                      time_ranges=trailing_range(TRAIL_S)))
    left.append(rrb.TextDocumentView(origin="/status", name="status"))
    ranges = signal_ranges(h)
    middle = rrb.Tabs(rrb.Vertical(*_series(SIGNALS, view.names, h, ranges),
                                   name="signals (engineering units)"),
                      rrb.Vertical(*_series(VOLTS, view.names, h, ranges), name="ADC volts"),
                      active_tab=0)
    cols = [rrb.Vertical(*left, row_shares=[3, 2, 3][:len(left)]), middle]
    shares = [1.0, 1.2]
    if view.panels is not None:
        def bounds(b):
            return rrb.VisualBounds2D(x_range=b[0], y_range=b[1])

        key_units = {"H_t": "m/(m/s^2)", "Theta_2": "rad/(m/s^2)"}
        names = {k: f"{k} = {'x' if k == 'H_t' else 'y'}/a: gain [dB re 1 {u}], phase [deg]"
                 for k, u in key_units.items()}
        cols.append(rrb.Vertical(
            rrb.Spatial2DView(origin="/analyzer/H_t", name=names["H_t"],
                              visual_bounds=bounds(BODE_BOUNDS)),
            rrb.Spatial2DView(origin="/analyzer/Theta_2", name=names["Theta_2"],
                              visual_bounds=bounds(BODE_BOUNDS)),
            rrb.Spatial2DView(origin="/analyzer/coherence",
                              name="coherence gamma^2 of x (H_t) and y (Theta_2)",
                              visual_bounds=bounds(COHERENCE_BOUNDS)),
            row_shares=[3, 3, 1.4]))
        shares.append(1.5)
    return rrb.Blueprint(rrb.Horizontal(*cols, column_shares=shares),
                         rrb.TimePanel(timeline=TIMELINE, play_state="following",
                                       state="collapsed"),
                         collapse_panels=True)
