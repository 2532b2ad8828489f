"""Measured frequency response against the exact model: random error, leakage bias, statistics.

A measured H1 differs from the exact response ``H`` of the system for two reasons (SPEC section 6):

* **leakage bias**, deterministic: for a white input the expected estimate is
  ``E[H1](f_k) = sum_tau g[tau] r_w(|tau|) exp(-2j pi f_k tau / fs)``, the discrete-time impulse
  response ``g`` tapered by the window's normalised autocorrelation ``r_w`` (zero beyond
  ``nperseg`` lags; :func:`processing.frf.expected_h1`, extended here to two-sided responses by
  :func:`expected_h1_taps`). ``bias = E[H1] - H``. It matters where ``H`` changes on the scale of
  a line: at the 2.48 Hz mode of the ``ishizaki2009`` preset (Q ~ 529, half-power bandwidth
  ``f/Q`` ~ 4.7 mHz) a 100 s record's 10 mHz lines cannot resolve the peak;
* **random error**: ``measured - E[H1]``, predicted by Bendat & Piersol from the measured coherence
  (:attr:`processing.frf.FrequencyResponse.relative_error`, ``eps``), as standard deviation of the
  relative error along (gain) and across (phase) the response.

:func:`compare` takes the measured response, the exact model on the same lines and (optionally)
``E[H1]``, and reports residuals normalised by ``eps``, per band, plus the bias and the random
part at each resonance peak.

The exact discrete-time impulse response
----------------------------------------
``E[H1]`` needs the impulse response ``g[tau]`` from the *sampled* input to the *sampled* output,
which depends on how the input behaves between samples. :class:`LinearModel` (the continuous
linear model ``z' = A z + B u``, ``y = C z``) offers both cases:

``method="zoh"``
    The input is held constant over each sample interval and the accelerometer reads the held
    value (a synthetic measurement driven by a zero-order-hold source). Then exactly
    ``z[n+1] = Phi z[n] + Gamma u[n]`` with ``Phi = expm(A T)``, ``Gamma = int_0^T expm(A s) ds B``
    (one :func:`scipy.linalg.expm` of the block matrix ``[[A T, B T], [0, 0]]``, Van Loan), so
    ``g[0] = 0`` and ``g[n] = C Phi^(n-1) Gamma``. Error: round-off only (``expm`` ~1e-15
    relative, and ``n`` matrix-vector products accumulate ~``n`` ulp: ~1e-12 at n = 10^4).
    Its frequency response is ``C (exp(i w T) I - Phi)^-1 Gamma``, which differs from the
    continuous ``H(i w)`` by the hold (about ``exp(-i w T / 2) sinc(f T)``: -1.8 deg at 1 Hz,
    -18 deg at 10 Hz for T = 10 ms) and by aliasing: compare such data with
    :meth:`DiscreteModel.frequency_response`, not with the continuous response.
``method="bandlimited"``
    Every channel passed through the same anti-alias filter before sampling (the bench of
    :mod:`daq`, whose common filter cancels in the ratio), so the sampled input is band-limited
    and the sampled output is ``g * u`` with ``g`` the inverse DTFT of the continuous ``H(i w)``
    on ``|f| < fs/2``. Computed by an inverse real FFT of ``H`` sampled on ``n_fft`` points of
    ``[0, fs/2]`` (the Nyquist bin takes ``Re H(fs/2)``, the midpoint of the jump of the
    periodic DTFT). ``g`` is two-sided (slightly non-causal: the band limit is an ideal low-pass).
    Error: sampling the DTFT aliases ``g`` in time with period ``n_fft``. The lightest-damped
    mode's envelope ``exp(-pi f n_fft / (fs Q))`` bounds one part (``n_fft`` is chosen to make it
    below 1e-12); the jump of the DTFT at Nyquist leaves a tail falling as ``1/tau`` whose alias
    is about ``|H(fs/2)| / (pi n_fft / 2)`` relative to ``|H|`` (1e-11 for the broad test chain at
    n_fft = 16384). The reported ``error`` measures both as the change when ``n_fft`` doubles.

Statistics of normalised residuals
----------------------------------
With ``n_d`` averages and the band from the *measured* coherence, a normalised gain or phase
residual of an unbiased H1 is Student-t distributed: ``t_nu sqrt(n_d / (n_d - 1))`` with
``nu = 2 (n_d - 1)`` degrees of freedom (conditional on the input, the error of H1 is Gaussian
with variance ``G_nn / (n_d G_xx)``; the residual power estimate behind the coherence is
``chi^2_nu`` and independent of it). :func:`expected_fraction_within` gives the fraction of lines
within ``k`` sigma (0.9460 for k = 2, n_d = 30, against 0.9545 for a normal law). Lines are
correlated through the window: the complex errors of lines ``j`` apart have correlation
``|rho_j|^2``, ``rho_j`` the normalised transform of ``w^2`` (Hann: 4/9, 1/36), so the binomial
standard error of a fraction over ``N`` lines is inflated by ``sqrt(1 + 2 sum_j c_j)`` with
``c_j`` the indicator correlations (Hann: 1.089; :func:`fraction_standard_error`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from processing.frf import FrequencyResponse
from processing.spectra import (ProcessingError, SettingsError, SpectralSettings, _autocorrelation,
                                _readonly)

__all__ = [
    "ModelError", "LinearModel", "DiscreteModel", "ImpulseResponse", "simulate_records",
    "window_autocorrelation", "expected_h1_taps",
    "line_correlation", "expected_fraction_within", "fraction_standard_error", "BandStats",
    "PeakBias", "Comparison", "compare",
]

IMPULSE_METHODS = ("zoh", "bandlimited")


class ModelError(ProcessingError, ValueError):
    """A model, or a model array, that does not fit the measurement (shape, frequencies, NaN)."""


def _as_matrix(name: str, value, shape: tuple | None = None) -> np.ndarray:
    a = np.array(value, dtype=float, ndmin=2)
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise ModelError(f"{name} has shape {a.shape} or non-finite entries: expected a finite "
                         "2-D array")
    if shape is not None:
        for i, (got, want) in enumerate(zip(a.shape, shape)):
            if want is not None and got != want:
                raise ModelError(f"{name} has shape {a.shape}: expected axis {i} of length {want}")
    a.setflags(write=False)
    return a


def _output_index(outputs: tuple, name) -> int:
    try:
        return outputs.index(name)
    except ValueError:
        raise ModelError(f"output {name!r} is not present: expected one of {outputs}") from None


def _pole_residues(a, b, c_row, key):
    lam, v = np.linalg.eig(a)
    res = (c_row @ v) * (np.linalg.inv(v) @ b[:, 0])
    up = lam.imag > 0
    lam, res = lam[up], res[up]
    order = np.argsort(key(lam))
    return lam[order], res[order]


def _poles_to_fq(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency [Hz] and Q of the oscillatory continuous poles (Im > 0), ascending."""
    osc = lam[lam.imag > 0]
    osc = osc[np.argsort(np.abs(osc))]
    with np.errstate(divide="ignore"):
        q = np.abs(osc) / (-2.0 * osc.real)
    return np.abs(osc) / (2 * np.pi), q


# -- the exact model -------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class LinearModel:
    """A continuous single-input linear model ``z' = A z + B u``, ``y = C z`` (no feedthrough).

    Parameters
    ----------
    a : (nz, nz) state matrix [1/s].
    b : (nz, 1) input matrix [state unit / (input unit s)].
    c : (n_out, nz) output matrix: one row per output channel.
    outputs : tuple of str
        Names of the output channels (rows of ``c``), e.g. ``("x", "y")``.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    outputs: tuple = ("y",)

    def __post_init__(self):
        a = _as_matrix("a", self.a)
        nz = a.shape[0]
        if a.shape != (nz, nz):
            raise ModelError(f"a has shape {a.shape}: expected a square matrix")
        set_ = object.__setattr__
        set_(self, "a", a)
        set_(self, "b", _as_matrix("b", np.reshape(self.b, (nz, -1)), (nz, 1)))
        set_(self, "c", _as_matrix("c", self.c, (None, nz)))
        outs = tuple(self.outputs)
        if len(outs) != self.c.shape[0] or len(set(outs)) != len(outs):
            raise ModelError(f"outputs = {self.outputs!r} is invalid: expected {self.c.shape[0]} "
                             "distinct names, one per row of c")
        set_(self, "outputs", outs)

    @classmethod
    def from_chain(cls, chain, outputs: Mapping[str, Sequence[float]]) -> LinearModel:
        """The linearised chain (:meth:`rig.chain.Chain.state_space`) with outputs
        ``weights . theta`` [output unit per rad], input the base acceleration [m/s^2]."""
        a, b = chain.state_space()
        n = chain.n
        rows = []
        for name, w in outputs.items():
            w = np.asarray(w, dtype=float)
            if w.shape != (n,):
                raise ModelError(f"output {name!r} has weights of shape {w.shape}: expected ({n},)")
            rows.append(np.concatenate([w, np.zeros(n)]))
        return cls(a, b, np.array(rows), tuple(outputs))

    @classmethod
    def from_scene(cls, scene) -> LinearModel:
        """SPEC section 5's channels of a scene: ``x`` (mirror translation relative to the stage
        [m per m/s^2]) and ``y`` (angle of the mirror's body [rad per m/s^2])."""
        n = scene.chain.n
        return cls.from_chain(scene.chain, {"x": scene.mirror_weights(),
                                            "y": np.eye(n)[scene.mirror.body]})

    def output_index(self, output) -> int:
        """Row of ``output`` in ``c``; :class:`ModelError` if absent."""
        return _output_index(self.outputs, output)

    def frequency_response(self, freqs_hz, output=None) -> np.ndarray:
        """``C (i w I - A)^-1 B`` at ``freqs_hz`` [Hz]: shape ``(nf, n_out)``, or ``(nf,)`` for one
        named ``output``."""
        w = 2 * np.pi * np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        nz = self.a.shape[0]
        m = 1j * w[:, None, None] * np.eye(nz) - self.a
        x = np.linalg.solve(m, np.broadcast_to(self.b.astype(complex), (w.size, nz, 1)))[..., 0]
        h = x @ self.c.T
        return h if output is None else h[:, self.output_index(output)]

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies [Hz] and Q of the oscillatory modes, ascending."""
        return _poles_to_fq(np.linalg.eigvals(self.a))

    def pole_residues(self, output) -> tuple[np.ndarray, np.ndarray]:
        """Poles ``p_r`` (Im > 0, ascending ``|p|``) [rad/s] and residues ``R_r`` of ``output``:
        ``H(s) = sum_r R_r / (s - p_r) + conj(R_r) / (s - conj(p_r))``."""
        return _pole_residues(self.a, self.b, self.c[self.output_index(output)], np.abs)

    def discretise(self, fs: float) -> DiscreteModel:
        """Exact zero-order-hold discretisation at ``fs`` [Hz] (Van Loan block ``expm``)."""
        if not (math.isfinite(fs) and fs > 0):
            raise ModelError(f"fs = {fs!r} is invalid: expected a finite rate > 0 Hz")
        t = 1.0 / fs
        nz = self.a.shape[0]
        big = np.zeros((nz + 1, nz + 1))
        big[:nz, :nz] = self.a * t
        big[:nz, nz:] = self.b * t
        from scipy.linalg import expm

        e = expm(big)
        return DiscreteModel(e[:nz, :nz], e[:nz, nz:], self.c, float(fs), self.outputs)

    def impulse_response(self, fs: float, n_taps: int, *, method: str = "zoh",
                         n_fft: int | None = None) -> ImpulseResponse:
        """Discrete-time impulse response from the sampled input to every sampled output.

        Parameters
        ----------
        fs : sample rate [Hz].
        n_taps : number of causal taps ``g[0 .. n_taps-1]`` (use ``settings.nperseg``: the
            window's autocorrelation is zero beyond).
        method : {"zoh", "bandlimited"}
            See the module notes: a held input sampled at the hold instants, or a band-limited
            input (common anti-alias filter).
        n_fft : for ``"bandlimited"``: FFT length (default: a power of two making the slowest
            mode's time aliasing below 1e-12 and at least ``4 n_taps``).

        Returns
        -------
        ImpulseResponse
        """
        if method not in IMPULSE_METHODS:
            raise ModelError(f"method = {method!r} is invalid: expected one of {IMPULSE_METHODS}")
        n_taps = int(n_taps)
        if n_taps < 2:
            raise ModelError(f"n_taps = {n_taps} is invalid: expected >= 2")
        if method == "zoh":
            taps = self.discretise(fs).impulse_response(n_taps)
            return ImpulseResponse(_readonly(taps), 0, float(fs), "zoh", 0.0, self.outputs)
        if n_fft is None:
            f, q = self.modes()
            tau = np.max(q / (np.pi * f)) if f.size else 0.0
            need = max(4 * n_taps, int(math.ceil(fs * tau * math.log(1e12))) if tau > 0 else 0)
            n_fft = 1 << max(need - 1, 1).bit_length()
        n_fft = int(n_fft)
        if n_fft < 2 * n_taps:
            raise ModelError(f"n_fft = {n_fft} is invalid: expected >= 2 n_taps = {2 * n_taps}")
        g1 = self._bandlimited(fs, n_fft)
        g2 = self._bandlimited(fs, 2 * n_fft)

        def two_sided(g):
            return np.concatenate([g[:, -(n_taps - 1):], g[:, :n_taps]], axis=1)

        t1, t2 = two_sided(g1), two_sided(g2)
        err = float(np.max(np.abs(t2 - t1)) / np.max(np.abs(t2)))
        return ImpulseResponse(_readonly(t2), -(n_taps - 1), float(fs), "bandlimited", err,
                               self.outputs)

    def _bandlimited(self, fs: float, n_fft: int) -> np.ndarray:
        f = np.fft.rfftfreq(n_fft, 1.0 / fs)
        h = self.frequency_response(f)  # (nf, n_out)
        if n_fft % 2 == 0:
            h[-1] = h[-1].real  # midpoint of the DTFT's jump at Nyquist
        return np.fft.irfft(h.T, n=n_fft, axis=-1)


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """The exact ZOH discretisation ``z[n+1] = Phi z[n] + Gamma u[n]``, ``y[n] = C z[n]``.

    Attributes
    ----------
    phi : (nz, nz); gamma : (nz, 1); c : (n_out, nz); fs : sample rate [Hz]; outputs : names.
    """

    phi: np.ndarray
    gamma: np.ndarray
    c: np.ndarray
    fs: float
    outputs: tuple = ("y",)

    def output_index(self, output) -> int:
        """Row of ``output`` in ``c``; :class:`ModelError` if absent."""
        return _output_index(self.outputs, output)

    def frequency_response(self, freqs_hz, output=None) -> np.ndarray:
        """``C (exp(i w T) I - Phi)^-1 Gamma`` at ``freqs_hz`` [Hz]: shape ``(nf, n_out)``, or
        ``(nf,)`` for one named ``output``."""
        zf = np.exp(2j * np.pi * np.atleast_1d(np.asarray(freqs_hz, dtype=float)) / self.fs)
        nz = self.phi.shape[0]
        m = zf[:, None, None] * np.eye(nz) - self.phi
        x = np.linalg.solve(m, np.broadcast_to(self.gamma.astype(complex), (zf.size, nz, 1)))
        h = x[..., 0] @ self.c.T
        return h if output is None else h[:, self.output_index(output)]

    def impulse_response(self, n_taps: int) -> np.ndarray:
        """``g[0] = 0``, ``g[n] = C Phi^(n-1) Gamma``: shape ``(n_out, n_taps)`` (state stepping,
        no polynomial forms)."""
        out = np.zeros((self.c.shape[0], int(n_taps)))
        v = self.gamma[:, 0].copy()
        for n in range(1, int(n_taps)):
            out[:, n] = self.c @ v
            v = self.phi @ v
        return out

    def pole_residues(self, output) -> tuple[np.ndarray, np.ndarray]:
        """Discrete poles ``z_r`` (Im > 0, ascending frequency) and residues ``c_r`` of
        ``output``: ``G(z) = sum_r c_r / (z - z_r) + conj(c_r) / (z - conj(z_r))``. The
        continuous-equivalent residue near the pole is ``c_r fs / z_r``."""
        return _pole_residues(self.phi, self.gamma, self.c[self.output_index(output)],
                              lambda z: np.abs(np.log(z)))

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``Phi`` (``exp(p T)`` of the continuous poles ``p``)."""
        return np.linalg.eigvals(self.phi)

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies [Hz] and Q of the continuous poles ``log(z) fs``, ascending."""
        return _poles_to_fq(np.log(self.poles().astype(complex)) * self.fs)

    def stationary_covariance(self, input_variance: float = 1.0) -> np.ndarray:
        """State covariance ``P = Phi P Phi^T + Gamma Gamma^T var(u)`` of the stationary response
        to white input (to start a simulation without a transient)."""
        from scipy.linalg import solve_discrete_lyapunov

        return solve_discrete_lyapunov(self.phi, input_variance * (self.gamma @ self.gamma.T))

    def simulate(self, u, z0=None) -> np.ndarray:
        """Outputs ``y[n] = C z[n]``, ``n = 0 .. len(u)-1``, for input samples ``u[n]`` held over
        ``[n T, (n+1) T)``, from state ``z0`` (default 0).

        Exact: the recursion runs in the modal coordinates of ``Phi`` (one first-order complex
        recursion per eigenvalue, :func:`scipy.signal.lfilter`), which keeps the lightly damped
        poles exact, unlike polynomial (``ss2tf``) forms. Returns shape ``(n_out, len(u))``.
        """
        from scipy.signal import lfilter

        u = np.asarray(u, dtype=float)
        nz = self.phi.shape[0]
        z0 = np.zeros(nz) if z0 is None else np.asarray(z0, dtype=float)
        lam, v = np.linalg.eig(self.phi)
        vinv = np.linalg.inv(v)
        gm = vinv @ self.gamma[:, 0]
        q0 = vinv @ z0
        cv = self.c @ v
        y = np.zeros((self.c.shape[0], u.size))
        for r in range(nz):
            if lam[r].imag < 0:
                continue  # the conjugate partner carries it (factor 2 below)
            q, _ = lfilter([0.0, gm[r]], [1.0, -lam[r]], u.astype(complex), zi=[q0[r]])
            fac = 2.0 if lam[r].imag > 0 else 1.0
            y += fac * np.real(np.outer(cv[:, r], q))
        return y


def simulate_records(model: DiscreteModel, *, n_records: int, n_samples: int, seed: int,
                     input_std: float = 1.0, output_noise: Mapping | None = None,
                     input_name: str = "a") -> dict:
    """A synthetic measurement: white input held over each sample, exact response, output noise.

    The input ``u[n] ~ N(0, input_std^2)`` is held over ``[n T, (n+1) T)`` and recorded as it is
    (channel ``input_name``); the outputs are :meth:`DiscreteModel.simulate` from a state drawn
    from the stationary covariance (no start-up transient), plus independent white noise of
    standard deviation ``output_noise[name]``. One continuous run is cut into ``n_records``
    contiguous records. The same seed gives the same arrays.

    Returns
    -------
    dict : ``{input_name: (n_records, n_samples), output name: (n_records, n_samples), ...}``.
    """
    n_records, n_samples = int(n_records), int(n_samples)
    if n_records < 1 or n_samples < 2:
        raise ModelError(f"n_records = {n_records}, n_samples = {n_samples}: expected >= 1, >= 2")
    rng = np.random.default_rng(seed)
    p = model.stationary_covariance(input_std**2)
    lam, vec = np.linalg.eigh(0.5 * (p + p.T))
    z0 = vec @ (np.sqrt(np.clip(lam, 0.0, None)) * rng.standard_normal(lam.size))
    u = input_std * rng.standard_normal(n_records * n_samples)
    y = model.simulate(u, z0)
    noise = dict(output_noise or {})
    out = {input_name: u.reshape(n_records, n_samples)}
    for i, name in enumerate(model.outputs):
        yi = y[i]
        sd = float(noise.pop(name, 0.0))
        if sd:
            yi = yi + sd * rng.standard_normal(yi.size)
        out[name] = yi.reshape(n_records, n_samples)
    if noise:
        raise ModelError(f"output_noise names {sorted(noise)} are not outputs {model.outputs}")
    return out


@dataclass(frozen=True, eq=False)
class ImpulseResponse:
    """Discrete impulse response ``g[tau]`` for ``tau = lag0 .. lag0 + n - 1``.

    Attributes
    ----------
    taps : (n_out, n) [output unit / input unit].
    lag0 : lag of the first tap (0 for causal, negative for two-sided).
    fs : [Hz]. method : "zoh" or "bandlimited".
    error : estimated relative error of the taps (0 for "zoh": round-off only).
    outputs : names of the rows.
    """

    taps: np.ndarray
    lag0: int
    fs: float
    method: str
    error: float
    outputs: tuple

    def output(self, name) -> np.ndarray:
        return self.taps[_output_index(self.outputs, name)]

    def expected_h1(self, settings: SpectralSettings, output=None) -> np.ndarray:
        """``E[H1]`` on ``settings.freqs_hz`` (:func:`expected_h1_taps`): ``(nf,)`` for one output,
        else ``(nf, n_out)``."""
        if abs(settings.fs - self.fs) > 1e-9 * self.fs:
            raise ModelError(f"settings.fs = {settings.fs} Hz differs from the impulse response's "
                             f"fs = {self.fs} Hz")
        if output is not None:
            return expected_h1_taps(self.output(output), settings, lag0=self.lag0)
        return np.stack([expected_h1_taps(t, settings, lag0=self.lag0) for t in self.taps], -1)


def window_autocorrelation(settings: SpectralSettings) -> np.ndarray:
    """``r_w(tau) = sum_n w[n] w[n + tau] / sum w^2`` for ``tau = 0 .. nperseg-1``."""
    return _autocorrelation(settings.window_array)


def expected_h1_taps(taps, settings: SpectralSettings, *, lag0: int = 0) -> np.ndarray:
    """Expected H1 for white input of a (possibly two-sided) impulse response, leakage included.

    ``E[H1](f_k) = sum_tau g[tau] r_w(|tau|) exp(-2j pi k tau / nperseg)`` over ``|tau| <
    nperseg``, with ``g[lag0 + i] = taps[i]``. For ``lag0 = 0`` this is
    :func:`processing.frf.expected_h1`. Exact for ``detrend=None``; the constant detrend changes
    only the lines whose window transform overlaps 0 Hz (k <= 1 for Hann).

    Returns
    -------
    numpy.ndarray : complex, shape ``(n_freqs,)`` on ``settings.freqs_hz``.
    """
    g = np.asarray(taps, dtype=float)
    if g.ndim != 1 or g.size == 0:
        raise SettingsError(f"taps has shape {g.shape}: expected (n_taps,)")
    n = settings.nperseg
    r = window_autocorrelation(settings)
    lags = np.arange(g.size) + int(lag0)
    keep = np.abs(lags) < n
    buf = np.zeros(n)
    np.add.at(buf, lags[keep] % n, g[keep] * r[np.abs(lags[keep])])
    return np.fft.rfft(buf)[: settings.freqs_hz.size]


# -- statistics of normalised residuals ------------------------------------------------------

def line_correlation(settings: SpectralSettings, *, tol: float = 1e-6) -> np.ndarray:
    """Correlation ``|rho_j|^2`` of the complex H1 errors of lines ``j`` apart, ``j = 0, 1, ...``
    while above ``tol`` (white input and noise): ``rho_j = sum w^2 exp(-2j pi j n / N) / sum w^2``.
    Hann: ``[1, 4/9, 1/36]``; uniform: ``[1]``."""
    w2 = settings.window_array ** 2
    rho = np.abs(np.fft.rfft(w2)) / w2.sum()
    c = rho**2
    big = np.nonzero(c > tol)[0]
    return c[: big[-1] + 1].copy() if big.size else np.ones(1)


def expected_fraction_within(k: float, n_effective: float) -> float:
    """Expected fraction of normalised gain (or phase) residuals within ``+-k`` for an unbiased H1
    with its band from the measured coherence: ``P(|t_nu| < k sqrt((n_d - 1)/n_d))``,
    ``nu = 2 (n_d - 1)`` (module notes); the normal value ``erf(k / sqrt 2)`` for large ``n_d``."""
    nd = float(n_effective)
    if nd <= 1.0:
        return float("nan")
    nu = 2.0 * (nd - 1.0)
    x = k * math.sqrt((nd - 1.0) / nd)
    return float(1.0 - _betainc(0.5 * nu, 0.5, nu / (nu + x * x)))


def _betainc(a: float, b: float, x: float) -> float:
    """The regularised incomplete beta function ``I_x(a, b)`` (``P(|t_nu| > t) = I_x(nu/2, 1/2)``
    with ``x = nu / (nu + t^2)``), by its continued fraction (modified Lentz; relative error
    ~1e-15, tests/test_compare.py checks it against scipy.stats.t)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
                     + b * math.log1p(-x))
    if x > (a + 1.0) / (a + b + 2.0):
        return 1.0 - front * _betacf(b, a, 1.0 - x) / b
    return front * _betacf(a, b, x) / a


def _betacf(a: float, b: float, x: float) -> float:
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 1000):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    return h


def fraction_standard_error(p: float, n_lines: int, settings: SpectralSettings | None = None,
                            k: float = 2.0) -> float:
    """Standard error of a fraction ``p`` of ``n_lines`` lines within ``k`` sigma.

    Binomial ``sqrt(p (1 - p) / N)``, inflated for the window's line correlation: indicators
    ``1{|z| < k}`` of Gaussians with correlation ``c`` have covariance ``sum_m a_m^2 c^m m!``
    over even ``m`` (Hermite expansion, ``a_2 = -k phi(k)``); ``c = |rho_j|^2`` per lag
    (:func:`line_correlation`). Without ``settings`` the lines are taken as independent.
    """
    if n_lines <= 0:
        return float("nan")
    var1 = p * (1.0 - p)
    infl = 1.0
    if settings is not None and var1 > 0:
        phi = math.exp(-0.5 * k * k) / math.sqrt(2 * math.pi)
        # Hermite coefficients of the even indicator: a_m = E[1{|z|<k} He_m(z)] / m!
        he = [-2 * k * phi, -2 * (k**3 - 3 * k) * phi, None]  # m = 2, 4
        he[2] = -2 * (k**5 - 10 * k**3 + 15 * k) * phi  # m = 6
        for c in line_correlation(settings)[1:]:
            cov = sum((h / math.factorial(m)) ** 2 * math.factorial(m) * c**m
                      for h, m in zip(he, (2, 4, 6)))
            infl += 2.0 * cov / var1
    return math.sqrt(var1 * infl / n_lines)


# -- the comparison --------------------------------------------------------------------------

_DB = 20.0 / math.log(10.0)  # dB per neper


def _projected(h: np.ndarray, ref: np.ndarray, sigma_abs: np.ndarray) -> tuple:
    """In-phase and quadrature components of ``h - ref`` relative to ``ref``'s phase, in units of
    ``sigma_abs``."""
    d = (h - ref) * np.exp(-1j * np.angle(ref)) / sigma_abs
    return d.real, d.imag


@dataclass(frozen=True)
class BandStats:
    """Residual statistics over one band of lines.

    A normalised residual ``z`` is the in-phase (gain, ``z_gain``) or quadrature (phase,
    ``z_phase``) component of ``measured - reference``, relative to the reference's phase, in
    units of the Bendat-Piersol standard deviation ``eps |measured|``. To first order in ``eps``
    these are the gain residual in units of ``sigma_dB`` and the phase residual in units of
    ``sigma_deg``; ``|z_gain| <= k`` is exactly "the reference's gain lies inside the measured
    ``k``-sigma gain band" (:meth:`FrequencyResponse.gain_band_db`) when ``z`` is small. Both are
    Student-t distributed at any coherence (module notes). ``*_total``: reference = exact model;
    ``*_random``: reference = ``E[H1]`` (NaN without it).

    Attributes
    ----------
    name : "away", "near f Hz" (a resonance) or "notch f Hz" (an anti-resonance).
    fmin_hz, fmax_hz : extent of the band's lines [Hz]; n_lines : lines used.
    k : the sigma multiple of the fractions.
    expected_fraction : :func:`expected_fraction_within` (k, n_d); fraction_se : its standard
        error over ``n_lines`` (:func:`fraction_standard_error`).
    rms_gain_total, max_gain_total, frac_gain_total : rms and max of ``|z_gain|`` and the
        fraction of lines with ``|z_gain| <= k``; ``*_phase_*`` the same for ``z_phase``.
    rms_gain_random ... frac_phase_random : the same against ``E[H1]``.
    max_bias_db, max_bias_deg : largest ``|20 log10|E[H1]/H||`` [dB] and ``|angle(E[H1]/H)|``
        [deg] in the band (signed values of those lines).
    max_bias_sigma : largest ``|E[H1] - H| / (eps |measured|)``: the bias in units of the random
        error's standard deviation per component.
    median_sigma_db : median 1-sigma gain error [dB]; median_coherence : median gamma^2.
    """

    name: str
    fmin_hz: float
    fmax_hz: float
    n_lines: int
    k: float
    expected_fraction: float
    fraction_se: float
    rms_gain_total: float
    max_gain_total: float
    frac_gain_total: float
    rms_phase_total: float
    max_phase_total: float
    frac_phase_total: float
    rms_gain_random: float
    max_gain_random: float
    frac_gain_random: float
    rms_phase_random: float
    max_phase_random: float
    frac_phase_random: float
    max_bias_db: float
    max_bias_deg: float
    max_bias_sigma: float
    median_sigma_db: float
    median_coherence: float


@dataclass(frozen=True)
class PeakBias:
    """Leakage bias against random error at one resonance.

    Attributes
    ----------
    f_hz, q : the model's mode [Hz], [-].
    half_power_bw_hz : ``f / Q`` [Hz]; lines_per_bw : that over the line spacing.
    leakage_limited : ``lines_per_bw < 8`` (the 35670A manual's rule, SPEC section 6).
    line_hz : the line nearest ``f_hz`` [Hz].
    model_db, expected_db, measured_db : gain at that line [dB] of the exact model, ``E[H1]``
        (NaN if not given) and the measurement.
    bias_db, bias_deg : ``E[H1] / H`` at that line [dB], [deg].
    random_db, random_deg : ``measured / E[H1]`` at that line [dB], [deg].
    sigma_db, sigma_deg : predicted 1-sigma random error there (measured coherence).
    bias_sigma : ``|E[H1] - H| / (eps |measured|)`` at that line.
    random_z_gain, random_z_phase : the random part's normalised components (``BandStats``).
    coherence : measured gamma^2 at that line.
    true_peak_db : the model's maximum gain near ``f_hz`` (on a fine grid when the model is a
        callable, else the largest of the 5 lines around it) [dB].
    measured_peak_db, expected_peak_db : largest measured / expected gain of those 5 lines [dB].
    peak_deficit_db : ``expected_peak_db - true_peak_db``: how low the peak reads on average.
    """

    f_hz: float
    q: float
    half_power_bw_hz: float
    lines_per_bw: float
    leakage_limited: bool
    line_hz: float
    model_db: float
    expected_db: float
    measured_db: float
    bias_db: float
    bias_deg: float
    random_db: float
    random_deg: float
    sigma_db: float
    sigma_deg: float
    bias_sigma: float
    random_z_gain: float
    random_z_phase: float
    coherence: float
    true_peak_db: float
    measured_peak_db: float
    expected_peak_db: float
    peak_deficit_db: float


@dataclass(frozen=True, eq=False)
class Comparison:
    """A measured frequency response next to the exact model and its expected estimate.

    Attributes
    ----------
    measured : FrequencyResponse, restricted to the compared lines.
    model : complex (nf,) exact response on ``measured.freqs_hz``.
    expected : complex (nf,) ``E[H1]`` on the same lines, or None.
    k : sigma multiple of the fractions.
    bands : BandStats: "away" first, then one per resonance and anti-resonance.
    peaks : PeakBias per resonance inside the compared lines.
    masks : dict band name -> (nf,) bool, the lines of each band.
    resolution_hz : line spacing [Hz].
    settings : the analyzer settings, if given.
    """

    measured: FrequencyResponse
    model: np.ndarray
    expected: np.ndarray | None
    k: float
    bands: tuple
    peaks: tuple
    masks: Mapping
    resolution_hz: float
    settings: SpectralSettings | None = None

    @property
    def freqs_hz(self) -> np.ndarray:
        return self.measured.freqs_hz

    @property
    def n_effective(self) -> float:
        return self.measured.n_effective

    @property
    def sigma_rel(self) -> np.ndarray:
        """Bendat-Piersol relative error ``eps`` per line (1-sigma of ``|H|`` / ``|H|`` and the
        phase's std [rad])."""
        return self.measured.relative_error

    @property
    def sigma_abs(self) -> np.ndarray:
        """``eps |measured|``: standard deviation of each component of the complex error."""
        return self.sigma_rel * np.abs(self.measured.h)

    @property
    def sigma_db(self) -> np.ndarray:
        """1-sigma gain error [dB], ``20/ln(10) eps``."""
        return _DB * self.sigma_rel

    @property
    def sigma_deg(self) -> np.ndarray:
        """1-sigma phase error [deg], ``degrees(eps)``."""
        return np.degrees(self.sigma_rel)

    @property
    def gain_residual_db(self) -> np.ndarray:
        """``20 log10 |measured / model|`` [dB]."""
        return _DB * np.log(np.abs(self.measured.h / self.model))

    @property
    def phase_residual_deg(self) -> np.ndarray:
        """``angle(measured / model)`` [deg] in (-180, 180]."""
        return np.degrees(np.angle(self.measured.h / self.model))

    @property
    def z_total(self) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (gain, phase) residual against the model (see :class:`BandStats`)."""
        return _projected(self.measured.h, self.model, self.sigma_abs)

    @property
    def z_random(self) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (gain, phase) residual against ``E[H1]`` (NaN without it)."""
        if self.expected is None:
            nan = np.full(self.model.shape, np.nan)
            return nan, nan
        return _projected(self.measured.h, self.expected, self.sigma_abs)

    def _ratio(self, a, b, kind):
        if a is None or b is None:
            return np.full(self.model.shape, np.nan)
        r = a / b
        return _DB * np.log(np.abs(r)) if kind == "db" else np.degrees(np.angle(r))

    @property
    def bias_db(self) -> np.ndarray:
        """``20 log10 |E[H1] / model|`` [dB] (NaN without E[H1])."""
        return self._ratio(self.expected, self.model, "db")

    @property
    def bias_deg(self) -> np.ndarray:
        """``angle(E[H1] / model)`` [deg] (NaN without E[H1])."""
        return self._ratio(self.expected, self.model, "deg")

    @property
    def bias_sigma(self) -> np.ndarray:
        """``|E[H1] - model| / (eps |measured|)`` (NaN without E[H1])."""
        if self.expected is None:
            return np.full(self.model.shape, np.nan)
        return np.abs(self.expected - self.model) / self.sigma_abs

    @property
    def random_db(self) -> np.ndarray:
        """``20 log10 |measured / E[H1]|`` [dB] (NaN without E[H1])."""
        return self._ratio(self.measured.h, self.expected, "db")

    @property
    def random_deg(self) -> np.ndarray:
        """``angle(measured / E[H1])`` [deg] (NaN without E[H1])."""
        return self._ratio(self.measured.h, self.expected, "deg")

    @property
    def away_mask(self) -> np.ndarray:
        return self.masks["away"]

    def band(self, name: str) -> BandStats:
        """The :class:`BandStats` called ``name`` (KeyError if absent)."""
        for b in self.bands:
            if b.name == name:
                return b
        raise KeyError(f"no band named {name!r}: have {[b.name for b in self.bands]}")


def _trio(z: np.ndarray, k: float) -> tuple:
    z = np.abs(z)
    if not z.size:
        return (math.nan,) * 3
    return float(np.sqrt(np.mean(z * z))), float(z.max()), float(np.mean(z <= k))


def _stats(name: str, mask: np.ndarray, cmp: Comparison) -> BandStats:
    zg, zp = cmp.z_total
    ok = mask & np.isfinite(zg) & np.isfinite(zp)
    n = int(ok.sum())
    k = cmp.k
    gt, pt = _trio(zg[ok], k), _trio(zp[ok], k)
    if cmp.expected is not None:
        rg, rp = cmp.z_random
        gr, pr = _trio(rg[ok], k), _trio(rp[ok], k)
        bdb, bdeg, bs = cmp.bias_db[ok], cmp.bias_deg[ok], cmp.bias_sigma[ok]
        if n:
            max_bias_db = float(bdb[np.argmax(np.abs(bdb))])
            max_bias_deg = float(bdeg[np.argmax(np.abs(bdeg))])
            max_bias_sigma = float(bs.max())
        else:
            max_bias_db = max_bias_deg = max_bias_sigma = math.nan
    else:
        gr = pr = (math.nan,) * 3
        max_bias_db = max_bias_deg = max_bias_sigma = math.nan
    p = expected_fraction_within(k, cmp.n_effective)
    f = cmp.freqs_hz[ok]
    return BandStats(
        name=name, fmin_hz=float(f.min()) if n else math.nan,
        fmax_hz=float(f.max()) if n else math.nan, n_lines=n, k=k, expected_fraction=p,
        fraction_se=fraction_standard_error(p, n, cmp.settings, k),
        rms_gain_total=gt[0], max_gain_total=gt[1], frac_gain_total=gt[2],
        rms_phase_total=pt[0], max_phase_total=pt[1], frac_phase_total=pt[2],
        rms_gain_random=gr[0], max_gain_random=gr[1], frac_gain_random=gr[2],
        rms_phase_random=pr[0], max_phase_random=pr[1], frac_phase_random=pr[2],
        max_bias_db=max_bias_db, max_bias_deg=max_bias_deg, max_bias_sigma=max_bias_sigma,
        median_sigma_db=float(np.median(cmp.sigma_db[ok])) if n else math.nan,
        median_coherence=float(np.median(cmp.measured.coherence[ok])) if n else math.nan)


def _db(x) -> float:
    with np.errstate(divide="ignore"):
        return float(_DB * np.log(np.abs(x)))


def compare(measured: FrequencyResponse, model, *, expected=None,
            resonances: Sequence[tuple[float, float]] = (),
            antiresonances_hz: Sequence[float] = (), settings: SpectralSettings | None = None,
            fmin_hz: float = 0.1, fmax_hz: float = 10.0, k: float = 2.0,
            near_lines: float = 20.0, near_bandwidths: float = 10.0) -> Comparison:
    """Compare a measured response with the exact model, separating leakage bias and random error.

    Parameters
    ----------
    measured : FrequencyResponse
        An H1 estimate (its coherence and ``n_effective`` give the Bendat-Piersol error).
    model : complex array (nf,) on ``measured.freqs_hz``, or a callable ``freqs_hz -> complex``
        (then also evaluated on a fine grid for each true peak height). For data sampled from a
        held input use the discrete model (:meth:`DiscreteModel.frequency_response`).
    expected : complex array (nf,), optional
        ``E[H1]`` on the same lines (:meth:`ImpulseResponse.expected_h1`). Without it the bias and
        random parts are NaN and only the total residual is reported.
    resonances : sequence of (f_hz, Q)
        The model's modes (e.g. ``zip(*chain.modes())``). Each has a "near" band of half-width
        ``max(near_lines * df, near_bandwidths * f / Q)``. Leakage bias falls off slowly away
        from a peak narrower than a line: relatively ``m2 / d^2`` at ``d`` lines, ``m2`` the
        second moment of the window's power kernel (1/3 line^2 for Hann: 0.03 dB at 10 lines,
        0.007 dB at 20), which matters where the coherence is very high (see
        ``BandStats.max_bias_sigma``); the default of 20 lines keeps it below 0.2 sigma at
        gamma^2 = 0.999 (eps = 0.004 with 30 averages).
    antiresonances_hz : sequence of float
        Sharp anti-resonances (notches are filled in by leakage too); each has a "notch" band of
        half-width ``near_lines * df``.
    settings : SpectralSettings, optional
        For the line correlation in the fractions' standard error (lines independent without).
    fmin_hz, fmax_hz : compared band [Hz] (default 0.1 - 10 Hz, the paper's plots).
    k : sigma multiple for the fractions (default 2).
    near_lines, near_bandwidths : band half-widths, see above.

    Returns
    -------
    Comparison

    Raises
    ------
    ModelError
        If ``model`` or ``expected`` do not match the measured lines, or are NaN or 0 in the band.
    """
    f_all = np.asarray(measured.freqs_hz)
    model_fn = model if callable(model) else None
    model_all = np.asarray(model_fn(f_all) if model_fn else model, dtype=complex)
    for name, arr in (("model", model_all), ("expected", expected)):
        if arr is not None and np.shape(arr) != f_all.shape:
            raise ModelError(f"{name} has shape {np.shape(arr)}: expected {f_all.shape}, one value "
                             "per measured line")
    sel = (f_all >= fmin_hz) & (f_all <= fmax_hz) & np.isfinite(measured.h) \
        & np.isfinite(measured.coherence)
    if not np.any(sel):
        raise ModelError(f"no finite measured lines in {fmin_hz} <= f <= {fmax_hz} Hz")
    idx = np.nonzero(sel)[0]
    meas = FrequencyResponse(f_all[idx], _readonly(measured.h[idx]),
                             _readonly(measured.coherence[idx]), measured.n_averages,
                             measured.n_effective, measured.estimator, measured.input,
                             measured.output, measured.units)
    mod = model_all[idx]
    exp_ = None if expected is None else np.asarray(expected, dtype=complex)[idx]
    for name, arr in (("model", mod), ("expected", exp_)):
        if arr is not None and not np.all(np.isfinite(arr) & (arr != 0)):
            raise ModelError(f"{name} has non-finite or zero values in the compared band")
    f = meas.freqs_hz
    df = float(np.median(np.diff(f_all))) if f_all.size > 1 else math.nan
    res = [(float(fr), float(q)) for fr, q in resonances]
    masks = {}
    for fr, q in res:
        half = max(near_lines * df, near_bandwidths * fr / q)
        masks[f"near {fr:.4g} Hz"] = np.abs(f - fr) <= half
    for fz in antiresonances_hz:
        masks[f"notch {float(fz):.4g} Hz"] = np.abs(f - float(fz)) <= near_lines * df
    away = np.ones(f.size, bool)
    for m in masks.values():
        away &= ~m
    masks = {"away": away, **masks}
    for m in masks.values():
        m.setflags(write=False)
    cmp = Comparison(meas, _readonly(mod), None if exp_ is None else _readonly(exp_), float(k),
                     (), (), masks, df, settings)
    bands = tuple(_stats(name, m, cmp) for name, m in masks.items())
    eps = meas.relative_error
    sig_abs = cmp.sigma_abs
    peaks = []
    for fr, q in res:
        j = int(np.argmin(np.abs(f - fr)))
        if abs(f[j] - fr) > df:
            continue  # the resonance lies outside the compared lines
        win = slice(max(j - 2, 0), j + 3)
        if model_fn is not None:
            fine = np.linspace(fr - 3 * fr / q, fr + 3 * fr / q, 2001)
            true_peak = _db(np.max(np.abs(np.asarray(model_fn(fine)))))
        else:
            true_peak = _db(np.max(np.abs(mod[win])))
        if exp_ is not None:
            e = exp_[j]
            zg, zp = _projected(meas.h[j], e, sig_abs[j])
            exp_vals = dict(expected_db=_db(e), bias_db=_db(e / mod[j]),
                            bias_deg=float(np.degrees(np.angle(e / mod[j]))),
                            random_db=_db(meas.h[j] / e),
                            random_deg=float(np.degrees(np.angle(meas.h[j] / e))),
                            bias_sigma=float(abs(e - mod[j]) / sig_abs[j]),
                            random_z_gain=float(zg), random_z_phase=float(zp),
                            expected_peak_db=_db(np.max(np.abs(exp_[win]))))
        else:
            exp_vals = dict.fromkeys(("expected_db", "bias_db", "bias_deg", "random_db",
                                      "random_deg", "bias_sigma", "random_z_gain",
                                      "random_z_phase", "expected_peak_db"), math.nan)
        peaks.append(PeakBias(
            f_hz=fr, q=q, half_power_bw_hz=fr / q, lines_per_bw=fr / q / df,
            leakage_limited=bool(fr / q / df < 8.0), line_hz=float(f[j]),
            model_db=_db(mod[j]), measured_db=_db(meas.h[j]),
            sigma_db=float(_DB * eps[j]), sigma_deg=float(np.degrees(eps[j])),
            coherence=float(meas.coherence[j]), true_peak_db=true_peak,
            measured_peak_db=_db(np.max(np.abs(meas.h[win]))),
            peak_deficit_db=exp_vals["expected_peak_db"] - true_peak, **exp_vals))
    return Comparison(meas, cmp.model, cmp.expected, float(k), bands, tuple(peaks),
                      MappingProxyType(masks), df, settings)
