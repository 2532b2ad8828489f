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

Coloured input (``input_spectrum``)
-----------------------------------
``E[H1] = E[G_ux] / E[G_uu]`` and both expectations are the window's smoothing of the true
spectra, so the input spectrum enters wherever it changes within the smoothing kernel: a notch
of the input *at* the mode reweights the lines beside the peak. With the input's PSD ``S`` (its
part coherent with the output), its noise ``N`` and an input sensor ``K`` (the recorded input is
``K`` times the input the modes respond to; the fitted response is the measured ratio times
``K``), :class:`InputSpectrum`, the model is::

    E_k = K_k T[S G / K]_k / T[S + N]_k + P(f_k),    T[F]_k = (1/n2) sum_j D[k M - j] F(nu_j)

with ``G`` the modal sum, ``nu_j = j fs / n2`` a grid ``M`` times finer than the lines
(``n2 = M N``) and ``D`` the window's power kernel, the DFT of ``r_w(|tau|)``,
``|tau| < N``, on ``n2`` points (real, even, ``sum_j D[j] / n2 = r_w(0) = 1``). This is the sum over
lags of :mod:`processing.analyzer`'s expected estimate written in frequency, exact up to

* the time aliasing of the correlations on the fine grid, ``exp(-(n2 - N) / (fs tau))`` for the
  slowest decay time ``tau`` of the modes (``Q / (pi f)``) and of the input (Q = 529 at 2.48 Hz,
  N = 10^4, M = 16: 2.6e-10; a note is added above 1e-8), and
* the kernel's tail beyond ``L`` lines, which the band-limited convolution neglects: below
  :data:`KERNEL_TOL` (1e-9) of the total (Hann: L = 27 lines, flat top: 102).

``M`` is the least that keeps the aliasing below :data:`KERNEL_TOL` for ``InputSpectrum.decay_s``
and the starting modes (at least :data:`FINE_PER_LINE`; a start read off a leakage-broadened peak
counts twice its Q); if the fitted modes decay more slowly, the fit is repeated once on the finer
grid they need. All modes' terms and their derivatives come from one batched FFT convolution per
evaluation. Windows whose kernel falls as ``1/L`` (uniform, force, exponential) use the same sum
in the lag domain instead (:class:`_LagInputLeakage`: the correlation of ``S / K`` once, then per
evaluation a convolution with ``z^n`` over ``|tau| < N`` and the geometric sum of its tail),
exact whatever the modes' Q, slower. With ``S = 1``, ``N = 0``, ``K = 1`` either equals the
white-input model above to 1e-8 (tests/processing/test_modal.py).

On the ``ishizaki2009`` bench the pendulum's reaction notches the stage acceleration at its own
modes (-16 dB at 2.48 Hz relative to the median over 0.1 - 10 Hz, about 4.7 mHz wide): the
white-input model reads Q1 = 494 +- 20 on the paper's run (seed 2009) and 491.4 on its noiseless
E[H1], chi^2/dof 1.6 (Theta_2) and 2.2 (H_t); with the bench's input spectrum it reads
524.7 +- 24 (Theta_2) and 546 +- 33 (H_t) against the exact 528.9, chi^2/dof 1.09 (expected
1.07 +- 0.04 and +- 0.06), and the noiseless E[H1] gives back f and Q within 2.4e-6 (Theta_2) and
5e-5 (H_t, whose band leaves the 0.83 Hz mode to the residual polynomial) relative. The
measured input auto spectrum cannot stand in for ``S``: its lines are the window's smoothing of
the notch, which is narrower than a line.

Solver
------
Variable projection: for every trial ``(f_r, Q_r)`` the residues and the residual polynomial,
which enter linearly, are solved by weighted linear least squares, and Levenberg-Marquardt
(Marquardt's diagonal scaling, Kaufman's Jacobian of the projected residual) moves only the
``2 M`` nonlinear parameters, as ``v = logit((f - f_lo) / (f_hi - f_lo))`` and
``u = logit((Q - 1/2) / Q_max)``: modes stay in the band and underdamped without bounds, and Q
below ``Q_max = 1000 pi f_hi / df`` (at least ten times the start), the Q of a decay over a
thousand records, which no fit can tell from an undamped mode. It stops when the Gauss-Newton
decrement is below ``1e-12`` of chi^2 (parameters then within ~1e-6 of their standard deviation
of the minimum). The minimum is that of the full problem; 4 - 15 iterations instead of 30 - 40 for
Levenberg-Marquardt over all parameters.

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

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from processing.compare import line_correlation
from processing.frf import MeasuredResponse
from processing.spectra import ProcessingError, SpectralSettings, _readonly, window_autocorrelation

__all__ = ["FitError", "Mode", "ModalFit", "InputSpectrum", "fit_modes", "RotationReading",
           "rotation_reading", "METHODS", "DOMAINS", "WEIGHTINGS", "MIN_LINES_PER_BANDWIDTH",
           "FINE_PER_LINE", "KERNEL_TOL"]

METHODS = ("direct", "leakage")
DOMAINS = ("z", "s")
WEIGHTINGS = ("coherence", "relative", "uniform")
MIN_LINES_PER_BANDWIDTH = 8.0
#: Fewest points of the coloured-input model's frequency grid per analyzer line (module notes).
FINE_PER_LINE = 16
#: Neglected tail of the window's power kernel in the coloured-input model's banded convolution,
#: and the largest time aliasing of its fine grid.
KERNEL_TOL = 1e-9
#: Widest band-limited kernel [lines] before the convolution is made around the whole circle.
MAX_KERNEL_LINES = 128
#: Largest fine grid (points around the circle) of the coloured-input model; beyond it a note
#: gives the aliasing.
MAX_FINE_GRID = 1 << 18
#: Largest lag grid of the lag-domain coloured-input model (windows with slowly falling kernels).
MAX_LAG_GRID = 1 << 21


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


@dataclass(frozen=True, eq=False)
class InputSpectrum:
    """The input of a measured H1, for the leakage-aware fit under a coloured input.

    ``E[H1]`` is ``E[G_ux] / E[G_uu]``, both the window's smoothing of the true spectra (module
    notes), so a sharp feature of the input spectrum near a mode -- on a bench, the notch the
    pendulum's reaction digs into the stage motion at its own modes -- changes the expected
    estimate there. This says what the input spectrum is; only its shape matters (any constant
    scale cancels).

    Parameters
    ----------
    psd : callable ``f_hz -> (nf,)`` float >= 0
        One-sided PSD of the recorded input's part that drives the output (coherent with it),
        at any frequencies ``0 <= f < fs/2`` [input unit^2/Hz]. It must resolve what matters:
        it is evaluated on a grid :data:`FINE_PER_LINE` times finer than the lines.
    noise_psd : callable, optional
        PSD of the recorded input's noise (sensor noise, quantisation: not coherent with the
        output), same units. It enters ``E[G_uu]`` only (the H1 input-noise bias). Default 0.
    sensor : callable ``f_hz -> (nf,)`` complex, optional
        ``K(f)``: the recorded input is ``K`` times the input the modes respond to (an input
        sensor's own response, e.g. an accelerometer's high-pass). The fitted response is then
        the measured ratio times ``K`` (the system's own response), and the model is
        ``K_k T[S G / K]_k / T[S + N]_k``. Default 1.
    decay_s : float, default 0
        Slowest decay time of the input's correlation function [s] (a sharp notch or peak of
        ``S`` decays slowly): with the modes' ``Q / (pi f)`` it sets the fine grid so that its
        time aliasing stays below :data:`KERNEL_TOL` (the fit is repeated on a finer grid if the
        fitted modes decay more slowly than the start said, up to :data:`MAX_FINE_GRID` points;
        beyond, a note gives the aliasing).
    label : str
        Where the spectrum comes from (for notes and reports).
    """

    psd: Callable
    noise_psd: Callable | None = None
    sensor: Callable | None = None
    decay_s: float = 0.0
    label: str = "given spectrum"

    def evaluate(self, freqs_hz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(coherent PSD, total PSD, K)`` at ``freqs_hz`` [Hz], which may be negative (real
        signals: ``S(-f) = S(f)``, ``K(-f) = conj(K(f))``).

        Raises
        ------
        FitError
            If a callable returns the wrong shape, negative or non-finite values.
        """
        f = np.asarray(freqs_hz, dtype=float)
        fa = np.abs(f)
        out = []
        for name, fn, default in (("psd", self.psd, None), ("noise_psd", self.noise_psd, 0.0)):
            v = np.zeros(f.shape) if fn is None else np.asarray(fn(fa))
            if np.iscomplexobj(v):
                v = v.real if np.all(v.imag == 0) else v
            if v.shape != f.shape or np.iscomplexobj(v) or not np.all(np.isfinite(v)) \
                    or np.any(v < 0):
                raise FitError(f"input_spectrum.{name} returned shape {v.shape} or negative, "
                               f"complex or non-finite values: expected a real PSD >= 0 of "
                               f"shape {f.shape}")
            out.append(v.astype(float))
        if self.sensor is None:
            k = np.ones(f.shape, complex)
        else:
            k = np.asarray(self.sensor(fa), dtype=complex)
            if k.shape != f.shape or not np.all(np.isfinite(k)):
                raise FitError(f"input_spectrum.sensor returned shape {k.shape} or non-finite "
                               f"values: expected complex values of shape {f.shape}")
            k = np.where(f < 0, np.conj(k), k)
        return out[0], out[0] + out[1], k


class _DirectTerms:
    """The modal model itself on the fitted lines: ``a = 1 / (x - z)``, ``b = 1 / (x - conj z)``
    with ``x = exp(i w T)`` (domain "z") or ``i w`` (domain "s")."""

    def __init__(self, f: np.ndarray, domain: str, fs: float | None):
        w = 2 * np.pi * f
        self.x = np.exp(1j * w / fs) if domain == "z" else 1j * w

    def __call__(self, z: np.ndarray, *, jac: bool):
        u1 = 1.0 / (self.x[None, :] - z[:, None])
        u2 = 1.0 / (self.x[None, :] - np.conj(z)[:, None])
        return (u1, u2, u1 * u1, u2 * u2) if jac else (u1, u2, None, None)


class _WhiteLeakage:
    """``E[H1]`` of the discrete modal impulse response under a white input (module notes):
    ``A_r[k] = sum_n r_w[n] z_r^(n-1) exp(-2j pi k n / N)``, one FFT of length ``N`` per mode."""

    def __init__(self, settings: SpectralSettings, lines: np.ndarray):
        self.n = settings.nperseg
        self.lines = lines
        self.r = window_autocorrelation(settings)
        self.nm1 = np.arange(self.n, dtype=float) - 1.0

    def __call__(self, z: np.ndarray, *, jac: bool):
        n, k = self.n, self.lines
        logz = np.log(z.astype(complex))[:, None]
        seq = np.zeros((z.size, n), complex)
        seq[:, 1:] = self.r[1:] * np.exp(logz * self.nm1[1:])  # r_w[n] z^(n-1)
        fa = np.fft.fft(seq, axis=-1)
        a, b = fa[:, k], np.conj(fa[:, (-k) % n])
        if not jac:
            return a, b, None, None
        dseq = np.zeros((z.size, n), complex)
        dseq[:, 2:] = self.r[2:] * self.nm1[2:] * np.exp(logz * (self.nm1[2:] - 1.0))  # d/dz
        fd = np.fft.fft(dseq, axis=-1)
        return a, b, fd[:, k], np.conj(fd[:, (-k) % n])


def _fast_len(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n (an FFT length pocketfft handles fast)."""
    best = 1 << max(int(n) - 1, 0).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p = p35
            while p < n:
                p *= 2
            best = min(best, p)
            p35 *= 3
        p5 *= 5
    return best


@functools.lru_cache(maxsize=8)
def _kernel(settings: SpectralSettings, fine: int):
    """The window's power kernel ``D[0 .. n2/2]`` on ``n2 = fine N`` points and the fewest lines
    ``L`` beyond which its tail is below :data:`KERNEL_TOL` (None if more than
    :data:`MAX_KERNEL_LINES`), with that tail."""
    n = settings.nperseg
    n2 = fine * n
    r = window_autocorrelation(settings)
    taper = np.zeros(n2)
    taper[:n] = r
    taper[n2 - n + 1:] = r[1:][::-1]
    d_half = np.fft.rfft(taper).real  # D[0 .. n2/2], even: D[-d] = D[d]
    tail = np.cumsum((2.0 * np.abs(d_half) / n2)[::-1])[::-1]  # ~ sum_{|d| >= q} |D[d]| / n2
    d_half.setflags(write=False)  # (cached: shared between fits)
    for ll in range(1, MAX_KERNEL_LINES + 1):
        if ll * fine + 1 < tail.size and tail[ll * fine + 1] < KERNEL_TOL:
            return d_half, ll, float(tail[ll * fine + 1])
    return d_half, None, math.nan


def _input_terms(settings: SpectralSettings):
    """The coloured-input model for this window: band-limited frequency-domain convolution where
    the window's power kernel falls fast enough (Hann, flat top), lag domain otherwise."""
    if _kernel(settings, FINE_PER_LINE)[1] is not None:
        return _InputLeakage
    return _LagInputLeakage


def _sensor_divided(coherent, sensor) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where((sensor == 0) & (coherent == 0), 0.0, coherent / sensor)
    if not np.all(np.isfinite(u)):
        raise FitError("input_spectrum.sensor is zero or the PSD is not finite where the leakage "
                       "model needs it")
    return u


class _InputLeakage:
    """``E[H1]`` of the discrete modal response under a coloured input (module notes):
    ``E_k = K_k T[S / K / (zeta - z)]_k / T[S + N]_k`` with ``T[F]_k = (1/n2) sum_j D[k M - j]
    F_j`` on a grid ``M`` times finer than the lines, ``D`` the window's power kernel, applied as
    a band-limited convolution over the ``L`` lines beyond which its tail is below
    :data:`KERNEL_TOL` (Hann: 27 lines, flat top: 102)."""

    def __init__(self, settings: SpectralSettings, lines: np.ndarray, spectrum: InputSpectrum,
                 fine: int = FINE_PER_LINE):
        n, fs, mm = settings.nperseg, settings.fs, int(fine)
        self.n2, self.fs, self.lines, self.fine = mm * n, fs, lines, mm
        d_half, ll, self.kernel_tail = _kernel(settings, mm)
        if ll is None:
            raise FitError(f"the {settings.window} window's power kernel falls too slowly for a "
                           "band-limited convolution")
        self.kernel_lines = ll
        jj = np.arange((lines.min() - ll) * mm, (lines.max() + ll) * mm + 1)
        off = np.arange(-ll * mm, ll * mm + 1)
        self.nc = _fast_len(jj.size + off.size - 1)
        self.khat = np.fft.fft(d_half[np.abs(off)], self.nc)
        self.pick = lines * mm - jj[0] + ll * mm
        nu = jj * (fs / self.n2)
        coherent, total, sensor = spectrum.evaluate(nu)
        self.u = _sensor_divided(coherent, sensor)
        den = self._apply(total[None, :].astype(complex))[0].real
        if not np.all(den > 0):
            raise FitError("input_spectrum.psd is zero on a fitted line: the input has no power "
                           "there")
        _, _, sensor_k = spectrum.evaluate(lines * (fs / n))
        self.factor = sensor_k / den
        self.zeta = np.exp(2j * np.pi * nu / fs)

    def _apply(self, f: np.ndarray) -> np.ndarray:
        """``T[F]`` at the fitted lines for each row of ``f`` (b, n_grid)."""
        out = np.fft.ifft(np.fft.fft(f, self.nc, axis=-1) * self.khat, axis=-1)
        return out[:, self.pick] / self.n2

    def __call__(self, z: np.ndarray, *, jac: bool):
        m = z.size
        g1 = 1.0 / (self.zeta[None, :] - z[:, None])
        g2 = 1.0 / (self.zeta[None, :] - np.conj(z)[:, None])
        rows = [g1, g2, g1 * g1, g2 * g2] if jac else [g1, g2]
        t = self._apply(np.concatenate(rows, axis=0) * self.u) * self.factor
        a, b = t[:m], t[m:2 * m]
        return (a, b, t[2 * m:3 * m], t[3 * m:]) if jac else (a, b, None, None)

    @staticmethod
    def fine_for(settings: SpectralSettings, tau_s: float) -> int:
        """Points per line making the fine grid's time aliasing, ``exp(-(M - 1) N / (fs tau))``,
        below :data:`KERNEL_TOL` for a slowest decay time ``tau_s`` [s] (at least
        :data:`FINE_PER_LINE`, at most :data:`MAX_FINE_GRID` points around the circle)."""
        need = 1.0 + settings.fs * tau_s * math.log(1.0 / KERNEL_TOL) / settings.nperseg
        most = max(FINE_PER_LINE, MAX_FINE_GRID // settings.nperseg)
        return max(FINE_PER_LINE, min(int(math.ceil(min(need, 1e9))), most))

    def alias_bound(self, tau_s: float) -> float:
        """Time aliasing of the fine grid for a slowest decay time ``tau_s`` [s]:
        ``exp(-(n2 - N) / (fs tau))``."""
        n = self.n2 // self.fine
        return math.exp(-(self.n2 - n) / (self.fs * tau_s)) if tau_s > 0 else 0.0


class _LagInputLeakage:
    """The same model in the lag domain, for any window: with ``R_U`` the correlation of
    ``U = S / K`` (an inverse FFT on ``n_r`` points, once) the numerator's correlation for the
    term ``1 / (zeta - z)`` is ``R[tau] = sum_{m >= 1} z^(m-1) R_U[tau - m]``, needed for
    ``|tau| < N``: a convolution of ``R_U[-N+1 .. N-2]`` with ``z^n`` (one FFT of ~4N) plus
    ``z^(tau+N-1) Q(z)``, ``Q(z) = sum_j z^j R_U[-N-j]`` over the tail of ``R_U`` (where it
    exceeds :data:`KERNEL_TOL` of its peak); then tapered by ``r_w`` and transformed like the
    white-input model. Exact up to the time aliasing of ``R_U`` (its decay ``decay_s`` sets
    ``n_r``; measured and reported as :attr:`alias`), whatever the modes' Q."""

    def __init__(self, settings: SpectralSettings, lines: np.ndarray, spectrum: InputSpectrum):
        n, fs = settings.nperseg, settings.fs
        self.n, self.lines = n, lines
        self.r = window_autocorrelation(settings)
        decay = max(float(spectrum.decay_s), n / fs)
        n_r = 1 << int(math.ceil(math.log2(max(8 * n, 4 * (n + fs * decay
                                                            * math.log(1 / KERNEL_TOL))))))
        n_r = min(n_r, MAX_LAG_GRID)
        f = np.arange(n_r // 2 + 1) * (fs / n_r)
        coherent, total, sensor = spectrum.evaluate(f)
        u = _sensor_divided(coherent, sensor)
        u[-1] = u[-1].real
        ru = np.fft.irfft(u, n_r)
        rs = np.fft.irfft(total, n_r)
        peak = float(np.max(np.abs(ru)))
        # R_U at lags -N+1 .. N-2 (the convolution) and the tail -N, -N-1, ... (to n_r/2)
        self.window_seq = np.concatenate([ru[n_r - n + 1:], ru[:n - 1]])
        tail = ru[n_r - n::-1][: n_r // 2 - n]
        big = np.nonzero(np.abs(tail) > KERNEL_TOL * peak)[0]
        self.tail = tail[: big[-1] + 1] if big.size else tail[:1]
        self.alias = float(np.max(np.abs(ru[n_r // 2 - n: n_r // 2 + n]))) / peak
        self.nc = _fast_len(4 * n)
        self.xhat = np.fft.fft(self.window_seq, self.nc)
        den = self._taper(np.concatenate([rs[n_r - n + 1:], rs[:n]])[None, :])[0]
        den = den[lines].real
        if not np.all(den > 0):
            raise FitError("input_spectrum.psd is zero on a fitted line: the input has no power "
                           "there")
        _, _, sensor_k = spectrum.evaluate(lines * (fs / n))
        self.factor = sensor_k / den

    def _taper(self, seq: np.ndarray) -> np.ndarray:
        """``sum_tau r_w(|tau|) R[tau] exp(-2j pi k tau / N)`` for all ``k`` from ``R`` at lags
        ``-N+1 .. N-1`` (rows of ``seq``)."""
        n = self.n
        buf = seq[:, n - 1:] * self.r  # lags 0 .. N-1
        buf[:, 1:] += seq[:, :n - 1] * self.r[1:][::-1]  # lags -(N-1) .. -1 wrap to 1 .. N-1
        return np.fft.fft(buf, axis=-1)

    def __call__(self, z: np.ndarray, *, jac: bool):
        n, k = self.n, self.lines
        logz = np.log(z.astype(complex))[:, None]
        nb = np.arange(2 * n - 1)
        pw = np.exp(logz * nb)  # z^0 .. z^(2N-2)
        jt = np.arange(self.tail.size)
        pt = np.exp(logz * jt)  # z^j over the tail
        q = pt @ self.tail  # Q(z)
        conv = np.fft.ifft(np.fft.fft(pw[:, :2 * n - 2], self.nc, axis=-1) * self.xhat,
                           axis=-1)[:, :2 * n - 2]
        seq = np.empty((z.size, 2 * n - 1), complex)  # R at lags -N+1 .. N-1
        seq[:, 0] = 0.0
        seq[:, 1:] = conv
        seq += pw * q[:, None]
        rows = [seq]
        if jac:
            dpw = np.zeros_like(pw)
            dpw[:, 1:] = nb[1:] * pw[:, :-1]  # d z^b / dz
            dq = (jt[1:] * pt[:, :-1]) @ self.tail[1:] if jt.size > 1 else np.zeros(z.size)
            dconv = np.fft.ifft(np.fft.fft(dpw[:, :2 * n - 2], self.nc, axis=-1) * self.xhat,
                                axis=-1)[:, :2 * n - 2]
            dseq = np.empty_like(seq)
            dseq[:, 0] = 0.0
            dseq[:, 1:] = dconv
            dseq += dpw * q[:, None] + pw * dq[:, None]
            rows.append(dseq)
        t = self._taper(np.concatenate(rows, axis=0))
        m = z.size
        a = t[:m, k] * self.factor
        b = np.conj(t[:m, (-k) % n]) * self.factor
        if not jac:
            return a, b, None, None
        return a, b, t[m:, k] * self.factor, np.conj(t[m:, (-k) % n]) * self.factor


# -- the fit ---------------------------------------------------------------------------------

def _correlation_matrix(lines: np.ndarray, corr: np.ndarray) -> np.ndarray:
    lag = np.abs(lines[:, None] - lines[None, :])
    return np.where(lag < corr.size, corr[np.minimum(lag, corr.size - 1)], 0.0)


def _correlate_lines(lines: np.ndarray, corr: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R @ x`` for ``R = _correlation_matrix(lines, corr)`` without forming ``R``: ``lines``
    ascending and distinct, ``corr`` (a few lags) from :func:`line_correlation`."""
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
    n_fit = len(initial) if initial is not None else (n_modes or 0)
    if n_fit and 2 * f.size <= 4 * n_fit + 2 * n_residual:  # checked again below, once known
        raise FitError(f"{f.size} lines in {band_hz} Hz for {4 * n_fit + 2 * n_residual} real "
                       "parameters: widen the band, fit fewer modes or use finer lines")
    starts = _initial_modes(f, h, n_modes, initial, df)
    broadened = [not given for _, _, given in starts]
    starts = [(f0, q0) for f0, q0, _ in starts]
    m = len(starts)
    n_lin = 2 * m + 2 * n_residual
    n_par = 2 * m + n_lin
    if 2 * f.size <= n_par:
        raise FitError(f"{f.size} lines in {band_hz} Hz for {n_par} real parameters: widen the "
                       "band, fit fewer modes or use finer lines")
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

    def slowest(fq, factors=None) -> float:  # decay time [s] the fine grid must hold
        factors = [1.0] * len(fq) if factors is None else factors
        return max([float(input_spectrum.decay_s)]
                   + [c * q / (math.pi * fr) for (fr, q), c in zip(fq, factors)])

    if method == "direct":
        terms = _DirectTerms(f, domain, fs)
    elif input_spectrum is None:
        terms = _WhiteLeakage(settings, lines)
    elif _input_terms(settings) is _LagInputLeakage:
        terms = _LagInputLeakage(settings, lines, input_spectrum)
    else:  # a Q read off a leakage-broadened peak is about half the mode's (module notes)
        terms = _InputLeakage(settings, lines, input_spectrum, _InputLeakage.fine_for(
            settings, slowest(starts, [2.0 if b else 1.0 for b in broadened])))
    basis = _poly_basis(f, n_residual, fc, fh)
    model = _Model(terms, basis, m, domain, fs)
    span = hi - lo
    # A decay over a thousand records is indistinguishable from none: Q is bounded there.
    q_max = max(1e3 * math.pi * hi / df, 10.0 * max(q for _, q in starts))
    theta, beta, n_iter, converged = _varpro(model, h, sigma, np.array(starts, float), lo, span,
                                             q_max)
    if isinstance(terms, _InputLeakage):
        fine = _InputLeakage.fine_for(settings, slowest(theta))
        if fine > terms.fine:  # the modes decay more slowly than the start said: once more, on
            terms = _InputLeakage(settings, lines, input_spectrum, fine)  # the grid they need
            model = _Model(terms, basis, m, domain, fs)
            theta, beta, more, converged = _varpro(model, h, sigma, theta, lo, span, q_max)
            n_iter += more
    params = np.concatenate([theta.ravel(), beta])
    fitted, jac = model.full(params)
    jw = _real_stack(jac / sigma[:, None])
    try:
        a_inv = np.linalg.inv(jw.T @ jw)
    except np.linalg.LinAlgError:
        raise FitError("the fit's normal matrix is singular: a mode is not determined by the "
                       "data (too few lines near it, or two modes at one frequency)") from None
    if correlated:  # sandwich: A^-1 (J^T R J) A^-1, R acting on the Re and Im halves alike
        nl = f.size
        rj = np.concatenate([_correlate_lines(lines, corr, jw[:nl]),
                             _correlate_lines(lines, corr, jw[nl:])], axis=0)
        cov = a_inv @ (jw.T @ rj) @ a_inv * cov_factor
    else:
        cov = a_inv * cov_factor
    r = _real_stack((fitted - h) / sigma)
    chi2 = float(r @ r)
    dof = 2 * f.size - n_par
    fq, c, a_res = _split(params, m, n_residual)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    notes = []
    modes = []
    order = np.argsort(fq[:, 0])
    input_txt = "white input" if input_spectrum is None else f"input: {input_spectrum.label}"
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
                         f"the leakage-aware model ({input_txt})")
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
        line_correlated=correlated, notes=(), input_spectrum=input_spectrum,
        iterations=n_iter)
    if not converged:
        notes.append(f"least squares did not converge in {n_iter} iterations")
    if isinstance(terms, _InputLeakage):
        tau = slowest(fq)
        bound = terms.alias_bound(tau)
        if bound > 10 * KERNEL_TOL:
            notes.append(f"the coloured-input model's fine grid ({terms.fine} points per line, "
                         f"at most {MAX_FINE_GRID} around the circle) aliases the slowest fitted "
                         f"decay (tau = {tau:.3g} s) by up to {bound:.1e} (relative)")
    if isinstance(terms, _LagInputLeakage) and terms.alias > 10 * KERNEL_TOL:
        notes.append(f"the input's correlation is not negligible at half the lag grid "
                     f"({terms.alias:.1e} of its peak): give input_spectrum.decay_s")
    if not fit.adequate:
        notes.append(f"reduced chi^2 = {fit.reduced_chi2:.3g} (expected {expected_chi2:.3g} +- "
                     f"{math.sqrt(2 / dof):.2g}): systematic misfit; uncertainties understate "
                     f"the error (Birge factor {fit.birge_factor:.3g})")
    if not correlated and weighting == "coherence" and settings is None:
        notes.append("no settings: lines taken as independent (uncertainties understated for "
                     "windows that correlate neighbouring lines)")
    object.__setattr__(fit, "notes", tuple(notes))
    return fit


def _real_stack(z: np.ndarray) -> np.ndarray:
    return np.concatenate([z.real, z.imag], axis=0)


def _expit(x):
    """The logistic function ``1 / (1 + exp(-x))``, accurate also for large negative ``x``."""
    e = np.exp(-np.abs(x))
    return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


class _Model:
    """The modal model on the fitted lines, from one of the term models: for poles ``z_r`` the
    terms ``a_r, b_r`` (and ``d a_r / d z_r``, ``d b_r / d conj(z_r)``) give
    ``H = sum_r [c_r a_r + conj(c_r) b_r] + P``, linear in ``c`` and ``P``'s coefficients."""

    def __init__(self, terms, basis: np.ndarray, m: int, domain: str, fs: float | None):
        self.terms, self.basis, self.m, self.domain, self.fs = terms, basis, m, domain, fs

    def poles(self, fq: np.ndarray):
        """``z_r`` and ``d z_r / d f_r``, ``d z_r / d Q_r`` for (m, 2) ``(f, Q)``."""
        z = np.empty(self.m, complex)
        dz = np.empty((self.m, 2), complex)
        for r, (fr, q) in enumerate(fq):
            p, dpf, dpq = _pole_derivs(float(fr), float(q))
            if self.domain == "z":
                z[r] = np.exp(p / self.fs)
                dz[r] = (z[r] * dpf / self.fs, z[r] * dpq / self.fs)
            else:
                z[r] = p
                dz[r] = (dpf, dpq)
        return z, dz

    def design(self, fq: np.ndarray, *, jac: bool):
        """The linear design matrix (n, n_lin) for ``[Re c_r, Im c_r, ..., Re a_j, Im a_j]`` and,
        with ``jac``, the terms and pole derivatives."""
        z, dz = self.poles(fq)
        a, b, da, db = self.terms(z, jac=jac)
        n = self.basis.shape[0]
        cols = np.empty((n, 2 * self.m + 2 * self.basis.shape[1]), complex)
        cols[:, 0:2 * self.m:2] = (a + b).T
        cols[:, 1:2 * self.m:2] = 1j * (a - b).T
        cols[:, 2 * self.m::2] = self.basis
        cols[:, 2 * self.m + 1::2] = 1j * self.basis
        return cols, (z, dz, da, db)

    def mode_derivs(self, c: np.ndarray, extra) -> np.ndarray:
        """d H / d (f_r, Q_r), complex (n, 2 m), for residues ``c``."""
        _, dz, da, db = extra
        out = np.empty((self.basis.shape[0], 2 * self.m), complex)
        for r in range(self.m):
            for i in range(2):
                out[:, 2 * r + i] = c[r] * da[r] * dz[r, i] + np.conj(c[r]) * db[r] * \
                    np.conj(dz[r, i])
        return out

    def full(self, params: np.ndarray):
        """Model and complex Jacobian (n, n_params) in the order of :attr:`ModalFit.params`."""
        m = self.m
        fq = params[:2 * m].reshape(m, 2)
        beta = params[2 * m:]
        cols, extra = self.design(fq, jac=True)
        c = beta[0:2 * m:2] + 1j * beta[1:2 * m:2]
        return cols @ beta, np.concatenate([self.mode_derivs(c, extra), cols], axis=1)


def _varpro(model: _Model, h: np.ndarray, sigma: np.ndarray, starts: np.ndarray, lo: float,
            span: float, q_max: float, *, max_iter: int = 200):
    """Weighted least squares by variable projection: the residues and the residual polynomial
    are solved linearly for every trial ``(f, Q)``, which Levenberg-Marquardt (Kaufman's
    Jacobian of the projected residual) moves in ``v = logit((f - lo) / span)``,
    ``u = logit((Q - 1/2) / q_max)`` (``Q - 1/2 ~ q_max e^u`` below ``q_max``): modes stay in the
    band, underdamped, with ``Q < q_max``. Returns ``(f, Q)`` (m, 2), the linear parameters, the
    iterations and whether it converged."""
    m = model.m
    y = _real_stack(h / sigma)
    yy = float(y @ y)

    def to_fq(x):
        fq = np.empty((m, 2))
        fq[:, 0] = lo + span * _expit(x[0::2])
        fq[:, 1] = 0.5 + q_max * _expit(x[1::2])
        return fq

    def evaluate(x):
        fq = to_fq(x)
        cols, extra = model.design(fq, jac=True)
        aw = _real_stack(cols / sigma[:, None])
        qm, rm = np.linalg.qr(aw)
        try:
            beta = np.linalg.solve(rm, qm.T @ y)
        except np.linalg.LinAlgError:
            beta = np.linalg.lstsq(aw, y, rcond=None)[0]
        res = y - aw @ beta
        c = beta[0:2 * m:2] + 1j * beta[1:2 * m:2]
        dv = _real_stack(model.mode_derivs(c, extra) / sigma[:, None])
        jac = -(dv - qm @ (qm.T @ dv))  # Kaufman: -P_perp (dA/dtheta) beta
        e = _expit(x[0::2])
        jac[:, 0::2] *= span * e * (1.0 - e)
        jac[:, 1::2] *= (fq[:, 1] - 0.5) * (1.0 - _expit(x[1::2]))
        return float(res @ res), res, jac, beta

    x = np.empty(2 * m)
    frac = np.clip((starts[:, 0] - lo) / span, 1e-9, 1 - 1e-9)
    x[0::2] = np.log(frac / (1.0 - frac))
    qf = np.clip((starts[:, 1] - 0.5) / q_max, 1e-300, 1 - 1e-9)
    x[1::2] = np.log(qf / (1.0 - qf))
    cost, res, jac, beta = evaluate(x)
    mu, nu = None, 2.0
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        g = jac.T @ res
        a = jac.T @ jac
        dscale = np.maximum(np.diag(a), 1e-300)
        try:  # the Gauss-Newton decrement: what is left to gain, to second order
            left = float(g @ np.linalg.solve(a, g))
        except np.linalg.LinAlgError:
            left = math.inf
        if left <= 1e-12 * cost + 1e-24 * yy:  # (the second term: round-off of a zero residual)
            converged = True
            break
        if mu is None:
            mu = 1e-3  # relative to each diagonal element (Marquardt's scaling)
        try:
            step = np.linalg.solve(a + mu * np.diag(dscale), -g)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        if np.max(np.abs(step)) < 1e-13 * (1.0 + np.max(np.abs(x))):
            converged = True  # no further decrease within round-off
            break
        x_new = x + step
        cost_new, res_new, jac_new, beta_new = evaluate(x_new)
        if cost_new < cost:
            predicted = -(step @ g) - 0.5 * step @ a @ step
            gain = (cost - cost_new) / (2.0 * predicted) if predicted > 0 else 0.0
            x, cost, res, jac, beta = x_new, cost_new, res_new, jac_new, beta_new
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
    return to_fq(x), beta, it, converged


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


def rotation_reading(theta2: MeasuredResponse, theta1, *, band_hz: tuple[float, float],
                     theta1_scale: float = 1.0, model_ratio=None, exact_limit: float | None = None,
                     alpha: float | None = None,
                     settings: SpectralSettings | None = None) -> RotationReading:
    """Measured ``|Theta_2 / Theta_1|`` in a band above f1, next to the exact model and alpha.

    Parameters
    ----------
    theta2 : MeasuredResponse of the rotation channel (rad per input unit).
    theta1 : MeasuredResponse of a channel proportional to Theta_1 (e.g. the mirror translation
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
    if isinstance(theta1, MeasuredResponse):
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
