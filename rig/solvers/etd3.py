"""etd3: the exponential integrator with two Gauss nodes (order 3), fixed step.

The linearised chain and the held input are propagated exactly (as ``linear``); only the nonlinear
remainder N is integrated, by 2-node Gauss exponential quadrature with stages extrapolated from the
previous step (the model: the comment above :func:`etd3_kernel`). Error O(h^3 |N| |dN/dz| +
h^4 |A|^2 |N|), i.e. proportional to the nonlinearity: for weakly nonlinear runs (the paper's
pendulum on a random base); no better than an explicit 3rd-order method when the motion is far
from linear. Cost: 2 evaluations of N per step. The native state carries the previous step's
stages (``theta,omega,history``), so blocks continue bit for bit.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np


from rig.jit import njit
from rig.linear import discretise, monomial_integrals
from rig.solvers.primitives import NONFINITE, OK, chain_args, sincos4, store
from rig.solvers.remainder import nsplit2, nsplit_n
from rig.solvers.base import SubstepSolver

if TYPE_CHECKING:
    from rig.chain import Chain


#: the two Gauss-Legendre nodes c_1,2 = 1/2 -+ sqrt(3)/6 (the model: the comment above
#: :func:`etd3_kernel`)
ETD3_NODES = (0.5 - math.sqrt(3.0) / 6.0, 0.5 + math.sqrt(3.0) / 6.0)


class Etd3Coefficients(NamedTuple):
    """Everything :func:`etd3_kernel` needs for one chain, step and hold, its second argument (all
    arrays C-contiguous).

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
    rows = np.arange(n, 2 * n)  # E = [0; I]: the remainder enters omega'
    phi, ks = monomial_integrals(a, rows, h, 2)
    _, g0, g1 = discretise(a, b, h, hold)
    # l_0(x) = (x - c_2)/(c_1 - c_2), l_1(x) = (x - c_1)/(c_2 - c_1)
    wq = np.array([(-c[1] * ks[0] + ks[1]) / (c[0] - c[1]),
                   (-c[0] * ks[0] + ks[1]) / (c[1] - c[0])])
    phic, g0c, g1c, pc = [], [], [], []
    for ci in c:
        ph, kc = monomial_integrals(a, rows, ci * h, 1)
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
        sub = self.substeps
        h = held.h_in / sub
        co = etd3_coefficients(chain, float(h), held.hold)
        z, hist, have = self.split_history(chain, y, h)
        kernel = etd3_kernel2 if chain.n == 2 else etd3_kernel
        status, nrow, i_done, nfev = kernel(
            chain_args(chain), co, held.kernel_args, held.h_in, sub, held.n_intervals,
            held.out_every, z, y_out, hist, have)
        y = np.concatenate([z, [1.0, h], hist.reshape(-1)])
        return self.finish(chain, status, y, y_out, nrow, i_done, held, substeps=sub,
                           n_steps=i_done * sub, n_fev=nfev)


# ================================================================================================
# compiled kernels
# ================================================================================================

# ================================================================================================
# etd3: exponential integrator (the linearised chain exactly, the nonlinear remainder by quadrature)
# ================================================================================================
#
# Split the vector field at the hanging equilibrium: z' = A z + B u(t) + E N(z, u(t)), z = (theta,
# omega), with (A, B) the linearised chain (:meth:`rig.chain.Chain.state_space`), E = [0; I] and
# N the remainder of the angular accelerations, affine in the base input:
#     N = N0(z) + ax N1(theta) + ay N2(theta)
#     N0 = M^-1 (-N(th) w^2 - C w - g S sin th) + H^-1 (K th + C w)
#     N1 = M^-1 (-S cos th) - H^-1 (-S),     N2 = M^-1 (-S sin th).
# Over a step [0, h] inside one input interval (the input is constant or linear there: the solution
# is smooth) variation of constants gives exactly
#     z(h) = e^{Ah} z(0) + [Gamma0 u_a + Gamma1 (u_b - u_a)] + int_0^h e^{A(h-s)} E N(s) ds.
# The first two terms are the exact held-input step of the linear model (:func:`discretise`); the
# integral is replaced by the exponential quadrature on the two Gauss-Legendre nodes c_1,2 =
# 1/2 -+ sqrt(3)/6, sum_i W_i N(Z_i, u(c_i h)) with W_i = int_0^h e^{A(h-s)} E l_i(s/h) ds (l_i the
# Lagrange basis on the nodes; exact for N linear in s and, by the nodes' symmetry, error
# O(h^5 |A|^2 |N''|) per step). The stage values Z_i = z(c_i h) are predicted, not iterated: the
# exact linear step to c_i h plus K0(c_i h) N^, with N^ the remainder extrapolated linearly from the
# previous step's two stages to the middle of [0, c_i h] (its three affine parts apart, each
# combined with the input there, so the input's jumps at sample instants do not enter the
# extrapolation). The stage error, O(|N| h^3), enters the step through dN/dz: the global error is
# O(h^3 |N| |dN/dz|) + O(h^4 |A|^2 |N|), which is small where the motion is close to linear
# (|N| << |A z|) and no better than an explicit third-order method where it is not. Two remainder
# evaluations per step, one after the other in neither case (the two stages are independent).
# The first step after a (re)start predicts with N(z0) (exponential Euler) at one more evaluation;
# the previous stages are part of the method's native state, so blocks continue bit for bit.

@njit(cache=True, nogil=True)
def etd3_kernel(chain, co, inp, h_in, nsub, n_int, out_every, y, y_out, hist, have):
    """etd3 (see the section comment above), ``nsub`` steps per input interval, any n.

    ``hist`` (2, 3n) holds (N0, N1, N2) at the previous step's two stages and is updated in place;
    ``have`` says whether it is valid (else the first step predicts with N(y), which costs one
    more evaluation). ``chain``, ``inp``: as :func:`rig.solvers.rk4.rk4_kernel`'s; ``co``:
    :class:`Etd3Coefficients`. ``y`` (2n,) is overwritten with the end state. Returns (status, rows
    written, intervals done, remainder evaluations).
    """
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
    p, q, bw, phi, g0, g1 = co.p, co.q, co.bw, co.phi, co.g0, co.g1
    phic, g0c, g1c, pc, wq, xp = co.phic, co.g0c, co.g1c, co.pc, co.wq, co.xp
    n2 = y.shape[0]
    n = n2 // 2
    zs = np.empty((3, n2))
    fh = np.empty(n)
    ff = np.empty((2, n))
    yt = np.empty(n2)
    w = np.empty((n, n + 5))
    uc = np.empty(2)
    vc = np.empty(2)
    h = h_in / nsub
    inv = 1.0 / h_in
    c0 = ETD3_NODES[0]
    c1 = ETD3_NODES[1]
    nev = 0
    zero = n_int - n_int  # run-time 0, 1: _NOTE_LITERALS, rig.solvers.primitives
    one = zero + 1
    two = one + 1
    if not have:
        for c in range(n2):
            zs[two, c] = y[c]
        nsplit_n(hc, s, cm, g, p, q, bw, zs, two, hist, zero, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
        nev += 1
    store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        b0 = ay[i * sa]
        db = ay[(i + la) * sa] - b0
        for jj in range(nsub):
            s0 = jj * h
            ua = a0 + da * (s0 * inv)
            ub = a0 + da * ((s0 + h) * inv)
            for st in range(2):
                ci = c0 if st == 0 else c1
                tm = (s0 + 0.5 * ci * h) * inv
                um = a0 + da * tm
                vm = b0 + db * tm
                tc = (s0 + ci * h) * inv
                uc[st] = a0 + da * tc
                vc[st] = b0 + db * tc
                x0 = xp[st, 0]
                x1 = xp[st, 1]
                for c in range(n):
                    fh[c] = (x0 * (hist[0, c] + um * hist[0, n + c] + vm * hist[0, 2 * n + c])
                             + x1 * (hist[1, c] + um * hist[1, n + c] + vm * hist[1, 2 * n + c]))
                du = uc[st] - ua
                for r in range(n2):
                    acc = g0c[st, r] * ua + g1c[st, r] * du
                    for c in range(n2):
                        acc += phic[st, r, c] * y[c]
                    for c in range(n):
                        acc += pc[st, r, c] * fh[c]
                    zs[st, r] = acc
            for st in range(2):
                nsplit_n(hc, s, cm, g, p, q, bw, zs, st, hist, st, w)
                for c in range(n):
                    ff[st, c] = (hist[st, c] + uc[st] * hist[st, n + c]
                                 + vc[st] * hist[st, 2 * n + c])
            nev += 2
            du = ub - ua
            for r in range(n2):
                acc = g0[r] * ua + g1[r] * du
                for c in range(n2):
                    acc += phi[r, c] * y[c]
                for c in range(n):
                    acc += wq[0, r, c] * ff[0, c] + wq[1, r, c] * ff[1, c]
                yt[r] = acc
            for r in range(n2):
                y[r] = yt[r]
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, nev
    return OK, row, n_int, nev


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3_kernel2(chain, co, inp, h_in, nsub, n_int, out_every, y, y_out, hist, have):
    """:func:`etd3_kernel` for n = 2 in scalar code (the same arithmetic up to the order of the
    sums; the state and history stay in registers). Same arguments and returns."""
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
    p, q, bw, phi, g0, g1 = co.p, co.q, co.bw, co.phi, co.g0, co.g1
    phic, g0c, g1c, pc, wq, xp = co.phic, co.g0c, co.g1c, co.pc, co.wq, co.xp
    z0 = y[0]
    z1 = y[1]
    z2 = y[2]
    z3 = y[3]
    h = h_in / nsub
    inv = 1.0 / h_in
    c0 = ETD3_NODES[0]
    c1 = ETD3_NODES[1]
    nev = 0
    if not have:
        sa0, ca0, sa1, ca1, _, _, _, _ = sincos4(z0, z1, 0.0, 0.0)
        a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, sa0, ca0,
                                                sa1, ca1)
        b00, b01, b10, b11, b20, b21 = a00, a01, a10, a11, a20, a21
        nev += 1
    else:
        a00, a01, a10, a11, a20, a21 = hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3], \
            hist[0, 4], hist[0, 5]
        b00, b01, b10, b11, b20, b21 = hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3], \
            hist[1, 4], hist[1, 5]
    x00 = xp[0, 0]
    x01 = xp[0, 1]
    x10 = xp[1, 0]
    x11 = xp[1, 1]
    zero = n_int - n_int  # run-time 0, 1: _NOTE_LITERALS, rig.solvers.primitives
    one = zero + 1
    store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        ia = ax[i]
        da = ax[i + la] - ia
        ib = ay[i * sa]
        db = ay[(i + la) * sa] - ib
        for jj in range(nsub):
            s0 = jj * h
            ua = ia + da * (s0 * inv)
            ub = ia + da * ((s0 + h) * inv)
            # stage 0: predicted remainder at c0 h / 2, then the exact linear step to c0 h
            tm = (s0 + 0.5 * c0 * h) * inv
            um = ia + da * tm
            vm = ib + db * tm
            fa0 = x00 * (a00 + um * a10 + vm * a20) + x01 * (b00 + um * b10 + vm * b20)
            fa1 = x00 * (a01 + um * a11 + vm * a21) + x01 * (b01 + um * b11 + vm * b21)
            tc = (s0 + c0 * h) * inv
            uc0 = ia + da * tc
            vc0 = ib + db * tc
            du = uc0 - ua
            p0 = (((phic[0, 0, 0] * z0 + phic[0, 0, 1] * z1)
                   + (phic[0, 0, 2] * z2 + phic[0, 0, 3] * z3))
                  + ((g0c[0, 0] * ua + g1c[0, 0] * du)
                     + (pc[0, 0, 0] * fa0 + pc[0, 0, 1] * fa1)))
            p1 = (((phic[0, 1, 0] * z0 + phic[0, 1, 1] * z1)
                   + (phic[0, 1, 2] * z2 + phic[0, 1, 3] * z3))
                  + ((g0c[0, 1] * ua + g1c[0, 1] * du)
                     + (pc[0, 1, 0] * fa0 + pc[0, 1, 1] * fa1)))
            p2 = (((phic[0, 2, 0] * z0 + phic[0, 2, 1] * z1)
                   + (phic[0, 2, 2] * z2 + phic[0, 2, 3] * z3))
                  + ((g0c[0, 2] * ua + g1c[0, 2] * du)
                     + (pc[0, 2, 0] * fa0 + pc[0, 2, 1] * fa1)))
            p3 = (((phic[0, 3, 0] * z0 + phic[0, 3, 1] * z1)
                   + (phic[0, 3, 2] * z2 + phic[0, 3, 3] * z3))
                  + ((g0c[0, 3] * ua + g1c[0, 3] * du)
                     + (pc[0, 3, 0] * fa0 + pc[0, 3, 1] * fa1)))
            # stage 1
            tm = (s0 + 0.5 * c1 * h) * inv
            um = ia + da * tm
            vm = ib + db * tm
            fb0 = x10 * (a00 + um * a10 + vm * a20) + x11 * (b00 + um * b10 + vm * b20)
            fb1 = x10 * (a01 + um * a11 + vm * a21) + x11 * (b01 + um * b11 + vm * b21)
            tc = (s0 + c1 * h) * inv
            uc1 = ia + da * tc
            vc1 = ib + db * tc
            du = uc1 - ua
            q0 = (((phic[1, 0, 0] * z0 + phic[1, 0, 1] * z1)
                   + (phic[1, 0, 2] * z2 + phic[1, 0, 3] * z3))
                  + ((g0c[1, 0] * ua + g1c[1, 0] * du)
                     + (pc[1, 0, 0] * fb0 + pc[1, 0, 1] * fb1)))
            q1 = (((phic[1, 1, 0] * z0 + phic[1, 1, 1] * z1)
                   + (phic[1, 1, 2] * z2 + phic[1, 1, 3] * z3))
                  + ((g0c[1, 1] * ua + g1c[1, 1] * du)
                     + (pc[1, 1, 0] * fb0 + pc[1, 1, 1] * fb1)))
            q2 = (((phic[1, 2, 0] * z0 + phic[1, 2, 1] * z1)
                   + (phic[1, 2, 2] * z2 + phic[1, 2, 3] * z3))
                  + ((g0c[1, 2] * ua + g1c[1, 2] * du)
                     + (pc[1, 2, 0] * fb0 + pc[1, 2, 1] * fb1)))
            q3 = (((phic[1, 3, 0] * z0 + phic[1, 3, 1] * z1)
                   + (phic[1, 3, 2] * z2 + phic[1, 3, 3] * z3))
                  + ((g0c[1, 3] * ua + g1c[1, 3] * du)
                     + (pc[1, 3, 0] * fb0 + pc[1, 3, 1] * fb1)))
            sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1 = sincos4(p0, p1, q0, q1)
            a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                    cp0, sp1, cp1)
            b00, b01, b10, b11, b20, b21 = nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                    cq0, sq1, cq1)
            nev += 2
            f00 = a00 + uc0 * a10 + vc0 * a20
            f01 = a01 + uc0 * a11 + vc0 * a21
            f10 = b00 + uc1 * b10 + vc1 * b20
            f11 = b01 + uc1 * b11 + vc1 * b21
            du = ub - ua
            n0 = ((((phi[0, 0] * z0 + phi[0, 1] * z1) + (phi[0, 2] * z2 + phi[0, 3] * z3))
                   + (g0[0] * ua + g1[0] * du))
                  + ((wq[0, 0, 0] * f00 + wq[0, 0, 1] * f01)
                     + (wq[1, 0, 0] * f10 + wq[1, 0, 1] * f11)))
            n1 = ((((phi[1, 0] * z0 + phi[1, 1] * z1) + (phi[1, 2] * z2 + phi[1, 3] * z3))
                   + (g0[1] * ua + g1[1] * du))
                  + ((wq[0, 1, 0] * f00 + wq[0, 1, 1] * f01)
                     + (wq[1, 1, 0] * f10 + wq[1, 1, 1] * f11)))
            n2 = ((((phi[2, 0] * z0 + phi[2, 1] * z1) + (phi[2, 2] * z2 + phi[2, 3] * z3))
                   + (g0[2] * ua + g1[2] * du))
                  + ((wq[0, 2, 0] * f00 + wq[0, 2, 1] * f01)
                     + (wq[1, 2, 0] * f10 + wq[1, 2, 1] * f11)))
            n3 = ((((phi[3, 0] * z0 + phi[3, 1] * z1) + (phi[3, 2] * z2 + phi[3, 3] * z3))
                   + (g0[3] * ua + g1[3] * du))
                  + ((wq[0, 3, 0] * f00 + wq[0, 3, 1] * f01)
                     + (wq[1, 3, 0] * f10 + wq[1, 3, 1] * f11)))
            z0 = n0
            z1 = n1
            z2 = n2
            z3 = n3
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            y[0] = z0
            y[1] = z1
            y[2] = z2
            y[3] = z3
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
                return NONFINITE, row, i + 1, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
    return OK, row, n_int, nev


@njit(cache=True)
def etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21):
    hist[0, 0] = a00
    hist[0, 1] = a01
    hist[0, 2] = a10
    hist[0, 3] = a11
    hist[0, 4] = a20
    hist[0, 5] = a21
    hist[1, 0] = b00
    hist[1, 1] = b01
    hist[1, 2] = b10
    hist[1, 3] = b11
    hist[1, 4] = b20
    hist[1, 5] = b21
