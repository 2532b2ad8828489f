"""The bench under a swept sine: the sweep-rate rule from its poles and zeros, and the exact
noiseless response of its linear chain to the sweep.

**The rule** (:func:`rule_rate`). Driven by ``e^{i theta(t)}`` with a moving frequency, a pole
``p`` [Hz, complex: ``f_p + i sigma_p / 2 pi``] of a response lags its steady state by the
relative amount ``(df/dt) / (2 pi (f - p)^2)`` to first order, and a response's zero near ``f``
magnifies the relative error the same way; the analysis window of ``T_w`` seconds averages the
response over the frequencies it sweeps. With ``d(f)`` the distance [Hz] from ``f`` to the
nearest pole of the chain (:class:`rig.bench.sine.SineChain`) or zero of a channel (a, x, y:
the zeros of a are the poles of H_t and Theta_2), the rule's rate is

    df/dt = tolerance * d(f) / max(1 / (2 pi d(f)), T_w(f))     [Hz/s]

the frequency moves at most ``tolerance`` of the distance to the nearest pole or zero during the
longer of that singularity's memory ``1 / (2 pi d)`` (at a mode's peak ``d`` is the half-power
half-bandwidth ``f / 2Q`` and the memory is the amplitude time constant ``Q / (pi f)``) and the
analysis window: a relative first-order sweep bias of about ``tolerance`` per singularity.

**The truth** (:class:`ModalSweep`). The chain ``x_{k+1} = A x_k + B v_k``, ``y_k = C x_k`` in
its modal coordinates ``x = V z``: over one output interval of the stair source
(:mod:`rig.devices.swept_sine`: frequency ``f_n``, phase ``phi_n``, amplitude ``a_n``) the
forced part is summed in closed form, ``z_m <- lambda_m^q z_m + beta_m a_n (P g_m(psi) - P* g_m(-psi))
/ 2i`` with ``P = e^{i 2 pi phi_n}``, ``psi = 2 pi f_n / fs``, ``g(psi) = (lambda^q - e^{i psi
q}) / (lambda - e^{i psi})``, ``beta = V^-1 B``; the channel volts at output sample n are ``Re(C V
z)`` before the interval. Only one mode of each conjugate pair is carried (its real part
doubled). From rest, it is the linear chain's exact noiseless response (round-off aside) to the
very DAC samples the bench receives: the sweep's bias is what the analysis makes of it.

Public API: :func:`singularities_hz`, :func:`rule_rate`, :class:`ModalSweep`.
"""

from __future__ import annotations

import math

import numpy as np

from rig.jit import njit


def _hz(chain, z: np.ndarray) -> np.ndarray:
    """Discrete poles or zeros (per DAC sample) as ``f + i sigma / 2 pi`` [Hz]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return chain.fs_hz * np.log(np.asarray(z, complex)) / (2j * np.pi)


def channel_zeros(chain, channel: int) -> np.ndarray:
    """The finite transmission zeros (per DAC sample) of one channel of the chain: the finite
    generalised eigenvalues of the pencil ``([[A, B], [C_c, 0]], [[I, 0], [0, 0]])``."""
    from scipy.linalg import eigvals

    nx = chain.a.shape[0]
    m, n = np.zeros((nx + 1, nx + 1)), np.zeros((nx + 1, nx + 1))
    m[:nx, :nx], m[:nx, nx], m[nx, :nx] = chain.a, chain.b, chain.c[channel]
    n[:nx, :nx] = np.eye(nx)
    z = eigvals(m, n)
    return z[np.isfinite(z) & (np.abs(z) > 0)]


def singularities_hz(chain) -> np.ndarray:
    """The chain's poles and the zeros of its three channels as ``f + i sigma / 2 pi`` [Hz]
    (both halves of each conjugate pair; zeros at z = 0 left out)."""
    zs = [chain.poles] + [channel_zeros(chain, c) for c in range(chain.c.shape[0])]
    s = _hz(chain, np.concatenate(zs))
    return s[np.isfinite(s)]


def rule_rate(f_hz, singularities: np.ndarray, tolerance: float, window_s) -> np.ndarray:
    """The rule's rate [Hz/s] at ``f_hz`` (module docstring); ``window_s`` the analysis
    window [s] at each frequency (an array like ``f_hz`` or a number)."""
    f = np.atleast_1d(np.asarray(f_hz, float))
    d = np.min(np.abs(f[:, None] - singularities[None, :]), axis=1)
    d = np.maximum(d, 1e-12)
    memory = np.maximum(1.0 / (2 * np.pi * d), np.broadcast_to(window_s, f.shape))
    return tolerance * d / memory


@njit(cache=True, nogil=True)
def _modal_kernel(lam, lam_q, beta, cv, f_out, phi, q, fs, amplitude, z, out):
    """The closed-form modal recursion over output intervals (module docstring)."""
    nm = lam.shape[0]
    for n in range(f_out.shape[0]):
        for c in range(out.shape[0]):
            acc = 0.0
            for m in range(nm):
                acc += (cv[c, m] * z[m]).real
            out[c, n] = acc
        psi = 2.0 * math.pi * f_out[n] / fs
        e1 = complex(math.cos(psi), math.sin(psi))
        eq = complex(math.cos(psi * q), math.sin(psi * q))
        ph = 2.0 * math.pi * (phi[n] - math.floor(phi[n]))
        p = complex(math.cos(ph), math.sin(ph))
        for m in range(nm):
            gp = (lam_q[m] - eq) / (lam[m] - e1)
            gm = (lam_q[m] - eq.conjugate()) / (lam[m] - e1.conjugate())
            w = beta[m] * amplitude[n] * (p * gp - p.conjugate() * gm) / 2j
            z[m] = lam_q[m] * z[m] + w


class ModalSweep:
    """The chain's exact noiseless response to the stair source, output interval by output
    interval, its modal state carried between calls (module docstring).

    Parameters
    ----------
    chain : the :class:`rig.bench.sine.SineChain`.
    """

    def __init__(self, chain):
        lam = chain.poles.astype(complex)
        keep = lam.imag >= 0  # real modes and one of each conjugate pair
        weight = np.where(lam.imag > 0, 2.0, 1.0)[keep]
        self._lam = np.ascontiguousarray(lam[keep])
        self._lam_q = self._lam ** chain.q
        self._beta = np.ascontiguousarray((chain.modes_inv @ chain.b.astype(complex))[keep])
        self._cv = np.ascontiguousarray((chain.c @ chain.modes)[:, keep] * weight[None, :])
        self.q, self.fs_hz = int(chain.q), float(chain.fs_hz)
        self.z = np.zeros(self._lam.size, complex)

    def run(self, f_out_hz: np.ndarray, phases_cycles: np.ndarray, level_vrms) -> np.ndarray:
        """The channel volts (3, n) at the next ``n`` output samples (the intervals' first DAC
        samples) of the stair ``f_out_hz``, ``phases_cycles`` at ``level_vrms`` [V rms] (one,
        or one per interval); the state moves on past them."""
        f = np.ascontiguousarray(f_out_hz, dtype=float)
        amp = np.ascontiguousarray(np.broadcast_to(
            math.sqrt(2.0) * np.asarray(level_vrms, float), f.shape))
        out = np.empty((self._cv.shape[0], f.size))
        _modal_kernel(self._lam, self._lam_q, self._beta, self._cv, f,
                      np.ascontiguousarray(phases_cycles, dtype=float), self.q, self.fs_hz,
                      amp, self.z, out)
        return out
