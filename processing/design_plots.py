"""Figures of a pendulum design (:mod:`rig.design`): its responses against its targets, the
trade-off sweeps and the tolerance Monte Carlo. Each function renders result data into a
:class:`matplotlib.figure.Figure` built without pyplot (the caller saves it)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from processing.plots import decade_axis


def _db(h):
    with np.errstate(divide="ignore"):
        return 20 * np.log10(np.abs(h))


def design_figure(d, curves: dict) -> Figure:
    """Three panels on log frequency: the mirror's translation |x/x0''|, the rotations |Theta_1|,
    |Theta_2| with the notch, and the suppression -20 log10|theta2/theta1| with the bands asked
    for, claim (29)'s alpha and the exact high-frequency limit. ``curves``:
    :func:`rig.design.report.design_curves`."""
    from rig.ishizaki import rotation_isolation

    f = curves["freqs_hz"]
    fig = Figure(figsize=(13, 4.6), layout="constrained")
    ax = fig.subplots(1, 3)
    ax[0].semilogx(f, _db(curves["x"]), "k", lw=1.4, label="mirror translation x (exact)")
    for t in d.targets.translation:
        if t.response == "x":
            for lim, mk in ((t.max_db, "v"), (t.min_db, "^")):
                if lim is not None:
                    ax[0].plot([t.freq_hz], [lim], mk, color="tab:red", ms=8,
                               label=f"target at {t.freq_hz:g} Hz")
    ax[0].set_ylabel("|x / x0''| [dB re 1 m/(m/s^2)]")
    ax[0].set_title("translation per stage acceleration")
    ax[1].semilogx(f, _db(curves["theta1"]), color="tab:blue", ls=":", lw=1.5,
                   label="stage 1 rotation θ₁")
    ax[1].semilogx(f, _db(curves["theta2"]), "k", lw=1.4, label="mirror rotation θ₂")
    if math.isfinite(d.notch_hz) and f[0] < d.notch_hz < f[-1]:
        ax[1].axvline(d.notch_hz, color="tab:green", ls="--", lw=1,
                      label=f"θ₂ notch {d.notch_hz:.3g} Hz")
    ax[1].set_ylabel("|Θ| [dB re 1 rad/(m/s^2)]")
    ax[1].set_title("rotation per stage acceleration")
    ax[2].semilogx(f, -_db(curves["ratio"]), "k", lw=1.4, label="-20 log10|θ₂/θ₁| (exact)")
    iso = rotation_isolation(d.params)
    ax[2].axhline(-iso.alpha_db, color="tab:orange", ls="--", lw=1,
                  label=f"claim (29): -20 log10 α = {-iso.alpha_db:.1f} dB")
    if math.isfinite(iso.ratio_db):
        ax[2].axhline(-iso.ratio_db, color="tab:purple", ls=":", lw=1,
                      label=f"exact limit above f1: {-iso.ratio_db:.1f} dB")
    bands = [s.band_hz for s in d.targets.suppression]
    if not d.targets.suppression and not d.targets.translation:
        bands_default = (1.5 * d.inputs.f1_hz, 10 * d.inputs.f1_hz)
        ax[2].axvspan(*bands_default, color="0.5", alpha=0.08,
                      label="default band of the report")
    for s, (lo, hi) in zip(d.targets.suppression, bands):
        if s.min_db is not None:
            ax[2].fill_between([lo, hi], [s.min_db] * 2, [s.min_db - 200] * 2, color="tab:red",
                               alpha=0.12, lw=0, label=f"not allowed: < {s.min_db:g} dB in band")
        else:
            ax[2].axvspan(lo, hi, color="tab:green", alpha=0.08, label="band maximised")
    ax[2].set_ylim(min(-20, float(np.nanmin(-_db(curves["ratio"]))) - 5),
                   max(60, float(np.nanmax(-_db(curves["ratio"])[np.isfinite(curves["ratio"])]))
                       + 5 if np.isfinite(curves["ratio"]).any() else 60))
    ax[2].set_ylabel("rotation suppression [dB]")
    ax[2].set_title("suppression of the mirror's rotation")
    for a in ax:
        a.set_xlabel("frequency [Hz]")
        a.set_xlim(f[0], f[-1])
        a.grid(True, which="both", alpha=0.3)
        decade_axis(a)
        a.legend(fontsize=7, loc="best")
    fig.suptitle(f"design {d.targets.name}: {'every target met' if d.status == 'met' else 'nearest feasible design'}"
                 f" (policy ({d.targets.policy}))")
    return fig


def tradeoff_figure(sweeps, *, title: str = "") -> Figure:
    """Columns: the sweeps (alpha, nu, sigma^2; log x); rows: rotation suppression in the band
    with the exact limit and claim (29), the translation's largest departure from one pendulum,
    the Theta_2 notch's frequency and its depth. The design's own value is a vertical line."""
    n = len(sweeps)
    fig = Figure(figsize=(4.4 * n, 11), layout="constrained")
    ax = fig.subplots(4, n, squeeze=False, sharex="col")
    for j, s in enumerate(sweeps):
        v = s.values
        a = ax[0, j]
        a.semilogx(v, s.suppression_db, "k", lw=1.5,
                   label=f"worst in {s.band_hz[0]:.3g}-{s.band_hz[1]:.3g} Hz (exact)")
        a.semilogx(v, np.where(np.isfinite(s.limit_db), s.limit_db, np.nan), color="tab:purple",
                   ls=":", lw=1.5, label="exact limit above f1")
        a.semilogx(v, s.alpha_db, color="tab:orange", ls="--", lw=1,
                   label="claim (29): -20 log10 α")
        a.set_ylabel("rotation suppression [dB]")
        ax[1, j].loglog(v, s.translation_dev_db, "k", lw=1.5)
        ax[1, j].set_ylabel("max |20 log10 |x/x_single|| [dB]")
        fin = np.isfinite(s.notch_hz)
        ax[2, j].loglog(v[fin], s.notch_hz[fin], color="tab:green", lw=1.5,
                        label="Θ₂ notch")
        ax[2, j].loglog(v, s.modes_hz[:, 0], color="tab:blue", ls=":", label="mode 1")
        ax[2, j].loglog(v, s.modes_hz[:, 1], color="tab:red", ls=":", label="mode 2")
        if not fin.all():
            ax[2, j].annotate("notch at infinity (σ² = 1)", xy=(v[~fin][0], s.modes_hz[-1, 1]),
                              fontsize=7, ha="right", va="bottom")
        ax[2, j].set_ylabel("frequency [Hz]")
        ax[3, j].semilogx(v[fin], s.notch_depth_db[fin], color="tab:green", lw=1.5)
        ax[3, j].set_ylabel("notch depth [dB]")
        ax[3, j].set_xlabel(s.group.replace("sigma2", "σ²").replace("alpha", "α = r2/r1")
                            .replace("nu", "ν = f2/f1"))
        for i in (1, 2):
            ax[i, j].yaxis.set_major_formatter(FuncFormatter(lambda y, _: f"{y:g}"))
            ax[i, j].yaxis.set_minor_formatter(FuncFormatter(lambda y, _: ""))
        for i in range(4):
            ax[i, j].axvline(s.design_value, color="0.5", lw=1, ls="-.",
                             label="the design" if i in (0, 2) else None)
            ax[i, j].grid(True, which="both", alpha=0.3)
        ax[0, j].legend(fontsize=7)
        ax[2, j].legend(fontsize=7)
        ax[0, j].set_title("sweep of " + {"alpha": "α", "nu": "ν", "sigma2": "σ²"}[s.group])
    if title:
        fig.suptitle(title)
    return fig


def policy_figure(curves_i: dict, curves_ii: dict, *, labels=("policy (i)", "policy (ii)"),
                  title: str = "") -> Figure:
    """Policy (i) and (ii) side by side: translation, |Theta_2| and the rotation suppression on
    log frequency, (i) solid and (ii) dashed (``curves_*``: :func:`rig.design.report.design_curves`
    of each)."""
    fig = Figure(figsize=(13, 4.6), layout="constrained")
    ax = fig.subplots(1, 3)
    for c, lab, ls in ((curves_i, labels[0], "-"), (curves_ii, labels[1], "--")):
        f = c["freqs_hz"]
        ax[0].semilogx(f, _db(c["x"]), "k", ls=ls, lw=1.3, label=lab)
        ax[1].semilogx(f, _db(c["theta2"]), "k", ls=ls, lw=1.3, label=lab)
        ax[2].semilogx(f, -_db(c["ratio"]), "k", ls=ls, lw=1.3, label=lab)
    ax[0].set_ylabel("|x / x0''| [dB re 1 m/(m/s^2)]")
    ax[0].set_title("mirror translation")
    ax[1].set_ylabel("|Θ₂| [dB re 1 rad/(m/s^2)]")
    ax[1].set_title("mirror rotation")
    ax[2].set_ylabel("-20 log10|θ₂/θ₁| [dB]")
    ax[2].set_title("rotation suppression")
    for a in ax:
        a.set_xlabel("frequency [Hz]")
        a.grid(True, which="both", alpha=0.3)
        decade_axis(a)
        a.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def tolerance_figure(mc, sens: dict, d, tol) -> Figure:
    """The Monte Carlo's distributions (the two modes, the first suppression band, the notch)
    with the acceptance windows and targets, and the sensitivity ranking of the suppression (or
    of the upper mode without a band): ``mc`` :class:`rig.design.tolerance.MonteCarlo`, ``sens``
    :func:`rig.design.tolerance.sensitivities`."""
    fig = Figure(figsize=(13, 7.5), layout="constrained")
    ax = fig.subplots(2, 3)
    panels = [("f_mode1_hz", "lower mode [Hz]", tol.accept.get("f2_hz")),
              ("f_mode2_hz", "upper mode [Hz]", tol.accept.get("f1_hz")),
              ("suppression1_db", "rotation suppression, band 1 [dB]", None),
              ("notch_hz", "Θ₂ notch [Hz]", None),
              ("notch_depth_db", "Θ₂ notch depth [dB]", None)]
    sup = d.targets.suppression[0].min_db if d.targets.suppression else None
    for a, (key, label, window) in zip(ax.flat, panels):
        v = mc.outputs.get(key)
        if v is None:
            a.set_visible(False)
            continue
        v = v[np.isfinite(v)]
        a.hist(v, bins=60, color="0.35")
        a.axvline(float(getattr(d, "modes_hz", (np.nan, np.nan))[0] if key == "f_mode1_hz" else
                        d.modes_hz[1] if key == "f_mode2_hz" else np.median(v)),
                  color="k", ls="-.", lw=1, label="design" if key.startswith("f_") else "median")
        if window:
            for w in window:
                a.axvline(w, color="tab:red", lw=1.2)
            a.axvspan(*window, color="tab:green", alpha=0.08, label="accepted")
        if key == "suppression1_db" and sup is not None:
            a.axvline(sup, color="tab:red", lw=1.2, label=f"target {sup:g} dB")
        a.set_xlabel(label)
        a.set_ylabel("samples")
        a.legend(fontsize=7)
        a.grid(True, alpha=0.3)
    key = "suppression1_db" if "suppression1_db" in sens else "f_mode2_hz"
    rows = sens[key][:8][::-1]
    a = ax.flat[5]
    a.barh([r.parameter for r in rows], [r.contribution for r in rows], color="tab:blue")
    a.set_xscale("log")
    a.set_xlabel(f"|d {key} / d p| × spread of p [{mc.units[key]}]")
    a.set_title("sensitivity ranking")
    a.grid(True, which="both", alpha=0.3)
    n = mc.passed.size
    fig.suptitle(f"{d.targets.name}: Monte Carlo of {n} pendulums (seed {mc.seed}), yield "
                 f"{100 * mc.yield_:.1f} % [{100 * mc.yield_ci[0]:.1f}, "
                 f"{100 * mc.yield_ci[1]:.1f}] (95 %)")
    return fig
