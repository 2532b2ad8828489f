"""A Markdown report of a measurement against the exact model: what a careful experimenter reads.

:func:`report_markdown` renders, from result objects only (no computation beyond formatting and
matching fitted modes to the exact ones):

1. the analyzer settings and the number of averages;
2. a coherence summary per channel;
3. fitted f and Q with uncertainties next to the scene's exact modes, with the leakage flag;
4. leakage bias against random error at each resonance peak;
5. residual statistics per band (away from resonances, near each one);
6. the rotation-isolation reading (claim (29)), if given;
7. the reading: plain sentences derived from the numbers above.

:func:`analysis_report` is the whole report of a :class:`processing.analyzer.Analysis`: the run
and the model first, then the same sections, with the coherence dips explained
(:mod:`processing.coherence_model`) and the fits' systematic error on the bench in their places;
every section is built as lines and the report is their concatenation. :func:`analysis_summary`
is the plain text ``daq analyze`` prints.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from processing.compare import Comparison
from processing.modal import MIN_LINES_PER_BANDWIDTH, ModalFit
from processing.rotation import RotationReading
from processing.spectra import SpectralSettings

__all__ = ["report_markdown", "analysis_report", "analysis_summary"]


def _f(x, fmt=".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, fmt)


def _pm(x, s, fmt=".5g", sfmt=".2g") -> str:
    return f"{_f(x, fmt)} ± {_f(s, sfmt)}"


def _settings_section(settings: SpectralSettings | None, comparisons: Mapping) -> list[str]:
    out = ["## Analyzer settings", ""]
    if settings is not None:
        s = settings
        rec = s.nperseg / s.fs
        out += [
            f"- sample rate {s.fs:g} Hz, time record {s.nperseg} samples = {rec:g} s, "
            f"line spacing {s.resolution_hz * 1e3:.4g} mHz",
            f"- window {s.window} (ENBW {s.window_info.enbw_bins:.3g} lines), overlap "
            f"{s.overlap_fraction:.0%}, averaging {s.averaging}, detrend {s.detrend}",
        ]
    for name, c in comparisons.items():
        m = c.measured
        out.append(f"- {name}: {m.estimator.upper()} of {m.output!s}/{m.input!s} [{m.units}], "
                   f"{m.n_averages} averages, n_eff = {m.n_effective:.4g}")
        break
    out.append("")
    return out


def _coherence_section(comparisons: Mapping) -> list[str]:
    out = ["## Coherence", "",
           "| channel | band [Hz] | lines | median γ² | min γ² | lines with γ² ≥ 0.9 | "
           "γ² at the peaks |",
           "|---|---|---|---|---|---|---|"]
    for name, c in comparisons.items():
        g = c.measured.coherence
        ok = np.isfinite(g)
        peaks = ", ".join(f"{p.coherence:.3f} ({p.f_hz:.3g} Hz)" for p in c.peaks) or "–"
        out.append(f"| {name} | {c.freqs_hz[0]:.3g}–{c.freqs_hz[-1]:.3g} | {int(ok.sum())} | "
                   f"{np.median(g[ok]):.4f} | {np.min(g[ok]):.3g} | "
                   f"{np.mean(g[ok] >= 0.9):.0%} | {peaks} |")
    out += ["", "Near a mode narrower than a line the coherence drops even without noise: the "
            "ringing carried into each record from before it is not coherent with the record's "
            "input (leakage noise).", ""]
    return out


def _match(f_hz: float, exact: Sequence[tuple[float, float]]):
    if not exact:
        return None
    i = int(np.argmin([abs(f_hz - fe) for fe, _ in exact]))
    return exact[i]


def _fit_section(fits: Mapping[str, ModalFit], exact: Sequence[tuple[float, float]]) -> list[str]:
    out = ["## Modal fit", "",
           "Uncertainties are 1σ from the coherence-weighted least squares (Bendat–Piersol "
           "variances, window line correlation in a sandwich covariance, not scaled by χ²).", "",
           "| fit | f [Hz] | exact f [Hz] | (f−f₀)/σ | Q | exact Q | (Q−Q₀)/σ | "
           "lines per f/Q | status |",
           "|---|---|---|---|---|---|---|---|---|"]
    for name, fit in fits.items():
        for md in fit.modes:
            ex = _match(md.f_hz, exact)
            fe, qe = ex if ex else (math.nan, math.nan)
            zf = (md.f_hz - fe) / md.f_std_hz if md.f_std_hz > 0 else math.nan
            zq = (md.q - qe) / md.q_std if md.q_std > 0 else math.nan
            if not md.reliable:
                status = "**leakage-limited: Q biased low**"
            elif md.leakage_limited:
                status = "leakage-aware fit"
            else:
                status = "resolved"
            if not fit.adequate:
                status += f"; χ²/dof = {fit.reduced_chi2:.3g} (misfit)"
            out.append(f"| {name} | {_pm(md.f_hz, md.f_std_hz, '.6g')} | {_f(fe, '.6g')} | "
                       f"{_f(zf, '+.2f')} | {_pm(md.q, md.q_std, '.4g')} | {_f(qe, '.4g')} | "
                       f"{_f(zq, '+.2f')} | {md.lines_per_bw:.3g} | {status} |")
    out.append("")
    for name, fit in fits.items():
        out.append(f"- {name}: {fit.method} fit, domain {fit.domain}, {fit.n_lines} lines in "
                   f"{fit.band_hz[0]:g}–{fit.band_hz[1]:g} Hz, χ²/dof = {fit.reduced_chi2:.4g} "
                   f"(expected {_f(fit.expected_reduced_chi2, '.4g')} ± "
                   f"{math.sqrt(2.0 / fit.dof):.2g})")
        for note in fit.notes:
            out.append(f"  - {note}")
    out.append("")
    return out


def _peak_section(comparisons: Mapping) -> list[str]:
    out = ["## Leakage bias and random error at the peaks", "",
           "bias = E[H1] − H (the expected estimate for this window and record length minus the "
           "exact response), random = measured − E[H1]; σ is the predicted 1σ random error at "
           "that line.", "",
           "| channel | mode f [Hz] | Q | f/Q [mHz] | lines per f/Q | line [Hz] | exact [dB] | "
           "E[H1] [dB] | measured [dB] | bias [dB] | bias [deg] | σ [dB] | bias/σ | "
           "random/σ (gain, phase) | peak deficit [dB] |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, c in comparisons.items():
        for p in c.peaks:
            out.append(
                f"| {name} | {p.f_hz:.5g} | {p.q:.4g} | {p.half_power_bw_hz * 1e3:.3g} | "
                f"{p.lines_per_bw:.2g} | {p.line_hz:.4g} | {p.model_db:.2f} | "
                f"{_f(p.expected_db, '.2f')} | {p.measured_db:.2f} | {_f(p.bias_db, '+.2f')} | "
                f"{_f(p.bias_deg, '+.1f')} | {p.sigma_db:.2f} | {_f(p.bias_sigma, '.1f')} | "
                f"{_f(p.random_z_gain, '+.2f')}, {_f(p.random_z_phase, '+.2f')} | "
                f"{_f(p.peak_deficit_db, '+.2f')} |")
    out.append("")
    return out


def _band_section(comparisons: Mapping) -> list[str]:
    out = ["## Residual statistics", "",
           "z = residual / predicted σ (in-phase component for gain, quadrature for phase). "
           "\"total\" is measured against the exact model, \"random\" against E[H1]. For an "
           "unbiased estimate z is Student-t (ν = 2(n_d − 1)), so the expected fraction within "
           "kσ is below the normal value; its standard error includes the window's line "
           "correlation.", "",
           "| channel | band | lines | rms z gain / phase (total) | max |z| (total) | "
           "within kσ gain / phase (total) | within kσ (random) | expected | max bias/σ | "
           "median σ [dB] | median γ² |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, c in comparisons.items():
        for b in c.bands:
            if not b.n_lines:
                continue
            out.append(
                f"| {name} | {b.name} | {b.n_lines} | {b.rms_gain_total:.2f} / "
                f"{b.rms_phase_total:.2f} | {max(b.max_gain_total, b.max_phase_total):.2f} | "
                f"{b.frac_gain_total:.1%} / {b.frac_phase_total:.1%} | "
                f"{_f(b.frac_gain_random, '.1%')} / {_f(b.frac_phase_random, '.1%')} | "
                f"{b.expected_fraction:.1%} ± {b.fraction_se:.1%} (k = {b.k:g}) | "
                f"{_f(b.max_bias_sigma, '.2f')} | {b.median_sigma_db:.3g} | "
                f"{b.median_coherence:.4f} |")
    out.append("")
    return out


def _rotation_section(rot: RotationReading) -> list[str]:
    lo, hi = rot.band_hz
    out = ["## Rotation isolation |Θ₂/Θ₁| above f1 (claim (29))", "",
           f"- measured, mean over {lo:g}–{hi:g} Hz ({rot.freqs_hz.size} lines): "
           f"{_pm(rot.mean_db, rot.mean_std_db, '.2f', '.2f')} dB",
           f"- exact model over the same lines: {_f(rot.model_mean_db, '.2f')} dB",
           f"- high-frequency limit extrapolated from the measurement with the model's shape: "
           f"{_pm(rot.limit_db, rot.limit_std_db, '.2f', '.2f')} dB",
           f"- exact limit ν²(1−σ²)/(1−β²/σ²): {_f(rot.exact_limit_db, '.2f')} dB; "
           f"α = r2/r1: {_f(rot.alpha_db, '.2f')} dB", ""]
    return out


def _reading(comparisons: Mapping, fits: Mapping, exact, rot, settings) -> list[str]:
    out = ["## Reading", ""]
    df = None
    for c in comparisons.values():
        df = c.resolution_hz
        break
    # Away from resonances.
    for name, c in comparisons.items():
        b = c.bands[0]
        if not b.n_lines:
            continue
        ok = abs(b.frac_gain_total - b.expected_fraction) <= 4 * b.fraction_se \
            and abs(b.frac_phase_total - b.expected_fraction) <= 4 * b.fraction_se
        verdict = ("agrees with the exact model within its random error" if ok else
                   "does **not** agree with the exact model within its random error")
        out.append(f"- {name}, away from the resonances ({b.n_lines} lines): "
                   f"{b.frac_gain_total:.1%} of the gains and {b.frac_phase_total:.1%} of the "
                   f"phases lie within {b.k:g}σ (expected {b.expected_fraction:.1%} ± "
                   f"{b.fraction_se:.1%}); rms z = {b.rms_gain_total:.2f} / "
                   f"{b.rms_phase_total:.2f}: the measurement {verdict}.")
    # Peaks.
    for name, c in comparisons.items():
        for p in c.peaks:
            if not math.isfinite(p.bias_db):
                continue
            if p.leakage_limited:
                out.append(
                    f"- {name} at {p.f_hz:.4g} Hz: the half-power bandwidth f/Q = "
                    f"{p.half_power_bw_hz * 1e3:.3g} mHz is {p.lines_per_bw:.2g} lines "
                    f"(the analyzer wants ≥ {MIN_LINES_PER_BANDWIDTH:g}). Leakage biases the "
                    f"line at {p.line_hz:.4g} Hz by {p.bias_db:+.2f} dB and {p.bias_deg:+.1f}°, "
                    f"{p.bias_sigma:.1f}σ of the random error there; the measured value is "
                    f"{p.random_z_gain:+.2f}σ (gain), {p.random_z_phase:+.2f}σ (phase) from "
                    f"E[H1]. The peak reads {-p.peak_deficit_db:.2f} dB below the true "
                    f"{p.true_peak_db:.2f} dB on average: "
                    + ("a systematic deficit, not noise." if p.bias_sigma > 3 else
                       "within a few σ of the random error here."))
    # Q readings.
    for name, fit in fits.items():
        for md in fit.modes:
            ex = _match(md.f_hz, exact)
            if ex is None:
                continue
            fe, qe = ex
            z = (md.q - qe) / md.q_std if md.q_std > 0 else math.nan
            if not md.reliable:
                line = (f"{df * 1e3:.3g} mHz lines" if df else "these lines")
                out.append(
                    f"- {name}: Q at {md.f_hz:.4g} Hz cannot be measured with {line} by a direct "
                    f"curve fit (f/Q = {md.lines_per_bw:.2g} lines < "
                    f"{MIN_LINES_PER_BANDWIDTH:g}): the fitted Q = {md.q:.4g} ± {md.q_std:.2g} "
                    f"is leakage-limited, its ± ignores the leakage bias ({z:+.1f}σ from the "
                    f"exact Q = {qe:.4g}; χ²/dof = {fit.reduced_chi2:.3g}, expected "
                    f"{_f(fit.expected_reduced_chi2, '.3g')}).")
            else:
                how = "leakage-aware fit" if md.leakage_limited else "fit"
                out.append(
                    f"- {name}: the {how} gives Q = {md.q:.4g} ± {md.q_std:.2g} at f = "
                    f"{md.f_hz:.6g} ± {md.f_std_hz:.2g} Hz against the exact Q = {qe:.4g}, "
                    f"f = {fe:.6g} Hz ({z:+.2f}σ in Q).")
    if rot is not None and math.isfinite(rot.exact_limit_db):
        lo, hi = rot.band_hz
        out.append(
            f"- Rotation isolation: between {lo:g} and {hi:g} Hz |Θ₂/Θ₁| reads "
            f"{rot.mean_db:.2f} ± {rot.mean_std_db:.2f} dB (model {rot.model_mean_db:.2f} dB), "
            f"still {abs(rot.mean_db - rot.exact_limit_db):.1f} dB from its limit: the ratio "
            f"approaches its asymptote only well above 10 Hz. With the model's shape the data "
            f"extrapolate to {rot.limit_db:.2f} ± {rot.limit_std_db:.2f} dB, the exact limit "
            f"ν²(1−σ²)/(1−β²/σ²) = {rot.exact_limit_db:.2f} dB, which is not α = "
            f"{rot.alpha_db:.2f} dB: claim (29) is a near-coincidence of "
            f"{abs(rot.exact_limit_db - rot.alpha_db):.1f} dB, not an identity.")
    out.append("")
    return out


def report_markdown(comparisons: Mapping[str, Comparison], *,
                    fits: Mapping[str, ModalFit] | None = None,
                    exact_modes: Sequence[tuple[float, float]] = (),
                    settings: SpectralSettings | None = None,
                    rotation: RotationReading | None = None,
                    title: str = "Measured frequency responses against the exact model") -> str:
    """The Markdown report of a measurement.

    Parameters
    ----------
    comparisons : Mapping[label, Comparison]
        One per channel (e.g. ``{"H_t (x/a)": ..., "Theta_2 (y/a)": ...}``).
    fits : Mapping[label, ModalFit], optional
        Modal fits to tabulate (e.g. a direct and a leakage-aware fit of the same channel).
    exact_modes : sequence of (f_hz, Q)
        The scene's exact modes (``zip(*chain.modes())``); each fitted mode is matched to the
        nearest.
    settings : SpectralSettings, optional
    rotation : RotationReading, optional
    title : str

    Returns
    -------
    str : Markdown, sections "Analyzer settings", "Coherence", "Modal fit", "Leakage bias and
    random error at the peaks", "Residual statistics", "Rotation isolation ..." and "Reading".
    """
    exact = [(float(f), float(q)) for f, q in exact_modes]
    lines = [f"# {title}", ""]
    for _, section in _sections(comparisons, dict(fits or {}), exact, settings, rotation):
        lines += section
    return "\n".join(lines)


def _sections(comparisons, fits, exact, settings, rotation) -> list[tuple[str, list[str]]]:
    """The report's sections in order, as ``(key, lines)``; each section ends with a blank
    line."""
    out = [("settings", _settings_section(settings, comparisons)),
           ("coherence", _coherence_section(comparisons))]
    if exact:
        out.append(("exact", ["Exact modes of the model: " + ", ".join(
            f"f = {f:.6g} Hz, Q = {q:.4g} (f/Q = {f / q * 1e3:.3g} mHz)" for f, q in exact), ""]))
    if fits:
        out.append(("fit", _fit_section(fits, exact)))
    out.append(("peaks", _peak_section(comparisons)))
    out.append(("bands", _band_section(comparisons)))
    if rotation is not None:
        out.append(("rotation", _rotation_section(rotation)))
    out.append(("reading", _reading(comparisons, fits, exact, rotation, settings)))
    return out


# -- the analyzer's whole report and summary --------------------------------------------------

def _pct(x) -> str:
    return f"{100 * x:.1f} %"


def _settings_line(a) -> str:
    sp = a.spectral
    return (f"{sp.window} window, {sp.nperseg}-sample FFT ({sp.nperseg / sp.fs:g} s, "
            f"{sp.resolution_hz * 1e3:.4g} mHz lines), overlap {sp.overlap_fraction:.0%}, "
            f"{sp.averaging} averaging, {a.settings.estimator.upper()}: "
            f"{a.h_t.n_averages} averages (n_eff {a.h_t.n_effective:.3g})")


def _run_line(a) -> str:
    r = a.run
    state = "complete" if r.complete else f"INCOMPLETE, status {r.status}"
    return (f"{r.source}: {r.scene}, seed {r.seed}, {r.records} of {r.records_planned} records "
            f"x {r.record_s:g} s at {r.rate_hz:g} Hz ({state})")


def _model_line(a) -> str:
    where = ("from the run file (its grid is the FFT lines: exact, not interpolated)"
             if a.model.source == "file" else
             "recomputed exactly at the FFT lines (rig.bench.expected_response, sampled)")
    return (f"model: the whole sampled chain, accelerometer high-pass included "
            f"({_highpass_text(a)}), {where}")


def _highpass_text(a) -> str:
    """What the high-pass changes at fmin against the pendulum alone (nothing at 0 Hz, where
    the ratio is undefined)."""
    db, deg = a.highpass_at_fmin
    if not (math.isfinite(db) and math.isfinite(deg)):
        return (f"no correction at {a.settings.fmin_hz:g} Hz: the high-pass passes nothing "
                "there, so the ratio to the pendulum alone is undefined")
    return f"{db:+.2f} dB, {deg:+.1f} deg against the pendulum alone at {a.settings.fmin_hz:g} Hz"


def _fmt_mode(md, check, exact) -> str:
    txt = f"{md.f_hz:.5f} ± {md.f_std_hz:.1e} Hz, Q {md.q:.4g} ± {md.q_std:.2g}"
    if not md.reliable:
        txt += " (leakage-limited: Q biased low)"
    if check is not None and exact is not None:
        cm = min(check.modes, key=lambda m: abs(m.f_hz - exact[0]))
        txt += (f"; method offset on this bench {1e3 * (cm.f_hz - exact[0]):+.3f} mHz, "
                f"Q {cm.q - exact[1]:+.2f}")
    return txt


def analysis_summary(a) -> str:
    """A concise plain-text summary of an :class:`processing.analyzer.Analysis` (what ``daq
    analyze`` prints)."""
    out = [f"analysed {_run_line(a)}", f"analyzer: {_settings_line(a)}", _model_line(a)]
    if a.expected is not None:
        out.append(f"E[H1]: from the bench's exact correlations under its source (n_fft "
                   f"{a.expected.n_fft}, aliasing < {a.expected.alias_bound:.0e})")
    for n in a.notes:
        out.append(f"note: {n}")
    co = []
    for label, c in a.comparisons.items():
        g = c.measured.coherence
        j = int(np.nanargmin(g))
        co.append(f"{label.split()[0]} median {np.nanmedian(g):.4f}, min {g[j]:.3g} at "
                  f"{c.freqs_hz[j]:.4g} Hz")
    out.append(f"coherence {a.settings.fmin_hz:g}-{a.settings.fmax_hz:g} Hz: " + "; ".join(co))
    if a.coherence_dips:
        out.append("coherence dips predicted by the bench's model (expected gamma^2 with the "
                   "optical lever's second-order geometry, noise floors and leakage):")
        out += [f"  {d.text}" for d in a.coherence_dips]
    ok = []
    for label, c in a.comparisons.items():
        b = c.bands[0]
        ok.append(f"{label.split()[0]} {_pct(b.frac_gain_total)} / {_pct(b.frac_phase_total)} "
                  f"of {b.n_lines} lines")
        exp_txt = f"{_pct(b.expected_fraction)} ± {_pct(b.fraction_se)}"
    out.append(f"away from the peaks, gain / phase within {a.settings.k:g} sigma of the exact "
               f"model: {'; '.join(ok)} (expected {exp_txt})")
    out.append("peaks (line nearest each mode): exact | E[H1] | measured gain, bias = E[H1] vs "
               "exact")
    for label, c in a.comparisons.items():
        for p in c.peaks:
            bias = (f"bias {p.bias_db:+.2f} dB {p.bias_deg:+.1f} deg ({p.bias_sigma:.1f} sigma)"
                    if math.isfinite(p.bias_db) else "bias n/a")
            out.append(f"  {label.split()[0]:8s} {p.line_hz:.4g} Hz: {p.model_db:.2f} | "
                       f"{p.expected_db:.2f} | {p.measured_db:.2f} dB, {bias}, "
                       f"gamma^2 {p.coherence:.3f}")
    if a.fits:
        out.append("modes (fit ± 1 sigma; method offset = the same fit of the noiseless E[H1] "
                   "minus exact):")
    else:
        out.append("modes: not fitted (see the notes)")
    for i, (fe, qe) in enumerate(a.exact_modes):
        out.append(f"  mode {i + 1}: exact {fe:.5f} Hz, Q {qe:.1f}")
        for key, fit in a.fits.items():
            if not fit.modes:
                continue
            md = min(fit.modes, key=lambda m: abs(m.f_hz - fe))
            if abs(md.f_hz - fe) > 0.1 * fe:
                continue
            out.append(f"    {key:24s} {_fmt_mode(md, a.fit_checks.get(key), (fe, qe))}")
    rot = a.rotation
    if rot is not None:
        out.append(f"|Theta_2/Theta_1| {rot.band_hz[0]:g}-{rot.band_hz[1]:g} Hz: "
                   f"{rot.mean_db:.2f} ± {rot.mean_std_db:.2f} dB (model "
                   f"{rot.model_mean_db:.2f} dB); extrapolated limit {rot.limit_db:.2f} ± "
                   f"{rot.limit_std_db:.2f} dB (exact {rot.exact_limit_db:.2f} dB, alpha = r2/r1 "
                   f"{rot.alpha_db:.2f} dB)")
    return "\n".join(out)


def analysis_report(a) -> str:
    """The whole Markdown report of an :class:`processing.analyzer.Analysis`: the run and the
    model, then the sections of :func:`report_markdown`, with the coherence dips explained before
    the modal fit (at the end without one) and the fits' systematic error on this bench before
    the peaks."""
    r = a.run
    title = f"# Analysis of {Path(r.source).name}: {r.scene}, seed {r.seed}"
    head = ["", "## Run", "", f"- {_run_line(a)}"]
    if any(r.clipped.values()):
        head.append("- clipped samples: " + ", ".join(f"{c} {v}" for c, v in r.clipped.items()))
    else:
        head.append("- no clipped samples")
    head += [f"- {n}" for n in a.notes]
    head += ["", "## Model", "",
             "H_t = W_ax/W_aa and Θ₂ = W_ay/W_aa are compared with the exact response of the "
             "*whole* sampled chain (rig.bench.expected_response, sampled=True): the "
             "accelerometer's high-pass is in the denominator of both "
             f"({_highpass_text(a)}); the anti-alias filter, common to all channels, cancels.",
             ""]
    if a.model.source == "file":
        head.append("- model values: the run file's, whose grid (k / record length) is the "
                    "analyzer's lines: exact, no interpolation.")
    else:
        head.append("- model values: recomputed exactly at the analyzer's lines (they are not on "
                    "the run file's grid; interpolating a 4.7 mHz wide mode would misplace its "
                    "peak).")
    e = a.expected
    if e is not None:
        notch = ", ".join(f"{v:+.1f} dB at {f:.4g} Hz" for f, v in e.input_notch_db.items())
        head.append(
            "- E[H1], the expected estimate for this window and record length, comes from the "
            "bench's exact auto and cross correlations under its source (input PSD, stage with "
            "the pendulum's reaction, accelerometer noise, ADC quantisation), tapered by the "
            f"window's autocorrelation (n_fft = {e.n_fft}, time aliasing < "
            f"{e.alias_bound:.0e}). The input is not white: relative to its median over the "
            f"display band the stage acceleration's PSD is {notch}, the notches the pendulum's "
            "reaction digs into the stage motion at its own modes. A white-input E[H1] would "
            "misstate the bias at the peaks.")
    head.append("")
    exact = [(float(f), float(q)) for f, q in a.exact_modes]
    sections = _sections(dict(a.comparisons), dict(a.fits), exact, a.spectral, a.rotation)
    keys = [k for k, _ in sections]
    if a.coherence_budget is not None:
        at = keys.index("fit") if "fit" in keys else len(sections)
        sections.insert(at, ("dips", _dips_section(a)))
        keys.insert(at, "dips")
    if a.fit_checks:
        sections.insert(keys.index("peaks"), ("checks", _checks_section(a)))
    lines = [title, *head]
    for _, section in sections:
        lines += section
    return "\n".join(lines)


def _dips_section(a) -> list[str]:
    """The report's "Coherence dips explained" section (processing.coherence_model)."""
    b = a.coherence_budget
    out = ["## Coherence dips explained", "",
           "The expected coherence comes from the bench's exact spectra tapered by the window "
           "(as E[H1]) with every mechanism that lowers it: the optical lever's second-order "
           f"geometry (calibrated x reads dx - {b.coefficients['x']:.4g} m/rad² θ², y reads "
           f"θ - {b.coefficients['y']:.4g} /m dx θ: products of Gaussian signals, uncorrelated "
           "with the input, at the sums and doubles of the frequencies in the motion), the "
           "accelerometer's and the PSD's noise floors, ADC quantisation and leakage, plus the "
           f"estimator's own bias (1 - γ²)²/n_d for n_d = {b.n_averages:g}. Each dip's causes "
           "are the shares of the lost coherence that each mechanism alone removes.", ""]
    if not a.coherence_dips:
        out.append(f"- no dip deeper than 1 - γ² = 0.05 is predicted over "
                   f"{a.settings.fmin_hz:g}-{a.settings.fmax_hz:g} Hz.")
    out += [f"- {d.text}" for d in a.coherence_dips]
    return out + [""]


def _input_text(a) -> str:
    for fit in a.fits.values():
        if fit.method == "leakage":
            sp = fit.input_spectrum
            return "a white input" if sp is None else sp.label
    return "a white input"


def _checks_section(a) -> list[str]:
    lines = ["## Systematic error of the modal fits on this bench", "",
             "Each fit is repeated on the noiseless E[H1] with the same lines and weights; the "
             "difference from the exact mode is the method's own error on this bench (the "
             f"leakage-aware model takes {_input_text(a)}; the direct one ignores leakage). It "
             "is reported, not subtracted. The fits use the pendulum's own response: the "
             "measured ratio times the accelerometer's known high-pass, whose pole at 0 Hz the "
             "modal model cannot represent.", "",
             "| fit | exact f [Hz] | f of E[H1] fit − exact [mHz] | in σ of the fit | exact Q | "
             "Q of E[H1] fit − exact | in σ of the fit |",
             "|---|---|---|---|---|---|---|"]
    for key, check in a.fit_checks.items():
        fit = a.fits[key]
        for md in fit.modes:
            fe, qe = min(a.exact_modes, key=lambda m: abs(m[0] - md.f_hz))
            cm = min(check.modes, key=lambda m: abs(m.f_hz - fe))
            df, dq = cm.f_hz - fe, cm.q - qe
            zf = df / md.f_std_hz if md.f_std_hz > 0 else math.nan
            zq = dq / md.q_std if md.q_std > 0 else math.nan
            lines.append(f"| {key} | {fe:.6g} | {1e3 * df:+.4f} | {zf:+.3f} | {qe:.1f} | "
                         f"{dq:+.2f} | {zq:+.3f} |")
    lines.append("")
    return lines
