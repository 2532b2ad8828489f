"""etd4m: the multi-sample exponential integrator with three Gauss nodes and a quadratic
remainder over the stages.

Like etd3m (:mod:`rig.integrators`), one step spans ``H = m h_in``, m whole held input samples:
the linearised chain and the held input are propagated exactly, and only the nonlinear remainder
(N0, the input gain's nonlinear part N1 and the vertical gain N2, :func:`rig.integrators.
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
sample a FIR of 6 weight sets (2n x n each), the stage sets skipped past their nodes. The first
step after a (re)start predicts with N(z0) at one more evaluation; the three stages are part of
the native state (theta, omega, valid flag, step H, then 9n numbers), so blocks that end on output
rows continue bit for bit.

Error: order 4 in H (the stages' error O(H^4) through the quadratic prediction; the quadrature
through three nodes is of order 6 for a smooth remainder); measured on the paper's run in
``tests/test_etd4m.py`` and BENCHMARKS.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rig.chain import Chain
from rig.errors import ConfigError
from rig.integrators import (HOLDS, NONFINITE, OK, _nsplit2, _nsplit_n, _piece_integral,
                             _sincos4, _sincos_pair, _store)
from rig.jit import njit

_R15 = math.sqrt(15.0)
ETD4M_NODES = (0.5 - _R15 / 10.0, 0.5, 0.5 + _R15 / 10.0)
ETD4M_SETS = 6  # weight sets per sample: end nodes 0, 1, 2, then stages 2, 1, 0


@dataclass(frozen=True, eq=False)
class Etd4mCoefficients:
    """Everything :func:`etd4m_kernel` needs for one chain, input interval, m and hold.

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
    p, q, bw : as :class:`rig.integrators.Etd3Coefficients`.
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
    if hold not in HOLDS:
        raise ConfigError(f"hold = {hold!r} is invalid: expected one of {', '.join(HOLDS)}")
    if m < 1:
        raise ConfigError(f"m = {m!r} is invalid: expected a whole number of samples >= 1")
    a, b = chain.state_space()
    n = chain.n
    n2 = 2 * n
    c = ETD4M_NODES
    big_h = m * h_in
    la = int(hold == "linear")
    poly = np.polynomial.Polynomial
    lag = [_lagrange(c, i, big_h) for i in range(3)]
    wt = np.zeros((m + la, ETD4M_SETS, n2, n))
    for qq in range(m):
        s_a, s_b = qq * h_in, (qq + 1) * h_in
        if la:
            pieces = [(qq, poly([1.0 + qq, -1.0 / h_in])), (qq + 1, poly([-qq, 1.0 / h_in]))]
        else:
            pieces = [(qq, poly([1.0]))]
        for tap, bas in pieces:
            for i in range(3):
                wt[tap, i] += _piece_integral(a, n, big_h, s_a, s_b, lag[i] * bas)
                ci = c[i] * big_h
                if s_a < ci:
                    wt[tap, 5 - i] += _piece_integral(a, n, ci, s_a, min(s_b, ci), bas)
    prev = tuple(ci - 1.0 for ci in c)
    lprev = [_lagrange(prev, j, big_h) for j in range(3)]
    pn = np.array([[_piece_integral(a, n, ci * big_h, 0.0, ci * big_h, lprev[j])
                    for j in range(3)] for ci in c])
    xp = np.array([[lprev[j](0.5 * ci * big_h) for j in range(3)] for ci in c])
    phic = np.array([scipy.linalg.expm(a * (ci * big_h)) for ci in c])
    ck = np.zeros(3)
    lohi = np.zeros((3, 2), dtype=np.int64)
    if m > 1 and not la:
        for i, ci in enumerate(c):
            x = ci * m
            qq = min(int(math.floor(x)), m - 1)
            f = x - qq
            lo, hi = max(qq - 1, 0), min(qq + 1, m - 1)
            ck[i] = h_in * (1.0 / 12.0 - 0.5 * f * (1.0 - f)) / (hi - lo)
            lohi[i] = lo, hi
    widths = np.array([min(int(math.ceil(ci * m * (1.0 + 1e-12) - 1e-12)) + la, m + la)
                       for ci in c], dtype=np.int64)
    hinv = np.linalg.inv(chain.H)
    arr = np.ascontiguousarray
    return Etd4mCoefficients(
        m=m, phi=arr(scipy.linalg.expm(a * big_h)), phic=arr(phic),
        wt=arr(wt.reshape(m + la, ETD4M_SETS * n2 * n)), wq=arr(wt[:, :3].sum(axis=0)),
        pn=arr(pn), xp=arr(xp), ck=ck, lohi=lohi, widths=widths, p=arr(hinv @ chain.K),
        q=arr(hinv @ chain.C), bw=arr(b[n:, 0]))


@njit(cache=True, inline="always")
def _fir6(u, i0, stride, wt, widths, nw, acc):
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
def _eval(hc, s, cm, g, p, q, bw, zs, i, hn, w):
    """hn[i] = (N0, N1, N2) at the state zs[i] (the n = 2 scalar code where n = 2)."""
    if zs.shape[1] == 4:
        s0, c0, s1, c1 = _sincos_pair(zs[i, 0], zs[i, 1])
        (hn[i, 0], hn[i, 1], hn[i, 2], hn[i, 3], hn[i, 4],
         hn[i, 5]) = _nsplit2(hc, s, cm, g, p, q, bw, zs[i, 0], zs[i, 1], zs[i, 2], zs[i, 3], s0,
                              c0, s1, c1)
    else:
        _nsplit_n(hc, s, cm, g, p, q, bw, zs, i, hn, i, w)


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd4m_kernel(hc, s, cm, g, p, q, bw, phi, phic, wt, wq, pn, xp, ck, lohi, widths, ax, ay,
                 sa, m, n_steps, out_steps, y, y_out, hist, have):
    """etd4m (module docstring): ``n_steps`` steps of ``m`` input samples, any n.

    ``ax``, ``ay`` hold the samples (``ay`` read with stride ``sa``: 0 for none); a row is stored
    every ``out_steps`` steps and at the end. ``hist`` (3, 3n) holds (N0, N1, N2) at the previous
    step's three stages and is updated in place; ``have`` says whether it is valid. ``y`` (2n,)
    is overwritten with the end state. Returns (status, rows written, input intervals done,
    remainder evaluations)."""
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
        _eval(hc, s, cm, g, p, q, bw, zs, zero, hist, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
            hist[one + one, c] = hist[zero, c]
        nev += 1
    _store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        _fir6(ax, i0, 1, wt, widths, nw, acc)
        if sa:
            _fir6(ay, i0, sa, wt, widths, nw, accv)
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
            _eval(hc, s, cm, g, p, q, bw, zs, i, hn, w)
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, (k + 1) * m, nev
    return OK, row, n_steps * m, nev


@njit(cache=True, inline="always")
def _fir48(u, i0, stride, wt, acc):
    """acc = sum_q u[(i0 + q) stride] wt[q] for n = 2: every row in full (48 numbers, a constant
    trip count the compiler vectorises: faster than skipping the stage sets' zero suffixes)."""
    for r in range(48):
        acc[r] = 0.0
    for qq in range(wt.shape[0]):
        x = u[(i0 + qq) * stride]
        for r in range(48):
            acc[r] += x * wt[qq, r]


@njit(cache=True, inline="always")
def _row2(mat, i, r, z0, z1, z2, z3, acc, accv, base, g0, g1, v0, v1):
    """Row r of mat[i] @ z + the (4, 2) blocks at ``base`` of acc @ g and accv @ v (n = 2)."""
    k = base + 2 * r
    return (((mat[i, r, 0] * z0 + mat[i, r, 1] * z1) + (mat[i, r, 2] * z2 + mat[i, r, 3] * z3))
            + ((acc[k] * g0 + acc[k + 1] * g1) + (accv[k] * v0 + accv[k + 1] * v1)))


@njit(cache=True, inline="always")
def _n0_2(pn, i, r, a0, a1, b0, b1, c0, c1):
    """Row r of sum_j pn[i, j] @ N0_j for the three stages' N0 (a, b, c) (n = 2)."""
    return ((pn[i, 0, r, 0] * a0 + pn[i, 0, r, 1] * a1)
            + (pn[i, 1, r, 0] * b0 + pn[i, 1, r, 1] * b1)
            + (pn[i, 2, r, 0] * c0 + pn[i, 2, r, 1] * c1))


@njit(cache=True, inline="always")
def _end2(r, acc, accv, wq, i, e0, e1, g0, g1, v0, v1):
    """Row r of node i's end weights: acc_i @ g + accv_i @ v + wq[i] @ e (n = 2)."""
    k = 8 * i + 2 * r
    return (((acc[k] * g0 + acc[k + 1] * g1) + (wq[i, r, 0] * e0 + wq[i, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd4m_kernel2(hc, s, cm, g, p, q, bw, phi, phic, wt, wq, pn, xp, ck, lohi, widths, ax, ay,
                  sa, m, n_steps, out_steps, y, y_out, hist, have):
    """:func:`etd4m_kernel` for the n = 2 chain: the state, the stages and the remainder parts in
    scalars (the same arithmetic to round-off)."""
    nw = 8
    acc = np.empty(6 * nw)
    accv = np.zeros(6 * nw)
    phi3 = phi.reshape((1, 4, 4))
    nev = 0
    z0, z1, z2, z3 = y[0], y[1], y[2], y[3]
    zero = n_steps - n_steps
    one = zero + 1
    if not have:
        s0, c0, s1, c1 = _sincos_pair(z0, z1)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0,
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
    _store(y, y_out, zero)
    row = one
    left = out_steps
    st = np.empty((3, 4))
    for k in range(n_steps):
        i0 = k * m
        _fir48(ax, i0, 1, wt, acc)
        if sa:
            _fir48(ay, i0, sa, wt, accv)
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
                st[i, r] = (_row2(phic, i, r, z0, z1, z2, z3, acc, accv, base, g0, g1, v0, v1)
                            + _n0_2(pn, i, r, a00, a01, b00, b01, d00, d01))
            st[i, 2] += du * g0 + dv * v0
            st[i, 3] += du * g1 + dv * v1
        p0, p1, p2, p3 = st[0, 0], st[0, 1], st[0, 2], st[0, 3]
        q0, q1, q2, q3 = st[1, 0], st[1, 1], st[1, 2], st[1, 3]
        r0, r1, r2, r3 = st[2, 0], st[2, 1], st[2, 2], st[2, 3]
        sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1 = _sincos4(p0, p1, q0, q1)
        sr0, cr0, sr1, cr1 = _sincos_pair(r0, r1)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                cp0, sp1, cp1)
        b00, b01, b10, b11, b20, b21 = _nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                cq0, sq1, cq1)
        d00, d01, d10, d11, d20, d21 = _nsplit2(hc, s, cm, g, p, q, bw, r0, r1, r2, r3, sr0,
                                                cr0, sr1, cr1)
        nev += 3
        n0 = (_row2(phi3, 0, 0, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 0, 0] * a00 + wq[0, 0, 1] * a01)
              + _end2(0, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _end2(0, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n1 = (_row2(phi3, 0, 1, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 1, 0] * a00 + wq[0, 1, 1] * a01)
              + _end2(1, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _end2(1, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n2 = (_row2(phi3, 0, 2, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 2, 0] * a00 + wq[0, 2, 1] * a01)
              + _end2(2, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _end2(2, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
        n3 = (_row2(phi3, 0, 3, z0, z1, z2, z3, acc, accv, 0, bw0 + a10, bw1 + a11, a20, a21)
              + (wq[0, 3, 0] * a00 + wq[0, 3, 1] * a01)
              + _end2(3, acc, accv, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20, b21)
              + _end2(3, acc, accv, wq, 2, d00, d01, bw0 + d10, bw1 + d11, d20, d21))
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                _hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00,
                       d01, d10, d11, d20, d21)
                return NONFINITE, row, (k + 1) * m, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    _hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00, d01, d10, d11,
           d20, d21)
    return OK, row, n_steps * m, nev


@njit(cache=True)
def _hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00, d01, d10, d11,
           d20, d21):
    hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3], hist[0, 4], hist[0, 5] = (
        a00, a01, a10, a11, a20, a21)
    hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3], hist[1, 4], hist[1, 5] = (
        b00, b01, b10, b11, b20, b21)
    hist[2, 0], hist[2, 1], hist[2, 2], hist[2, 3], hist[2, 4], hist[2, 5] = (
        d00, d01, d10, d11, d20, d21)
