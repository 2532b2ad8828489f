"""Modal curve fit of a measured FRF (the 35670A's curve-fit option), leakage-aware if asked,
and the paper's reading of rotation isolation |Theta_2 / Theta_1| above f1.

The model
---------
A sum of ``M`` lightly damped modes plus a smooth residual over the fitted band ``[f_lo, f_hi]``::

    domain "z":  H(f) = sum_r [ c_r / (zeta - z_r) + conj(c_r) / (zeta - conj(z_r)) ] + P(f)
    domain "s":  H(f) = sum_r [ R_r / (i w - p_r) + conj(R_r) / (i w - conj(p_r)) ] + P(f)

with ``zeta = exp(i w T)``, ``T = 1/fs``, ``z_r = exp(p_r T)``, ``p_r = w_r (-1/(2 Q_r) + i sqrt(1 -
1/(4 Q_r^2)))``, ``w_r = 2 pi f_r``, and ``P(f) = sum_j a_j ((f - f_c) / f_h)^j`` a complex
polynomial of ``n_residual`` terms (``f_c``, ``f_h`` the band's centre and half-width: residual
effects of modes outside the band). Domain "z" is the discrete-time modal model: it is exact for
a system sampled from a held input (the ZOH discretisation of a 2-mode chain is exactly 2 discrete
modes), and near each pole identical to "s" (``c_r / (zeta - z_r) ~ R_r / (i w - p_r)`` with
``R_r = c_r / (z_r T)``, the continuous-equivalent residue reported either way). Fitted
parameters: ``f_r`` [Hz], ``Q_r``, the complex ``c_r`` (or ``R_r``) and ``a_j``.

Leakage-aware fit (``method="leakage"``)
-----------------------------------------
A mode narrower than a line cannot be fitted by the model above: the measured peak is the
expected H1 of the window, not ``H`` (:mod:`processing.compare`). With ``method="leakage"`` the fit
model is ``E[H1]`` of the modal impulse response ``g[n] = sum_r 2 Re(c_r z_r^(n-1))`` (n >= 1)::

    E_k = sum_r [ c_r A_r[k] + conj(c_r) B_r[k] ] + P(f_k)
    A_r[k] = sum_{n=1}^{N-1} r_w[n] z_r^(n-1) exp(-2j pi k n / N),  B_r[k] = conj(A_r[-k mod N])

(one FFT of length ``N = nperseg`` per mode and evaluation; ``r_w`` the window's normalised
autocorrelation). It is exact for white input and the ``"z"`` domain; ``P`` is added untapered
(a smooth residual is unchanged by the kernel to second order in its curvature). The decay of
the response inside the record then carries the information on Q, so a Q ~ 530 mode with 0.47
lines per half-power bandwidth is measurable.

Weights and uncertainties
-------------------------
Each line's complex error has the Bendat-Piersol standard deviation ``sigma_k = eps_k |H_k|``
per real component (``eps`` from the measured coherence and ``n_effective``); the fit minimises
``sum_k |model_k - H_k|^2 / sigma_k^2`` (weights ``1 / sigma^2``, i.e. coherence-weighted).

Lines are not independent: with a window ``w`` the errors of lines ``j`` apart are correlated.
For white output noise the correlation is ``|rho_j|^2`` (:func:`processing.compare.
line_correlation`; Hann: 4/9 and 1/36); near a sharp resonance the unexplained output is mostly
the ringing carried over from before each segment, whose spectrum is smooth across lines, and
the correlation approaches ``rho_j`` itself (Hann: -2/3, 1/6). No single correlation model holds
over a band, so the estimate keeps the diagonal weights (generalised least squares with the
white-noise correlation inflated the chi^2 to 1.26 and lost efficiency in the test ensembles),
and the covariance is the sandwich ``A^-1 (J_w^T R J_w) A^-1`` (``A = J_w^T J_w``, ``J_w`` the
Jacobian divided by ``sigma``, ``R`` the ``|rho_j|^2`` correlation) when ``settings`` are given, or
``A^-1`` without them (lines independent: understated by up to ``sqrt(1 + 2 (4/9 + 1/36)) =
1.39`` for Hann).

The covariance is **not scaled by the reduced chi^2**: the weights are absolute variances
predicted from the coherence, so the scatter is known, and a chi^2 that happens to be low must
not shrink the error bars. It is multiplied by ``n_d / (n_d - 2)``, the mean of ``sigma^2 /
sigma_hat^2`` for a variance estimated from ``n_d`` averages (``sigma_hat^2 ~ sigma^2
chi^2_nu / nu (n_d - 1)/n_d``, ``nu = 2 n_d - 2``); the expected reduced chi^2 of an adequate
model is that same factor (1.071 for 30 averages) whatever the line correlation. A reduced chi^2
above it by more than ``4 sqrt(2 / dof)`` means a systematic misfit (leakage bias in a direct fit
of a sharp mode, a missing mode), which no scaling turns into a random error: the fit is flagged
(``ModalFit.adequate``), and ``ModalFit.birge_factor`` gives the inflation ``sqrt(chi2_red /
expected)`` that would cover it.

Measured calibration (the ``ishizaki2009`` bench emulated exactly by ZOH, 30 x 100 s records,
Hann, output noise 5e-5 m on x, leakage-aware fit of Theta_2 over 0.3 - 6 Hz), empirical over
stated standard deviation:

=========================  ======  ======  ======  ======  ===========
y noise, seeds             Q2      Q1      f2      f1      chi2_red
=========================  ======  ======  ======  ======  ===========
2e-4 rad, 100-129          0.99    0.99    0.43    0.46    1.069
2e-4 rad, 500-539          1.02    0.91    0.40    0.39    1.065
2e-3 rad, 100-129          1.08    1.02    0.57    0.56    1.069
=========================  ======  ======  ======  ======  ===========

The Q uncertainties are right; the frequency uncertainties are conservative by 2 - 2.5 (the
near-peak errors are negatively correlated, which the white-noise ``R`` does not know). The mean
fitted Q1 was above 528.9 by +0.47 and +0.19 of its sigma in the two 2e-4 ensembles (2.6 and
1.2 standard errors of the mean): at most a small high bias of the nonlinear estimate.

Reliability flag (SPEC section 6): the 35670A asks for at least ~8 lines across a half-power
bandwidth ``f/Q``. A direct fit of a mode with fewer lines is ``leakage_limited``: its Q is biased
low (the peak is broadened to the window's resolution) and its stated uncertainty is meaningless.
A leakage-aware fit models that bias and is not flagged unreliable for it. Eight lines are not
a guarantee either: with coherence ~0.999 a direct fit of Q1 = 20, Q2 = 5 (12 and 16.5 lines)
still read Q low by 0.6 and 1.0 sigma on average (0.1 % of Q) over 30 seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.optimize
import scipy.signal
import scipy.special

from processing.compare import line_correlation, window_autocorrelation
from processing.frf import FrequencyResponse
from processing.spectra import ProcessingError, SpectralSettings, _readonly

__all__ = ["FitError", "Mode", "ModalFit", "fit_modes", "RotationReading", "rotation_reading",
           "METHODS", "DOMAINS", "WEIGHTINGS", "MIN_LINES_PER_BANDWIDTH"]

METHODS = ("direct", "leakage")
DOMAINS = ("z", "s")
WEIGHTINGS = ("coherence", "relative", "uniform")
MIN_LINES_PER_BANDWIDTH = 8.0


class FitError(ProcessingError, ValueError):
    """Invalid fit arguments, or a fit that cannot be made (too few lines, singular Jacobian)."""


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
        return _pole(self.f_hz, self.q)


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
        h, _ = _direct(self.params, f, len(self.modes), self.residual_coeffs.size, self.domain,
                       self.fs, self.f_centre_hz, self.f_half_hz, jac=False)
        return h


# -- model evaluation ------------------------------------------------------------------------

def _pole(f_hz: float, q: float) -> complex:
    w = 2 * np.pi * f_hz
    return complex(w * (-0.5 / q + 1j * math.sqrt(max(1.0 - 0.25 / q**2, 0.0))))


def _pole_derivs(f_hz: float, q: float) -> tuple[complex, complex, complex]:
    """p and dp/df, dp/dQ."""
    s = math.sqrt(max(1.0 - 0.25 / q**2, 1e-300))
    w = 2 * np.pi * f_hz
    p = w * (-0.5 / q + 1j * s)
    dp_df = 2 * np.pi * (-0.5 / q + 1j * s)
    dp_dq = w * (0.5 / q**2 + 1j * 0.25 / (q**3 * s))
    return p, dp_df, dp_dq


def _poly_basis(f, n_res, fc, fh) -> np.ndarray:
    x = (f - fc) / fh
    return np.stack([x**j for j in range(n_res)], axis=-1) if n_res else np.zeros((f.size, 0))


def _split(params, m, n_res):
    fq = params[: 2 * m].reshape(m, 2)
    c = params[2 * m: 4 * m].reshape(m, 2)
    a = params[4 * m: 4 * m + 2 * n_res].reshape(n_res, 2)
    return fq, c[:, 0] + 1j * c[:, 1], a[:, 0] + 1j * a[:, 1]


def _direct(params, f, m, n_res, domain, fs, fc, fh, *, jac=True):
    """Modal model and its Jacobian (complex, (n, n_params))."""
    fq, c, a = _split(params, m, n_res)
    w = 2 * np.pi * f
    if domain == "z":
        x = np.exp(1j * w / fs)
    else:
        x = 1j * w
    basis = _poly_basis(f, n_res, fc, fh)
    h = basis @ a if n_res else np.zeros(f.size, complex)
    J = np.zeros((f.size, params.size), complex) if jac else None
    for r in range(m):
        p, dpf, dpq = _pole_derivs(*fq[r])
        if domain == "z":
            zr = np.exp(p / fs)
            dz = (zr * dpf / fs, zr * dpq / fs)
        else:
            zr = p
            dz = (dpf, dpq)
        u1, u2 = 1.0 / (x - zr), 1.0 / (x - np.conj(zr))
        h = h + c[r] * u1 + np.conj(c[r]) * u2
        if jac:
            for i, d in enumerate(dz):
                J[:, 2 * r + i] = c[r] * u1**2 * d + np.conj(c[r]) * u2**2 * np.conj(d)
            J[:, 2 * m + 2 * r] = u1 + u2
            J[:, 2 * m + 2 * r + 1] = 1j * (u1 - u2)
    if jac and n_res:
        J[:, 4 * m::2] = basis
        J[:, 4 * m + 1::2] = 1j * basis
    return h, J


class _LeakageModel:
    """E[H1] of a discrete modal impulse response on given lines of ``settings`` (module notes)."""

    def __init__(self, settings: SpectralSettings, lines: np.ndarray):
        self.n = settings.nperseg
        self.fs = settings.fs
        self.lines = lines
        r = window_autocorrelation(settings)
        self.r = r
        self.nn = np.arange(self.n, dtype=float)

    def mode_terms(self, p: complex, *, jac: bool):
        n, k = self.n, self.lines
        pt = p / self.fs
        nm1 = self.nn - 1.0
        seq = np.zeros(self.n, complex)
        seq[1:] = self.r[1:] * np.exp(pt * nm1[1:])  # r_w[n] z^(n-1)
        fa = scipy.fft.fft(seq)
        a = fa[k]
        b = np.conj(fa[(-k) % n])
        if not jac:
            return a, b, None, None
        dseq = np.zeros(self.n, complex)
        dseq[2:] = self.r[2:] * nm1[2:] * np.exp(pt * (nm1[2:] - 1.0))  # d/dz
        fd = scipy.fft.fft(dseq)
        return a, b, fd[k], np.conj(fd[(-k) % n])

    def __call__(self, params, f, m, n_res, fc, fh, *, jac=True):
        fq, c, a_res = _split(params, m, n_res)
        basis = _poly_basis(f, n_res, fc, fh)
        h = basis @ a_res if n_res else np.zeros(f.size, complex)
        J = np.zeros((f.size, params.size), complex) if jac else None
        for r in range(m):
            p, dpf, dpq = _pole_derivs(*fq[r])
            a, b, da, db = self.mode_terms(p, jac=jac)
            h = h + c[r] * a + np.conj(c[r]) * b
            if jac:
                zr = np.exp(p / self.fs)
                for i, dp in enumerate((dpf, dpq)):
                    dz = zr * dp / self.fs
                    J[:, 2 * r + i] = c[r] * da * dz + np.conj(c[r]) * db * np.conj(dz)
                J[:, 2 * m + 2 * r] = a + b
                J[:, 2 * m + 2 * r + 1] = 1j * (a - b)
        if jac and n_res:
            J[:, 4 * m::2] = basis
            J[:, 4 * m + 1::2] = 1j * basis
        return h, J


# -- the fit ---------------------------------------------------------------------------------

def _correlation_matrix(lines: np.ndarray, corr: np.ndarray) -> np.ndarray:
    lag = np.abs(lines[:, None] - lines[None, :])
    return np.where(lag < corr.size, corr[np.minimum(lag, corr.size - 1)], 0.0)


def _initial_modes(f, h, n_modes, initial, df):
    """Initial (f, Q) per mode: given, or the largest peaks of |H| with a half-power Q."""
    mag = np.abs(h)
    out = []
    if initial is None:
        if n_modes is None:
            raise FitError("give initial (frequencies or (f_hz, Q) pairs) or n_modes")
        pk, props = scipy.signal.find_peaks(mag, prominence=0)
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
        if q0 is None:  # half-power width of the measured peak, at least 1.5 lines
            j = int(np.argmin(np.abs(f - f0)))
            lo = j
            while lo > 0 and mag[lo] > mag[j] / math.sqrt(2):
                lo -= 1
            hi = j
            while hi < f.size - 1 and mag[hi] > mag[j] / math.sqrt(2):
                hi += 1
            q0 = f0 / max(f[hi] - f[lo], 1.5 * df)
        out.append((f0, max(q0, 0.6)))
    return sorted(out)


def fit_modes(frf: FrequencyResponse, band_hz: tuple[float, float], *, initial=None,
              n_modes: int | None = None, method: str = "direct", domain: str = "z",
              settings: SpectralSettings | None = None, fs: float | None = None,
              n_residual: int = 2, weighting: str = "coherence") -> ModalFit:
    """Fit modes (f, Q, complex residue) plus a residual polynomial to a measured FRF.

    Parameters
    ----------
    frf : FrequencyResponse
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

    Returns
    -------
    ModalFit

    Raises
    ------
    FitError
        For invalid arguments, too few lines, or a singular fit.
    """
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
    starts = _initial_modes(f, h, n_modes, initial, df)
    m = len(starts)
    n_par = 4 * m + 2 * n_residual
    if 2 * f.size <= n_par:
        raise FitError(f"{f.size} lines in {band_hz} Hz for {n_par} real parameters: widen the "
                       "band or fit fewer modes")
    fc, fh = 0.5 * (f[0] + f[-1]), max(0.5 * (f[-1] - f[0]), df)
    nd = float(frf.n_effective)
    if weighting == "coherence":
        sigma = np.asarray(frf.relative_error)[sel] * np.abs(h)
        cov_factor = nd / (nd - 2.0) if nd > 2 else math.inf
        expected_chi2 = cov_factor
    elif weighting == "relative":
        sigma = np.abs(h)
        cov_factor, expected_chi2 = 1.0, math.nan
    else:
        sigma = np.ones(f.size)
        cov_factor, expected_chi2 = 1.0, math.nan
    # Line correlation of the errors (each of Re, Im): R_ij = c_|k_i - k_j| (window only).
    corr = line_correlation(settings) if settings is not None else np.ones(1)
    correlated = corr.size > 1
    rmat = _correlation_matrix(lines, corr) if correlated else None

    if method == "leakage":
        model = _LeakageModel(settings, lines)

        def evaluate(params, jac=True):
            return model(params, f, m, n_residual, fc, fh, jac=jac)
    else:
        def evaluate(params, jac=True):
            return _direct(params, f, m, n_residual, domain, fs, fc, fh, jac=jac)

    def real_stack(z):
        return np.concatenate([z.real, z.imag], axis=0)

    def resid(params):
        hm, _ = evaluate(params, jac=False)
        return real_stack((hm - h) / sigma)

    def jacobian(params):
        _, J = evaluate(params)
        return real_stack(J / sigma[:, None])

    # Initial residues and residual terms: linear least squares for the starting poles.
    p0 = np.zeros(n_par)
    p0[: 2 * m] = np.ravel(starts)
    _, J0 = evaluate(p0)
    lin = slice(2 * m, n_par)
    a_lin = real_stack(J0[:, lin] / sigma[:, None])
    b_lin = real_stack(h / sigma)
    p0[lin] = np.linalg.lstsq(a_lin, b_lin, rcond=None)[0]
    # The optimiser sees v = logit((f - f_lo) / (f_hi - f_lo)) and u = ln(Q - 1/2) in place of f
    # and Q: modes stay in the band and underdamped without bounds, so MINPACK's
    # Levenberg-Marquardt applies.
    i_f = np.arange(0, 2 * m, 2)
    iq = np.arange(1, 2 * m, 2)
    span = hi - lo

    def to_params(x):
        p = x.copy()
        p[i_f] = lo + span * scipy.special.expit(x[i_f])
        p[iq] = 0.5 + np.exp(np.clip(x[iq], -30.0, 30.0))
        return p

    def resid_x(x):
        return resid(to_params(x))

    def jac_x(x):
        p = to_params(x)
        jw = jacobian(p)
        e = scipy.special.expit(x[i_f])
        jw[:, i_f] *= span * e * (1.0 - e)
        jw[:, iq] *= p[iq] - 0.5
        return jw

    x0 = p0.copy()
    frac = np.clip((p0[i_f] - lo) / span, 1e-9, 1 - 1e-9)
    x0[i_f] = scipy.special.logit(frac)
    x0[iq] = np.log(p0[iq] - 0.5)
    sol = scipy.optimize.least_squares(resid_x, x0, jac=jac_x, method="lm", x_scale="jac",
                                       xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    params = to_params(sol.x)
    jw = jacobian(params)
    try:
        a_inv = np.linalg.inv(jw.T @ jw)
    except np.linalg.LinAlgError:
        raise FitError("the fit's normal matrix is singular: a mode is not determined by the "
                       "data (too few lines near it, or two modes at one frequency)") from None
    if correlated:  # sandwich: A^-1 (J^T R J) A^-1, R acting on the Re and Im halves alike
        nl = f.size
        rj = np.concatenate([rmat @ jw[:nl], rmat @ jw[nl:]], axis=0)
        cov = a_inv @ (jw.T @ rj) @ a_inv * cov_factor
    else:
        cov = a_inv * cov_factor
    r = resid(params)
    chi2 = float(r @ r)
    dof = 2 * f.size - n_par
    fitted, _ = evaluate(params, jac=False)
    fq, c, a_res = _split(params, m, n_residual)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    notes = []
    modes = []
    order = np.argsort(fq[:, 0])
    for r_i in order:
        fr, q = (float(v) for v in fq[r_i])
        p, dpf, dpq = _pole_derivs(fr, q)
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
                         "the leakage-aware model (assumes white input)")
        modes.append(Mode(f_hz=fr, f_std_hz=float(std[2 * r_i]), q=q,
                          q_std=float(std[2 * r_i + 1]), residue=complex(res),
                          residue_std=res_std, bandwidth_hz=bw, lines_per_bw=lpb,
                          leakage_limited=limited, reliable=reliable))
    fit = ModalFit(
        modes=tuple(modes), residual_coeffs=_readonly(a_res), method=method, domain=domain,
        weighting=weighting, band_hz=(lo, hi), f_centre_hz=fc, f_half_hz=fh,
        freqs_hz=_readonly(f), data=_readonly(h), fitted=_readonly(fitted),
        sigma=_readonly(sigma if weighting != "uniform" else np.full(f.size, np.nan)),
        n_lines=int(f.size), n_params=n_par, dof=dof, chi2=chi2, reduced_chi2=chi2 / dof,
        expected_reduced_chi2=expected_chi2, covariance=_readonly(cov), params=_readonly(params),
        fs=float(fs) if fs is not None else math.nan, resolution_hz=df, settings=settings,
        line_correlated=correlated, notes=())
    if not sol.success:
        notes.append(f"least squares did not converge: {sol.message}")
    if not fit.adequate:
        notes.append(f"reduced chi^2 = {fit.reduced_chi2:.3g} (expected {expected_chi2:.3g} +- "
                     f"{math.sqrt(2 / dof):.2g}): systematic misfit; uncertainties understate "
                     f"the error (Birge factor {fit.birge_factor:.3g})")
    if not correlated and weighting == "coherence" and settings is None:
        notes.append("no settings: lines taken as independent (uncertainties understated for "
                     "windows that correlate neighbouring lines)")
    object.__setattr__(fit, "notes", tuple(notes))
    return fit


# -- rotation isolation ----------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class RotationReading:
    """The paper's claim (29): ``|Theta_2 / Theta_1|`` above f1, measured and modelled.

    Attributes
    ----------
    freqs_hz : (n,) lines of the band [Hz].
    ratio : (n,) measured ``Theta_2 / Theta_1`` (complex) on those lines.
    ratio_sigma_rel : (n,) its relative standard deviation (``sqrt(eps_1^2 + eps_2^2)``).
    model_ratio : (n,) the exact model's ratio, or None.
    band_hz : (f_lo, f_hi).
    mean_db, mean_std_db : mean over the lines of ``20 log10 |ratio|`` and its standard
        deviation [dB] (line correlation included when settings are given).
    model_mean_db : the same mean of the model's ratio [dB] (NaN without model).
    limit_db : extrapolated high-frequency limit ``20 log10 |L|`` from the measured ratio with the
        model's shape (``ratio(f) = L * model_ratio(f) / model_limit``) [dB]; limit_std_db its
        standard deviation (NaN without a model and its limit).
    exact_limit_db : the exact limit ``nu^2 (1 - sigma^2) / (1 - beta^2 / sigma^2)`` [dB] (NaN if
        not given); alpha_db : ``20 log10 alpha`` (claim (29)) [dB] (NaN if not given).
    """

    freqs_hz: np.ndarray
    ratio: np.ndarray
    ratio_sigma_rel: np.ndarray
    model_ratio: np.ndarray | None
    band_hz: tuple
    mean_db: float
    mean_std_db: float
    model_mean_db: float
    limit_db: float
    limit_std_db: float
    exact_limit_db: float
    alpha_db: float


def rotation_reading(theta2: FrequencyResponse, theta1, *, band_hz: tuple[float, float],
                     theta1_scale: float = 1.0, model_ratio=None, exact_limit: float | None = None,
                     alpha: float | None = None,
                     settings: SpectralSettings | None = None) -> RotationReading:
    """Measured ``|Theta_2 / Theta_1|`` in a band above f1, next to the exact model and alpha.

    Parameters
    ----------
    theta2 : FrequencyResponse of the rotation channel (rad per input unit).
    theta1 : FrequencyResponse of a channel proportional to Theta_1 (e.g. the mirror translation
        ``x = l theta_1`` with ``theta1_scale = l``), measured with the same input; or a complex
        array of Theta_1 from the model on ``theta2.freqs_hz`` (then only Theta_2's error enters).
    band_hz : (f_lo, f_hi) [Hz]: above f1 and, to approach the limit, above Theta_2's
        anti-resonance.
    theta1_scale : ``theta1 = channel / theta1_scale`` (e.g. the lever l [m/rad]).
    model_ratio : complex array of the model's ``Theta_2 / Theta_1`` on ``theta2.freqs_hz``,
        or a callable ``freqs_hz -> ratio``.
    exact_limit : the model's high-frequency limit (``rig.ishizaki.rotation_isolation(d).ratio``).
    alpha : ``r2 / r1`` (claim (29)).
    settings : for the line correlation in the band mean's uncertainty.
    """
    lo, hi = (float(v) for v in band_hz)
    f_all = np.asarray(theta2.freqs_hz, dtype=float)
    if isinstance(theta1, FrequencyResponse):
        if theta1.freqs_hz.shape != f_all.shape or not np.allclose(theta1.freqs_hz, f_all):
            raise FitError("theta1 and theta2 must be on the same lines")
        t1 = np.asarray(theta1.h) / theta1_scale
        e1 = np.asarray(theta1.relative_error)
    else:
        t1 = np.asarray(theta1, dtype=complex) / theta1_scale
        if t1.shape != f_all.shape:
            raise FitError(f"theta1 has shape {t1.shape}: expected {f_all.shape}")
        e1 = np.zeros(f_all.shape)
    e2 = np.asarray(theta2.relative_error)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_all = np.asarray(theta2.h) / t1
    sel = (f_all >= lo) & (f_all <= hi) & np.isfinite(ratio_all) & np.isfinite(e1) \
        & np.isfinite(e2)
    if sel.sum() < 2:
        raise FitError(f"fewer than 2 usable lines in band_hz = {band_hz}")
    f = f_all[sel]
    ratio = ratio_all[sel]
    srel = np.sqrt(e1[sel] ** 2 + e2[sel] ** 2)
    if model_ratio is not None:
        mr = np.asarray(model_ratio(f_all) if callable(model_ratio) else model_ratio,
                        dtype=complex)[sel]
    else:
        mr = None
    # Unweighted mean of ln|ratio| over the lines: weights from the measured coherence would
    # correlate with the values (a line whose output happens to read high also reads a higher
    # coherence) and bias the mean up (0.35 dB at 6-10 Hz in the ishizaki2009 test). Its
    # variance 1^T C 1 / n^2 uses srel and, with settings, the window's line correlation.
    y = np.log(np.abs(ratio))
    cmat = np.diag(srel**2)
    if settings is not None:
        lines = np.round(f / settings.resolution_hz).astype(int)
        cmat = _correlation_matrix(lines, line_correlation(settings)) * np.outer(srel, srel)
    n = f.size
    std = math.sqrt(float(cmat.sum())) / n
    db = 20.0 / math.log(10.0)
    mean = float(np.mean(y)) * db
    model_mean = float(np.mean(np.log(np.abs(mr)))) * db if mr is not None else math.nan
    if mr is not None and exact_limit is not None:
        lim = float(np.mean(y - np.log(np.abs(mr / exact_limit)))) * db
        lim_std = std * db
    else:
        lim = lim_std = math.nan
    return RotationReading(
        freqs_hz=_readonly(f), ratio=_readonly(ratio), ratio_sigma_rel=_readonly(srel),
        model_ratio=None if mr is None else _readonly(mr), band_hz=(lo, hi), mean_db=mean,
        mean_std_db=std * db, model_mean_db=model_mean, limit_db=lim,
        limit_std_db=lim_std,
        exact_limit_db=20 * math.log10(abs(exact_limit)) if exact_limit else math.nan,
        alpha_db=20 * math.log10(alpha) if alpha else math.nan)
