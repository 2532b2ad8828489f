"""Bode diagrams in the style of the paper's Figs. 9 and 10 (gain and phase on a 0.1-10 Hz log axis),
and the analyzer's other views: Nyquist with real and imaginary parts, coherence.

Plot functions only render result data and return a :class:`matplotlib.figure.Figure` built
without pyplot: no backend is selected and nothing is registered globally (the caller saves it;
there is nothing to close).
Every figure is drawn the way a paper prints it: the legend outside the data, decade ticks
labelled 0.1 / 1 / 10 Hz, the wrapped phase on the branch where it is one band
(:mod:`processing.phase_display`, named in the axis label) and broken at each wrap (no vertical
lines) or unwrapped,
axis labels naming the quantity, and an incomplete run marked in red in the title.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rig.errors import import_extra

import_extra("matplotlib", "plot", "drawing figures")

from matplotlib.colors import LogNorm  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import FuncFormatter, MultipleLocator, NullFormatter  # noqa: E402

from processing.line_steps import line_steps
from processing.phase_display import branch_text, branch_ticks, phase_branch, wrap_to
from rig.describe import MirrorResponse, gain_db, phase_deg

PHASES = ("wrapped", "unwrapped")
#: size of a measured Bode diagram (:func:`measured_bode_figure`) [in]
BODE_SIZE_IN = (8, 9.5)


@dataclass(frozen=True)
class Curve:
    """One complex response to draw: label, values on ``freqs_hz`` and matplotlib style."""

    label: str
    freqs_hz: np.ndarray
    h: np.ndarray
    style: dict = field(default_factory=dict)


def _log_lo(fmin_hz: float, freqs_hz) -> float:
    """The lower limit of a log frequency axis: ``fmin_hz``, or the lowest positive line if
    ``fmin_hz`` is 0."""
    if fmin_hz > 0:
        return fmin_hz
    f = np.asarray(freqs_hz, dtype=float)
    f = f[f > 0]
    return float(f.min()) if f.size else 1e-3


def decade_axis(ax) -> None:
    """Label a log frequency axis's decades as plain numbers (0.1, 1, 10), minor ticks unlabelled."""
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def phase_curve(f, h, phase: str = "wrapped",
                lo: float = -180.0) -> tuple[np.ndarray, np.ndarray]:
    """``(f, phase [deg])`` ready to draw as a line: ``"wrapped"`` to (lo, lo + 360] with a NaN
    inserted at every wrap (a break, not a vertical line), or ``"unwrapped"`` along frequency."""
    f, h = np.asarray(f, dtype=float), np.asarray(h)
    if phase not in PHASES:
        raise ValueError(f"phase = {phase!r} is invalid: expected one of {', '.join(PHASES)}")
    if phase == "unwrapped":
        out = np.full(h.shape, np.nan)
        ok = np.isfinite(h)
        out[ok] = np.degrees(np.unwrap(np.angle(h[ok])))
        return f, out
    p = wrap_to(phase_deg(h), lo)
    return wrap_breaks(f, p)


def wrap_breaks(f, p, *others):
    """Insert NaN into ``f``, ``p`` (and ``others``) between neighbours whose phases ``p`` differ
    by more than 180 deg, so a line drawn through them breaks at the wrap."""
    jump = np.nonzero(np.abs(np.diff(p)) > 180.0)[0] + 1
    return tuple(np.insert(np.asarray(a, dtype=float), jump, np.nan) for a in (f, p, *others))


def _phase_axis(ax, phase: str, what: str = "", lo: float = -180.0) -> None:
    """Label and ticks of a phase axis; wrapped: on the branch (lo, lo + 360], named in the label
    (:mod:`processing.phase_display`)."""
    of = f" of {what}" if what else ""
    if phase == "wrapped":
        ax.set_ylabel(f"phase{of} [deg], on {branch_text(lo)}")
        ax.set_ylim(lo - 10, lo + 370)
        ax.set_yticks(branch_ticks(lo))
    else:
        ax.set_ylabel(f"phase{of} [deg]")
        lo, hi = ax.get_ylim()
        ax.yaxis.set_major_locator(MultipleLocator(90 if hi - lo <= 900 else 180))


def outside_legend(fig, ax, ncols: int = 2) -> None:
    """The legend of ``ax``'s labelled artists below the figure's panels, outside the data."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=ncols, fontsize=8,
                   frameon=False)


def title_with_status(fig, title: str, incomplete: str = "") -> None:
    """``title`` as the figure's title; an incomplete run's note first, in red and bold."""
    if incomplete:
        fig.suptitle(f"INCOMPLETE RUN: {incomplete}\n{title}", color="tab:red",
                     fontweight="bold")
    elif title:
        fig.suptitle(title)


def bode_axes(fig, col: int, ncols: int, title: str, unit: str, curves: list[Curve], *,
              what: str = "", phase: str = "wrapped"):
    """Draw gain [dB re unit] and phase [deg] panels of ``curves`` in column ``col`` of ``fig``
    (``what``: the quantity's symbol for the axis labels); the caller places the legend
    (:func:`outside_legend`)."""
    ax_g = fig.add_subplot(2, ncols, col + 1)
    ax_p = fig.add_subplot(2, ncols, ncols + col + 1, sharex=ax_g)
    lo = phase_branch(*((c.freqs_hz, c.h) for c in curves))
    for c in curves:
        ax_g.semilogx(c.freqs_hz, gain_db(c.h), label=c.label, **c.style)
        ax_p.semilogx(*phase_curve(c.freqs_hz, c.h, phase, lo), **c.style)
    ax_g.set_title(title)
    ax_g.set_ylabel(f"gain{' |' + what + '|' if what else ''} [dB re 1 {unit}]")
    _phase_axis(ax_p, phase, what, lo)
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_g, ax_p):
        ax.grid(True, which="both", alpha=0.3)
        decade_axis(ax)
    return ax_g, ax_p


def model_bode_figure(resp: MirrorResponse, *, title: str = "", paper_figures: bool = False,
                      phase: str = "wrapped"):
    """Translation x and rotation y of the mirror per unit stage acceleration (the model), with
    stage 1 dotted; ``paper_figures`` names the paper's Figs. 9 and 10 (for its pendulum)."""
    f = resp.freqs_hz
    fig = Figure(figsize=(12, 7.5), layout="constrained")
    fig9, fig10 = (" (cf. the paper's Fig. 9)", " (cf. Fig. 10)") if paper_figures else ("", "")
    blue = {"color": "tab:blue", "ls": ":", "lw": 1.5}
    ax1, _ = bode_axes(fig, 0, 2, f"mirror translation x per stage acceleration{fig9}",
                       "m/(m/s^2)", [
                           Curve("mirror translation x (model)", f, resp.x,
                                 {"color": "k", "lw": 1.5}),
                           Curve("stage 1: translation of its centre of mass G1 (model)", f,
                                 resp.stage1_x, blue)], what="x/a", phase=phase)
    ax2, _ = bode_axes(fig, 1, 2, f"mirror rotation y per stage acceleration{fig10}",
                       "rad/(m/s^2)", [
                           Curve("mirror rotation y (model)", f, resp.y,
                                 {"color": "k", "lw": 1.5}),
                           Curve("stage 1: rotation θ₁ (model)", f, resp.stage1_theta, blue)],
                       what="y/a", phase=phase)
    h1, l1 = ax1.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    fig.legend(h1 + h2, l1 + l2, loc="outside lower center", ncols=2, fontsize=8, frameon=False)
    title_with_status(fig, title)
    return fig


def measured_bode_figure(measured, *, model: Curve | None = None, stage1: Curve | None = None,
                         expected: Curve | None = None, k: float = 2.0, title: str = "",
                         unit: str = "", fmin_hz: float = 0.1, fmax_hz: float = 10.0,
                         what: str = "", phase: str = "wrapped", incomplete: str = "",
                         into=None):
    """Measured Bode diagram in the style of the paper's Figs. 9 and 10, plus coherence.

    Gain [dB] and phase [deg] panels on a log frequency axis from ``fmin_hz`` to ``fmax_hz``:
    the measured lines as markers with their ``k``-sigma Bendat-Piersol band
    (:meth:`MeasuredResponse.gain_band_db`, :meth:`~MeasuredResponse.phase_band_deg`) shaded,
    the model as a line, stage 1 dotted, and optionally ``E[H1]`` dashed; a third panel shows
    the coherence gamma^2. The legend is below the panels.

    Parameters
    ----------
    measured : processing.frf.MeasuredResponse
    model, stage1, expected : Curve, optional
        Exact model, stage-1 model (dotted, as in the paper) and expected estimate (at the
        lines only: each line's value held over its bin, :func:`processing.line_steps.
        line_steps`; its SVG elements' ids are ``expected-estimate-gain`` and ``-phase``).
        Default styles apply unless the Curve's ``style`` sets them.
    k : band width in sigma (default 2).
    title : figure title; unit : unit of the response for the gain label (default
        ``measured.units``); what : the response's symbol for the axis labels (e.g. "H_t").
    fmin_hz, fmax_hz : x range [Hz].
    phase : "wrapped" (to (-180, 180], lines broken at the wraps) or "unwrapped".
    incomplete : if not empty, the run is incomplete: this note heads the title in red.
    into : a matplotlib SubFigure to draw into (several diagrams in one file) instead of a new
        Figure.

    Returns
    -------
    matplotlib.figure.Figure (or ``into``)
    """
    f = np.asarray(measured.freqs_hz)
    sel = (f >= fmin_hz) & (f <= fmax_hz) & np.isfinite(measured.h)
    fs = f[sel]
    fig = Figure(figsize=BODE_SIZE_IN, layout="constrained") if into is None else into
    ax_g = fig.add_subplot(3, 1, 1)
    ax_p = fig.add_subplot(3, 1, 2, sharex=ax_g)
    ax_c = fig.add_subplot(3, 1, 3, sharex=ax_g)
    unwrapped = phase == "unwrapped"
    if phase not in PHASES:
        raise ValueError(f"phase = {phase!r} is invalid: expected one of {', '.join(PHASES)}")
    g_lo, g_hi = (b[sel] for b in measured.gain_band_db(k))
    p_lo, p_hi = (b[sel] for b in measured.phase_band_deg(k, unwrapped=unwrapped))
    p_meas = (measured.phase_unwrapped_deg if unwrapped else measured.phase_deg)[sel]
    lo = phase_branch((model.freqs_hz, model.h) if model is not None else (fs, measured.h[sel]))
    if not unwrapped:  # onto the branch, the bands moved with their centres
        shift = wrap_to(p_meas, lo) - p_meas
        p_meas, p_lo, p_hi = p_meas + shift, p_lo + shift, p_hi + shift
    band_style = {"color": "tab:red", "alpha": 0.25, "lw": 0}
    ax_g.fill_between(fs, np.where(np.isfinite(g_lo), g_lo, np.nan), g_hi,
                      label=f"±{k:g}σ (Bendat-Piersol)", **band_style)
    bf, _, blo, bhi = wrap_breaks(fs, p_meas, p_lo, p_hi) if not unwrapped else (fs, p_meas,
                                                                                   p_lo, p_hi)
    ax_p.fill_between(bf, blo, bhi, **band_style)
    marker = {"ls": "none", "marker": "o", "ms": 2.0, "color": "tab:red", "mfc": "none",
              "mew": 0.6}
    name = f"{what} " if what else ""
    ax_g.semilogx(fs, measured.magnitude_db[sel], label=f"measured {name}"
                  f"({measured.estimator.upper()}, {measured.n_averages} averages)", **marker)
    ax_p.semilogx(fs, p_meas, **marker)
    defaults = ((model, {"color": "k", "lw": 1.2}), (stage1, {"color": "tab:blue", "ls": ":",
                                                              "lw": 1.5}),
                (expected, {"color": "tab:green", "lw": 0.9}))
    for curve, style in defaults:
        if curve is None:
            continue
        cf, ch = np.asarray(curve.freqs_hz), np.asarray(curve.h)
        gid = {}
        if curve is expected:  # defined at the lines only: held over each line's bin
            cf, ch = line_steps(cf, ch)
            gid = {"gain": "expected-estimate-gain", "phase": "expected-estimate-phase"}
        m = (cf >= fmin_hz) & (cf <= fmax_hz)
        st = {**style, **curve.style}
        ax_g.semilogx(cf[m], gain_db(ch[m]), label=curve.label, gid=gid.get("gain"), **st)
        ax_p.semilogx(*phase_curve(cf[m], ch[m], phase, lo), gid=gid.get("phase"), **st)
    ax_c.semilogx(fs, measured.coherence[sel], color="tab:red", lw=0.8)
    ax_g.set_ylabel(f"gain{' |' + what + '|' if what else ''} [dB re 1 {unit or measured.units}]")
    _phase_axis(ax_p, phase, what, lo)
    ax_c.set_ylabel(f"coherence γ²{' of ' + what if what else ''}")
    ax_c.set_ylim(0, 1.05)
    ax_c.set_xlabel("frequency [Hz]")
    ax_c.set_xlim(_log_lo(fmin_hz, fs), fmax_hz)
    for ax in (ax_g, ax_p, ax_c):
        ax.grid(True, which="both", alpha=0.3)
        decade_axis(ax)
    outside_legend(fig, ax_g)
    title_with_status(fig, title, incomplete)
    return fig


def bode_figure(response, *, title: str = "", what: str = "", phase: str = "wrapped",
                fmin_hz: float = 0.1, fmax_hz: float = 10.0, **measured_options):
    """The Bode diagram of one frequency response of either kind.

    A measured response (:class:`processing.frf.MeasuredResponse`: it has a coherence) goes to
    :func:`measured_bode_figure` (``measured_options``: ``model``, ``stage1``, ``expected``,
    ``k``, ``unit``, ``incomplete``); a model response (:class:`rig.linear.MeasuredResponse`,
    1-D or one column per name) is drawn as gain and phase lines over ``fmin_hz .. fmax_hz``.
    Returns a :class:`matplotlib.figure.Figure` (no backend selected).
    """
    if hasattr(response, "coherence"):
        return measured_bode_figure(response, title=title, what=what, phase=phase,
                                    fmin_hz=fmin_hz, fmax_hz=fmax_hz, **measured_options)
    if measured_options:
        raise TypeError(f"{sorted(measured_options)}: options of a measured response only")
    f = np.asarray(response.freqs_hz)
    h = np.asarray(response.h)
    cols = h.reshape(f.size, -1)
    names = tuple(response.names) or (what or "h",)
    m = (f >= fmin_hz) & (f <= fmax_hz)
    curves = [Curve(str(n), f[m], cols[m, i]) for i, n in enumerate(names[:cols.shape[1]])]
    fig = Figure(figsize=(8, 7), layout="constrained")
    ax_g, _ = bode_axes(fig, 0, 1, "", response.units or "unit", curves, what=what, phase=phase)
    outside_legend(fig, ax_g)
    title_with_status(fig, title)
    return fig


@dataclass(frozen=True)
class Response:
    """One measured response for the Nyquist and coherence views: its symbol, the
    :class:`processing.frf.MeasuredResponse`, its unit and the model :class:`Curve` (or None)."""

    name: str
    measured: object
    unit: str
    model: Curve | None = None
    expected_coherence: np.ndarray | None = None


def nyquist_figure(responses: list[Response], *, fmin_hz: float = 0.1, fmax_hz: float = 10.0,
                   title: str = "", incomplete: str = ""):
    """The Nyquist view and the real and imaginary parts against frequency, one column per
    response: measured lines as markers (coloured by frequency in the Nyquist panel), the model
    as a line. Returns the figure."""
    n = len(responses)
    fig = Figure(figsize=(6.5 * n, 11), layout="constrained")
    for col, r in enumerate(responses):
        f = np.asarray(r.measured.freqs_hz)
        sel = (f >= fmin_hz) & (f <= fmax_hz) & np.isfinite(r.measured.h)
        fs, h = f[sel], r.measured.h[sel]
        ax_n = fig.add_subplot(3, n, col + 1)
        ax_r = fig.add_subplot(3, n, n + col + 1)
        ax_i = fig.add_subplot(3, n, 2 * n + col + 1, sharex=ax_r)
        if r.model is not None:
            cf = np.asarray(r.model.freqs_hz)
            m = (cf >= fmin_hz) & (cf <= fmax_hz)
            style = {"color": "k", "lw": 1.0, **r.model.style}
            ax_n.plot(r.model.h[m].real, r.model.h[m].imag, label=r.model.label, **style)
            ax_r.semilogx(cf[m], r.model.h[m].real, **style)
            ax_i.semilogx(cf[m], r.model.h[m].imag, **style)
        sc = ax_n.scatter(h.real, h.imag, c=fs, s=6, cmap="viridis",
                          norm=LogNorm(_log_lo(fmin_hz, fs), fmax_hz),
                          label=f"measured {r.name} ({r.measured.estimator.upper()}, "
                                f"{r.measured.n_averages} averages)")
        cb = fig.colorbar(sc, ax=ax_n, label="frequency [Hz]")
        cb.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        marker = {"ls": "none", "marker": "o", "ms": 2.0, "color": "tab:red", "mfc": "none",
                  "mew": 0.6}
        ax_r.semilogx(fs, h.real, **marker)
        ax_i.semilogx(fs, h.imag, **marker)
        ax_n.set_aspect("equal", adjustable="datalim")
        ax_n.set_title(f"{r.name}: Nyquist")
        ax_n.set_xlabel(f"Re {r.name} [{r.unit}]")
        ax_n.set_ylabel(f"Im {r.name} [{r.unit}]")
        ax_r.set_ylabel(f"Re {r.name} [{r.unit}]")
        ax_i.set_ylabel(f"Im {r.name} [{r.unit}]")
        ax_i.set_xlabel("frequency [Hz]")
        ax_r.set_xlim(_log_lo(fmin_hz, fs), fmax_hz)
        for ax in (ax_n, ax_r, ax_i):
            ax.grid(True, which="both", alpha=0.3)
            ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax_n.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))
        decade_axis(ax_r)
        decade_axis(ax_i)
        if col == 0:
            outside_legend(fig, ax_n)
    title_with_status(fig, title, incomplete)
    return fig


def coherence_figure(responses: list[Response], *, fmin_hz: float = 0.1, fmax_hz: float = 10.0,
                     marks: tuple = (), title: str = "", incomplete: str = ""):
    """The coherence gamma^2 of every response on one log frequency axis, with optional
    ``marks`` ``(frequency_hz, label)`` (e.g. the frequencies where a known mechanism lowers
    it) as thin vertical lines labelled at the top. Returns the figure."""
    fig = Figure(figsize=(9, 6), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    styles = ({"color": "tab:red", "marker": "o"}, {"color": "tab:blue", "marker": "s"},
              {"color": "tab:green", "marker": "^"})
    for r, st in zip(responses, styles):
        f = np.asarray(r.measured.freqs_hz)
        sel = (f >= fmin_hz) & (f <= fmax_hz) & np.isfinite(r.measured.h)
        ax.semilogx(f[sel], r.measured.coherence[sel], lw=0.7, ms=2.0, mfc="none", mew=0.6,
                    label=f"γ² of {r.name} ({r.measured.n_averages} averages)", **st)
        if r.expected_coherence is not None:
            ax.semilogx(f[sel], np.asarray(r.expected_coherence)[sel], color="k",
                        ls="--" if st["marker"] == "o" else ":", lw=0.9,
                        label=f"expected γ² of {r.name} (model: lever geometry, noise, leakage)")
    for fm, label in marks:
        if fmin_hz <= fm <= fmax_hz:
            ax.axvline(fm, color="0.5", lw=0.6, ls="--")
            ax.text(fm, 1.06, label, rotation=90, ha="center", va="bottom", fontsize=7,
                    color="0.3", transform=ax.get_xaxis_transform())
    ax.set_xlim(_log_lo(fmin_hz, responses[0].measured.freqs_hz), fmax_hz)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("coherence γ² [1]")
    ax.grid(True, which="both", alpha=0.3)
    decade_axis(ax)
    outside_legend(fig, ax)
    title_with_status(fig, title, incomplete)
    return fig
