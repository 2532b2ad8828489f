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
