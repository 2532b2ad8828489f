"""etd3: the exponential integrator with two Gauss nodes (order 3), fixed step.

The linearised chain and the held input are propagated exactly (as ``linear``); only the nonlinear
remainder N is integrated, by 2-node Gauss exponential quadrature with stages extrapolated from the
previous step (the model: :mod:`rig.solvers._kernels`, section etd3). Error O(h^3 |N| |dN/dz| +
h^4 |A|^2 |N|), i.e. proportional to the nonlinearity: for weakly nonlinear runs (the paper's
pendulum on a random base); no better than an explicit 3rd-order method when the motion is far
from linear. Cost: 2 evaluations of N per step. The native state carries the previous step's
stages (``theta,omega,history``), so blocks continue bit for bit.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np


from rig.solvers._kernels import ETD3_NODES, etd3_kernel, etd3_kernel2
from rig.solvers.base import SubstepSolver
from rig.solvers.exact import discretise

if TYPE_CHECKING:
    from rig.chain import Chain


def _expm(a):
    """scipy.linalg.expm, imported on first use (importing rig.solvers stays light)."""
    import scipy.linalg

    return scipy.linalg.expm(a)


def _phi_integrals(a: np.ndarray, n: int, h: float, kmax: int):
    """e^{Ah} and K_k = int_0^h e^{A(h-s)} E (s/h)^k ds for k = 0..kmax (E = [0; I], (2n, n)).

    One matrix exponential of the augmented system x' = A x + E y_0, y_k' = y_{k+1} (in t / h):
    block (0, k) of ``expm`` is int_0^h e^{A(h-s)} E (s/h)^k / k! ds.
    """
    n2 = a.shape[0]
    size = n2 + (kmax + 1) * n
    big = np.zeros((size, size))
    big[:n2, :n2] = a * h
    big[n:n2, n2:n2 + n] = np.eye(n) * h
    for k in range(kmax):
        r0 = n2 + k * n
        big[r0:r0 + n, r0 + n:r0 + 2 * n] = np.eye(n)
    e = _expm(big)
    ks = [math.factorial(k) * e[:n2, n2 + k * n:n2 + (k + 1) * n] for k in range(kmax + 1)]
    return e[:n2, :n2].copy(), ks


@dataclass(frozen=True, eq=False)
class Etd3Coefficients:
    """Everything :func:`etd3_kernel` needs for one chain, step and hold (all arrays C-contiguous).

    Attributes
    ----------
    phi, g0, g1 : the exact held-input step of the linearised chain over h (:func:`discretise`;
        g1 is zero for zoh), (2n, 2n), (2n,), (2n,).
    phic, g0c, g1c : the same over c_i h for the two nodes, (2, 2n, 2n), (2, 2n), (2, 2n).
    pc : K0(c_i h) = int_0^{c_i h} e^{A(c_i h - s)} E ds, (2, 2n, n).
    wq : quadrature weights W_i, (2, 2n, n).
    xp : predictor weights, (2, 2): the value at c_i / 2 of the line through the previous step's
        stages (at c_1 - 1 and c_2 - 1, in units of h).
    p, q, bw : H^-1 K, H^-1 C (n, n) and H^-1 (-S) (n,), to split off the linear part.
    """

    phi: np.ndarray
    g0: np.ndarray
    g1: np.ndarray
    phic: np.ndarray
    g0c: np.ndarray
    g1c: np.ndarray
    pc: np.ndarray
    wq: np.ndarray
    xp: np.ndarray
    p: np.ndarray
    q: np.ndarray
    bw: np.ndarray


@functools.lru_cache(maxsize=64)
def etd3_coefficients(chain: Chain, h: float, hold: str) -> Etd3Coefficients:
    """The matrices of :func:`etd3_kernel` for ``chain``, step ``h`` [s] and ``hold`` (cached)."""
    a, b = chain.state_space()
    n = chain.n
    c = ETD3_NODES
    phi, ks = _phi_integrals(a, n, h, 1)
    _, g0, g1 = discretise(a, b, h, hold)
    # l_0(x) = (x - c_2)/(c_1 - c_2), l_1(x) = (x - c_1)/(c_2 - c_1)
    wq = np.array([(-c[1] * ks[0] + ks[1]) / (c[0] - c[1]),
                   (-c[0] * ks[0] + ks[1]) / (c[1] - c[0])])
    phic, g0c, g1c, pc = [], [], [], []
    for ci in c:
        ph, kc = _phi_integrals(a, n, ci * h, 0)
        _, gc0, gc1 = discretise(a, b, ci * h, hold)
        phic.append(ph)
        g0c.append(gc0[:, 0])
        g1c.append(gc1[:, 0])
        pc.append(kc[0])
    nodes = (c[0] - 1.0, c[1] - 1.0)
    xp = np.array([[(0.5 * ci - nodes[1]) / (nodes[0] - nodes[1]),
                    (0.5 * ci - nodes[0]) / (nodes[1] - nodes[0])] for ci in c])
    hinv = np.linalg.inv(chain.H)
    arr = np.ascontiguousarray
    return Etd3Coefficients(
        phi=arr(phi), g0=arr(g0[:, 0]), g1=arr(g1[:, 0]), phic=arr(np.array(phic)),
        g0c=arr(np.array(g0c)), g1c=arr(np.array(g1c)), pc=arr(np.array(pc)), wq=arr(wq),
        xp=arr(xp), p=arr(hinv @ chain.K), q=arr(hinv @ chain.C), bw=arr(b[n:, 0]))


@dataclass(frozen=True)
class Etd3(SubstepSolver):
    """etd3 with ``substeps`` steps per input interval."""

    substeps: int = 1

    name: ClassVar[str] = "etd3"
    order: ClassVar[int] = 3
    kind: ClassVar[str] = "exponential"
    description: ClassVar[str] = (
        "exponential integrator: the linearised chain and its held input exactly, the nonlinear "
        "remainder by 2-node Gauss exponential quadrature with extrapolated stages (2 evaluations "
        "per step)")
    native: ClassVar[str] = "theta,omega,history"
    history_rows: ClassVar[int] = 2

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, ay, sa, la = held.kernel_args
        sub = self.substeps
        h = held.h_in / sub
        co = etd3_coefficients(chain, float(h), held.hold)
        z, hist, have = self.split_history(chain, y, h)
        kernel = etd3_kernel2 if chain.n == 2 else etd3_kernel
        status, nrow, i_done, nfev = kernel(
            chain.H, chain.S, chain.C, chain.g_mps2, co.p, co.q, co.bw, co.phi, co.g0, co.g1,
            co.phic, co.g0c, co.g1c, co.pc, co.wq, co.xp, ax, ay, sa, la, held.h_in, sub,
            held.n_intervals, held.out_every, z, y_out, hist, have)
        y = np.concatenate([z, [1.0, h], hist.reshape(-1)])
        return self.finish(chain, status, y, y_out, nrow, i_done, held, substeps=sub,
                           n_steps=i_done * sub, n_fev=nfev)
