"""The files of a sine sweep (stepped or swept): CSV, Bode PNG over the exact model, report.

:func:`write_sine_csv` writes one row per point: the columns of ``daq analyze``'s CSV
(:data:`processing.writers.CSV_COLUMNS`; the coherence columns hold the fundamental's share of
the output channel's power) followed by :data:`EXTRA_COLUMNS`: the point's settle and
integration time (simulated seconds), source level, the random errors (1 sigma, dB and degrees),
the exact steady state and the settling (swept: sweep) bias (dB, degrees) of H_t (x) and
Theta_2 (y), and the magnitudes of harmonics 2..H of a, x, y in engineering units with the
optical lever's predicted 2f magnitudes of x and y. :func:`sine_bode_figure` draws the points over the exact whole-chain
response, with their difference from it against the stated settling bias and random error;
:func:`sine_report` writes the report (settling bias, random error and distortion separated at
every point). Files are written under a temporary name and renamed when complete; an existing
file is replaced only with ``force``.

Public API: :func:`write_sine_csv`, :func:`sine_bode_figure`, :func:`write_sine_bode_png`,
:func:`sine_report`, :func:`write_sine_report`, :func:`write_sine_uff` (UFF 58 FRFs at the points),
:data:`EXTRA_COLUMNS`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from processing.sine import DB
from processing.writers import CSV_COLUMNS
from rig.output_files import atomic_output, write_columns_csv

EXTRA_COLUMNS = ("settle_s", "integrate_s", "level_vrms",
                 "x_error_db", "x_error_deg", "y_error_db", "y_error_deg",
                 "x_exact_gain_db", "x_exact_phase_deg", "y_exact_gain_db", "y_exact_phase_deg",
                 "x_bias_db", "x_bias_deg", "y_bias_db", "y_bias_deg")
_NAMES = (("x", "h_t"), ("y", "theta_2"))


def _gain_phase(h):
    h = np.asarray(h, complex)
    return DB * np.log(np.abs(h)), np.degrees(np.angle(h))


def sine_columns(sweep) -> tuple[tuple, list]:
    """(header, columns) of :func:`write_sine_csv`."""
    pts = sweep.points
    cols = {"frequency_hz": [p.frequency_hz for p in pts]}
    for ch, name in _NAMES:
        h = np.array([getattr(p, name) for p in pts])
        g, ph = _gain_phase(h)
        cols.update({f"{ch}_re": h.real, f"{ch}_im": h.imag, f"{ch}_gain_db": g,
                     f"{ch}_phase_deg": ph,
                     f"{ch}_coherence": [p.fundamental_ratio[1 if ch == "x" else 2]
                                         for p in pts]})
    cols.update({k: [getattr(p, k) for p in pts] for k in ("settle_s", "integrate_s",
                                                            "level_vrms")})
    for ch, name in _NAMES:
        e = np.array([p.error_db_deg(name) for p in pts])
        ex = np.array([getattr(p, f"{name}_exact") for p in pts])
        b = np.array([p.bias_db_deg(name) for p in pts])
        g, ph = _gain_phase(ex)
        cols.update({f"{ch}_error_db": e[:, 0], f"{ch}_error_deg": e[:, 1],
                     f"{ch}_exact_gain_db": g, f"{ch}_exact_phase_deg": ph,
                     f"{ch}_bias_db": b[:, 0], f"{ch}_bias_deg": b[:, 1]})
    h = sweep.settings.harmonics
    for k in range(2, h + 1):
        for i, (c, unit) in enumerate((("a", "mps2"), ("x", "m"), ("y", "rad"))):
            cols[f"{c}_h{k}_{unit}"] = [abs(p.harmonics[i, k - 1]) for p in pts]
    cols["x_lever_2f_m"] = [abs(p.lever_2f[0]) for p in pts]
    cols["y_lever_2f_rad"] = [abs(p.lever_2f[1]) for p in pts]
    header = tuple(cols)
    assert header[:len(CSV_COLUMNS)] == CSV_COLUMNS
    return header, [np.asarray(v, float) for v in cols.values()]


def write_sine_csv(sweep, path, *, force: bool = False) -> Path:
    """The sweep's CSV (module docstring); returns the path."""
    header, columns = sine_columns(sweep)
    return write_columns_csv(path, header, columns, force=force)


def _model_grid(sweep, scene) -> np.ndarray:
    st = sweep.settings
    f = np.geomspace(st.fmin_hz, st.fmax_hz, 3000)
    modes = np.asarray(scene.chain.modes()[0], float)
    fine = [np.linspace(m * (1 - 0.01), m * (1 + 0.01), 401) for m in modes
            if st.fmin_hz < m < st.fmax_hz]
    f = np.concatenate([f, *fine, [p.frequency_hz for p in sweep.points]])
    return np.unique(f[(f >= st.fmin_hz) & (f <= st.fmax_hz)])


def sine_bode_figure(sweep, scene, *, title: str = ""):
    """Gain, phase and the difference from the exact response of H_t and Theta_2: the points
    (markers) over the exact whole-chain model (:func:`rig.expected_response`, ``sampled=True``:
    what the points should read in their steady state), and below each the points' difference
    from it [dB] with the stated settling bias and the +-2 sigma random error."""
    from rig.errors import import_extra

    import_extra("matplotlib", "plot", "drawing figures")
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    import rig
    from processing.plots import decade_axis, phase_curve

    fm = _model_grid(sweep, scene)
    model = rig.expected_response(scene, fm, sampled=True)
    fig = Figure(figsize=(11, 8.2), layout="constrained")
    f = sweep.column("frequency_hz")
    kind = "sweep" if sweep.settings.mode == "swept" else "settling"
    for col, (name, what, unit) in enumerate((("h_t", "H_t", "m/(m/s^2)"),
                                              ("theta_2", "Theta_2", "rad/(m/s^2)"))):
        ax_g = fig.add_subplot(3, 2, col + 1)
        ax_p = fig.add_subplot(3, 2, col + 3, sharex=ax_g)
        ax_e = fig.add_subplot(3, 2, col + 5, sharex=ax_g)
        hm = getattr(model, name)
        h = np.array([getattr(p, name) for p in sweep.points])
        ax_g.semilogx(fm, DB * np.log(np.abs(hm)), color="0.35", lw=1.0,
                      label="exact model of the whole chain (steady state)")
        ax_g.semilogx(f, DB * np.log(np.abs(h)), "o", ms=2.6, color="tab:red",
                      label=f"{sweep.settings.mode} sine, {len(f)} points")
        ax_p.semilogx(*phase_curve(fm, hm), color="0.35", lw=1.0)
        ax_p.semilogx(f, np.degrees(np.angle(h)), "o", ms=2.6, color="tab:red")
        diff = np.array([p.gain_phase_error(name)[0] for p in sweep.points])
        bias = np.array([p.bias_db_deg(name)[0] for p in sweep.points])
        sig = np.array([p.error_db_deg(name)[0] for p in sweep.points])
        ax_e.fill_between(f, bias - 2 * sig, bias + 2 * sig, color="tab:blue", alpha=0.2,
                          lw=0, label=f"stated {kind} bias +- 2 sigma random error")
        ax_e.semilogx(f, bias, color="tab:blue", lw=0.8, label=f"stated {kind} bias")
        ax_e.semilogx(f, diff, "o", ms=2.2, color="tab:red",
                      label="measured - exact steady state")
        ax_e.axhline(0.0, color="0.5", lw=0.6)
        lim = max(0.12, float(np.nanmax(np.abs(diff))) * 1.15 if diff.size else 0.12)
        ax_e.set_ylim(-lim, lim)
        ax_g.set_title(f"{what} per stage acceleration")
        ax_g.set_ylabel(f"gain |{what}| [dB re 1 {unit}]")
        ax_p.set_ylabel(f"phase of {what} [deg]")
        ax_p.set_ylim(-190, 190)
        ax_p.set_yticks([-180, -90, 0, 90, 180])
        ax_e.set_ylabel("measured - exact [dB]")
        ax_e.set_xlabel("frequency [Hz]")
        for ax in (ax_g, ax_p, ax_e):
            ax.grid(True, which="both", alpha=0.3)
            decade_axis(ax)
        ax_g.set_xlim(sweep.settings.fmin_hz, sweep.settings.fmax_hz)
        if sweep.settings.fmax_hz / sweep.settings.fmin_hz < 10:  # no decade inside: label more
            for ax in (ax_g, ax_p, ax_e):
                ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
                ax.tick_params(axis="x", which="minor", labelsize=7)
        if col == 0:
            handles, labels = [], []
            for ax in (ax_g, ax_e):
                h_, l_ = ax.get_legend_handles_labels()
                handles += h_
                labels += l_
            fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=8,
                       frameon=False)
    fig.suptitle(title or f"{scene.name}: {sweep.settings.mode} sine "
                          f"{sweep.settings.fmin_hz:g}-"
                          f"{sweep.settings.fmax_hz:g} Hz, {sweep.bench_s / 3600:.1f} h of bench "
                          f"time ({sweep.model_info.get('model', '?')} model)")
    return fig


def write_sine_bode_png(sweep, scene, path, *, force: bool = False, dpi: int = 110) -> Path:
    """:func:`sine_bode_figure` as a PNG; returns the path."""
    path = Path(path)
    fig = sine_bode_figure(sweep, scene)
    with atomic_output(path, force=force) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return path


def _near(sweep, f0: float):
    return min(sweep.points, key=lambda p: abs(p.frequency_hz - f0))


def sine_report(sweep, scene) -> str:
    """The Markdown report: the sweep, the model that ran, the accuracy against the exact
    response separated into settling bias, random error and the rest (distortion: what neither
    explains), the points at the modes and anti-resonance, the harmonics against the optical
    lever's prediction, and any clipping or saturation."""
    st, pts = sweep.settings, sweep.points
    lines = [f"# {st.mode.capitalize()} sine: {scene.name}", "", "## Sweep", ""]
    lines += [f"- {len(pts)} points {st.fmin_hz:g}-{st.fmax_hz:g} Hz ({st.spacing}, "
              f"{st.direction}); {len(sweep.discarded)} more run and discarded (auto "
              f"resolution {st.auto_resolution}, auto level {st.auto_level})",
              f"- simulated bench time {sweep.bench_s:.0f} s ({sweep.bench_s / 3600:.2f} h), "
              f"CPU {sweep.cpu_s:.2f} s: {sweep.bench_s / max(sweep.cpu_s, 1e-9):,.0f} x",
              f"- settle: " + (f"{st.settle_s:g} s" if st.settle_s is not None else
                               f"{st.settle_cycles:g} cycles" if st.settle_cycles is not None
                               else f"the rule from the poles: until every channel's modal "
                                    f"transient bound is {st.settle_tolerance:g} of its steady "
                                    f"amplitude (at most {st.max_settle_s:g} s)"),
              *([f"- swept: " + (f"a {st.spacing} chirp of {st.sweep_s:g} s" if st.sweep_s
                                   else f"the rule's path from the poles and zeros (tolerance "
                                        f"{st.sweep_tolerance:g})") + "; settle above: the "
                 "lead-in at the first frequency; a point's bias is the sweep's"]
                if st.mode == "swept" else []),
              *[f"- WARNING: {w}" for w in sweep.warnings],
              f"- model: {sweep.model_info.get('model')} "
              f"({sweep.model_info.get('reason', 'forced')})", ""]
    lines += ["## Accuracy against the exact response", "",
              "| response | max abs measured - exact [dB] | [deg] | max abs stated bias [dB] "
              "| [deg] | max random error 1 sigma [dB] | [deg] | points beyond bias + 4 sigma |",
              "|---|---|---|---|---|---|---|---|"]
    for name, what in (("h_t", "H_t"), ("theta_2", "Theta_2")):
        d = np.array([p.gain_phase_error(name) for p in pts])
        b = np.array([p.bias_db_deg(name) for p in pts])
        e = np.array([p.error_db_deg(name) for p in pts])
        beyond = int(np.sum((np.abs(d[:, 0] - b[:, 0]) > 4 * e[:, 0] + 1e-9)
                            | (np.abs(d[:, 1] - b[:, 1]) > 4 * e[:, 1] + 1e-9)))
        lines.append(f"| {what} | {np.max(np.abs(d[:, 0])):.4f} | {np.max(np.abs(d[:, 1])):.3f}"
                     f" | {np.max(np.abs(b[:, 0])):.4f} | {np.max(np.abs(b[:, 1])):.3f} | "
                     f"{np.max(e[:, 0]):.4f} | {np.max(e[:, 1]):.3f} | {beyond} |")
    lines += ["", "A point beyond its stated settling bias plus 4 random errors is distortion "
              "(the nonlinear bench, saturation, clipping) or a random error underestimated.", "",
              "## At the modes and the anti-resonance", "",
              "| target [Hz] | point [Hz] | settle [s] | window [s] | level [V] | H_t measured - "
              "exact [dB, deg] | bias [dB, deg] | Theta_2 measured - exact [dB, deg] | bias |",
              "|---|---|---|---|---|---|---|---|---|"]
    targets = list(np.asarray(scene.chain.modes()[0], float))
    w = np.zeros(scene.chain.n)
    w[scene.mirror.body] = 1.0  # the mirror's rotation: Theta_2's anti-resonances
    targets += list(np.asarray(scene.chain.antiresonances_hz(w), float).ravel())
    for f0 in sorted(t for t in targets if st.fmin_hz <= t <= st.fmax_hz):
        p = _near(sweep, f0)
        g, b = p.gain_phase_error("h_t"), p.bias_db_deg("h_t")
        g2, b2 = p.gain_phase_error("theta_2"), p.bias_db_deg("theta_2")
        lines.append(f"| {f0:.4f} | {p.frequency_hz:.5f} | {p.settle_s:.0f} | "
                     f"{p.integrate_s:.0f} | {p.level_vrms:.4g} | {g[0]:+.4f}, {g[1]:+.3f} | "
                     f"{b[0]:+.4f}, {b[1]:+.3f} | {g2[0]:+.4f}, {g2[1]:+.3f} | "
                     f"{b2[0]:+.4f}, {b2[1]:+.3f} |")
    lines += ["", "## Harmonics", "", _harmonics_text(sweep), ""]
    clip = sum(int(p.clipped.sum()) for p in pts)
    sat = [p for p in pts if p.saturated.sum() > 0]
    lines += ["## Clipping and saturation", ""]
    if not clip and not sat:
        lines.append("No sample was clipped and no sensor was over its range.")
    else:
        lines.append(f"{clip} samples clipped; {len(sat)} points with a sensor over its range"
                     + (f" (first at {sat[0].frequency_hz:.4g} Hz: lower the level or use "
                        "auto level)" if sat else "") + ".")
    return "\n".join(lines) + "\n"


def _harmonics_text(sweep) -> str:
    """The measured 2f components of x and y against the optical lever's prediction, and the
    third harmonics that stand above the noise (4 random errors of the coefficient)."""
    pts = [p for p in sweep.points if np.all(np.isfinite(p.lever_2f))]
    if not pts or sweep.settings.harmonics < 2:
        return "No harmonic below the Nyquist frequency was measured."
    rows = ["| channel | points where the 2f component is 10 x its random error | median "
            "measured / predicted by the lever (magnitude) | IQR |", "|---|---|---|---|"]
    for i, c in ((1, "x"), (2, "y")):
        ratio = [abs(p.harmonics[i, 1]) / abs(p.lever_2f[i - 1]) for p in pts
                 if abs(p.harmonics[i, 1]) > 10 * p.coef_sd[i] and abs(p.lever_2f[i - 1]) > 0]
        if ratio:
            q = np.percentile(ratio, [25, 50, 75])
            rows.append(f"| {c} | {len(ratio)} | {q[1]:.3f} | {q[0]:.3f}-{q[2]:.3f} |")
        else:
            rows.append(f"| {c} | 0 | - | - |")
    text = "\n".join(rows)
    if sweep.settings.harmonics < 3:
        return text
    third = [(abs(p.harmonics[i, 2]) / abs(p.harmonics[i, 0]), p, c)
             for p in sweep.points for i, c in ((1, "x"), (2, "y"))
             if np.isfinite(p.harmonics[i, 2]) and abs(p.harmonics[i, 2]) > 4 * p.coef_sd[i]]
    if third:
        r, p, c = max(third, key=lambda t: t[0])
        text += (f"\n\nThird harmonics above 4 random errors at {len(third)} channel-points; "
                 f"the largest relative to its fundamental: {DB * math.log(r):.1f} dB in {c} at "
                 f"{p.frequency_hz:.4g} Hz (level {p.level_vrms:.3g} V; the pendulum's own odd "
                 "harmonics come from the nonlinear model, the lever's geometry adds mostly "
                 "even ones).")
    else:
        text += ("\n\nNo third harmonic of x or y stands above 4 random errors (the linear "
                 "model makes none but the lever's third-order geometry; the nonlinear bench's "
                 "appear at large drives).")
    return text


def write_sine_report(sweep, scene, path, *, force: bool = False) -> Path:
    """:func:`sine_report` as a file; returns the path."""
    path = Path(path)
    with atomic_output(path, force=force) as tmp:
        Path(tmp).write_text(sine_report(sweep, scene))
    return path


def sine_uff_datasets(sweep, scene) -> list[dict]:
    """UFF 58 sets of the sweep: H_t and Theta_2 at the points (function type 4, FRF, uneven
    abscissa), with the nodes and directions of ``daq analyze --uff`` (:mod:`rig.uff`). ASCII
    UFF 58 writes an uneven abscissa as E13.5 (6 significant digits: the frequencies within
    5e-6 relative; the run file and the CSV keep them whole), the values with 12 digits."""
    from rig.uff import CHANNEL_DOFS, FRF, uff58

    f = sweep.column("frequency_hz")
    out = []
    for name, attr, ch, unit in (("H_t", "h_t", "x", "m/(m/s^2)"),
                                 ("Theta_2", "theta_2", "y", "rad/(m/s^2)")):
        h = np.array([getattr(p, attr) for p in sweep.points])
        out.append(uff58(func_type=FRF, response=CHANNEL_DOFS[ch], reference=CHANNEL_DOFS["a"],
                         x=f, data=h, abscissa="frequency", even=False, ids=(
                             f"{name} = {ch}/a [{unit}], {sweep.settings.mode} sine "
                             "(synchronous DFT)",
                             f"scene {scene.name}, {len(f)} points {f.min():.4g}-{f.max():.4g} Hz",
                             f"model {sweep.model_info.get('model')}, bench "
                             f"{sweep.bench_s:.0f} s simulated")))
    return out


def write_sine_uff(sweep, scene, path, *, force: bool = False) -> Path:
    """:func:`sine_uff_datasets` as a UFF file (``.uff``/``.unv``); returns the path."""
    from rig.uff import write_uff

    return write_uff(sine_uff_datasets(sweep, scene), path, force=force)
