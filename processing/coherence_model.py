"""Expected coherence of H_t and Theta_2, with every mechanism that lowers it, and the dips named.

Why the coherence dips (SPEC sections 1, 5, 6)
----------------------------------------------
The analyzer's coherence of (a, x) is ``gamma^2 = |G_ax|^2 / (G_aa G_xx)``: one minus the share of
the output's (or input's) power not linearly related to the input. On this bench four mechanisms
lower it, each computable from the bench's exact linear model:

1. **The optical lever's second-order geometry.** The spot position is not linear in the mirror's
   motion (:mod:`rig.devices.optical_lever`, exact ``u = 2 sin(phi) (dx + dz tan theta) - s sin(2 phi) sin^2
   theta``, ``v = s cos(phi) sin(2 theta)`` with ``s = D - dx cos(2 phi)/cos(phi) + O(theta^2)``).
   To second order the calibrated channels read

       x = dx - D cos(phi) theta^2,      y = theta - cos(2 phi) / (D cos(phi)) dx theta

   (``dx`` the mirror's translation relative to the stage, ``theta`` the mirror body's angle;
   ``dx`` is odd in the angles, ``dz tan theta`` third order). For Gaussian motion the quadratic
   terms are uncorrelated with the stage acceleration (third moments vanish): they bias neither
   H_t nor Theta_2 but add power, at the sums and differences of the frequencies present. By
   Isserlis' theorem their autocorrelations are ``R_{theta^2}(tau) = 2 R_tt(tau)^2`` and
   ``R_{dx theta}(tau) = R_dd(tau) R_tt(tau) + R_dt(tau) R_dt(-tau)``: theta^2 peaks at 2 f2
   (1.65 Hz), f1 + f2 (3.31 Hz) and 2 f1, and dx theta (dx peaks at f1, theta at f2 and f1) at
   f1 + f2 and 2 f1 -- the dips of H_t at 1.65 Hz and of Theta_2 at 3.31 Hz.
2. **The accelerometer's noise floor under the input's notch**: the pendulum's reaction digs a
   notch into the stage acceleration at the 2.48 Hz mode (about 16 dB), where the white
   accelerometer noise becomes a visible share of ``G_aa`` (both channels dip).
3. **The PSD's noise floor** where a response is small: Theta_2 near its anti-resonance
   (4.66 Hz).
4. **Resolution (leakage) bias**: a mode narrower than the line spacing is not resolved by the
   time record; the window's expectation of ``G_ax``, ``G_aa``, ``G_xx`` then no longer factorises
   (the dips at the 0.83 Hz and 2.48 Hz modes).

:func:`coherence_budget` computes the expected periodogram of every term exactly as ``E[H1]``
does (the window-tapered correlation functions of the bench's spectra, one FFT length
``n_fft``), the expected coherence ``|E G_ax|^2 / (E G_aa E G_xx)`` plus the estimator's own bias
for ``n_d`` averages, ``(1 - gamma^2)^2 / n_d`` (first order, Carter 1973), and the same with
each mechanism left out, which says how much of each dip each causes. :func:`named_dips` turns
that into the dips a reader should be told about.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MECHANISMS = ("geometry", "accelerometer noise", "PSD noise", "leakage")
#: A predicted dip is named when it loses at least this much coherence (1 - gamma^2) [1].
DIP_DEPTH = 0.05


@dataclass(frozen=True, eq=False)
class CoherenceBudget:
    """Expected coherence at the analyzer's lines and what each mechanism costs.

    Attributes
    ----------
    freqs_hz : (nf,) [Hz].
    expected : {"x", "y": (nf,) expected gamma^2 of (a, x), (a, y) with everything}.
    without : {"x", "y": {mechanism: (nf,) expected gamma^2 with that mechanism left out}};
        for "leakage": every noise and the geometry left out (what the window alone gives).
    geometry_fraction : {"x", "y": (nf,) share of the channel's expected power that is the
        optical lever's second-order term [1]}.
    coefficients : {"x": D cos(phi) [m/rad^2], "y": cos(2 phi)/(D cos(phi)) [1/m]}.
    n_averages : n_d used for the estimator's bias.
    """

    freqs_hz: np.ndarray
    expected: dict
    without: dict
    geometry_fraction: dict
    coefficients: dict
    n_averages: float


def lever_quadratic_coefficients(lever) -> dict[str, float]:
    """The optical lever's second-order terms (module docstring, mechanism 1) as coefficients:
    the calibrated channels read ``x = dx - c_x theta^2`` and ``y = theta - c_y dx theta``,
    ``c_x = D cos(phi)`` [m/rad^2], ``c_y = cos(2 phi) / (D cos(phi))`` [1/m]."""
    phi, dist = lever.phi_rad, lever.distance_m
    return {"x": dist * math.cos(phi), "y": math.cos(2 * phi) / (dist * math.cos(phi))}


def quadratic_spectra(f_hz, fs: float, n_fft: int, g_tt, g_dd, g_dt) -> tuple:
    """One-sided PSDs of ``theta^2`` [rad^4/Hz] and ``dx theta`` [m^2 rad^2/Hz] (means removed)
    of zero-mean jointly Gaussian ``dx``, ``theta`` with one-sided spectra ``g_tt``, ``g_dd`` and
    cross spectrum ``g_dt`` (``<DX conj(THETA)>``) on the grid ``f_hz = k fs / n_fft``,
    ``k = 0 .. n_fft/2`` (Isserlis; module docstring)."""
    def corr(g):  # R[m] = int_0^inf G(f) e^{2 pi i f m / fs} df, real
        return 0.5 * fs * np.fft.irfft(np.asarray(g, complex), n=n_fft)

    r_tt, r_dd, r_dt = corr(g_tt), corr(g_dd), corr(g_dt)
    r_td = np.roll(r_dt[::-1], 1)  # R_dt(-m)
    def spectrum(r):
        return (2.0 / fs) * np.fft.rfft(r).real[: np.asarray(f_hz).size]

    return spectrum(2.0 * r_tt * r_tt), spectrum(r_dd * r_tt + r_dt * r_td)


def coherence_budget(header, settings, bench, *, n_fft: int, n_averages: float) -> CoherenceBudget:
    """The expected coherences of the run's bench under ``settings`` (a
    :class:`processing.spectra.SpectralSettings`) on the FFT length ``n_fft`` of the correlation
    functions; ``bench`` evaluates the exact sampled responses per source volt
    (:class:`rig.bench.SampledResponse`). Stationary noise sources only (as
    ``E[H1]``)."""
    from processing.leakage import expected_h1_taps

    scene, plan = header.scene, header.plan
    fs = plan.rate_hz
    source, acc, lever = scene.source, scene.accelerometer, scene.lever
    vpu = {c: header.channel(c).volts_per_unit for c in ("a", "x", "y")}
    quant = {c: (header.channel(c).adc.lsb_v / vpu[c]) ** 2 / (6.0 * fs) for c in vpu}
    noise = {"a": (acc.sensitivity_vpmps2 * acc.noise_mps2_rthz / vpu["a"]) ** 2,
             "x": (lever.gain_vpm * lever.noise_m_rthz / vpu["x"]) ** 2,
             "y": (lever.gain_vpm * lever.noise_m_rthz / vpu["y"]) ** 2}
    coef = lever_quadratic_coefficients(lever)

    f = np.arange(n_fft // 2 + 1) * (fs / n_fft)
    s_v = source.design_psd(f)
    band = s_v > 0
    resp = {k: np.zeros(f.size, complex) for k in ("a", "x", "y", "dx", "theta")}
    r = bench(f[band])
    for c in ("a", "x", "y"):
        resp[c][band] = getattr(r, c) / vpu[c]
    resp["dx"][band], resp["theta"][band] = r.mirror_x, r.mirror_rot
    f2 = np.abs(header.antialias.response(f)) ** 2
    q_tt, q_dt = quadratic_spectra(f, fs, n_fft, s_v * np.abs(resp["theta"]) ** 2,
                                   s_v * np.abs(resp["dx"]) ** 2,
                                   s_v * resp["dx"] * np.conj(resp["theta"]))
    geo = {"x": coef["x"] ** 2 * q_tt, "y": coef["y"] ** 2 * q_dt}
    n = settings.nperseg

    def tapered(s):
        rr = np.fft.irfft(np.asarray(s, complex), n=n_fft)
        taps = np.concatenate([rr[-(n - 1):], rr[:n]]) if n > 1 else rr[:1]
        return expected_h1_taps(taps, settings, lag0=-(n - 1))

    # E[G] is linear in the spectrum: taper each part once, add the parts per variant.
    t_f2, t_one = tapered(f2).real, tapered(np.ones(f.size)).real
    t_a = tapered(s_v * np.abs(resp["a"]) ** 2 * f2).real

    def gamma2(out: str, parts: dict, *, geometry=True, accel=True, psd=True,
               quantisation=True):
        g_aa = t_a + (noise["a"] * t_f2 if accel else 0.0) + (quant["a"] * t_one if quantisation
                                                               else 0.0)
        g_oo = (parts["lin"] + (parts["geo"] if geometry else 0.0)
                + (noise[out] * t_f2 if psd else 0.0) + (quant[out] * t_one if quantisation
                                                         else 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.abs(parts["cross"]) ** 2 / (g_aa * g_oo)
        g = np.clip(g, 0.0, 1.0)
        return g + (1.0 - g) ** 2 / n_averages, g_oo

    expected, without, frac = {}, {}, {}
    for out in ("x", "y"):
        parts = {"lin": tapered(s_v * np.abs(resp[out]) ** 2 * f2).real,
                 "geo": tapered(geo[out] * f2).real,
                 "cross": tapered(s_v * np.conj(resp["a"]) * resp[out] * f2)}
        expected[out], g_oo = gamma2(out, parts)
        without[out] = {
            "geometry": gamma2(out, parts, geometry=False)[0],
            "accelerometer noise": gamma2(out, parts, accel=False)[0],
            "PSD noise": gamma2(out, parts, psd=False)[0],
            "leakage": gamma2(out, parts, geometry=False, accel=False, psd=False,
                              quantisation=False)[0],
        }
        with np.errstate(divide="ignore", invalid="ignore"):
            frac[out] = np.where(g_oo > 0, parts["geo"] / g_oo, 0.0)
    return CoherenceBudget(settings.freqs_hz, expected, without, frac, coef, float(n_averages))


@dataclass(frozen=True)
class Dip:
    """A predicted coherence dip: channel ("x" for H_t, "y" for Theta_2), line frequency [Hz],
    expected and measured gamma^2 at that line, the mechanisms causing it with their share of
    the lost coherence (largest first), and a sentence naming it."""

    channel: str
    frequency_hz: float
    expected: float
    measured: float
    causes: tuple
    text: str


def _combination(f: float, modes: list[float], tol: float) -> str:
    """The doubles, sums and differences of the mode frequencies within ``tol`` of ``f``,
    nearest first ("2 f 0.827 = 1.654 Hz or 2.478 - 0.827 = 1.651 Hz")."""
    found = []
    for i, fi in enumerate(modes):
        for j, fj in enumerate(modes):
            if j < i:
                continue
            cands = [(fi + fj, f"2 x {fi:.4g}" if i == j else f"{fi:.4g} + {fj:.4g}")]
            if j > i:
                cands.append((fj - fi, f"{fj:.4g} - {fi:.4g}"))
            found += [(abs(v - f), f"{name} = {v:.4g} Hz") for v, name in cands
                      if abs(v - f) <= tol]
    return " or ".join(t for _, t in sorted(found))


def named_dips(budget: CoherenceBudget, measured: dict, *, modes_hz, antiresonances_hz: dict,
               input_notch_db: dict, fmin_hz: float, fmax_hz: float,
               depth: float = DIP_DEPTH) -> list[Dip]:
    """The predicted dips (local minima of the expected gamma^2 losing >= ``depth``) over the
    band, each with the measured gamma^2 at its line (``measured[channel]``, on the same lines)
    and its mechanisms: a mechanism's share is the coherence it alone removes (gamma^2 without it
    minus with everything); leakage's is ``1 - gamma^2`` of the window alone."""
    f = budget.freqs_hz
    df = float(f[1] - f[0]) if f.size > 1 else 1.0
    modes = sorted(float(m) for m in modes_hz)
    out = []
    for ch in ("x", "y"):
        g = budget.expected[ch]
        ok = (f >= fmin_hz) & (f <= fmax_hz) & np.isfinite(g)
        idx = np.nonzero(ok)[0]
        for k in idx[1:-1]:
            if not (g[k] <= g[k - 1] and g[k] < g[k + 1] and 1.0 - g[k] >= depth):
                continue
            lost = 1.0 - g[k]
            shares = {m: max(0.0, float(budget.without[ch][m][k] - g[k]))
                      for m in MECHANISMS[:-1]}
            shares["leakage"] = max(0.0, 1.0 - float(budget.without[ch]["leakage"][k]))
            total = sum(shares.values()) or 1.0
            causes = tuple(sorted(((m, v / total) for m, v in shares.items() if v / total >= 0.2),
                                  key=lambda mv: -mv[1]))
            words = []
            for m, share in causes:
                if m == "geometry":
                    comb = _combination(float(f[k]), modes, max(6 * df, 0.06))
                    term = ("-D cos(phi) theta^2" if ch == "x"
                            else "-cos(2 phi)/(D cos(phi)) dx theta")
                    words.append(f"the optical lever's second-order geometry ({term}"
                                 f"{', at ' + comb if comb else ''})")
                elif m == "accelerometer noise":
                    near = min(modes, key=lambda m_: abs(m_ - f[k])) if modes else None
                    notch = input_notch_db.get(near) if near is not None else None
                    words.append("the accelerometer's noise floor" + (
                        f" under the stage acceleration's notch at the {near:.3g} Hz mode "
                        f"({notch:+.0f} dB)" if notch is not None and abs(near - f[k]) < 3 * df
                        else ""))
                elif m == "PSD noise":
                    anti = [a for a in antiresonances_hz.get(ch, ()) if abs(a - f[k]) < 0.5]
                    words.append("the PSD's noise floor" + (
                        f" near the anti-resonance at {anti[0]:.3g} Hz" if anti else ""))
                else:
                    feats = [(abs(m_ - f[k]), f"the {m_:.3g} Hz mode") for m_ in modes]
                    feats += [(abs(a_ - f[k]), f"the anti-resonance at {a_:.3g} Hz")
                              for a_ in antiresonances_hz.get(ch, ())]
                    near = min(feats)[1] if feats else "the peak"
                    words.append(f"leakage: the time record does not resolve {near}")
                words[-1] += f" ({share:.0%})"
            meas = measured[ch][k]
            name = "H_t" if ch == "x" else "Theta_2"
            text = (f"{name} at {f[k]:.3f} Hz: expected gamma^2 = {g[k]:.3f}, measured "
                    f"{meas:.3f}; " + ", ".join(words))
            out.append(Dip(ch, float(f[k]), float(g[k]), float(meas), causes, text))
    return out
