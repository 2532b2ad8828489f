"""The modal model of :func:`processing.modal.fit_modes` and its leakage-aware design terms.

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

Leakage-aware terms: :class:`WhiteLeakage` (white input) and, for a coloured input
(:class:`InputSpectrum`), :class:`InputLeakage` (banded convolution on a fine frequency grid) or
:class:`LagInputLeakage` (lag domain, for windows whose power kernel falls slowly); their
equations and errors are in :mod:`processing.modal`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from processing.spectra import ProcessingError, SpectralSettings, window_autocorrelation

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


def mode_pole(f_hz: float, q: float) -> complex:
    """The s-plane pole ``p = w (-1/(2Q) + i sqrt(1 - 1/(4Q^2)))`` [rad/s] of a mode of natural
    frequency ``f_hz`` [Hz] and quality factor ``q``, ``w = 2 pi f_hz`` (real for ``Q <= 1/2``:
    the square root's argument is clipped at 0)."""
    w = 2 * np.pi * f_hz
    return complex(w * (-0.5 / q + 1j * math.sqrt(max(1.0 - 0.25 / q**2, 0.0))))


def mode_pole_derivs(f_hz: float, q: float) -> tuple[complex, complex, complex]:
    """:func:`mode_pole` and its derivatives ``dp/df`` [rad/s per Hz], ``dp/dQ`` [rad/s]."""
    s = math.sqrt(max(1.0 - 0.25 / q**2, 1e-300))
    w = 2 * np.pi * f_hz
    p = w * (-0.5 / q + 1j * s)
    dp_df = 2 * np.pi * (-0.5 / q + 1j * s)
    dp_dq = w * (0.5 / q**2 + 1j * 0.25 / (q**3 * s))
    return p, dp_df, dp_dq


def poly_basis(f, n_res, fc, fh) -> np.ndarray:
    """The residual polynomial's basis ``((f - fc) / fh)^j``, ``j < n_res``, shape
    ``(f.size, n_res)`` (module docstring: ``fc``, ``fh`` the band's centre and half-width)."""
    x = (f - fc) / fh
    return np.stack([x**j for j in range(n_res)], axis=-1) if n_res else np.zeros((f.size, 0))


def unpack_params(params, m, n_res):
    """The fit's real parameter vector ``[f_1, Q_1, ..., Re c_1, Im c_1, ..., Re a_0, Im a_0,
    ...]`` as ``(f, Q)`` (m, 2), the complex residues ``c`` (m,) and the complex polynomial
    coefficients ``a`` (n_res,)."""
    fq = params[: 2 * m].reshape(m, 2)
    c = params[2 * m: 4 * m].reshape(m, 2)
    a = params[4 * m: 4 * m + 2 * n_res].reshape(n_res, 2)
    return fq, c[:, 0] + 1j * c[:, 1], a[:, 0] + 1j * a[:, 1]


def direct_model(params, f, m, n_res, domain, fs, fc, fh, *, jac=True):
    """The modal model (module docstring) at ``f`` [Hz] for the parameters ``params``
    (:func:`unpack_params`) and its complex Jacobian (n, n_params), None without ``jac``."""
    fq, c, a = unpack_params(params, m, n_res)
    w = 2 * np.pi * f
    if domain == "z":
        x = np.exp(1j * w / fs)
    else:
        x = 1j * w
    basis = poly_basis(f, n_res, fc, fh)
    h = basis @ a if n_res else np.zeros(f.size, complex)
    J = np.zeros((f.size, params.size), complex) if jac else None
    for r in range(m):
        p, dpf, dpq = mode_pole_derivs(*fq[r])
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


class DirectTerms:
    """The modal model itself on the fitted lines: ``a = 1 / (x - z)``, ``b = 1 / (x - conj z)``
    with ``x = exp(i w T)`` (domain "z") or ``i w`` (domain "s")."""

    def __init__(self, f: np.ndarray, domain: str, fs: float | None):
        w = 2 * np.pi * f
        self.x = np.exp(1j * w / fs) if domain == "z" else 1j * w

    def __call__(self, z: np.ndarray, *, jac: bool):
        u1 = 1.0 / (self.x[None, :] - z[:, None])
        u2 = 1.0 / (self.x[None, :] - np.conj(z)[:, None])
        return (u1, u2, u1 * u1, u2 * u2) if jac else (u1, u2, None, None)


class WhiteLeakage:
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


def coloured_input_terms(settings: SpectralSettings):
    """The coloured-input model for this window: band-limited frequency-domain convolution where
    the window's power kernel falls fast enough (Hann, flat top), lag domain otherwise."""
    if _kernel(settings, FINE_PER_LINE)[1] is not None:
        return InputLeakage
    return LagInputLeakage


def _sensor_divided(coherent, sensor) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where((sensor == 0) & (coherent == 0), 0.0, coherent / sensor)
    if not np.all(np.isfinite(u)):
        raise FitError("input_spectrum.sensor is zero or the PSD is not finite where the leakage "
                       "model needs it")
    return u


class InputLeakage:
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


class LagInputLeakage:
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
