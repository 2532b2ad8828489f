"""The stepped-sine analysis of one point: a tracking synchronous DFT over whole cycles.

Each point's window (``N`` output samples after the settle time, holding ``K`` whole cycles of
the drive, :mod:`rig.devices.stepped_sine`) is transformed at the drive's own phase: for
harmonic ``k`` of channel c, ``Y_ck = (2 / N) sum_j y_c[j] e^{-i 2 pi k phi_j}`` [V], with
``phi_j`` the source's phase at sample j (the phase the DAC used). Over whole cycles the
exponentials are orthogonal, so DC and the other harmonics do not leak into ``Y_ck``.

- the responses: ``H_t = (Y_x1 / cal_x) / (Y_a1 / cal_a)`` [m/(m/s^2)], ``Theta_2 = (Y_y1 /
  cal_y) / (Y_a1 / cal_a)`` [rad/(m/s^2)] (calibrations and sensor signs undone, SPEC 5);
- their random error: the residual after DC and harmonics 1..H has variance ``s_c^2`` (``N - 2H
  - 1`` degrees of freedom), so each part of ``Y_c1`` has the standard deviation ``s_c sqrt(2 /
  N)``, and the ratio's relative error (1 sigma, in gain and, in radians, in phase) is
  ``sqrt(sum_c (s_c sqrt(2/N) / |Y_c1|)^2)`` over its two channels (the residual also holds
  what is left of the step's transient and harmonics above H: conservative after a short
  settle);
- the fundamental's share of the window's power per channel (the coherence-like ratio),
  ``|Y_c1|^2 / 2`` over the window's variance;
- the truth beside it (:func:`rig.bench.sine.settling_bias`): the exact steady state and the
  estimate the exact linear chain gives with the step's transient (the settling bias), and the
  optical lever's second-order prediction of the 2f components (x: ``-coef_x Theta^2 / 2``, y:
  ``-coef_y X Theta / 2`` for the mirror's phasors X, Theta at f:
  :func:`processing.coherence_model.lever_quadratic_coefficients`), through the filter at 2f.

Harmonics at or above half the output rate are not measured (NaN).

Public API: :class:`SinePointResult`, :func:`analyze_point`, :func:`point_result` (shared
with the swept analysis, :mod:`processing.swept_sine`), :func:`tracking_fit`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from processing.coherence_model import lever_quadratic_coefficients

DB = 20.0 / math.log(10.0)


@dataclass(frozen=True, eq=False)
class SinePointResult:
    """One analysed point (complex responses in engineering units; see the module docstring).

    Attributes
    ----------
    frequency_hz, level_vrms, settle_s, integrate_s, cycles, t0_s : the point.
    h_t, theta_2 : measured complex responses; h_t_exact, theta_2_exact : the exact steady
        state; h_t_bias, theta_2_bias : the exact settling bias (estimate of the noiseless
        linear chain minus the steady state).
    rel_error : {"h_t", "theta_2"}: relative random error (1 sigma) [1].
    harmonics : (3, H) complex amplitudes of a, x, y at k f, k = 1..H, engineering units.
    fundamental_ratio : (3,) fundamental's share of each channel's window power [1].
    lever_2f : (2,) predicted 2f components of x [m] and y [rad] (optical lever geometry).
    clipped, saturated : (3,) samples clipped / saturated in the point.
    settle_bound : (3,) the settle rule's modal bound at the window's start, relative [1].
    coef_sd : (3,) standard deviation of each part (real, imaginary) of any harmonic's
        coefficient of a, x, y from the noise, engineering units.
    """

    frequency_hz: float
    level_vrms: float
    settle_s: float
    integrate_s: float
    cycles: int
    t0_s: float
    h_t: complex
    theta_2: complex
    h_t_exact: complex
    theta_2_exact: complex
    h_t_bias: complex
    theta_2_bias: complex
    rel_error: dict
    harmonics: np.ndarray
    fundamental_ratio: np.ndarray
    lever_2f: np.ndarray
    clipped: np.ndarray
    saturated: np.ndarray
    settle_bound: np.ndarray
    coef_sd: np.ndarray

    def gain_phase_error(self, name: str) -> tuple[float, float]:
        """``(dB, deg)`` of the measured ``name`` ("h_t" or "theta_2") against the exact steady
        state: ``20 log10 |H / H_exact|`` and the angle of ``H / H_exact``."""
        r = getattr(self, name) / getattr(self, f"{name}_exact")
        return DB * math.log(abs(r)), math.degrees(math.atan2(r.imag, r.real))

    def bias_db_deg(self, name: str) -> tuple[float, float]:
        """The settling bias as ``(dB, deg)``: the noiseless estimate against the steady state."""
        ex = getattr(self, f"{name}_exact")
        r = (ex + getattr(self, f"{name}_bias")) / ex
        return DB * math.log(abs(r)), math.degrees(math.atan2(r.imag, r.real))

    def error_db_deg(self, name: str) -> tuple[float, float]:
        """The random error (1 sigma) as ``(dB, deg)``."""
        e = self.rel_error[name]
        return DB * e, math.degrees(e)


def synchronous_dft(y: np.ndarray, phase_cycles: np.ndarray, harmonics: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(Y, residual variance)``: ``Y[c, k-1] = (2/N) sum_j y[c, j] e^{-i 2 pi k phi_j}`` for
    k = 1..harmonics over the rows of ``y`` (channels, N), and the variance of each row's
    residual after its mean and those harmonics (``N - 2 H - 1`` degrees of freedom)."""
    y = np.asarray(y, float)
    n = y.shape[1]
    k = np.arange(1, harmonics + 1)
    basis = np.exp(-2j * np.pi * np.outer(phase_cycles, k))  # (N, H)
    coef = (2.0 / n) * (y @ basis)
    fit = y.mean(axis=1, keepdims=True) + (coef @ basis.conj().T).real
    dof = max(n - 2 * harmonics - 1, 1)
    var = np.sum((y - fit) ** 2, axis=1) / dof
    return coef, var


def analyze_point(record, truth, chain, lever, harmonics: int = 5) -> SinePointResult:
    """Analyse a :class:`daq.sine.PointRecord` with its exact :class:`rig.bench.sine.PointTruth`
    (module docstring); ``chain`` the :class:`rig.bench.sine.SineChain`, ``lever`` the scene's
    optical lever."""
    p = record.point
    n, s = p.integrate_samples, p.settle_samples
    fs, q = chain.fs_hz, chain.q
    rate = fs / q
    phase_w = record.phase_cycles + p.frequency_hz * q * s / fs
    phases = phase_w + p.cycles * np.arange(n) / n
    y = record.volts[:, s:s + n]
    coef, var = synchronous_dft(y, phases, harmonics)
    return point_result(
        coef, var, np.var(y, axis=1), n, truth.steady_v, truth.steady_v + truth.transient_v,
        chain, lever, frequency_hz=p.frequency_hz, level_vrms=p.level_vrms, settle_s=s / rate,
        integrate_s=n / rate, cycles=p.cycles, t0_s=record.t0_s,
        clipped=np.array([record.clipped[c] for c in ("a", "x", "y")]),
        saturated=np.array([record.saturated.get(c, 0) for c in ("a", "x", "y")]),
        settle_bound=np.asarray(truth.settle_bound))


def point_result(coef, var, ac_power, n, steady_v, noiseless_v, chain, lever, *, frequency_hz,
                 level_vrms, settle_s, integrate_s, cycles, t0_s, clipped, saturated,
                 settle_bound) -> SinePointResult:
    """A :class:`SinePointResult` from a window's coefficients [V] ``coef`` (3, H) of a, x, y,
    the residual variances ``var`` (3,) [V^2], the window's variances ``ac_power`` (3,) and
    length ``n`` (output samples), the exact steady coefficients ``steady_v`` (3,) and those of
    the noiseless linear chain's estimate ``noiseless_v`` (3,) (their difference is the stated
    bias), with the point's description (module docstring; the stepped and the swept
    analysis share it)."""
    rate = chain.fs_hz / chain.q
    harmonics = coef.shape[1]
    vpu = chain.volts_per_unit
    eu = coef / vpu[:, None]
    nyq = np.arange(1, harmonics + 1) * frequency_hz >= rate / 2
    eu[:, nyq] = np.nan
    ratio = (np.abs(coef[:, 0]) ** 2 / 2) / np.maximum(ac_power, 1e-300)
    sd = np.sqrt(var * 2.0 / n)
    rel = sd / np.maximum(np.abs(coef[:, 0]), 1e-300)
    steady = steady_v / vpu
    noiseless = noiseless_v / vpu
    h = eu[1:, 0] / eu[0, 0]
    ex = steady[1:] / steady[0]
    biased = noiseless[1:] / noiseless[0]
    # the lever's 2f: the mirror's phasors at f (the filter's response at f undone) through the
    # filter at 2f
    from rig.bench.sine import filter_response

    g1, g2 = filter_response(chain, frequency_hz), filter_response(chain, 2 * frequency_hz)
    dx, th = steady[1] / g1, steady[2] / g1
    cf = lever_quadratic_coefficients(lever)
    lever_2f = np.array([-cf["x"] * th * th / 2, -cf["y"] * dx * th / 2]) * g2
    if 2 * frequency_hz >= rate / 2:
        lever_2f[:] = np.nan
    return SinePointResult(
        frequency_hz=float(frequency_hz), level_vrms=float(level_vrms), settle_s=float(settle_s),
        integrate_s=float(integrate_s), cycles=int(cycles), t0_s=float(t0_s),
        h_t=complex(h[0]), theta_2=complex(h[1]), h_t_exact=complex(ex[0]),
        theta_2_exact=complex(ex[1]), h_t_bias=complex(biased[0] - ex[0]),
        theta_2_bias=complex(biased[1] - ex[1]),
        rel_error={"h_t": float(math.hypot(rel[0], rel[1])),
                   "theta_2": float(math.hypot(rel[0], rel[2]))},
        harmonics=eu, fundamental_ratio=ratio, lever_2f=lever_2f, clipped=np.asarray(clipped),
        saturated=np.asarray(saturated), settle_bound=np.asarray(settle_bound),
        coef_sd=sd / np.abs(vpu))


def tracking_fit(y: np.ndarray, phase_cycles: np.ndarray, harmonics: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(Y, residual variance)`` as :func:`synchronous_dft` for a phase that need not run
    uniformly (a swept source): the least-squares fit of ``mean + sum_k Re(Y_k e^{i 2 pi k
    phi_j})``, k = 1..harmonics, to each row of ``y`` (channels, N). Over whole cycles of a
    uniform phase the basis is orthogonal and the fit is the synchronous DFT; harmonics whose
    basis cannot be fitted (fewer than two samples per period) are NaN."""
    y = np.asarray(y, float)
    n = y.shape[1]
    phi = np.asarray(phase_cycles, float)
    ref = math.floor(phi[n // 2])
    d = phi - ref  # small numbers: the basis keeps its precision
    k = np.arange(1, harmonics + 1)
    step = np.max(np.diff(phi)) if n > 1 else 1.0
    fit_k = k[k * step < 0.5]
    cols = [np.ones(n)]
    for kk in fit_k:
        cols += [np.cos(2 * np.pi * kk * d), -np.sin(2 * np.pi * kk * d)]
    basis = np.stack(cols, axis=1)
    sol, *_ = np.linalg.lstsq(basis, y.T, rcond=None)
    resid = y.T - basis @ sol
    dof = max(n - basis.shape[1], 1)
    var = np.sum(resid ** 2, axis=0) / dof
    coef = np.full((y.shape[0], harmonics), np.nan + 0j)
    for i, kk in enumerate(fit_k):
        coef[:, kk - 1] = sol[1 + 2 * i] + 1j * sol[2 + 2 * i]
    return coef, var


_RESP_UNITS = {"h_t": "m/(m/s^2)", "theta_2": "rad/(m/s^2)"}
_EU = {"a": "m/s^2", "x": "m", "y": "rad"}


def _point_columns() -> dict:
    """name -> (unit, long_name, per harmonic) of a point's row (:func:`point_row`)."""
    cols = {"frequency": ("Hz", "drive frequency (whole cycles in the window)", False),
            "level_vrms": ("V", "source level (rms)", False),
            "settle_s": ("s", "settle time before the window (simulated)", False),
            "integrate_s": ("s", "integration window (simulated)", False),
            "cycles": ("1", "whole cycles in the window", False),
            "t0_s": ("s", "start of the point from the sweep's start", False)}
    for r, unit in _RESP_UNITS.items():
        for kind, what in (("", "measured"), ("_exact", "exact steady state"),
                           ("_bias", "exact settling bias (noiseless estimate - steady)")):
            for part in ("real", "imag"):
                cols[f"{r}{kind}_{part}"] = (unit, f"{r} {what}, {part} part", False)
        cols[f"{r}_gain_db"] = ("dB", f"measured {r} gain 20 log10|H| re 1 {unit}", False)
        cols[f"{r}_phase_deg"] = ("degree", f"measured {r} phase, wrapped", False)
        cols[f"{r}_rel_error"] = ("1", f"relative random error of {r} (1 sigma)", False)
    for c, unit in _EU.items():
        for part in ("real", "imag"):
            cols[f"harmonic_{c}_{part}"] = (unit, f"channel {c} at k f, {part} part "
                                                  "(NaN at or above Nyquist)", True)
        cols[f"fundamental_ratio_{c}"] = ("1", f"fundamental's share of channel {c}'s window "
                                                "power", False)
        cols[f"clipped_{c}"] = ("1", f"samples of channel {c} the ADC clipped", False)
        cols[f"saturated_{c}"] = ("1", f"samples channel {c}'s sensor was over range", False)
        cols[f"settle_bound_{c}"] = ("1", f"settle rule's transient bound of {c} at the "
                                          "window's start, relative", False)
    for c in ("x", "y"):
        for part in ("real", "imag"):
            cols[f"lever_2f_{c}_{part}"] = (_EU[c], f"optical lever's predicted 2f component "
                                                    f"of {c}, {part} part", False)
    return cols


#: the columns of a point's row: name -> (unit, long_name, per harmonic)
POINT_COLUMNS = _point_columns()


def point_row(res: SinePointResult) -> dict:
    """A point as ``{column: value}`` for :data:`POINT_COLUMNS` (files, CSV)."""
    row = {"frequency": res.frequency_hz, "level_vrms": res.level_vrms,
           "settle_s": res.settle_s, "integrate_s": res.integrate_s, "cycles": res.cycles,
           "t0_s": res.t0_s}
    for r in _RESP_UNITS:
        for kind in ("", "_exact", "_bias"):
            v = getattr(res, f"{r}{kind}")
            row[f"{r}{kind}_real"], row[f"{r}{kind}_imag"] = v.real, v.imag
        v = getattr(res, r)
        row[f"{r}_gain_db"] = DB * math.log(abs(v))
        row[f"{r}_phase_deg"] = math.degrees(math.atan2(v.imag, v.real))
        row[f"{r}_rel_error"] = res.rel_error[r]
    for i, c in enumerate(_EU):
        row[f"harmonic_{c}_real"] = res.harmonics[i].real
        row[f"harmonic_{c}_imag"] = res.harmonics[i].imag
        row[f"fundamental_ratio_{c}"] = res.fundamental_ratio[i]
        row[f"clipped_{c}"] = res.clipped[i]
        row[f"saturated_{c}"] = res.saturated[i]
        row[f"settle_bound_{c}"] = res.settle_bound[i]
    for i, c in enumerate(("x", "y")):
        row[f"lever_2f_{c}_real"], row[f"lever_2f_{c}_imag"] = (res.lever_2f[i].real,
                                                                res.lever_2f[i].imag)
    return row
