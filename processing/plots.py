"""Bode diagrams in the style of the paper's Figs. 9 and 10 (gain and phase on a 0.1-10 Hz log axis).

Plot functions only render result data and return the matplotlib figure; they never show it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rig.response import MirrorResponse, gain_db, phase_deg  # noqa: E402


@dataclass(frozen=True)
class Curve:
    """One complex response to draw: label, values on ``freqs_hz`` and matplotlib style."""

    label: str
    freqs_hz: np.ndarray
    h: np.ndarray
    style: dict = field(default_factory=dict)


def bode_axes(fig, col: int, ncols: int, title: str, unit: str, curves: list[Curve]):
    """Draw gain [dB re unit] and phase [deg] panels of ``curves`` in column ``col`` of ``fig``."""
    ax_g = fig.add_subplot(2, ncols, col + 1)
    ax_p = fig.add_subplot(2, ncols, ncols + col + 1, sharex=ax_g)
    for c in curves:
        ax_g.semilogx(c.freqs_hz, gain_db(c.h), label=c.label, **c.style)
        ax_p.semilogx(c.freqs_hz, phase_deg(c.h), **c.style)
    ax_g.set_title(title)
    ax_g.set_ylabel(f"gain [dB re 1 {unit}]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_p.set_ylim(-190, 190)
    ax_p.set_yticks([-180, -90, 0, 90, 180])
    for ax in (ax_g, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    ax_g.legend(fontsize=8, loc="lower left")
    return ax_g, ax_p


def model_bode_figure(resp: MirrorResponse, *, title: str = ""):
    """Translation (x, like Fig. 9) and rotation (y, like Fig. 10) of the model, stage 1 dotted."""
    f = resp.freqs_hz
    fig = plt.figure(figsize=(12, 7), layout="constrained")
    bode_axes(fig, 0, 2, "translation x (mirror centre, like Fig. 9)", "m/(m/s^2)", [
        Curve("mirror x (model)", f, resp.x, {"color": "k", "lw": 1.5}),
        Curve("stage 1, G1 (model)", f, resp.stage1_x, {"color": "tab:blue", "ls": ":", "lw": 1.5}),
    ])
    bode_axes(fig, 1, 2, "rotation y (mirror body, like Fig. 10)", "rad/(m/s^2)", [
        Curve("mirror rotation (model)", f, resp.y, {"color": "k", "lw": 1.5}),
        Curve("stage 1, theta_1 (model)", f, resp.stage1_theta,
              {"color": "tab:blue", "ls": ":", "lw": 1.5}),
    ])
    if title:
        fig.suptitle(title)
    return fig


def measured_bode_figure(measured, *, model: Curve | None = None, stage1: Curve | None = None,
                         expected: Curve | None = None, k: float = 2.0, title: str = "",
                         unit: str = "", fmin_hz: float = 0.1, fmax_hz: float = 10.0):
    """Measured Bode diagram in the style of the paper's Figs. 9 and 10, plus coherence.

    Gain [dB] and phase [deg] panels on a log frequency axis from ``fmin_hz`` to ``fmax_hz``:
    the measured lines as markers with their ``k``-sigma Bendat-Piersol band
    (:meth:`FrequencyResponse.gain_band_db`, :meth:`~FrequencyResponse.phase_band_deg`) shaded,
    the model as a line, stage 1 dotted, and optionally ``E[H1]`` dashed; a third panel shows
    the coherence gamma^2.

    Parameters
    ----------
    measured : processing.frf.FrequencyResponse
    model, stage1, expected : Curve, optional
        Exact model, stage-1 model (dotted, as in the paper) and expected estimate (dashed).
        Default styles apply unless the Curve's ``style`` sets them.
    k : band width in sigma (default 2).
    title : figure title; unit : unit of the response for the gain label (default
        ``measured.units``).
    fmin_hz, fmax_hz : x range [Hz].

    Returns
    -------
    matplotlib.figure.Figure
    """
    f = np.asarray(measured.freqs_hz)
    sel = (f >= fmin_hz) & (f <= fmax_hz) & np.isfinite(measured.h)
    fs = f[sel]
    fig = plt.figure(figsize=(8, 9), layout="constrained")
    ax_g = fig.add_subplot(3, 1, 1)
    ax_p = fig.add_subplot(3, 1, 2, sharex=ax_g)
    ax_c = fig.add_subplot(3, 1, 3, sharex=ax_g)
    g_lo, g_hi = (b[sel] for b in measured.gain_band_db(k))
    p_lo, p_hi = (b[sel] for b in measured.phase_band_deg(k))
    band_style = {"color": "tab:red", "alpha": 0.25, "lw": 0}
    ax_g.fill_between(fs, np.where(np.isfinite(g_lo), g_lo, np.nan), g_hi,
                      label=f"±{k:g}σ (Bendat-Piersol)", **band_style)
    ax_p.fill_between(fs, p_lo, p_hi, **band_style)
    marker = {"ls": "none", "marker": "o", "ms": 2.0, "color": "tab:red", "mfc": "none",
              "mew": 0.6}
    ax_g.semilogx(fs, measured.magnitude_db[sel], label=f"measured ({measured.estimator.upper()}, "
                  f"{measured.n_averages} averages)", **marker)
    ax_p.semilogx(fs, measured.phase_deg[sel], **marker)
    defaults = ((model, {"color": "k", "lw": 1.2}), (stage1, {"color": "tab:blue", "ls": ":",
                                                              "lw": 1.5}),
                (expected, {"color": "tab:green", "ls": "--", "lw": 1.0}))
    for curve, style in defaults:
        if curve is None:
            continue
        cf = np.asarray(curve.freqs_hz)
        m = (cf >= fmin_hz) & (cf <= fmax_hz)
        st = {**style, **curve.style}
        ax_g.semilogx(cf[m], gain_db(curve.h[m]), label=curve.label, **st)
        ax_p.semilogx(cf[m], phase_deg(curve.h[m]), **st)
    ax_c.semilogx(fs, measured.coherence[sel], color="tab:red", lw=0.8)
    ax_g.set_ylabel(f"gain [dB re 1 {unit or measured.units}]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_ylim(-190, 190)
    ax_p.set_yticks([-180, -90, 0, 90, 180])
    ax_c.set_ylabel("coherence γ²")
    ax_c.set_ylim(0, 1.05)
    ax_c.set_xlabel("frequency [Hz]")
    ax_c.set_xlim(fmin_hz, fmax_hz)
    for ax in (ax_g, ax_p, ax_c):
        ax.grid(True, which="both", alpha=0.3)
    ax_g.legend(fontsize=8, loc="lower left")
    if title:
        fig.suptitle(title)
    return fig
