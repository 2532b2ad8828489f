"""etd4m: the multi-sample exponential integrator with three Gauss nodes and a quadratic
remainder over the stages.

Like etd3m (:mod:`rig.solvers.etd3m`), one step spans ``H = m h_in``, m whole held input samples:
the linearised chain and the held input are propagated exactly, and only the nonlinear remainder
(N0, the input gain's nonlinear part N1 and the vertical gain N2, :func:`rig.solvers.rhs.
nonlinear_remainder`) is approximated,

    z(H) = e^{AH} z(0) + int_0^H e^{A(H-s)} E [N0(z) + u(s) (b + N1(theta)) + v(s) N2(theta)] ds.

The differences from etd3m, both raising the order in the step:

* **three Gauss-Legendre nodes** c_i = 1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10: N0, b + N1 and
  N2 are interpolated by the quadratic through the three stages, and each product with the held
  input is integrated exactly against the staircase (or the straight lines of the linear hold):
  per sample q and node i the weight ``W_iq = int_0^H e^{A(H-s)} E l_i(s/H) phi_q(s) ds``, with
  the hold's basis function phi_q (as etd3m, so the input's kinks at every sample are integrated,
  never assumed smooth);
* **the stages predicted by a quadratic**: the remainder over ``[0, c_i H]`` is the quadratic
  through the previous step's three stages (at c_j - 1 in units of H), integrated exactly against
  e^{A(c_i H - s)} for N0 (matrices ``PN[i, j]``, no per-sample cost), and, for the products with
  the input, held at its value at c_i H / 2 against the staircase (one weight set per stage: the
  input gain's nonlinear part N1 is of the order of theta^2 relative to b, so its variation over
  a stage enters at that relative size times H^2).

The stage omegas, where N is evaluated, carry etd3m's correction for the staircase's sawtooth
(the interpolation then sees each interval's mean). Three remainder evaluations per step; per
sample a FIR of 6 weight sets (2n x n each), the stage sets skipped past their nodes (for n = 2
every row in full, which the compiler vectorises; without a vertical input the n = 2 kernel
forms neither N2 nor its products with the zero input, the same numbers, and forms the FIR, which
no state enters, as BLAS products of :data:`FIR_CHUNK_STEPS` steps' input windows ahead of its
serial chain: the same sums within round-off; docs/benchmarks/history.md, speed round 7). The first
step after a (re)start predicts with N(z0) at one more evaluation; the three stages are part of
the native state (theta, omega, valid flag, step H, then 9n numbers), so blocks that end on output
rows continue bit for bit.

Error: order 4 in H (the stages' error O(H^4) through the quadratic prediction; the quadrature
through three nodes is of order 6 for a smooth remainder); measured on the paper's run in
``tests/rig/solvers/test_etd4m.py`` and BENCHMARKS.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np


from rig.jit import njit
from rig.linear import expm
from rig.solvers.primitives import NONFINITE, OK, chain_args, sincos6, sincos_pair, store
from rig.solvers.remainder import n2_at, nsplit2, nsplit2h, nsplit_n
from rig.solvers.base import Refinement, multisample_refinement
from rig.solvers.dop853 import Dop853
from rig.solvers.etd3m import (MultiSample, piece_integral, check_hold_and_m,
                               check_samples_per_step, linear_parts, sawtooth_corrections,
                               staircase_weights)

if TYPE_CHECKING:
    from rig.chain import Chain


_R15 = math.sqrt(15.0)
ETD4M_NODES = (0.5 - _R15 / 10.0, 0.5, 0.5 + _R15 / 10.0)
ETD4M_SETS = 6  # weight sets per sample: end nodes 0, 1, 2, then stages 2, 1, 0
#: n = 2 without a vertical input: the kernel that forms neither N2 nor its zero products
#: (:func:`etd4m_kernel2h`, the same numbers as etd4m_kernel2); False runs
#: etd4m_kernel2 there (the path before, for benchmarks/targets.py)
HORIZONTAL_KERNEL = True
#: steps whose input FIR etd4m_kernel2h forms as one BLAS product before its serial chain reads
#: it (the same sums within round-off; 0: the FIR in the loop, step by step, the path before,
#: for benchmarks/targets.py), at most what keeps the product in one BLAS thread
#: (:func:`fir_chunk_steps`)
FIR_CHUNK_STEPS = 256
#: OpenBLAS computes a product of m n k <= 65536 x GEMM_MULTITHREAD_THRESHOLD (4 by default)
#: multiply-adds in the calling thread (interface/gemm.c); above, it wakes its threads, whose
#: start and spinning cost more CPU than such a product
BLAS_ONE_THREAD_MULADDS = 65536 * 4


def fir_chunk_steps(window: int) -> int:
    """Steps per BLAS product of etd4m_kernel2h's input FIR for ``window`` samples a step
    (``m`` + 1 for the linear hold): :data:`FIR_CHUNK_STEPS`, fewer where the product of
    (steps, window) by (window, 48) would exceed :data:`BLAS_ONE_THREAD_MULADDS`; 0 if
    :data:`FIR_CHUNK_STEPS` is 0."""
    if FIR_CHUNK_STEPS <= 0:
        return 0
    return max(1, min(FIR_CHUNK_STEPS, BLAS_ONE_THREAD_MULADDS // (48 * window)))


class Etd4mCoefficients(NamedTuple):
    """Everything :func:`etd4m_kernel` needs for one chain, input interval, m and hold, its second
    argument.

    Attributes
    ----------
    m : input samples per step; ``H = m h_in`` [s].
    phi : e^{AH}, (2n, 2n).
    phic : e^{A c_i H}, (3, 2n, 2n).
    wt : per-sample weights, (m + la, 6 (2n) n), la = 1 for the linear hold: row q holds W_0q,
        W_1q, W_2q (end of step) and P_2q, P_1q, P_0q (the stages, ``int_0^{c_i H}
        e^{A(c_i H - s)} E phi_q(s) ds``), each (2n, n) row-major.
    wq : sum_q W_iq (N0's end quadrature weights), (3, 2n, n).
    pn : PN[i, j] = int_0^{c_i H} e^{A(c_i H - s)} E L_j(s/H) ds, L_j the Lagrange basis through
        the previous step's nodes c_j - 1, (3, 3, 2n, n).
    xp : L_j(c_i / 2), the predictor of the input gain at the stage's midpoint, (3, 3).
    ck : the stage omega shift's factor h_in (1/12 - f_i (1 - f_i)/2) / (hi_i - lo_i), (3,)
        (zero for m = 1 or the linear hold).
    lohi : (3, 2) the samples (within the step) whose difference is du_i.
    widths : (e0, e1, e2): rows [0, e0) of wt carry 6 sets, [e0, e1) 5, [e1, e2) 4, the rest 3.
    p, q, bw : as :class:`rig.solvers.etd3.Etd3Coefficients`.
    """

    m: int
    phi: np.ndarray
    phic: np.ndarray
    wt: np.ndarray
    wq: np.ndarray
    pn: np.ndarray
    xp: np.ndarray
    ck: np.ndarray
    lohi: np.ndarray
    widths: np.ndarray
    p: np.ndarray
    q: np.ndarray
    bw: np.ndarray


def _lagrange(nodes, j, scale):
    """The Lagrange basis polynomial j through ``nodes`` (in units of ``scale``), in s."""
    poly = np.polynomial.Polynomial([1.0])
    for k, ck in enumerate(nodes):
        if k != j:
            poly = poly * np.polynomial.Polynomial([-ck, 1.0 / scale]) / (nodes[j] - ck)
    return poly


@functools.lru_cache(maxsize=32)
def etd4m_coefficients(chain: Chain, h_in: float, m: int, hold: str) -> Etd4mCoefficients:
    """The matrices of :func:`etd4m_kernel` for ``chain``, input interval ``h_in`` [s], ``m``
    samples per step and ``hold`` (cached; ~6 m small matrix exponentials)."""
    check_hold_and_m(hold, m)
    a, b = chain.state_space()
    n = chain.n
    n2 = 2 * n
    c = ETD4M_NODES
    big_h = m * h_in
    la = int(hold == "linear")
    lag = [_lagrange(c, i, big_h) for i in range(3)]
    wt = staircase_weights(a, n, h_in, m, la, c, lag)
    prev = tuple(ci - 1.0 for ci in c)
    lprev = [_lagrange(prev, j, big_h) for j in range(3)]
    pn = np.array([[piece_integral(a, n, ci * big_h, 0.0, ci * big_h, lprev[j])
                    for j in range(3)] for ci in c])
    xp = np.array([[lprev[j](0.5 * ci * big_h) for j in range(3)] for ci in c])
    phic = np.array([expm(a * (ci * big_h)) for ci in c])
    ck, lohi = sawtooth_corrections(c, m, la, h_in)
    widths = np.array([min(int(math.ceil(ci * m * (1.0 + 1e-12) - 1e-12)) + la, m + la)
                       for ci in c], dtype=np.int64)
    arr = np.ascontiguousarray
    return Etd4mCoefficients(
        m=m, phi=arr(expm(a * big_h)), phic=arr(phic),
        wt=arr(wt.reshape(m + la, ETD4M_SETS * n2 * n)), wq=arr(wt[:, :3].sum(axis=0)),
        pn=arr(pn), xp=arr(xp), ck=ck, lohi=lohi, widths=widths, **linear_parts(chain, b))


@dataclass(frozen=True)
class Etd4m(MultiSample):
    """etd4m with ``samples_per_step`` input intervals per step (as :class:`rig.solvers.etd3m.
    Etd3m`)."""

    samples_per_step: int = 1

    name: ClassVar[str] = "etd4m"
    order: ClassVar[int] = 4
    description: ClassVar[str] = (
        "etd3m with three Gauss nodes and the stages predicted by the quadratic through the "
        "previous step's three (rig.solvers.etd4m; 3 evaluations per step)")
    native: ClassVar[str] = "theta,omega,history3"
    history_rows: ClassVar[int] = 3

    def refined(self) -> Refinement:
        def reference():
            return Refinement(Dop853(rtol=1e-12, atol=1e-14), 1.0, (
                "|y - y_ref| against dop853 at rtol = 1e-12, atol = 1e-14 from the same start "
                f"state ({self.name} at one input interval per step cannot halve its step)"))
        return multisample_refinement(self, self.samples_per_step, reference)

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, ay, sa, _ = held.kernel_args
        m = check_samples_per_step(self, held)
        co = etd4m_coefficients(chain, float(held.h_in), m, held.hold)
        big_h = m * held.h_in
        z, hist, have = self.split_history(chain, y, big_h)
        if chain.n == 2 and not sa and HORIZONTAL_KERNEL:
            status, nrow, i_done, nfev = etd4m_kernel2h(
                chain_args(chain), co, ax, m, held.n_intervals // m, held.out_every // m, z, y_out,
                hist, have, fir_chunk_steps(co.wt.shape[0]))
        else:
            status, nrow, i_done, nfev = (etd4m_kernel2 if chain.n == 2 else etd4m_kernel)(
                chain_args(chain), co, ax, ay, sa, m, held.n_intervals // m, held.out_every // m,
                z, y_out, hist, have)
        y = np.concatenate([z, [1.0, big_h], hist.reshape(-1)])
        return self.finish(chain, status, y, y_out, nrow, i_done, held, n_steps=i_done // m,
                           n_fev=nfev)


# ================================================================================================
# compiled kernels
# ================================================================================================

@njit(cache=True, inline="always")
def _etd4m_fir6(u, i0, stride, wt, widths, nw, acc):
    """acc = sum_q u[(i0 + q) stride] wt[q], the stage sets skipped past their nodes."""
    for r in range(6 * nw):
        acc[r] = 0.0
    lo = 0
    for seg in range(4):
        hi = widths[seg] if seg < 3 else wt.shape[0]
        width = (6 - seg) * nw
        for qq in range(lo, hi):
            x = u[(i0 + qq) * stride]
            for r in range(width):
                acc[r] += x * wt[qq, r]
        lo = max(lo, hi)


@njit(cache=True)
def _etd4m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w):
    """hn[i] = (N0, N1, N2) at the state zs[i] (the n = 2 scalar code where n = 2)."""
    if zs.shape[1] == 4:
        s0, c0, s1, c1 = sincos_pair(zs[i, 0], zs[i, 1])
        (hn[i, 0], hn[i, 1], hn[i, 2], hn[i, 3], hn[i, 4],
         hn[i, 5]) = nsplit2(hc, s, cm, g, p, q, bw, zs[i, 0], zs[i, 1], zs[i, 2], zs[i, 3], s0,
                              c0, s1, c1)
    else:
        nsplit_n(hc, s, cm, g, p, q, bw, zs, i, hn, i, w)


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd4m_kernel(chain, co, ax, ay, sa, m, n_steps, out_steps, y, y_out, hist, have):
    """etd4m (module docstring): ``n_steps`` steps of ``m`` input samples, any n.

    ``chain``: :class:`rig.solvers.primitives.ChainArgs`; ``co``: :class:`Etd4mCoefficients`.
    ``ax``, ``ay`` hold the samples (``ay`` read with stride ``sa``: 0 for none); a row is stored
    every ``out_steps`` steps and at the end. ``hist`` (3, 3n) holds (N0, N1, N2) at the previous
    step's three stages and is updated in place; ``have`` says whether it is valid. ``y`` (2n,)
    is overwritten with the end state. Returns (status, rows written, input intervals done,
    remainder evaluations)."""
    hc, s, cm, g = chain
    p, q, bw, phi, phic, wt = co.p, co.q, co.bw, co.phi, co.phic, co.wt
    wq, pn, xp, ck, lohi, widths = co.wq, co.pn, co.xp, co.ck, co.lohi, co.widths
    n2 = y.shape[0]
    n = n2 // 2
    nw = n2 * n
    acc = np.empty(6 * nw)
    accv = np.zeros(6 * nw)
    zs = np.empty((3, n2))
    hn = np.empty((3, 3 * n))
    gg = np.empty(n)
    g2 = np.empty(n)
    zt = np.empty(n2)
    w = np.empty((n, n + 5))
    nev = 0
    zero = n_steps - n_steps
    one = zero + 1
    if not have:
        for c in range(n2):
            zs[zero, c] = y[c]
        _etd4m_eval(hc, s, cm, g, p, q, bw, zs, zero, hist, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
            hist[one + one, c] = hist[zero, c]
        nev += 1
    store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        _etd4m_fir6(ax, i0, 1, wt, widths, nw, acc)
        if sa:
            _etd4m_fir6(ay, i0, sa, wt, widths, nw, accv)
        for i in range(3):
            for j in range(n):
                gj = bw[j]
                vj = 0.0
                for jj in range(3):
                    gj += xp[i, jj] * hist[jj, n + j]
                    vj += xp[i, jj] * hist[jj, 2 * n + j]
                gg[j] = gj
                g2[j] = vj
            du = ck[i] * (ax[i0 + lohi[i, 1]] - ax[i0 + lohi[i, 0]])
            dv = ck[i] * (ay[(i0 + lohi[i, 1]) * sa] - ay[(i0 + lohi[i, 0]) * sa])
            base = (5 - i) * nw
            for r in range(n2):
                t = 0.0
                for c in range(n2):
                    t += phic[i, r, c] * y[c]
                for j in range(n):
                    t += acc[base + r * n + j] * gg[j] + accv[base + r * n + j] * g2[j]
                    for jj in range(3):
                        t += pn[i, jj, r, j] * hist[jj, j]
                zs[i, r] = t
            for j in range(n):
                zs[i, n + j] += du * gg[j] + dv * g2[j]
        for i in range(3):
            _etd4m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w)
        nev += 3
        for r in range(n2):
            t = 0.0
            for c in range(n2):
                t += phi[r, c] * y[c]
            for i in range(3):
                base = i * nw
                for j in range(n):
                    t += (acc[base + r * n + j] * (bw[j] + hn[i, n + j])
                          + accv[base + r * n + j] * hn[i, 2 * n + j] + wq[i, r, j] * hn[i, j])
            zt[r] = t
        for r in range(n2):
            y[r] = zt[r]
        for i in range(3):
            for c in range(3 * n):
                hist[i, c] = hn[i, c]
        left -= 1
        if left == 0 or k + 1 == n_steps:
            left = out_steps
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, (k + 1) * m, nev
    return OK, row, n_steps * m, nev


@njit(cache=True, inline="always")
def _etd4m_fir48(u, i0, stride, wt, acc):
    """acc = sum_q u[(i0 + q) stride] wt[q] for n = 2: every row in full (48 numbers, a constant
    trip count the compiler vectorises: faster than skipping the stage sets' zero suffixes)."""
    for r in range(48):
        acc[r] = 0.0
    for qq in range(wt.shape[0]):
        x = u[(i0 + qq) * stride]
        for r in range(48):
            acc[r] += x * wt[qq, r]


@njit(cache=True, inline="always")
def _etd4m_row2(mat, i, r, z0, z1, z2, z3, acc, accv, base, g0, g1, v0, v1):
    """Row r of mat[i] @ z + the (4, 2) blocks at ``base`` of acc @ g and accv @ v (n = 2)."""
    k = base + 2 * r
    return (((mat[i, r, 0] * z0 + mat[i, r, 1] * z1) + (mat[i, r, 2] * z2 + mat[i, r, 3] * z3))
            + ((acc[k] * g0 + acc[k + 1] * g1) + (accv[k] * v0 + accv[k + 1] * v1)))


@njit(cache=True, inline="always")
def _etd4m_n0_2(pn, i, r, a0, a1, b0, b1, c0, c1):
    """Row r of sum_j pn[i, j] @ N0_j for the three stages' N0 (a, b, c) (n = 2)."""
    return ((pn[i, 0, r, 0] * a0 + pn[i, 0, r, 1] * a1)
            + (pn[i, 1, r, 0] * b0 + pn[i, 1, r, 1] * b1)
            + (pn[i, 2, r, 0] * c0 + pn[i, 2, r, 1] * c1))


@njit(cache=True, inline="always")
def _etd4m_end2(r, acc, accv, wq, i, e0, e1, g0, g1, v0, v1):
    """Row r of node i's end weights: acc_i @ g + accv_i @ v + wq[i] @ e (n = 2)."""
    k = 8 * i + 2 * r
    return (((acc[k] * g0 + acc[k + 1] * g1) + (wq[i, r, 0] * e0 + wq[i, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd4m_kernel2(chain, co, ax, ay, sa, m, n_steps, out_steps, y, y_out, hist, have):
    """:func:`etd4m_kernel` for the n = 2 chain: the state, the stages and the remainder parts in
    scalars (the same arithmetic to round-off)."""
    hc, s, cm, g = chain
    p, q, bw, phi, phic, wt = co.p, co.q, co.bw, co.phi, co.phic, co.wt
    wq, pn, xp, ck, lohi = co.wq, co.pn, co.xp, co.ck, co.lohi
    nw = 8
    acc = np.empty(6 * nw)
    accv = np.zeros(6 * nw)
    phi3 = phi.reshape((1, 4, 4))
    nev = 0
    z0, z1, z2, z3 = y[0], y[1], y[2], y[3]
    zero = n_steps - n_steps
    one = zero + 1
    if not have:
        s0, c0, s1, c1 = sincos_pair(z0, z1)
        a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0,
                                                s1, c1)
        b00, b01, b10, b11, b20, b21 = a00, a01, a10, a11, a20, a21
        d00, d01, d10, d11, d20, d21 = a00, a01, a10, a11, a20, a21
        nev += 1
    else:
        a00, a01, a10, a11, a20, a21 = (hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3],
                                        hist[0, 4], hist[0, 5])
        b00, b01, b10, b11, b20, b21 = (hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3],
                                        hist[1, 4], hist[1, 5])
        d00, d01, d10, d11, d20, d21 = (hist[2, 0], hist[2, 1], hist[2, 2], hist[2, 3],
                                        hist[2, 4], hist[2, 5])
    bw0 = bw[0]
    bw1 = bw[1]
    store(y, y_out, zero)
    row = one
    left = out_steps
    st = np.empty((3, 4))
    for k in range(n_steps):
        i0 = k * m
        _etd4m_fir48(ax, i0, 1, wt, acc)
        if sa:
            _etd4m_fir48(ay, i0, sa, wt, accv)
        for i in range(3):
            x0 = xp[i, 0]
            x1 = xp[i, 1]
            x2 = xp[i, 2]
            g0 = bw0 + ((x0 * a10 + x1 * b10) + x2 * d10)
            g1 = bw1 + ((x0 * a11 + x1 * b11) + x2 * d11)
            v0 = (x0 * a20 + x1 * b20) + x2 * d20
            v1 = (x0 * a21 + x1 * b21) + x2 * d21
            du = ck[i] * (ax[i0 + lohi[i, 1]] - ax[i0 + lohi[i, 0]])
            dv = ck[i] * (ay[(i0 + lohi[i, 1]) * sa] - ay[(i0 + lohi[i, 0]) * sa])
            base = (5 - i) * nw
            for r in range(4):
                st[i, r] = (_etd4m_row2(phic, i, r, z0, z1, z2, z3, acc, accv, base, g0, g1, v0, v1)
                            + _etd4m_n0_2(pn, i, r, a00, a01, b00, b01, d00, d01))
            st[i, 2] += du * g0 + dv * v0
            st[i, 3] += du * g1 + dv * v1
        p0, p1, p2, p3 = st[0, 0], st[0, 1], st[0, 2], st[0, 3]
        q0, q1, q2, q3 = st[1, 0], st[1, 1], st[1, 2], st[1, 3]
        r0, r1, r2, r3 = st[2, 0], st[2, 1], st[2, 2], st[2, 3]
        (sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1, sr0, cr0, sr1,
         cr1) = sincos6(p0, p1, q0, q1, r0, r1)
        a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                cp0, sp1, cp1)
        b00, b01, b10, b11, b20, b21 = nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                cq0, sq1, cq1)
        d00, d01, d10, d11, d20, d21 = nsplit2(hc, s, cm, g, p, q, bw, r0, r1, r2, r3, sr0,
                                                cr0, sr1, cr1)
        nev += 3
        n0 = (_etd4m_row2(phi3, 0, 0, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 0, 0] * a00 + wq[0, 0, 1] * a01)
              + _etd4m_end2(0, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _etd4m_end2(0, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n1 = (_etd4m_row2(phi3, 0, 1, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 1, 0] * a00 + wq[0, 1, 1] * a01)
              + _etd4m_end2(1, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _etd4m_end2(1, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n2 = (_etd4m_row2(phi3, 0, 2, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 2, 0] * a00 + wq[0, 2, 1] * a01)
              + _etd4m_end2(2, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _etd4m_end2(2, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n3 = (_etd4m_row2(phi3, 0, 3, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 3, 0] * a00 + wq[0, 3, 1] * a01)
              + _etd4m_end2(3, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _etd4m_end2(3, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        z0 = n0
        z1 = n1
        z2 = n2
        z3 = n3
        left -= 1
        if left == 0 or k + 1 == n_steps:
            left = out_steps
            y[0] = z0
            y[1] = z1
            y[2] = z2
            y[3] = z3
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                _etd4m_hist2(hist, (a00, a01, a10, a11, a20, a21),
                             (b00, b01, b10, b11, b20, b21), (d00, d01, d10, d11, d20, d21))
                return NONFINITE, row, (k + 1) * m, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    _etd4m_hist2(hist, (a00, a01, a10, a11, a20, a21), (b00, b01, b10, b11, b20, b21),
                 (d00, d01, d10, d11, d20, d21))
    return OK, row, n_steps * m, nev


@njit(cache=True)
def _etd4m_hist2(hist, a, b, d):
    """hist[0], hist[1], hist[2] = a, b, d (each the remainder's six numbers at a stage)."""
    a00, a01, a10, a11, a20, a21 = a
    b00, b01, b10, b11, b20, b21 = b
    d00, d01, d10, d11, d20, d21 = d
    hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3], hist[0, 4], hist[0, 5] = (
        a00, a01, a10, a11, a20, a21)
    hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3], hist[1, 4], hist[1, 5] = (
        b00, b01, b10, b11, b20, b21)
    hist[2, 0], hist[2, 1], hist[2, 2], hist[2, 3], hist[2, 4], hist[2, 5] = (
        d00, d01, d10, d11, d20, d21)


@njit(cache=True, inline="always")
def _etd4m_row2h(mat, i, r, z0, z1, z2, z3, acc, base, g0, g1):
    """:func:`_etd4m_row2` without the vertical input: row r of mat[i] @ z + the (4, 2) block at
    ``base`` of acc @ g (n = 2)."""
    k = base + 2 * r
    return (((mat[i, r, 0] * z0 + mat[i, r, 1] * z1) + (mat[i, r, 2] * z2 + mat[i, r, 3] * z3))
            + (acc[k] * g0 + acc[k + 1] * g1))


@njit(cache=True, inline="always")
def _etd4m_end2h(r, acc, wq, i, e0, e1, g0, g1):
    """:func:`_etd4m_end2` without the vertical input (n = 2)."""
    k = 8 * i + 2 * r
    return (acc[k] * g0 + acc[k + 1] * g1) + (wq[i, r, 0] * e0 + wq[i, r, 1] * e1)


@njit(cache=True, inline="always")
def _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, i, z, bw0, bw1, a, b, d):
    """Stage i of :func:`etd4m_kernel2h` (n = 2): its four numbers (``z`` the state's four,
    ``a``, ``b``, ``d`` the first four of the remainder at the previous step's stages)."""
    z0, z1, z2, z3 = z
    a00, a01, a10, a11 = a
    b00, b01, b10, b11 = b
    d00, d01, d10, d11 = d
    x0 = xp[i, 0]
    x1 = xp[i, 1]
    x2 = xp[i, 2]
    g0 = bw0 + ((x0 * a10 + x1 * b10) + x2 * d10)
    g1 = bw1 + ((x0 * a11 + x1 * b11) + x2 * d11)
    du = ck[i] * (ax[i0 + lohi[i, 1]] - ax[i0 + lohi[i, 0]])
    base = (5 - i) * 8
    t0 = (_etd4m_row2h(phic, i, 0, z0, z1, z2, z3, acc, base, g0, g1)
          + _etd4m_n0_2(pn, i, 0, a00, a01, b00, b01, d00, d01))
    t1 = (_etd4m_row2h(phic, i, 1, z0, z1, z2, z3, acc, base, g0, g1)
          + _etd4m_n0_2(pn, i, 1, a00, a01, b00, b01, d00, d01))
    t2 = (_etd4m_row2h(phic, i, 2, z0, z1, z2, z3, acc, base, g0, g1)
          + _etd4m_n0_2(pn, i, 2, a00, a01, b00, b01, d00, d01))
    t3 = (_etd4m_row2h(phic, i, 3, z0, z1, z2, z3, acc, base, g0, g1)
          + _etd4m_n0_2(pn, i, 3, a00, a01, b00, b01, d00, d01))
    # (+ 0.0: etd4m_kernel2 adds du g + dv v as one rounded product, not fused with the row)
    t2 += du * g0 + 0.0
    t3 += du * g1 + 0.0
    return t0, t1, t2, t3


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd4m_kernel2h(chain, co, ax, m, n_steps, out_steps, y, y_out, hist, have, fir_chunk):
    """:func:`etd4m_kernel2` for a run without a vertical input: neither the vertical gain N2 at
    the stages nor its products with the (zero) vertical input are formed, except N2 at the
    last step's stages, which the native state carries (so a next block with a vertical input
    continues as from :func:`etd4m_kernel2`). Every other number is formed by the same
    operations in the same order, without the terms that are exactly zero there: with
    ``fir_chunk`` = 0 the result equals :func:`etd4m_kernel2`'s with ``sa`` = 0
    (tests/rig/solvers/test_etd4m_horizontal.py).

    ``fir_chunk`` > 0: the input FIR (each step's 48 sums over its samples, which no state
    enters) is formed ``fir_chunk`` steps at a time, as one matrix product of the steps' input
    windows by ``wt`` (BLAS ``dgemm`` through numba's ``np.dot``; the last chunk padded with
    zero windows, so every product has the same shape), before the serial chain reads it: BLAS
    keeps the sums in registers, where the loop (``fir_chunk`` = 0, the path before) carries 48
    of them through memory sample by sample. BLAS may order or fuse a sum's terms otherwise
    than the loop (it does in a one-row product), so the sums, and the run, equal the loop's
    within round-off (the bound and what it measured: tests/rig/solvers/
    test_etd4m_horizontal.py); for one chunk size every step's sums are formed by the same
    arithmetic wherever the step falls, so blocks continue a run bit for bit (measured in
    BENCHMARKS.md, speed round 7)."""
    hc, s, cm, g = chain
    p, q, bw, phi, phic, wt = co.p, co.q, co.bw, co.phi, co.phic, co.wt
    wq, pn, xp, ck, lohi = co.wq, co.pn, co.xp, co.ck, co.lohi
    nw = 8
    acc = np.empty(6 * nw)
    nq = wt.shape[0]
    kc = max(fir_chunk, 0)  # 0: the FIR in the loop, no chunk buffers
    accs = np.empty((kc, 6 * nw))
    win = np.empty((kc, nq))
    phi3 = phi.reshape((1, 4, 4))
    nev = 0
    z0, z1, z2, z3 = y[0], y[1], y[2], y[3]
    zero = n_steps - n_steps
    one = zero + 1
    if not have:
        s0, c0, s1, c1 = sincos_pair(z0, z1)
        a00, a01, a10, a11, _, _ = nsplit2h(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0, s1,
                                             c1)
        b00, b01, b10, b11 = a00, a01, a10, a11
        d00, d01, d10, d11 = a00, a01, a10, a11
        nev += 1
    else:
        a00, a01, a10, a11 = hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3]
        b00, b01, b10, b11 = hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3]
        d00, d01, d10, d11 = hist[2, 0], hist[2, 1], hist[2, 2], hist[2, 3]
    bw0 = bw[0]
    bw1 = bw[1]
    store(y, y_out, zero)
    row = one
    left = out_steps
    status = OK
    done = n_steps
    for k in range(n_steps):
        i0 = k * m
        if kc > 0:
            kk = k % kc
            if kk == 0:  # the next chunk's windows (rows of nq samples, m apart) times wt
                kn = min(kc, n_steps - k)
                if nq == m and kn == kc:  # zero-order hold: the windows tile the input
                    np.dot(ax[i0:i0 + kc * m].reshape((kc, m)), wt, accs)
                else:
                    for c in range(kn):
                        for qq in range(nq):
                            win[c, qq] = ax[i0 + c * m + qq]
                    for c in range(kn, kc):  # zero windows: the product's shape never changes
                        for qq in range(nq):
                            win[c, qq] = 0.0
                    np.dot(win, wt, accs)
            acc = accs[kk]
        else:
            _etd4m_fir48(ax, i0, 1, wt, acc)
        p0, p1, p2, p3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, zero,
                                        (z0, z1, z2, z3), bw0, bw1, (a00, a01, a10, a11),
                                        (b00, b01, b10, b11), (d00, d01, d10, d11))
        q0, q1, q2, q3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, one,
                                        (z0, z1, z2, z3), bw0, bw1, (a00, a01, a10, a11),
                                        (b00, b01, b10, b11), (d00, d01, d10, d11))
        r0, r1, r2, r3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, one + one,
                                        (z0, z1, z2, z3), bw0, bw1, (a00, a01, a10, a11),
                                        (b00, b01, b10, b11), (d00, d01, d10, d11))
        (sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1, sr0, cr0, sr1,
         cr1) = sincos6(p0, p1, q0, q1, r0, r1)
        a00, a01, a10, a11, _, _ = nsplit2h(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0, cp0,
                                             sp1, cp1)
        b00, b01, b10, b11, _, _ = nsplit2h(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0, cq0,
                                             sq1, cq1)
        d00, d01, d10, d11, _, _ = nsplit2h(hc, s, cm, g, p, q, bw, r0, r1, r2, r3, sr0, cr0,
                                             sr1, cr1)
        nev += 3
        n0 = ((_etd4m_row2h(phi3, 0, 0, z0, z1, z2, z3, acc, 0, bw0 + a10, bw1 + a11)
               + (wq[0, 0, 0] * a00 + wq[0, 0, 1] * a01))
              + _etd4m_end2h(0, acc, wq, 1, b00, b01, bw0 + b10, bw1 + b11)
              + _etd4m_end2h(0, acc, wq, 2, d00, d01, bw0 + d10, bw1 + d11))
        n1 = ((_etd4m_row2h(phi3, 0, 1, z0, z1, z2, z3, acc, 0, bw0 + a10, bw1 + a11)
               + (wq[0, 1, 0] * a00 + wq[0, 1, 1] * a01))
              + _etd4m_end2h(1, acc, wq, 1, b00, b01, bw0 + b10, bw1 + b11)
              + _etd4m_end2h(1, acc, wq, 2, d00, d01, bw0 + d10, bw1 + d11))
        n2 = ((_etd4m_row2h(phi3, 0, 2, z0, z1, z2, z3, acc, 0, bw0 + a10, bw1 + a11)
               + (wq[0, 2, 0] * a00 + wq[0, 2, 1] * a01))
              + _etd4m_end2h(2, acc, wq, 1, b00, b01, bw0 + b10, bw1 + b11)
              + _etd4m_end2h(2, acc, wq, 2, d00, d01, bw0 + d10, bw1 + d11))
        n3 = ((_etd4m_row2h(phi3, 0, 3, z0, z1, z2, z3, acc, 0, bw0 + a10, bw1 + a11)
               + (wq[0, 3, 0] * a00 + wq[0, 3, 1] * a01))
              + _etd4m_end2h(3, acc, wq, 1, b00, b01, bw0 + b10, bw1 + b11)
              + _etd4m_end2h(3, acc, wq, 2, d00, d01, bw0 + d10, bw1 + d11))
        z0, z1, z2, z3 = n0, n1, n2, n3
        left -= 1
        if left == 0 or k + 1 == n_steps:
            left = out_steps
            row += 1
            if not _store4(y, y_out, row - 1, z0, z1, z2, z3):
                status = NONFINITE
                done = k + 1
                break
    y[0], y[1], y[2], y[3] = z0, z1, z2, z3
    # N2 at the last step's stages for the native state (their sines and cosines as the step
    # formed them); without a step, the history's or the start state's
    if n_steps > 0:
        (sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1, sr0, cr0, sr1,
         cr1) = sincos6(p0, p1, q0, q1, r0, r1)
        a20, a21 = n2_at(hc, s, sp0, cp0, sp1, cp1)
        b20, b21 = n2_at(hc, s, sq0, cq0, sq1, cq1)
        d20, d21 = n2_at(hc, s, sr0, cr0, sr1, cr1)
    elif have:
        a20, a21, b20, b21 = hist[0, 4], hist[0, 5], hist[1, 4], hist[1, 5]
        d20, d21 = hist[2, 4], hist[2, 5]
    else:
        s0, c0, s1, c1 = sincos_pair(z0, z1)
        a20, a21 = n2_at(hc, s, s0, c0, s1, c1)
        b20, b21, d20, d21 = a20, a21, a20, a21
    _etd4m_hist2(hist, (a00, a01, a10, a11, a20, a21), (b00, b01, b10, b11, b20, b21),
                 (d00, d01, d10, d11, d20, d21))
    return status, row, done * m, nev


@njit(cache=True, inline="always")
def _store4(y, y_out, row, z0, z1, z2, z3):
    """y = z (n = 2), stored as :func:`store` does; returns whether it is finite."""
    y[0], y[1], y[2], y[3] = z0, z1, z2, z3
    return store(y, y_out, row)
