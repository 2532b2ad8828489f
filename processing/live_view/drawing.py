"""What the live view draws: the entities and their colours, the bench's static parts, the
moving parts (the pendulum as line strips, its pivots and centres of mass as points) and the
analyzer's panels on a drawn log-frequency axis (:mod:`processing.bode_canvas`)."""

from __future__ import annotations

import math

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from processing import bode_canvas as bc
from processing.bench_geometry import BenchDrawing
from processing.live_view.stream import ViewerStream
from processing.phase_display import wrap_to

#: The channels in engineering units and in ADC volts: one entity each, one series per channel
SIGNALS, VOLTS = "/signals", "/volts"
CHANNEL_COLORS = {"a": (230, 159, 0), "x": (86, 180, 233), "y": (0, 158, 115)}
MEASURED, MODEL, EXPECTED = (255, 200, 60), (90, 160, 255), (200, 120, 255)
#: Units shown with a prefix in the signal plots, whose axis labels show few decimals (a mirror
#: translation of 1e-4 m or a rotation of 1e-5 rad would be labelled "0" only): unit -> (factor,
#: shown unit). The .rrd holds the engineering values times the factor.
DISPLAY_UNITS = {"m": (1e6, "\u00b5m"), "rad": (1e6, "\u00b5rad")}


def display_unit(unit: str) -> tuple[float, str]:
    """(factor, unit) in which a channel of ``unit`` is plotted (:data:`DISPLAY_UNITS`)."""
    return DISPLAY_UNITS.get(unit, (1.0, unit))


#: A signal plot's half-height, in predicted standard deviations of its channel (signal and
#: noise): a stationary Gaussian signal exceeds 4 sigma in about 6e-5 of its samples.
SIGNAL_SIGMAS = 4.0
#: What a signal plot's half-height is rounded up to, times a power of ten. The plots label
#: their values every power of ten, hide labels closer than 20 px and fade them below 30 px: a
#: plot from -5 to 5 (x 10^k), 165 px high at 1280x720, is labelled "0" alone. From -3.4 to 3.4
#: it has seven labels 24 px apart, and the 0.4 left above and below the outer ones keeps them
#: clear of the plot's edges (and of the time axis's labels).
HALF_HEIGHT_MANTISSAS = (1.4, 2.4, 3.4, 14.0)


def half_height(value: float) -> float:
    """The smallest ``m x 10^k`` >= ``value`` > 0, m in :data:`HALF_HEIGHT_MANTISSAS`."""
    k = math.floor(math.log10(value))
    return next(m * 10.0**k for m in HALF_HEIGHT_MANTISSAS
                if value <= m * 10.0**k * (1 + 1e-12))


def signal_ranges(header) -> dict[str, tuple[float, float]]:
    """Per channel (a, x, y) the half-heights of its plots, in display units
    (:func:`display_unit`) and in ADC volts: :data:`SIGNAL_SIGMAS` times the channel's predicted
    standard deviation (the scene's stationary response to its source,
    :func:`rig.bench.response.stationary_levels`, with its sensor's noise,
    :meth:`daq.records.Header.noise_rms`), rounded up by :func:`half_height`. Empty where there is
    no prediction (a source without a model PSD): those plots fit their data."""
    from rig.bench.response import stationary_levels
    from rig.errors import RigError

    try:
        levels = stationary_levels(header.scene, points=20_001)
        noise = header.noise_rms()
    except (RigError, TypeError, ValueError, ArithmeticError):
        return {}
    out = {}
    for c in header.names:
        if f"{c}_v" not in levels or c not in noise:
            continue
        ch = header.channel(c)
        per = abs(ch.volts_per_unit)
        sigma = math.hypot(levels[f"{c}_v"] / per, noise[c])  # engineering units
        if not (math.isfinite(sigma) and sigma > 0):
            continue
        out[c] = (half_height(SIGNAL_SIGMAS * sigma * display_unit(ch.unit)[0]),
                  half_height(SIGNAL_SIGMAS * sigma * per))
    return out

_FRAME_COLOR = (150, 150, 150)
_BODY_COLORS = [(255, 170, 40), (255, 90, 40), (230, 60, 120), (160, 90, 230)]


def bench_layout(d: BenchDrawing) -> dict:
    """Static positions of the stage frame, rail, laser and PSD in the side view [mm]."""
    reach = d.reach_mm
    w = max(40.0, 0.6 * reach)
    floor = reach + 0.25 * reach + 10.0
    return {"reach": reach, "half_width": w, "floor": floor,
            "laser": (w * 0.95, d.reach_mm * 0.25), "psd": (w * 0.95, d.reach_mm * 0.75)}


def log_bench_static(s: ViewerStream, d: BenchDrawing, *, moving_stage: bool,
                     optics: bool) -> None:
    """Log the bench's fixed parts once under ``/bench``: frame and table, rail (twice as long
    with a ``moving_stage``), laser and PSD (with ``optics``), the scale note and a scale bar."""
    lay = bench_layout(d)
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


def bench_bounds(d: BenchDrawing, moving_stage: bool) -> rrb.VisualBounds2D:
    """The side view's visible area [mm] around :func:`bench_layout` (wider with a
    ``moving_stage``)."""
    lay = bench_layout(d)
    w, r = lay["half_width"] * (1.7 if moving_stage else 1.2), lay["reach"]
    return rrb.VisualBounds2D(x_range=(-w, w), y_range=(-0.45 * r - 15, lay["floor"] + 30))


# the moving parts go out as two entities, whatever the number of bodies (each entity costs a
# send and a time column per record): ``pendulum``, line strips [the bodies, the mirror's face,
# (the laser beam)]; ``marks``, points [the pivots, the centres of mass]. Their colours and
# radii are logged once, instance by instance (:func:`log_chain_style`).
PENDULUM, MARKS = "/bench/stage/pendulum", "/bench/stage/marks"
_PIVOT_COLOR, _COM_COLOR = (255, 255, 255), (255, 90, 40)
_MIRROR_COLOR, _BEAM_COLOR = (190, 230, 255), (255, 60, 60)


def chain_frames(d: BenchDrawing, theta: np.ndarray):
    """The pendulum at frames of the angles ``theta`` (frames, n) [rad], drawn [mm]: the line
    strips (frames, n + 3, 2) of the bodies (n + 1 joints) and the mirror's face (2 points),
    their lengths (n + 1, 2), the marks (frames, 2 n, 2): n pivots then n centres of mass, and
    the mirror's centres (frames, 2)."""
    joints = d.joints(theta)
    centre, face = d.mirror(theta, joints, half_mm=max(3.0, 0.12 * d.reach_mm))
    lines = np.concatenate([joints, face], axis=1)
    marks = np.concatenate([joints[:, :-1], d.centres_of_mass(theta, joints)], axis=1)
    return lines, (joints.shape[1], 2), marks, centre


def log_chain_style(s: ViewerStream, n: int, *, body: float = 1.2, pivot: float = 1.4,
                    com: float = 1.0, mirror: float = 1.5, beam: float = 0.4) -> None:
    """Colours and radii [mm] of the strips of :data:`PENDULUM` and the points of
    :data:`MARKS`, per instance (the order of :func:`chain_frames`)."""
    s.static(PENDULUM, rr.LineStrips2D.from_fields(
        colors=[_BODY_COLORS[0], _MIRROR_COLOR, _BEAM_COLOR], radii=[body, mirror, beam]))
    s.static(MARKS, rr.Points2D.from_fields(colors=[_PIVOT_COLOR] * n + [_COM_COLOR] * n,
                                            radii=[pivot] * n + [com] * n))


#: The analyzer's drawn panels: plot width [scene units] (the frequency axis, whatever its
#: decades) and the scene's bounds around it, for a view about 2.2 times as wide as high (the
#: right column at 16:9): value labels on the left, the legend in a row above, decades below.
ANALYZER_WIDTH = 262.0
BODE_BOUNDS = ((-bc.LABEL_MARGIN - 2.0, ANALYZER_WIDTH + 12.0), (-18.0, 122.0))
COHERENCE_BOUNDS = ((-bc.LABEL_MARGIN - 2.0, ANALYZER_WIDTH + 12.0), (-16.0, 44.0))
LEGEND_Y = -15.0


def analyzer_panels(freqs, model_db, expected_db, branches=None):
    """The panels of H_t / Theta_2 (gain, phase) and coherence on a common frequency range; each
    phase panel spans its response's branch (lo, lo + 360] (``branches[key]`` = lo [deg],
    :func:`processing.phase_display.phase_branch`; default -180), named by its tick labels."""
    fmin, fmax = float(freqs[0]), float(freqs[-1])
    upd = ANALYZER_WIDTH / np.log10(fmax / fmin)
    out = {}
    for key in ("H_t", "Theta_2"):
        lo, hi = bc.db_range(model_db[key], expected_db.get(key, []), step=20.0)
        lo = max(lo, hi - 120.0)  # an anti-resonance's notch need not set the scale
        gain = bc.Panel(fmin, fmax, lo, hi, bc.ticks(lo, hi, 20.0), "dB", 0.0, 62.0, "", upd)
        p_lo = (branches or {}).get(key, -180.0)
        phase = bc.Panel(fmin, fmax, p_lo, p_lo + 360.0, bc.ticks(p_lo, p_lo + 360.0, 180.0),
                         "deg", 72.0, 36.0, "", upd)
        out[key] = (gain, phase)
    out["coherence"] = (bc.Panel(fmin, fmax, 0.0, 1.0, bc.ticks(0, 1, 0.5), "", 0.0, 30.0,
                                 "", upd),)
    return out


def legend_row(entries) -> tuple[list, list, list]:
    """Positions, colours and texts of a legend row above a panel: ``entries`` [(text,
    colour)], spread evenly over :data:`ANALYZER_WIDTH` (each text hangs below its dot)."""
    n = len(entries)
    xs = [ANALYZER_WIDTH * (i + 0.5) / n for i in range(n)]
    return ([(x, LEGEND_Y) for x in xs], [c for _, c in entries], [t for t, _ in entries])


def gain_db(h) -> np.ndarray:
    """``20 log10 |h|`` [dB], -inf at a zero without a warning."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 20.0 * np.log10(np.abs(h))


def _deg(h) -> np.ndarray:
    return np.degrees(np.angle(h))


def log_panel_static(s: ViewerStream, entity: str, panels) -> None:
    """Log the grids, tick labels (decades under the last panel) and titles of ``panels``
    (:class:`processing.bode_canvas.Panel`) once under ``entity``."""
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


def bode_strips(gain: bc.Panel, phase: bc.Panel, f, h) -> list:
    """Gain and phase strips of ``h``; the phase wrapped onto its panel's branch
    (phase.lo, phase.lo + 360]."""
    return gain.curve(f, gain_db(h)) + phase.curve(f, wrap_to(_deg(h), phase.lo), wrap=360.0)
