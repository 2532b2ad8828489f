"""The exponential methods' split of the chain's angular accelerations off the linearised chain
(compiled; :mod:`rig.solvers.etd3`, :mod:`rig.solvers.etd3m`, :mod:`rig.solvers.etd4m`).

``z' = A z + B u(t) + E N(z, u(t))``, z = (theta, omega), with (A, B) the linearised chain
(:meth:`rig.chain.Chain.state_space`), E = [0; I] and N the remainder, affine in the base input::

    N = N0(z) + ax N1(theta) + ay N2(theta)
    N0 = M^-1 (-N(th) w^2 - C w - g S sin th) + H^-1 (K th + C w)
    N1 = M^-1 (-S cos th) - H^-1 (-S),     N2 = M^-1 (-S sin th)

as scalar code for n = 2 (:func:`nsplit2`, :func:`nsplit2h` without N2) and for any n with a
Cholesky solve (:func:`nsplit_n`). :func:`rig.solvers.rhs.nonlinear_remainder` evaluates them at
one state.
"""

from __future__ import annotations

import math

from rig.jit import njit


@njit(cache=True, inline="always")
def nsplit2(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0, s1, c1):
    """(N0, N1, N2) of the n = 2 chain at (theta, omega), as six numbers (N0_0, N0_1, N1_0, ...);
    s0, c0, s1, c1 are sin and cos of th0 and th1."""
    n00, n01, n10, n11, m01, idet = nsplit2h(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0,
                                              s1, c1)
    n20, n21 = n2_two(hc, s, s0, s1, m01, idet)
    return n00, n01, n10, n11, n20, n21


@njit(cache=True, inline="always")
def mass2(hc, s0, c0, s1, c1):
    """The n = 2 mass matrix's coupling m01 = H01 cos(th0 - th1), H01 sin(th0 - th1) and
    1 / det M."""
    h01 = hc[0, 1]
    m01 = h01 * (c0 * c1 + s0 * s1)
    hs = h01 * (s0 * c1 - c0 * s1)
    idet = 1.0 / (hc[0, 0] * hc[1, 1] - m01 * m01)
    return m01, hs, idet


@njit(cache=True, inline="always")
def nsplit2h(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0, s1, c1):
    """(N0, N1) of the n = 2 chain at (theta, omega), and m01, 1 / det M for the vertical gain
    (:func:`n2_two`); :func:`nsplit2` without N2."""
    m01, hs, idet = mass2(hc, s0, c0, s1, c1)
    h00 = hc[0, 0]
    h11 = hc[1, 1]
    f0 = -s[0] * g * s0 - cm[0, 0] * w0 - cm[0, 1] * w1 - hs * w1 * w1
    f1 = -s[1] * g * s1 - cm[1, 0] * w0 - cm[1, 1] * w1 + hs * w0 * w0
    lin0 = p[0, 0] * th0 + p[0, 1] * th1 + q[0, 0] * w0 + q[0, 1] * w1
    lin1 = p[1, 0] * th0 + p[1, 1] * th1 + q[1, 0] * w0 + q[1, 1] * w1
    n00 = (h11 * f0 - m01 * f1) * idet + lin0
    n01 = (h00 * f1 - m01 * f0) * idet + lin1
    e0 = -s[0] * c0
    e1 = -s[1] * c1
    n10 = (h11 * e0 - m01 * e1) * idet - bw[0]
    n11 = (h00 * e1 - m01 * e0) * idet - bw[1]
    return n00, n01, n10, n11, m01, idet


@njit(cache=True, inline="always")
def n2_two(hc, s, s0, s1, m01, idet):
    """The vertical gain N2 of the n = 2 chain from sin th0, sin th1, m01 and 1 / det M."""
    e0 = -s[0] * s0
    e1 = -s[1] * s1
    return (hc[1, 1] * e0 - m01 * e1) * idet, (hc[0, 0] * e1 - m01 * e0) * idet


@njit(cache=True)
def nsplit_n(hc, s, cm, g, p, q, bw, z, rz, out, ro, w):
    """out[ro, 0:3n] = (N0, N1, N2) at the state z[rz] = (theta, omega), any n (dense Cholesky
    of M(theta), three solves); ``w`` is scratch of shape (n, n + 5)."""
    n = hc.shape[0]
    for j in range(n):
        sj = math.sin(z[rz, j])
        cj = math.cos(z[rz, j])
        w[j, n] = sj
        w[j, n + 1] = cj
        w[j, j] = hc[j, j]
        fj = -s[j] * g * sj
        for k in range(n):
            fj -= cm[j, k] * z[rz, n + k]
        w[j, n + 2] = fj
        w[j, n + 3] = -s[j] * cj
        w[j, n + 4] = -s[j] * sj
    for j in range(n):
        sj = w[j, n]
        cj = w[j, n + 1]
        wj2 = z[rz, n + j] * z[rz, n + j]
        for k in range(j + 1, n):
            sk = w[k, n]
            ck = w[k, n + 1]
            w[k, j] = hc[j, k] * (cj * ck + sj * sk)
            hsd = hc[j, k] * (sj * ck - cj * sk)
            w[j, n + 2] -= hsd * z[rz, n + k] * z[rz, n + k]
            w[k, n + 2] += hsd * wj2
    # Cholesky of M in the lower triangle of w[:, :n]
    for j in range(n):
        acc = w[j, j]
        for k in range(j):
            acc -= w[j, k] * w[j, k]
        d = math.sqrt(acc)
        w[j, j] = d
        for i in range(j + 1, n):
            acc = w[i, j]
            for k in range(j):
                acc -= w[i, k] * w[j, k]
            w[i, j] = acc / d
    for col in range(3):
        cc = n + 2 + col
        for i in range(n):
            acc = w[i, cc]
            for k in range(i):
                acc -= w[i, k] * w[k, cc]
            w[i, cc] = acc / w[i, i]
        for i in range(n - 1, -1, -1):
            acc = w[i, cc]
            for k in range(i + 1, n):
                acc -= w[k, i] * w[k, cc]
            w[i, cc] = acc / w[i, i]
    for j in range(n):
        lin = 0.0
        for k in range(n):
            lin += p[j, k] * z[rz, k] + q[j, k] * z[rz, n + k]
        out[ro, j] = w[j, n + 2] + lin
        out[ro, n + j] = w[j, n + 3] - bw[j]
        out[ro, 2 * n + j] = w[j, n + 4]


@njit(cache=True, inline="always")
def n2_at(hc, s, s0, c0, s1, c1):
    """The vertical gain N2 of the n = 2 chain at the angles with these sines and cosines."""
    m01, _, idet = mass2(hc, s0, c0, s1, c1)
    return n2_two(hc, s, s0, s1, m01, idet)
