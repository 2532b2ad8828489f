"""Modal curve fit of a measured FRF (the 35670A's curve-fit option), leakage-aware if asked.

:func:`fit_modes` fits :class:`ModalFit` (its :class:`Mode` s with uncertainties) to a
:class:`processing.frf.MeasuredResponse` over a band. The model (modes in the z or s domain plus a
smooth residual) and its leakage-aware forms are in :mod:`processing.modal_model`, the
variable-projection solver in :mod:`processing.modal_solver`, the paper's rotation-isolation
reading in :mod:`processing.rotation`.

- ``method="leakage"`` fits the expected H1 of the window (:mod:`processing.compare`) of the modal
  impulse response instead of ``H``, exact for white input in the ``"z"`` domain, so that a mode
  narrower than a line (Q ~ 530 at 0.47 lines per half-power bandwidth) is measurable. With
  ``input_spectrum`` (:class:`InputSpectrum`: the input's PSD, its noise and an input sensor) the
  model is the window's smoothing of the coloured spectra, exact to :data:`KERNEL_TOL`.
- Weights: each line's Bendat-Piersol standard deviation ``sigma_k = eps_k |H_k|`` per real
  component (coherence-weighted). The covariance is the sandwich with the window's line
  correlation when ``settings`` are given (without them the lines count as independent), times
  ``n_d / (n_d - 2)``, and **not** scaled by the reduced chi^2. A reduced chi^2 above its
  expectation by more than ``4 sqrt(2 / dof)`` marks a systematic misfit: ``ModalFit.adequate``
  is false and ``ModalFit.birge_factor`` is the inflation that would cover it.
- Reliability (SPEC section 6): a direct fit of a mode with fewer than ~8 lines across its
  half-power bandwidth ``f/Q`` is ``leakage_limited`` (its Q biased low, its uncertainty
  meaningless); a leakage-aware fit is not flagged for it.

The derivations (the leakage kernel, the coloured-input model and its error bounds, the line
correlations and the covariance): docs/modal-fit.md. Measured on the paper's bench:
docs/modal-fit-calibration.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from processing.compare import line_correlation
from processing.frf import MeasuredResponse
from processing.modal_model import (FINE_PER_LINE, KERNEL_TOL, MAX_FINE_GRID, DirectTerms,
                                    FitError, InputLeakage, InputSpectrum, LagInputLeakage,
                                    WhiteLeakage, coloured_input_terms, direct_model, mode_pole,
                                    mode_pole_derivs, poly_basis, unpack_params)
from processing.modal_solver import LineModel, real_stack, varpro
from processing.spectra import SpectralSettings
from rig.readonly import readonly

__all__ = ["FitError", "Mode", "ModalFit", "InputSpectrum", "fit_modes", "METHODS", "DOMAINS",
           "WEIGHTINGS", "MIN_LINES_PER_BANDWIDTH", "FINE_PER_LINE", "KERNEL_TOL"]

METHODS = ("direct", "leakage")
DOMAINS = ("z", "s")
WEIGHTINGS = ("coherence", "relative", "uniform")
MIN_LINES_PER_BANDWIDTH = 8.0


@dataclass(frozen=True)
class Mode:
    """One fitted mode.

    Attributes
    ----------
    f_hz, f_std_hz : natural frequency ``|p| / 2 pi`` and its standard deviation [Hz].
    q, q_std : quality factor ``|p| / (-2 Re p)`` and its standard deviation.
    residue, residue_std : continuous-equivalent complex residue ``R`` [H unit rad/s] and the
        standard deviations of its real and imaginary parts (complex ``std(Re) + 1j std(Im)``).
    bandwidth_hz : half-power bandwidth ``f / Q`` [Hz].
    lines_per_bw : ``bandwidth_hz`` over the line spacing.
    leakage_limited : ``lines_per_bw < 8``: the record is too short to resolve the peak.
    reliable : False for a leakage-limited mode of a direct fit (Q unreliable, biased low).
    """

    f_hz: float
    f_std_hz: float
    q: float
    q_std: float
    residue: complex
    residue_std: complex
    bandwidth_hz: float
    lines_per_bw: float
    leakage_limited: bool
    reliable: bool

    @property
    def pole(self) -> complex:
        """Continuous pole ``p`` [rad/s]."""
        return mode_pole(self.f_hz, self.q)


@dataclass(frozen=True, eq=False)
class ModalFit:
    """Result of :func:`fit_modes`.

    Attributes
    ----------
    modes : tuple of Mode, ascending in frequency.
    residual_coeffs : complex (n_residual,) ``a_j`` of ``P(f)``.
    method, domain, weighting : as requested.
    band_hz : (f_lo, f_hi) of the fitted lines [Hz]; f_centre_hz, f_half_hz : of ``P``.
    freqs_hz : (n,) fitted lines [Hz]; data : (n,) measured H there; fitted : (n,) model there.
    sigma : (n,) per-component standard deviation used as weight (NaN for "uniform").
    n_lines, n_params, dof : lines fitted, real parameters, ``2 n_lines - n_params``.
    chi2, reduced_chi2 : weighted residual sum of squares and ``chi2 / dof``.
    expected_reduced_chi2 : ``n_d / (n_d - 2)`` for "coherence" weighting, else NaN.
    covariance : (n_params, n_params) of ``[f_1, Q_1, ..., Re c_1, Im c_1, ..., Re a_0, ...]``
        (sandwich with the line correlation, times ``n_d / (n_d - 2)``; not scaled by chi^2: see
        the module notes).
    params : (n_params,) the solution in the same order.
    fs : sample rate [Hz] (domain "z"); resolution_hz : line spacing [Hz].
    settings : the analyzer settings used, or None.
    line_correlated : True if the covariance includes the window's line correlation.
    notes : tuple of str, human-readable warnings.
    input_spectrum : the InputSpectrum of a leakage-aware fit under a coloured input, or None
        (white input, or a direct fit).
    iterations : Levenberg-Marquardt iterations of the variable-projection solver.
    """

    modes: tuple
    residual_coeffs: np.ndarray
    method: str
    domain: str
    weighting: str
    band_hz: tuple
    f_centre_hz: float
    f_half_hz: float
    freqs_hz: np.ndarray
    data: np.ndarray
    fitted: np.ndarray
    sigma: np.ndarray
    n_lines: int
    n_params: int
    dof: int
    chi2: float
    reduced_chi2: float
    expected_reduced_chi2: float
    covariance: np.ndarray
    params: np.ndarray
    fs: float
    resolution_hz: float
    settings: SpectralSettings | None
    line_correlated: bool
    notes: tuple
    input_spectrum: InputSpectrum | None = None
    iterations: int = 0

    @property
    def adequate(self) -> bool:
        """``reduced_chi2 <= expected + 4 sqrt(2 / dof)`` (always True without absolute weights)."""
        if not math.isfinite(self.expected_reduced_chi2):
            return True
        return self.reduced_chi2 <= self.expected_reduced_chi2 + 4.0 * math.sqrt(2.0 / self.dof)

    @property
    def birge_factor(self) -> float:
        """``sqrt(max(1, reduced_chi2 / expected))``: the factor the uncertainties would need to
        cover the misfit if it were random (it is not: see module notes)."""
        e = self.expected_reduced_chi2 if math.isfinite(self.expected_reduced_chi2) else 1.0
        return math.sqrt(max(1.0, self.reduced_chi2 / e))

    def response(self, freqs_hz) -> np.ndarray:
        """The fitted modal model ``H(f)`` (not the leakage-tapered one) at ``freqs_hz`` [Hz]."""
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        h, _ = direct_model(self.params, f, len(self.modes), self.residual_coeffs.size, self.domain,
                            self.fs, self.f_centre_hz, self.f_half_hz, jac=False)
        return h


# -- model evaluation ------------------------------------------------------------------------


def _correlate_lines(lines: np.ndarray, corr: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R @ x`` for ``R`` of :func:`processing.compare.correlation_matrix` without forming it:
    ``lines`` ascending and distinct, ``corr`` (a few lags) from :func:`line_correlation`."""
    out = corr[0] * x
    for d in range(1, corr.size):
        i = np.searchsorted(lines, lines + d)  # pairs (j, i) with lines[i] = lines[j] + d
        ok = i < lines.size
        ok[ok] &= lines[i[ok]] == lines[ok] + d
        j, i = np.nonzero(ok)[0], i[ok]
        out[j] += corr[d] * x[i]
        out[i] += corr[d] * x[j]
    return out


def _initial_modes(f, h, n_modes, initial, df):
    """Initial (f, Q, Q given?) per mode: given, or the largest peaks of |H| with a half-power
    Q."""
    mag = np.abs(h)
    out = []
    if initial is None:
        if n_modes is None:
            raise FitError("give initial (frequencies or (f_hz, Q) pairs) or n_modes")
        from scipy.signal import find_peaks

        pk, props = find_peaks(mag, prominence=0)
        if pk.size < n_modes:
            raise FitError(f"found {pk.size} peaks of |H| in the band: fewer than n_modes = "
                           f"{n_modes}; give initial frequencies")
        pk = np.sort(pk[np.argsort(props["prominences"])[::-1][:n_modes]])
        initial = [float(f[i]) for i in pk]
    for item in initial:
        if np.ndim(item) == 0:
            f0, q0 = float(item), None
        else:
            f0, q0 = (float(v) for v in item)
        given = q0 is not None
        if not given:  # half-power width of the measured peak, at least 1.5 lines
            j = int(np.argmin(np.abs(f - f0)))
            lo = j
            while lo > 0 and mag[lo] > mag[j] / math.sqrt(2):
                lo -= 1
            hi = j
            while hi < f.size - 1 and mag[hi] > mag[j] / math.sqrt(2):
                hi += 1
            q0 = f0 / max(f[hi] - f[lo], 1.5 * df)
        out.append((f0, max(q0, 0.6), given))
    return sorted(out)


def fit_modes(frf: MeasuredResponse, band_hz: tuple[float, float], *, initial=None,
              n_modes: int | None = None, method: str = "direct", domain: str = "z",
              settings: SpectralSettings | None = None, fs: float | None = None,
              n_residual: int = 2, weighting: str = "coherence",
              input_spectrum: InputSpectrum | None = None) -> ModalFit:
    """Fit modes (f, Q, complex residue) plus a residual polynomial to a measured FRF.

    Parameters
    ----------
    frf : MeasuredResponse
        Measured H1 (coherence and ``n_effective`` give the weights).
    band_hz : (f_lo, f_hi)
        Lines fitted [Hz].
    initial : sequence of f_hz or (f_hz, Q), optional
        Starting modes. Without Q, Q starts from the measured half-power width (at least 1.5
        lines). Without ``initial``, the ``n_modes`` most prominent peaks of ``|H|``.
    n_modes : int, optional
        Number of modes when ``initial`` is not given.
    method : {"direct", "leakage"}
        Fit the modal model itself (the analyzer's curve fit) or its expected H1 (module notes;
        needs ``settings`` and domain "z").
    domain : {"z", "s"}
        Discrete (exact for a held input) or continuous modal model.
    settings : SpectralSettings, optional
        The analyzer settings of ``frf``: the window's line correlation (for the weights) and,
        for ``method="leakage"``, the window and segment length. Without it, lines are taken as
        independent.
    fs : float, optional
        Sample rate [Hz] for domain "z" (default ``settings.fs``).
    n_residual : int
        Terms of the residual polynomial (0: none; 1: constant; 2: + linear, the default).
    weighting : {"coherence", "relative", "uniform"}
        ``1 / sigma^2`` from Bendat-Piersol (default); ``1 / |H|^2`` (noiseless synthetic data;
        uncertainties then in units of a relative error of 1); or 1 (absolute).
    input_spectrum : InputSpectrum, optional
        ``method="leakage"`` only: the input's PSD (and noise, and input sensor), for the
        expected H1 under a coloured input (module notes). Default: a white input.

    Returns
    -------
    ModalFit

    Raises
    ------
    FitError
        For invalid arguments, too few lines, or a singular fit.
    """
    lo, hi, fs = _check_fit_arguments(band_hz, method, domain, weighting, n_residual, settings,
                                      fs, input_spectrum)
    sel, f, h, df, lines = _fit_lines(frf, lo, hi, weighting, settings)
    n_fit = len(initial) if initial is not None else (n_modes or 0)
    if n_fit and 2 * f.size <= 4 * n_fit + 2 * n_residual:  # checked again below, once known
        raise FitError(f"{f.size} lines in {band_hz} Hz for {4 * n_fit + 2 * n_residual} real "
                       "parameters: widen the band, fit fewer modes or use finer lines")
    starts = _initial_modes(f, h, n_modes, initial, df)
    broadened = [not given for _, _, given in starts]
    starts = [(f0, q0) for f0, q0, _ in starts]
    m = len(starts)
    n_par = 2 * m + 2 * m + 2 * n_residual
    if 2 * f.size <= n_par:
        raise FitError(f"{f.size} lines in {band_hz} Hz for {n_par} real parameters: widen the "
                       "band, fit fewer modes or use finer lines")
    fc, fh = 0.5 * (f[0] + f[-1]), max(0.5 * (f[-1] - f[0]), df)
    sigma, cov_factor, expected_chi2 = _weights(frf, sel, h, weighting)
    # Line correlation of the errors (each of Re, Im): R_ij = c_|k_i - k_j| (window only).
    corr = line_correlation(settings) if settings is not None else np.ones(1)
    correlated = corr.size > 1
    terms = _terms(method, f, domain, fs, settings, lines, input_spectrum,
                   _slowest(input_spectrum, starts, [2.0 if b else 1.0 for b in broadened])
                   if input_spectrum is not None else None)
    model = LineModel(terms, poly_basis(f, n_residual, fc, fh), m, domain, fs)
    # A decay over a thousand records is indistinguishable from none: Q is bounded there.
    q_max = max(1e3 * math.pi * hi / df, 10.0 * max(q for _, q in starts))
    model, params, n_iter, converged = _solve(model, h, sigma, np.array(starts, float), lo, hi,
                                              q_max, settings, lines, input_spectrum)
    terms = model.terms
    fitted, cov = _covariance(model, params, h, sigma, lines, corr if correlated else None,
                              cov_factor)
    r = real_stack((fitted - h) / sigma)
    chi2 = float(r @ r)
    dof = 2 * f.size - n_par
    fq, c, a_res = unpack_params(params, m, n_residual)
    input_txt = "white input" if input_spectrum is None else f"input: {input_spectrum.label}"
    modes, notes = _modes(fq, c, cov, domain, fs, df, method, input_txt)
    fit = ModalFit(
        modes=tuple(modes), residual_coeffs=readonly(a_res), method=method, domain=domain,
        weighting=weighting, band_hz=(lo, hi), f_centre_hz=fc, f_half_hz=fh,
        freqs_hz=readonly(f), data=readonly(h), fitted=readonly(fitted),
        sigma=readonly(sigma if weighting != "uniform" else np.full(f.size, np.nan)),
        n_lines=int(f.size), n_params=n_par, dof=dof, chi2=chi2, reduced_chi2=chi2 / dof,
        expected_reduced_chi2=expected_chi2, covariance=readonly(cov), params=readonly(params),
        fs=float(fs) if fs is not None else math.nan, resolution_hz=df, settings=settings,
        line_correlated=correlated, notes=(), input_spectrum=input_spectrum,
        iterations=n_iter)
    notes.extend(_fit_notes(fit, converged, terms, _slowest(input_spectrum, fq)
                            if isinstance(terms, InputLeakage) else None))
    object.__setattr__(fit, "notes", tuple(notes))
    return fit


def _terms(method: str, f, domain: str, fs, settings, lines, input_spectrum,
           tau_start: float | None):
    """The model's terms: the modal model itself (direct), or its expected H1 under a white or
    coloured input (leakage); ``tau_start``: the slowest decay [s] of the starting modes."""
    if method == "direct":
        return DirectTerms(f, domain, fs)
    if input_spectrum is None:
        return WhiteLeakage(settings, lines)
    if coloured_input_terms(settings) is LagInputLeakage:
        return LagInputLeakage(settings, lines, input_spectrum)
    # a Q read off a leakage-broadened peak is about half the mode's (module notes)
    return InputLeakage(settings, lines, input_spectrum,
                         InputLeakage.fine_for(settings, tau_start))


def _solve(model, h, sigma, starts, lo: float, hi: float, q_max: float, settings, lines,
           input_spectrum):
    """The variable-projection fit from ``starts``; a coloured-input model whose fitted modes
    decay more slowly than the start said is refitted once on the finer grid they need.
    Returns ``(model, params, iterations, converged)``."""
    theta, beta, n_iter, converged = varpro(model, h, sigma, starts, lo, hi - lo, q_max)
    terms = model.terms
    if isinstance(terms, InputLeakage):
        fine = InputLeakage.fine_for(settings, _slowest(input_spectrum, theta))
        if fine > terms.fine:
            terms = InputLeakage(settings, lines, input_spectrum, fine)
            model = LineModel(terms, model.basis, model.m, model.domain, model.fs)
            theta, beta, more, converged = varpro(model, h, sigma, theta, lo, hi - lo, q_max)
            n_iter += more
    return model, np.concatenate([theta.ravel(), beta]), n_iter, converged


def _check_fit_arguments(band_hz, method, domain, weighting, n_residual, settings, fs,
                         input_spectrum) -> tuple[float, float, float | None]:
    """:func:`fit_modes`'s arguments checked (a FitError naming the bad one); returns the band
    ``(lo, hi)`` [Hz] and the sample rate ``fs`` (default ``settings.fs``)."""
    if method not in METHODS:
        raise FitError(f"method = {method!r} is invalid: expected one of {METHODS}")
    if domain not in DOMAINS:
        raise FitError(f"domain = {domain!r} is invalid: expected one of {DOMAINS}")
    if weighting not in WEIGHTINGS:
        raise FitError(f"weighting = {weighting!r} is invalid: expected one of {WEIGHTINGS}")
    if isinstance(n_residual, bool) or not isinstance(n_residual, (int, np.integer)) \
            or n_residual < 0:
        raise FitError(f"n_residual = {n_residual!r} is invalid: expected an integer >= 0")
    lo, hi = (float(v) for v in band_hz)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise FitError(f"band_hz = {band_hz!r} is invalid: expected 0 <= f_lo < f_hi")
    if fs is None and settings is not None:
        fs = settings.fs
    if domain == "z" and fs is None:
        raise FitError("domain 'z' needs the sample rate: give settings or fs")
    if method == "leakage":
        if settings is None:
            raise FitError("method 'leakage' needs the analyzer settings (window, nperseg)")
        if domain != "z":
            raise FitError("method 'leakage' models a discrete impulse response: use domain 'z'")
    if input_spectrum is not None:
        if method != "leakage":
            raise FitError("input_spectrum is for method 'leakage' (a direct fit has no leakage "
                           "for the input to shape)")
        if not isinstance(input_spectrum, InputSpectrum):
            raise FitError(f"input_spectrum = {input_spectrum!r} is invalid: expected an "
                           "InputSpectrum")
    return lo, hi, fs


def _fit_lines(frf, lo: float, hi: float, weighting: str, settings):
    """The lines fitted: ``(sel, f, h, df, lines)``: the mask over ``frf``'s lines, their
    frequencies [Hz] and values, the line spacing [Hz] and the line indices ``f / df``."""
    f_all = np.asarray(frf.freqs_hz, dtype=float)
    sel = (f_all >= lo) & (f_all <= hi) & np.isfinite(frf.h)
    if weighting == "coherence":
        sel &= np.isfinite(frf.coherence) & (frf.coherence > 0) & (frf.coherence < 1)
    f = f_all[sel]
    h = np.asarray(frf.h)[sel]
    df = float(np.median(np.diff(f_all))) if f_all.size > 1 else math.nan
    if settings is not None:
        df = settings.resolution_hz
        kk = f / df
        if np.any(np.abs(kk - np.round(kk)) > 1e-6):
            raise FitError("frf.freqs_hz are not lines of settings (k fs / nperseg)")
        lines = np.round(kk).astype(int)
    else:
        lines = np.round(f / df).astype(int)
    return sel, f, h, df, lines


def _weights(frf, sel, h, weighting: str) -> tuple[np.ndarray, float, float]:
    """``(sigma, cov_factor, expected_chi2)``: each line's standard error, the covariance's
    scale and the expected reduced chi^2 (NaN where the weighting states no error)."""
    nd = float(frf.n_effective)
    if weighting == "coherence":
        sigma = np.asarray(frf.relative_error)[sel] * np.abs(h)
        cov_factor = nd / (nd - 2.0) if nd > 2 else math.inf
        return sigma, cov_factor, cov_factor
    if weighting == "relative":
        return np.abs(h), 1.0, math.nan
    return np.ones(h.size), 1.0, math.nan


def _slowest(input_spectrum, fq, factors=None) -> float:
    """The slowest decay time [s] the coloured-input model's fine grid must hold: the input's
    and each mode's ``Q / (pi f)`` (times its factor)."""
    factors = [1.0] * len(fq) if factors is None else factors
    return max([float(input_spectrum.decay_s)]
               + [c * q / (math.pi * fr) for (fr, q), c in zip(fq, factors)])


def _covariance(model, params, h, sigma, lines, corr, cov_factor):
    """The fitted values and the parameters' covariance: ``A^-1`` (``A = J^T J`` of the
    weighted Jacobian), or the sandwich ``A^-1 (J^T R J) A^-1`` with the lines' correlation
    ``corr`` (R acting on the Re and Im halves alike), times ``cov_factor``."""
    fitted, jac = model.full(params)
    jw = real_stack(jac / sigma[:, None])
    try:
        a_inv = np.linalg.inv(jw.T @ jw)
    except np.linalg.LinAlgError:
        raise FitError("the fit's normal matrix is singular: a mode is not determined by the "
                       "data (too few lines near it, or two modes at one frequency)") from None
    if corr is not None:
        nl = h.size
        rj = np.concatenate([_correlate_lines(lines, corr, jw[:nl]),
                             _correlate_lines(lines, corr, jw[nl:])], axis=0)
        return fitted, a_inv @ (jw.T @ rj) @ a_inv * cov_factor
    return fitted, a_inv * cov_factor


def _modes(fq, c, cov, domain: str, fs, df: float, method: str,
           input_txt: str) -> tuple[list, list]:
    """The fitted :class:`Mode` s in increasing frequency (continuous-equivalent residues with
    their standard deviations) and a note for each leakage-limited one."""
    m = len(fq)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    notes, modes = [], []
    for r_i in np.argsort(fq[:, 0]):
        fr, q = (float(v) for v in fq[r_i])
        p, dpf, dpq = mode_pole_derivs(fr, q)
        # Continuous-equivalent residue and its Jacobian w.r.t. (f, Q, Re c, Im c).
        if domain == "z":
            e = np.exp(-p / fs) * fs
            res = c[r_i] * e
            dr = np.array([-c[r_i] * e * dpf / fs, -c[r_i] * e * dpq / fs, e, 1j * e])
        else:
            res = c[r_i]
            dr = np.array([0, 0, 1, 1j], complex)
        idx = [2 * r_i, 2 * r_i + 1, 2 * m + 2 * r_i, 2 * m + 2 * r_i + 1]
        sub = cov[np.ix_(idx, idx)]
        res_std = complex(math.sqrt(max(dr.real @ sub @ dr.real, 0.0)),
                          math.sqrt(max(dr.imag @ sub @ dr.imag, 0.0)))
        bw = fr / q
        lpb = bw / df
        limited = bool(lpb < MIN_LINES_PER_BANDWIDTH)
        reliable = not (limited and method == "direct")
        if limited and method == "direct":
            notes.append(f"mode at {fr:.4g} Hz: half-power bandwidth {bw * 1e3:.3g} mHz is "
                         f"{lpb:.2g} lines (< {MIN_LINES_PER_BANDWIDTH:g}): Q = {q:.4g} is "
                         "leakage-limited (unreliable, biased low by an amount that depends on "
                         "the weighting); fit with method='leakage' or longer records")
        elif limited:
            notes.append(f"mode at {fr:.4g} Hz: {lpb:.2g} lines per half-power bandwidth; Q from "
                         f"the leakage-aware model ({input_txt})")
        modes.append(Mode(f_hz=fr, f_std_hz=float(std[2 * r_i]), q=q,
                          q_std=float(std[2 * r_i + 1]), residue=complex(res),
                          residue_std=res_std, bandwidth_hz=bw, lines_per_bw=lpb,
                          leakage_limited=limited, reliable=reliable))
    return modes, notes


def _fit_notes(fit: ModalFit, converged: bool, terms, tau: float | None) -> list[str]:
    """What limits ``fit``: no convergence, the coloured-input model's aliasing (``tau``: its
    slowest decay [s]), the lag grid's truncation, a misfit, lines taken as independent."""
    notes = []
    if not converged:
        notes.append(f"least squares did not converge in {fit.iterations} iterations")
    if isinstance(terms, InputLeakage):
        bound = terms.alias_bound(tau)
        if bound > 10 * KERNEL_TOL:
            notes.append(f"the coloured-input model's fine grid ({terms.fine} points per line, "
                         f"at most {MAX_FINE_GRID} around the circle) aliases the slowest fitted "
                         f"decay (tau = {tau:.3g} s) by up to {bound:.1e} (relative)")
    if isinstance(terms, LagInputLeakage) and terms.alias > 10 * KERNEL_TOL:
        notes.append(f"the input's correlation is not negligible at half the lag grid "
                     f"({terms.alias:.1e} of its peak): give input_spectrum.decay_s")
    if not fit.adequate:
        notes.append(f"reduced chi^2 = {fit.reduced_chi2:.3g} (expected "
                     f"{fit.expected_reduced_chi2:.3g} +- {math.sqrt(2 / fit.dof):.2g}): "
                     "systematic misfit; uncertainties understate the error (Birge factor "
                     f"{fit.birge_factor:.3g})")
    if not fit.line_correlated and fit.weighting == "coherence" and fit.settings is None:
        notes.append("no settings: lines taken as independent (uncertainties understated for "
                     "windows that correlate neighbouring lines)")
    return notes
