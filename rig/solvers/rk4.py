"""rk4: the classic 4-stage Runge-Kutta method, fixed step (order 4).

Global error O(h^4); the energy drifts secularly (~ t h^4). ``substeps`` equal steps per input
interval; the right-hand side is the n = 2 scalar code, the dense solve or the O(n) recursion
(:func:`rig.solvers.rhs.rhs_algorithm`). Cost: 4 right-hand sides per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import math

import numpy as np

from rig.jit import njit
from rig.solvers.primitives import (ALG_TWO, NONFINITE, OK, SINCOS_POLY_MAX, chain_args, rhs2,
                                    rhs_n, rhs_rec, sincos_poly, store)
from rig.solvers.base import SubstepSolver
from rig.solvers.rhs import bodies_array, rhs_algorithm


@dataclass(frozen=True)
class RK4(SubstepSolver):
    """Classic RK4 with ``substeps`` steps per input interval (``algorithm``: the right-hand side,
    ``"auto"``, ``"dense"`` or ``"recursive"``)."""

    substeps: int = 1
    algorithm: str = "auto"

    name: ClassVar[str] = "rk4"
    order: ClassVar[int] = 4
    kind: ClassVar[str] = "fixed"
    description: ClassVar[str] = "classic 4-stage Runge-Kutta, fixed step dt_s"
    selectable_rhs: ClassVar[bool] = True

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        alg = rhs_algorithm(chain, self.algorithm)
        inp, ca = held.kernel_args, chain_args(chain)
        sub = self.substeps
        if alg == ALG_TWO:
            status, nrow, i_done = rk4_kernel2(ca, inp, held.h_in, sub, held.n_intervals,
                                               held.out_every, y, y_out)
        else:
            status, nrow, i_done = rk4_kernel(ca, bodies_array(chain), alg, inp, held.h_in, sub,
                                              held.n_intervals, held.out_every, y, y_out)
        return self.finish(chain, status, y, y_out, nrow, i_done, held, substeps=sub,
                           n_steps=i_done * sub, n_fev=4 * i_done * sub)


# ================================================================================================
# compiled kernels
# ================================================================================================

@njit(cache=True, nogil=True)
def rk4_kernel(chain, bod, alg, inp, h_in, nsub, n_int, out_every, y, y_out):
    """Classic RK4, ``nsub`` equal steps per input interval, over ``n_int`` intervals.

    Input (all kernels): interval i holds ``ax[i] + (ax[i + la] - ax[i]) s / h_in`` (la = 1 for
    linear hold, 0 for zoh) and likewise ``ay[i sa]`` (sa = 0 with ay = [0.]: no vertical input);
    written with indices rather than branches so LLVM does not unswitch (duplicate) the loops.

    ``chain``: :class:`rig.solvers.primitives.ChainArgs`; ``inp``: the held input,
    :class:`rig.solvers.primitives.HeldArgs`. ``y`` (2n,) is the state at the start and is
    overwritten with the state at the end. Rows of ``y_out`` receive the state at interval
    counts 0, out_every, 2 out_every, ..., n_int.
    ``bod``, ``alg``: the right-hand side's body table and algorithm (:func:`rhs_alg`).
    Returns (status, rows written, intervals done).
    """
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
    n2 = y.shape[0]
    n = n2 // 2
    kk = np.zeros((4, n2))
    yt = np.empty(n2)
    work = np.empty((n, max(n + 2, 6)))
    h = h_in / nsub
    inv = 1.0 / h_in
    zero = n_int - n_int  # run-time 0, 1: _NOTE_LITERALS, rig.solvers.primitives
    one = zero + 1
    store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        b0 = ay[i * sa]
        db = ay[(i + la) * sa] - b0
        for j in range(nsub):
            s0 = j * h
            for st in range(4):
                # stage st at y + a h k_{st-1}, time s0 + a h, a = 0, 1/2, 1/2, 1
                a = 0.0 if st == 0 else (1.0 if st == 3 else 0.5)
                for c in range(n2):
                    yt[c] = y[c] + (a * h) * kk[st - 1 if st > 0 else 0, c]
                fr = (s0 + a * h) * inv
                if alg == 0:
                    rhs2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st)
                elif alg == 1:
                    rhs_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
                else:
                    rhs_rec(bod, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
            for c in range(n2):
                y[c] += h / 6.0 * (kk[0, c] + 2.0 * (kk[1, c] + kk[2, c]) + kk[3, c])
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1
    return OK, row, n_int


@njit(cache=True, inline="always")
def _sincos2(a, b):
    """sin and cos of two angles, (sa, ca, sb, cb): the polynomial when both |angles| <=
    SINCOS_POLY_MAX (one branch), libm otherwise."""
    if max(abs(a), abs(b)) <= SINCOS_POLY_MAX:
        sa, ca = sincos_poly(a)
        sb, cb = sincos_poly(b)
        return sa, ca, sb, cb
    return math.sin(a), math.cos(a), math.sin(b), math.cos(b)


@njit(cache=True, inline="always")
def _acc2(hc, s, cm, g, th0, th1, w0, w1, ax, ay):
    """th'' of the n = 2 chain as two numbers (the arithmetic of :func:`rhs2`)."""
    s0, c0, s1, c1 = _sincos2(th0, th1)
    ga = g + ay
    h01 = hc[0, 1]
    m01 = h01 * (c0 * c1 + s0 * s1)
    hs = h01 * (s0 * c1 - c0 * s1)
    f0 = -s[0] * (ga * s0 + ax * c0) - cm[0, 0] * w0 - cm[0, 1] * w1 - hs * w1 * w1
    f1 = -s[1] * (ga * s1 + ax * c1) - cm[1, 0] * w0 - cm[1, 1] * w1 + hs * w0 * w0
    h00 = hc[0, 0]
    h11 = hc[1, 1]
    idet = 1.0 / (h00 * h11 - m01 * m01)
    return (h11 * f0 - m01 * f1) * idet, (h00 * f1 - m01 * f0) * idet


@njit(cache=True, nogil=True, fastmath={"contract"})
def rk4_kernel2(chain, inp, h_in, nsub, n_int, out_every, y, y_out):
    """:func:`rk4_kernel` for n = 2 in scalar code (the state in registers, the sines and
    cosines from the inlined polynomial, fused multiply-adds). Same arguments (without the body
    table) and returns."""
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
    z0 = y[0]
    z1 = y[1]
    z2 = y[2]
    z3 = y[3]
    h = h_in / nsub
    hh = 0.5 * h
    h6 = h / 6.0
    inv = 1.0 / h_in
    zero = n_int - n_int  # run-time 0, 1: _NOTE_LITERALS, rig.solvers.primitives
    one = zero + 1
    store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        b0 = ay[i * sa]
        db = ay[(i + la) * sa] - b0
        for j in range(nsub):
            s0 = j * h
            f0 = s0 * inv
            f1 = (s0 + hh) * inv
            f2 = (s0 + h) * inv
            u0 = a0 + da * f0
            u1 = a0 + da * f1
            u2 = a0 + da * f2
            v0 = b0 + db * f0
            v1 = b0 + db * f1
            v2 = b0 + db * f2
            p0, p1 = _acc2(hc, s, cm, g, z0, z1, z2, z3, u0, v0)
            t0 = z0 + hh * z2
            t1 = z1 + hh * z3
            r0 = z2 + hh * p0
            r1 = z3 + hh * p1
            q0, q1 = _acc2(hc, s, cm, g, t0, t1, r0, r1, u1, v1)
            t0 = z0 + hh * r0
            t1 = z1 + hh * r1
            x0 = z2 + hh * q0
            x1 = z3 + hh * q1
            e0, e1 = _acc2(hc, s, cm, g, t0, t1, x0, x1, u1, v1)
            t0 = z0 + h * x0
            t1 = z1 + h * x1
            c0 = z2 + h * e0
            c1 = z3 + h * e1
            d0, d1 = _acc2(hc, s, cm, g, t0, t1, c0, c1, u2, v2)
            z0 = z0 + h6 * (z2 + 2.0 * (r0 + x0) + c0)
            z1 = z1 + h6 * (z3 + 2.0 * (r1 + x1) + c1)
            z2 = z2 + h6 * (p0 + 2.0 * (q0 + e0) + d0)
            z3 = z3 + h6 * (p1 + 2.0 * (q1 + e1) + d1)
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
                return NONFINITE, row, i + 1
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    return OK, row, n_int
