"""Linear time-invariant systems and their frequency responses: one type of each for the project.

:class:`LinearSystem` is a continuous single-input model ``z' = A z + B u``, ``y = C z`` (no
feedthrough); :meth:`LinearSystem.discretise` gives its exact zero-order-hold step
:class:`SampledSystem` ``z[n+1] = Phi z[n] + Gamma u[n]`` (Van Loan: one matrix exponential of
``[[A T, B T], [0, 0]]``), whose transfer function is ``C (zeta I - Phi)^-1 Gamma`` at
``zeta = exp(2 pi i f T)``. :meth:`SampledSystem.modal` puts that into the modal form
``sum_r (C v_r)(w_r . Gamma) / (zeta - lambda_r)`` (``Phi = V diag(lambda) V^-1``): O(nz) per
frequency and output instead of one ``(nz, nz)`` solve; its round-off differs from the solve's
only where modal terms cancel (near 0 Hz, at anti-resonances), which the bench's tests bound.

Van Loan's block exponential is built here once for every user: :func:`van_loan` (a held input's
exact step), :func:`discretise` (its zero-order and linear holds, for the solvers and the bench)
and :func:`monomial_integrals` (``int e^{A(h-s)} P (s/h)^k ds``, the exponential methods'
weights); :func:`expm` is scipy's, imported on first use.

:class:`FrequencyResponse` is a complex response on a frequency grid with its channel names and
units, gain in dB and wrapped phase; the measured response of :mod:`processing.frf` extends it
with coherence and averages, so a plot takes either.

Units: frequencies in Hz, rates in Hz, ``A`` in 1/s; the responses in output unit per input unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError

__all__ = ["FrequencyResponse", "LinearSystem", "SampledSystem", "ModalForm", "ImpulseResponse",
           "IMPULSE_METHODS", "wrap_deg", "expm", "van_loan", "discretise", "monomial_integrals"]

IMPULSE_METHODS = ("zoh", "bandlimited")


def wrap_deg(p: np.ndarray) -> np.ndarray:
    """Phase in degrees wrapped from ``[-180, 180]`` to ``(-180, 180]``."""
    return np.where(p <= -180.0, p + 360.0, p)


def expm(a: np.ndarray) -> np.ndarray:
    """``scipy.linalg.expm(a)``, scipy imported on first use (importing rig stays light)."""
    import scipy.linalg

    return scipy.linalg.expm(a)


def van_loan(a, b, h: float, *, ramp: bool = True) -> np.ndarray:
    """Van Loan's block exponential of z' = A z + B u over one step ``h`` [s]:
    ``expm([[A h, B h, 0], [0, 0, I], [0, 0, 0]])`` (``ramp``; its first block row is ``[Phi,
    Gamma0, Gamma1]`` of :func:`discretise`), or ``expm([[A h, B h], [0, 0]])`` without the ramp
    block (``[Phi, Gamma0]``). ``a`` (N, N), ``b`` (N, m); returns the whole exponential."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    nz, m = b.shape
    size = nz + (2 * m if ramp else m)
    big = np.zeros((size, size))
    big[:nz, :nz] = a * h
    big[:nz, nz:nz + m] = b * h
    if ramp:
        big[nz:nz + m, nz + m:] = np.eye(m)
    return expm(big)


def discretise(a, b, h: float, hold: str = "zoh"):
    """Exact discretisation of z' = A z + B u over one step h for a held input (Van Loan).

    With ``u(t_k + s) = u_k + (u_{k+1} - u_k) s / h`` (``linear``; ``zoh`` drops the second term)::

        z_{k+1} = Phi z_k + Gamma0 u_k + Gamma1 (u_{k+1} - u_k)
        Phi = e^{A h},  Gamma0 = int_0^h e^{A r} dr B,  Gamma1 = int_0^h e^{A (h - r)} B r / h dr

    all read off ``expm([[A h, B h, 0], [0, 0, I], [0, 0, 0]]) = [[Phi, Gamma0, Gamma1], ...]``
    (:func:`van_loan`). No one-sample delay and no start-up transient are introduced (unlike
    ``zpk2sos`` of a hold model or ``dlsim`` with first-order hold from a zero state).

    Returns (Phi (N, N), Gamma0 (N, m), Gamma1 (N, m)); Gamma1 is zero for ``zoh``.
    """
    nz, m = np.shape(b)
    e = van_loan(a, b, h)
    phi = e[:nz, :nz].copy()
    g0 = e[:nz, nz:nz + m].copy()
    g1 = e[:nz, nz + m:].copy() if hold == "linear" else np.zeros_like(g0)
    return phi, g0, g1


def monomial_integrals(a, rows, h: float, count: int):
    """``(e^{A h}, [K_0, ..., K_{count-1}])`` with ``K_k = int_0^h e^{A(h-s)} P (s/h)^k ds``
    (N, nf), ``P`` putting ``nf`` values into the ``rows`` of z (N): one matrix exponential of
    the system augmented by the monomials (Van Loan; block k of its first block row is
    ``K_k / k!``)."""
    a = np.asarray(a, float)
    rows = np.asarray(rows)
    nz = a.shape[0]
    nf = rows.size
    big = np.zeros((nz + count * nf, nz + count * nf))
    big[:nz, :nz] = a * h
    big[rows, nz + np.arange(nf)] = h
    for k in range(count - 1):
        r0 = nz + k * nf
        big[r0:r0 + nf, r0 + nf:r0 + 2 * nf] = np.eye(nf)
    e = expm(big)
    ks = [math.factorial(k) * e[:nz, nz + k * nf:nz + (k + 1) * nf] for k in range(count)]
    return e[:nz, :nz].copy(), ks


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """A complex frequency response ``h`` on ``freqs_hz``.

    Attributes
    ----------
    freqs_hz : (nf,) [Hz].
    h : (nf,) or (nf, n_out) complex [output unit / input unit].
    names : names of the outputs (one per column of a 2-D ``h``), may be empty.
    units : the units of ``h``, e.g. ``"m/(m/s^2)"``.
    """

    freqs_hz: np.ndarray
    h: np.ndarray
    names: tuple = ()
    units: str = ""

    @property
    def magnitude(self) -> np.ndarray:
        """``|h|`` [output unit / input unit]."""
        return np.abs(self.h)

    @property
    def magnitude_db(self) -> np.ndarray:
        """Gain ``20 log10 |h|`` [dB re 1 output unit / input unit] (-inf where h = 0)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.h))

    @property
    def phase_deg(self) -> np.ndarray:
        """Phase wrapped to ``(-180, 180]`` [deg]."""
        return wrap_deg(np.degrees(np.angle(self.h)))

    @property
    def phase_unwrapped_deg(self) -> np.ndarray:
        """Phase unwrapped along frequency over the finite values [deg] (NaN kept); 1-D only."""
        out = np.full(self.h.shape, np.nan)
        ok = np.isfinite(self.h)
        out[ok] = np.degrees(np.unwrap(np.angle(self.h[ok])))
        return out

    def channel(self, name) -> FrequencyResponse:
        """The one-output response of column ``name`` of a 2-D ``h``."""
        try:
            i = tuple(self.names).index(name)
        except ValueError:
            raise ConfigError(f"output {name!r} is not present: expected one of "
                              f"{tuple(self.names)}") from None
        return FrequencyResponse(self.freqs_hz, self.h[:, i], (name,), self.units)


def _as_matrix(name: str, value, shape: tuple | None = None) -> np.ndarray:
    a = np.array(value, dtype=float, ndmin=2)
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} has shape {a.shape} or non-finite entries: expected a finite "
                          "2-D array")
    if shape is not None:
        for i, (got, want) in enumerate(zip(a.shape, shape)):
            if want is not None and got != want:
                raise ConfigError(f"{name} has shape {a.shape}: expected axis {i} of length "
                                  f"{want}")
    a.setflags(write=False)
    return a


def _output_index(outputs: tuple, name) -> int:
    try:
        return outputs.index(name)
    except ValueError:
        raise ConfigError(f"output {name!r} is not present: expected one of {outputs}") from None


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


@dataclass(frozen=True, eq=False)
class LinearSystem:
    """A continuous single-input linear model ``z' = A z + B u``, ``y = C z`` (no feedthrough).

    Parameters
    ----------
    a : (nz, nz) state matrix [1/s].
    b : (nz, 1) input matrix [state unit / (input unit s)].
    c : (n_out, nz) output matrix: one row per output channel.
    outputs : names of the output channels (rows of ``c``), e.g. ``("x", "y")``.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    outputs: tuple = ("y",)

    def __post_init__(self):
        a = _as_matrix("a", self.a)
        nz = a.shape[0]
        if a.shape != (nz, nz):
            raise ConfigError(f"a has shape {a.shape}: expected a square matrix")
        set_ = object.__setattr__
        set_(self, "a", a)
        set_(self, "b", _as_matrix("b", np.reshape(self.b, (nz, -1)), (nz, 1)))
        set_(self, "c", _as_matrix("c", self.c, (None, nz)))
        outs = tuple(self.outputs)
        if len(outs) != self.c.shape[0] or len(set(outs)) != len(outs):
            raise ConfigError(f"outputs = {self.outputs!r} is invalid: expected "
                              f"{self.c.shape[0]} distinct names, one per row of c")
        set_(self, "outputs", outs)

    @classmethod
    def from_chain(cls, chain, outputs: Mapping[str, Sequence[float]]) -> LinearSystem:
        """The linearised chain (:meth:`rig.chain.Chain.state_space`) with outputs
        ``weights . theta`` [output unit per rad], input the base acceleration [m/s^2]."""
        a, b = chain.state_space()
        n = chain.n
        rows = []
        for name, w in outputs.items():
            w = np.asarray(w, dtype=float)
            if w.shape != (n,):
                raise ConfigError(f"output {name!r} has weights of shape {w.shape}: expected "
                                  f"({n},)")
            rows.append(np.concatenate([w, np.zeros(n)]))
        return cls(a, b, np.array(rows), tuple(outputs))

    @classmethod
    def from_scene(cls, scene) -> LinearSystem:
        """SPEC section 5's channels of a scene's pendulum: ``x`` (mirror translation relative to
        the stage [m per m/s^2]) and ``y`` (angle of the mirror's body [rad per m/s^2])."""
        n = scene.chain.n
        return cls.from_chain(scene.chain, {"x": scene.mirror_weights(),
                                            "y": np.eye(n)[scene.mirror.body]})

    def output_index(self, output) -> int:
        """Row of ``output`` in ``c``; :class:`ConfigError` if absent."""
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

    def response(self, freqs_hz, units: str = "") -> FrequencyResponse:
        """:meth:`frequency_response` of every output as a :class:`FrequencyResponse`."""
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        return FrequencyResponse(f, self.frequency_response(f), self.outputs, units)

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies [Hz] and Q of the oscillatory modes, ascending."""
        return _poles_to_fq(np.linalg.eigvals(self.a))

    def pole_residues(self, output) -> tuple[np.ndarray, np.ndarray]:
        """Poles ``p_r`` (Im > 0, ascending ``|p|``) [rad/s] and residues ``R_r`` of ``output``:
        ``H(s) = sum_r R_r / (s - p_r) + conj(R_r) / (s - conj(p_r))``."""
        return _pole_residues(self.a, self.b, self.c[self.output_index(output)], np.abs)

    def discretise(self, fs: float) -> SampledSystem:
        """Exact zero-order-hold discretisation at ``fs`` [Hz] (Van Loan block ``expm``)."""
        if not (math.isfinite(fs) and fs > 0):
            raise ConfigError(f"fs = {fs!r} is invalid: expected a finite rate > 0 Hz")
        nz = self.a.shape[0]
        e = van_loan(self.a, self.b, 1.0 / fs, ramp=False)
        return SampledSystem(e[:nz, :nz], e[:nz, nz:], self.c, float(fs), self.outputs)

    def impulse_response(self, fs: float, n_taps: int, *, method: str = "zoh",
                         n_fft: int | None = None) -> ImpulseResponse:
        """Discrete-time impulse response from the sampled input to every sampled output.

        ``method="zoh"``: the input held over each sample and read at the hold instants, so
        ``g[0] = 0``, ``g[n] = C Phi^(n-1) Gamma`` (round-off only). ``method="bandlimited"``:
        every channel through one ideal anti-alias low-pass, so ``g`` is the inverse DTFT of
        ``H(i w)`` on ``|f| < fs/2``, computed by an inverse real FFT of ``n_fft`` points (the
        Nyquist bin takes ``Re H(fs/2)``); two-sided, ``lag0 = -(n_taps - 1)``; ``error`` is the
        change when ``n_fft`` doubles (time aliasing). ``n_fft`` defaults to a power of two
        making the slowest mode's aliasing below 1e-12 and at least ``4 n_taps``.
        """
        if method not in IMPULSE_METHODS:
            raise ConfigError(f"method = {method!r} is invalid: expected one of "
                              f"{IMPULSE_METHODS}")
        n_taps = int(n_taps)
        if n_taps < 2:
            raise ConfigError(f"n_taps = {n_taps} is invalid: expected >= 2")
        if method == "zoh":
            taps = self.discretise(fs).impulse_response(n_taps)
            taps.setflags(write=False)
            return ImpulseResponse(taps, 0, float(fs), "zoh", 0.0, self.outputs)
        if n_fft is None:
            f, q = self.modes()
            tau = np.max(q / (np.pi * f)) if f.size else 0.0
            need = max(4 * n_taps, int(math.ceil(fs * tau * math.log(1e12))) if tau > 0 else 0)
            n_fft = 1 << max(need - 1, 1).bit_length()
        n_fft = int(n_fft)
        if n_fft < 2 * n_taps:
            raise ConfigError(f"n_fft = {n_fft} is invalid: expected >= 2 n_taps = {2 * n_taps}")
        g1 = self._bandlimited(fs, n_fft)
        g2 = self._bandlimited(fs, 2 * n_fft)

        def two_sided(g):
            return np.concatenate([g[:, -(n_taps - 1):], g[:, :n_taps]], axis=1)

        t1, t2 = two_sided(g1), two_sided(g2)
        err = float(np.max(np.abs(t2 - t1)) / np.max(np.abs(t2)))
        t2.setflags(write=False)
        return ImpulseResponse(t2, -(n_taps - 1), float(fs), "bandlimited", err, self.outputs)

    def _bandlimited(self, fs: float, n_fft: int) -> np.ndarray:
        f = np.fft.rfftfreq(n_fft, 1.0 / fs)
        h = self.frequency_response(f)  # (nf, n_out)
        if n_fft % 2 == 0:
            h[-1] = h[-1].real  # midpoint of the DTFT's jump at Nyquist
        return np.fft.irfft(h.T, n=n_fft, axis=-1)


@dataclass(frozen=True, eq=False)
class SampledSystem:
    """An exact sampled system ``z[n+1] = Phi z[n] + Gamma u[n]``, ``y[n] = C z[n]``.

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
        """Row of ``output`` in ``c``; :class:`ConfigError` if absent."""
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

    def modal(self) -> ModalForm:
        """The transfer function in modal form (one eigendecomposition of ``Phi``)."""
        lam, vec = np.linalg.eig(self.phi)
        w = np.linalg.solve(vec, np.asarray(self.gamma, complex))
        residues = (np.asarray(self.c, float) @ vec) * w.reshape(1, -1)
        return ModalForm(lam, residues, float(self.fs), tuple(self.outputs))

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


@dataclass(frozen=True, eq=False)
class ModalForm:
    """``G(zeta) = sum_r residues[:, r] / (zeta - lam[r])``, ``zeta = exp(2 pi i f / fs)``.

    Attributes
    ----------
    lam : (nz,) eigenvalues of ``Phi``; residues : (n_out, nz) ``(C v_r)(w_r . Gamma)``;
    fs : sample rate [Hz]; outputs : names of the rows.
    """

    lam: np.ndarray
    residues: np.ndarray
    fs: float
    outputs: tuple = ()

    def frequency_response(self, freqs_hz) -> np.ndarray:
        """``G`` at ``freqs_hz`` [Hz], shape ``(nf, n_out)``: O(nz n_out) per frequency."""
        zf = np.exp(2j * np.pi * np.asarray(freqs_hz, dtype=float) / self.fs)
        g = 1.0 / (zf[:, None] - self.lam[None, :])  # (nf, nz)
        # (nf, n_out) by einsum's own loop: BLAS threads on this thin product cost ten times
        # its work on a busy two-core machine.
        return np.einsum("fr,or->fo", g, self.residues)
