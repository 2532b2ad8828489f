"""The compiled primitives the pendulum solvers' kernels share (each method's own loop is in its
module, :mod:`rig.solvers.rk4` ... :mod:`rig.solvers.etd4m`).

The right-hand side of ``M(th) th'' + N(th) th'^2 + C th' + diag(S)[(g + y0'') sin th + x0'' cos
th] = 0`` (:mod:`rig.chain`) as scalar code for n = 2 (:func:`rhs2`), a dense mass-matrix Cholesky
solve, O(n^3) (:func:`rhs_n`, :func:`cholesky_solve`), and the articulated-body recursion, O(n)
(:func:`rhs_rec`); the canonical (theta, p) form of the Gauss methods (:func:`canon2`,
:func:`canon_n`); an LU solve; the sines and cosines (:func:`sincos_poly`: inlined polynomials
within 2 ulp of libm for angles up to :data:`SINCOS_POLY_MAX`, which lets several of them overlap
in the pipeline); the output rows' store with its divergence check.

The kernels are ``numba.njit(cache=True)`` (releasing the GIL in the loops); they run a whole block
(many input intervals) per call into caller-owned output arrays, the state goes in and comes out.
Non-finite values are looked for once per output sample (not per step); a kernel returns a status
(:data:`OK`, :data:`NONFINITE`, :data:`STEP_TOO_SMALL`, :data:`NO_CONVERGENCE`) that the driver
turns into :class:`rig.errors.DivergenceError`. Some are compiled with ``fastmath={"contract"}``
(fused multiply-adds only: no reassociation, the same results for any block split).

These primitives are called from the methods' modules, :mod:`rig.chain` (the Cholesky solve) and
:mod:`rig.solvers.coupled` (the polynomial sines); numba's on-disk cache would not see a change
here from there (numba/numba#1833), so :mod:`rig.jit` keys the cache directory by a hash of every
kernel file. Tests hold the right-hand sides to :func:`rig.chain.accel_kernel`.

References
----------
R. Featherstone, *Rigid Body Dynamics Algorithms*, Springer 2008, ch. 7 (articulated-body
algorithm).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rig.jit import njit

# Kernel status codes
OK, NONFINITE, STEP_TOO_SMALL, NO_CONVERGENCE = 0, 1, 2, 3


class ChainArgs(NamedTuple):
    """The chain as the pendulum kernels take it, one argument (:func:`chain_args`): ``hc`` the
    mass matrix's constant H (n, n) [kg m^2], ``s`` the static moments S (n,) [kg m], ``cm`` the
    damping C (n, n) [N m s], ``g`` [m/s^2]."""

    hc: np.ndarray
    s: np.ndarray
    cm: np.ndarray
    g: float


def chain_args(chain) -> ChainArgs:
    """:class:`ChainArgs` of a :class:`rig.chain.Chain`."""
    return ChainArgs(chain.H, chain.S, chain.C, chain.g_mps2)


class HeldArgs(NamedTuple):
    """The held base input as the kernels take it, one argument (:attr:`rig.solvers.base.
    HeldInput.kernel_args`): ``ax`` the horizontal samples [m/s^2], ``ay`` the vertical ones (a
    1-sample dummy with ``sa`` = 0 where there are none), ``la`` 1 for the linear hold, 0 for
    zoh."""

    ax: np.ndarray
    ay: np.ndarray
    sa: int
    la: int


# _NOTE_LITERALS (the methods' kernels refer to this note): numba compiles a separate copy of a
# jitted function for every integer *literal* it is called with (f(x, 0) and f(x, 1) are two
# compilations, each inlined where called); the kernels therefore pass run-time integers (e.g.
# ``zero = n - n``) to their helpers, which keeps the first (cold-cache) compilation several
# seconds shorter.


# ================================================================================================
# compiled helpers
# ================================================================================================

@njit(cache=True)
def cholesky_solve(w, f, r, off, n):
    """Solve M x = f[r, off:off+n] in place for M (SPD) in the lower triangle of w[:, :n]
    (overwritten by its Cholesky factor)."""
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
    for i in range(n):
        acc = f[r, off + i]
        for k in range(i):
            acc -= w[i, k] * f[r, off + k]
        f[r, off + i] = acc / w[i, i]
    for i in range(n - 1, -1, -1):
        acc = f[r, off + i]
        for k in range(i + 1, n):
            acc -= w[k, i] * f[r, off + k]
        f[r, off + i] = acc / w[i, i]


# Right-hand sides. Each writes row r of a 2-D output f (no array views are made in the hot loops:
# numba's reference counting of views and of calls that may take them costs more than the physics
# here). ``rhs2``/``canon2`` are branch-free scalar code for n = 2 (the paper's pendulum), which
# LLVM inlines into the kernels; ``rhs_n``/``canon_n`` take any n with one sin/cos per body,
# cos(th_j - th_k) = c_j c_k + s_j s_k and sin(th_j - th_k) = s_j c_k - c_j s_k (O(n) transcendental
# calls instead of O(n^2)), and a Cholesky solve; ``w`` is their scratch of shape (n, n + 2).
# Kernels choose between them once per call site (``if two: ... else: ...``).

@njit(cache=True)
def rhs2(hc, s, cm, g, y, ax, ay, f, r):
    """f[r] = (omega, th'') for y = (theta, omega), n = 2."""
    ga = g + ay
    w0 = y[2]
    w1 = y[3]
    s0 = math.sin(y[0])
    c0 = math.cos(y[0])
    s1 = math.sin(y[1])
    c1 = math.cos(y[1])
    h01 = hc[0, 1]
    m01 = h01 * (c0 * c1 + s0 * s1)
    hs = h01 * (s0 * c1 - c0 * s1)
    f0 = -s[0] * (ga * s0 + ax * c0) - cm[0, 0] * w0 - cm[0, 1] * w1 - hs * w1 * w1
    f1 = -s[1] * (ga * s1 + ax * c1) - cm[1, 0] * w0 - cm[1, 1] * w1 + hs * w0 * w0
    h00 = hc[0, 0]
    h11 = hc[1, 1]
    det = h00 * h11 - m01 * m01
    f[r, 0] = w0
    f[r, 1] = w1
    f[r, 2] = (h11 * f0 - m01 * f1) / det
    f[r, 3] = (h00 * f1 - m01 * f0) / det


@njit(cache=True)
def rhs_n(hc, s, cm, g, y, ax, ay, f, r, w):
    """f[r] = (omega, th'') for y = (theta, omega), any n."""
    n = hc.shape[0]
    ga = g + ay
    for j in range(n):
        sj = math.sin(y[j])
        cj = math.cos(y[j])
        w[j, n] = sj
        w[j, n + 1] = cj
        w[j, j] = hc[j, j]
        f[r, j] = y[n + j]
        fj = -s[j] * (ga * sj + ax * cj)
        for k in range(n):
            fj -= cm[j, k] * y[n + k]
        f[r, n + j] = fj
    for j in range(n):
        sj = w[j, n]
        cj = w[j, n + 1]
        wj2 = y[n + j] * y[n + j]
        for k in range(j + 1, n):
            sk = w[k, n]
            ck = w[k, n + 1]
            w[k, j] = hc[j, k] * (cj * ck + sj * sk)
            hsd = hc[j, k] * (sj * ck - cj * sk)
            f[r, n + j] -= hsd * y[n + k] * y[n + k]
            f[r, n + k] += hsd * wj2
    cholesky_solve(w, f, r, n, n)


@njit(cache=True)
def canon2(hc, s, cm, g, y, ax, ay, f, r):
    """f[r] = (theta', p') for y = (theta, p), n = 2."""
    ga = g + ay
    s0 = math.sin(y[0])
    c0 = math.cos(y[0])
    s1 = math.sin(y[1])
    c1 = math.cos(y[1])
    h01 = hc[0, 1]
    m01 = h01 * (c0 * c1 + s0 * s1)
    hs = h01 * (s0 * c1 - c0 * s1)
    h00 = hc[0, 0]
    h11 = hc[1, 1]
    det = h00 * h11 - m01 * m01
    w0 = (h11 * y[2] - m01 * y[3]) / det
    w1 = (h00 * y[3] - m01 * y[2]) / det
    t = hs * w0 * w1
    f[r, 0] = w0
    f[r, 1] = w1
    f[r, 2] = -t - cm[0, 0] * w0 - cm[0, 1] * w1 - s[0] * (ga * s0 + ax * c0)
    f[r, 3] = t - cm[1, 0] * w0 - cm[1, 1] * w1 - s[1] * (ga * s1 + ax * c1)


@njit(cache=True)
def canon_n(hc, s, cm, g, y, ax, ay, f, r, w):
    """f[r] = (theta', p') for y = (theta, p), any n:
    theta' = omega = M^{-1} p;  p'_j = -sum_k H_jk sin(th_j - th_k) w_j w_k - (C w)_j
    - S_j ((g + ay) sin th_j + ax cos th_j)."""
    n = hc.shape[0]
    ga = g + ay
    for j in range(n):
        w[j, n] = math.sin(y[j])
        w[j, n + 1] = math.cos(y[j])
        w[j, j] = hc[j, j]
        f[r, j] = y[n + j]
    for j in range(n):
        for k in range(j + 1, n):
            w[k, j] = hc[j, k] * (w[j, n + 1] * w[k, n + 1] + w[j, n] * w[k, n])
    cholesky_solve(w, f, r, n - n, n)  # f[r, :n] = omega (n - n: see _NOTE_LITERALS)
    for j in range(n):
        fp = -s[j] * (ga * w[j, n] + ax * w[j, n + 1])
        for k in range(n):
            fp -= cm[j, k] * f[r, k]
        f[r, n + j] = fp
    for j in range(n):
        for k in range(j + 1, n):
            t = hc[j, k] * (w[j, n] * w[k, n + 1] - w[j, n + 1] * w[k, n]) * f[r, j] * f[r, k]
            f[r, n + j] -= t
            f[r, n + k] += t


# Taylor polynomials of sin and cos: on |x| <= SINCOS_POLY_MAX the truncated series (through x^15
# and x^16) are within 2 ulp of math.sin/math.cos (the next terms are below 6e-18);
# tests/rig/solvers/test_exponential.py checks this on a dense grid.
SINCOS_POLY_MAX = 0.8


@njit(cache=True, inline="always")
def sincos_poly(x):
    """(sin x, cos x) by their Taylor polynomials, for |x| <= SINCOS_POLY_MAX only (Estrin's
    scheme: the dependency chain is 5 multiplications deep instead of Horner's 9)."""
    x2 = x * x
    x4 = x2 * x2
    x8 = x4 * x4
    # sin x / x = sum_k a_k x2^k, k = 0..7
    s01 = 1.0 + x2 * (-1.0 / 6.0)
    s23 = 1.0 / 120.0 + x2 * (-1.0 / 5040.0)
    s45 = 1.0 / 362880.0 + x2 * (-1.0 / 39916800.0)
    s67 = 1.0 / 6227020800.0 + x2 * (-1.0 / 1307674368000.0)
    sn = x * ((s01 + x4 * s23) + x8 * (s45 + x4 * s67))
    # cos x = sum_k b_k x2^k, k = 0..8
    c01 = 1.0 + x2 * (-0.5)
    c23 = 1.0 / 24.0 + x2 * (-1.0 / 720.0)
    c45 = 1.0 / 40320.0 + x2 * (-1.0 / 3628800.0)
    c67 = 1.0 / 479001600.0 + x2 * (-1.0 / 87178291200.0)
    c8 = 1.0 / 20922789888000.0
    cs = (c01 + x4 * c23) + x8 * ((c45 + x4 * c67) + x8 * c8)
    return sn, cs


@njit(cache=True, inline="always")
def sincos(x):
    """(sin x, cos x): the polynomial for |x| <= SINCOS_POLY_MAX, libm otherwise."""
    if abs(x) <= SINCOS_POLY_MAX:
        return sincos_poly(x)
    return math.sin(x), math.cos(x)


@njit(cache=True, fastmath={"contract"})
def rhs_rec(bod, g, y, ax, ay, f, r, w):
    """f[r] = (omega, th'') for y = (theta, omega), any n, in O(n) operations; returns the
    horizontal force the chain exerts on the base [N] (= -F_x at the top joint, the reaction a
    stage feels).

    The articulated-body recursion: the same equations as the dense mass-matrix solve
    (:func:`rig.chain.accel_kernel`), solved by eliminating the joint forces from the tip up. For
    body j with upper joint P, unit vectors e = (sin th, -cos th) along and n = (cos th, sin th)
    across it, the force the parent exerts on it at P is ``F = A_j a_P + b_j`` (2x2 articulated
    inertia A_j, bias b_j), and ``alpha_j = -(w_j . a_P + beta_j) / d_j``; a forward pass from
    the base (a_P0 = 0 in the base frame, where the base acceleration ``(ax, ay)`` is a uniform
    inertial force) gives every alpha_j. Each body's sin and cos are computed once (kept in
    w[j, 4:6]). ``bod`` (6, n) holds the rows mass, length, com, inertia, damping and (row 5,
    any column) 1.0 for relative damping (:meth:`rig.chain.Chain.body_table`); ``w`` is scratch
    of shape (n, >= 6). The one pendulum-on-a-given-base recursion: the solvers' kernels and
    :meth:`rig.chain.Chain.accelerations` (``algorithm="recursive"``) call it.
    """
    n = bod.shape[1]
    relative = bod[5, 0] != 0.0
    gx = -ax
    gy = -(g + ay)
    c11 = 0.0
    c12 = 0.0
    c22 = 0.0
    cb1 = 0.0
    cb2 = 0.0
    for j in range(n - 1, -1, -1):
        om = y[n + j]
        st, ct = sincos(y[j])
        w[j, 4] = st
        w[j, 5] = ct
        m = bod[0, j]
        l = bod[1, j]
        c = bod[2, j]
        w2 = om * om
        if relative:
            tau = -bod[4, j] * (om - (y[n + j - 1] if j > 0 else 0.0))
            if j + 1 < n:
                tau += bod[4, j + 1] * (y[n + j + 1] - om)
        else:
            tau = -bod[4, j] * om
        # A' n and A' e of the child's articulated inertia A' (symmetric); e = (st, -ct),
        # n = (ct, st)
        an_x = c11 * ct + c12 * st
        an_y = c12 * ct + c22 * st
        ae_x = c11 * st - c12 * ct
        ae_y = c12 * st - c22 * ct
        bo_x = -l * w2 * ae_x + cb1
        bo_y = -l * w2 * ae_y + cb2
        bi_x = -m * c * w2 * st + bo_x - m * gx
        bi_y = m * c * w2 * ct + bo_y - m * gy
        ux = m * c * ct + l * an_x
        uy = m * c * st + l * an_y
        d = bod[3, j] + m * c * c + l * l * (ct * an_x + st * an_y)
        beta = c * (ct * bi_x + st * bi_y) + (l - c) * (ct * bo_x + st * bo_y) - tau
        w[j, 0] = ux
        w[j, 1] = uy
        w[j, 3] = beta
        dinv = 1.0 / d
        w[j, 2] = dinv
        c11 = m + c11 - ux * ux * dinv
        c12 = c12 - ux * uy * dinv
        c22 = m + c22 - uy * uy * dinv
        cb1 = bi_x - ux * beta * dinv
        cb2 = bi_y - uy * beta * dinv
    apx = 0.0
    apy = 0.0
    for j in range(n):
        alpha = -(w[j, 0] * apx + w[j, 1] * apy + w[j, 3]) * w[j, 2]
        om = y[n + j]
        f[r, j] = om
        f[r, n + j] = alpha
        l = bod[1, j]
        w2 = om * om
        st = w[j, 4]
        ct = w[j, 5]
        apx += l * (ct * alpha - st * w2)
        apy += l * (st * alpha + ct * w2)
    return -cb1  # a_P0 = 0: F_top = b_1


# Right-hand-side algorithms (``alg`` argument of the kernels): the scalar n = 2 code, the dense
# mass-matrix solve (O(n^3), Cholesky) and the articulated-body recursion (O(n)).
ALG_TWO, ALG_DENSE, ALG_RECURSIVE = 0, 1, 2
#: Bodies from which rk4 and dop853 use the O(n) recursion instead of the dense solve. Measured
#: (``python benchmarks/run.py --only rhs``, BENCHMARKS.md): the recursion is faster for every
#: n >= 2 (1.5x at n = 2, 3x at n = 10, 60x at n = 100), but the n = 2 scalar code beats both.
RECURSIVE_FROM_N = 3


@njit(cache=True)
def rhs_alg(hc, s, cm, g, bod, alg, y, ax, ay, f, r, w):
    """f[r] = (omega, th'') by the algorithm ``alg`` (ALG_TWO, ALG_DENSE or ALG_RECURSIVE); ``w``
    is scratch of shape (n, max(n + 2, 6)). (Outside the hot loops: there the kernels branch
    themselves, which measured 3 times faster for n = 2 than calling through this function.)"""
    if alg == 0:
        rhs2(hc, s, cm, g, y, ax, ay, f, r)
    elif alg == 2:
        rhs_rec(bod, g, y, ax, ay, f, r, w)
    else:
        rhs_n(hc, s, cm, g, y, ax, ay, f, r, w)


@njit(cache=True)
def omega_to_momentum(hc, theta, omega, p):
    """p = M(theta) omega for rows of theta, omega (T, n) into p (T, n)."""
    t_len, n = theta.shape
    for t in range(t_len):
        for j in range(n):
            acc = hc[j, j] * omega[t, j]
            for k in range(n):
                if k != j:
                    acc += hc[j, k] * math.cos(theta[t, j] - theta[t, k]) * omega[t, k]
            p[t, j] = acc


@njit(cache=True)
def momentum_to_omega(hc, theta, p, omega):
    """omega = M(theta)^{-1} p for rows of theta, p (T, n) into omega (T, n)."""
    t_len, n = theta.shape
    m = np.empty((n, n + 2))
    b = np.empty((1, n))
    zero = n - n
    for t in range(t_len):
        for j in range(n):
            m[j, j] = hc[j, j]
            b[0, j] = p[t, j]
            for k in range(j + 1, n):
                m[k, j] = hc[j, k] * math.cos(theta[t, j] - theta[t, k])
        cholesky_solve(m, b, zero, zero, n)
        for j in range(n):
            omega[t, j] = b[0, j]


@njit(cache=True)
def all_finite(y):
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return True


@njit(cache=True)
def store(y, y_out, row):
    """y_out[row] = y; returns whether y is finite (the once-per-output divergence check)."""
    ok = True
    for c in range(y.shape[0]):
        y_out[row, c] = y[c]
        if not math.isfinite(y[c]):
            ok = False
    return ok


# Output rows are kept with a countdown (``left``), not ``i % out_every``: an integer division
# per input interval costs as much as the linear method's whole step.


# -- LU with partial pivoting (the Gauss methods' Newton systems) --------------------------------

@njit(cache=True)
def lu_factor(a, piv):
    """In-place LU with partial pivoting of a (m, m); returns False if singular."""
    m = a.shape[0]
    for k in range(m):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, m):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                p = i
        piv[k] = p
        if big == 0.0 or not math.isfinite(big):
            return False
        if p != k:
            for j in range(m):
                t = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = t
        for i in range(k + 1, m):
            a[i, k] /= a[k, k]
            lik = a[i, k]
            for j in range(k + 1, m):
                a[i, j] -= lik * a[k, j]
    return True


@njit(cache=True)
def lu_solve(a, piv, b):
    m = a.shape[0]
    for k in range(m):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t
    for i in range(m):
        acc = b[i]
        for j in range(i):
            acc -= a[i, j] * b[j]
        b[i] = acc
    for i in range(m - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, m):
            acc -= a[i, j] * b[j]
        b[i] = acc / a[i, i]


# -- several sines and cosines at once (the exponential methods) ---------------------------------

@njit(cache=True, inline="always")
def sincos4(a, b, c, d):
    """sin and cos of four angles: (sa, ca, sb, cb, sc, cc, sd, cd). One branch for all four: the
    polynomial when every |angle| <= SINCOS_POLY_MAX (straight-line code whose four evaluations
    overlap in the pipeline), libm otherwise (a branch per angle, or libm calls queued one
    after the other, measured 1.3 to 2.6 times slower per etd3 step)."""
    if max(max(abs(a), abs(b)), max(abs(c), abs(d))) <= SINCOS_POLY_MAX:
        sa, ca = sincos_poly(a)
        sb, cb = sincos_poly(b)
        sc, cc = sincos_poly(c)
        sd, cd = sincos_poly(d)
        return sa, ca, sb, cb, sc, cc, sd, cd
    return (math.sin(a), math.cos(a), math.sin(b), math.cos(b), math.sin(c), math.cos(c),
            math.sin(d), math.cos(d))


@njit(cache=True)
def sincos_pair(a, b):
    sa, ca, sb, cb, _, _, _, _ = sincos4(a, b, 0.0, 0.0)
    return sa, ca, sb, cb


@njit(cache=True, inline="always")
def sincos6(a, b, c, d, e, f):
    """``sincos4(a, b, c, d)`` and ``sincos_pair(e, f)``, the same twelve numbers: the six
    polynomials as one straight line where every |angle| <= SINCOS_POLY_MAX (no call, no
    polynomials of the pair's padding zeros), else those two calls."""
    if max(max(max(abs(a), abs(b)), max(abs(c), abs(d))), max(abs(e), abs(f))) <= SINCOS_POLY_MAX:
        sa, ca = sincos_poly(a)
        sb, cb = sincos_poly(b)
        sc, cc = sincos_poly(c)
        sd, cd = sincos_poly(d)
        se, ce = sincos_poly(e)
        sf, cf = sincos_poly(f)
        return sa, ca, sb, cb, sc, cc, sd, cd, se, ce, sf, cf
    sa, ca, sb, cb, sc, cc, sd, cd = sincos4(a, b, c, d)
    se, ce, sf, cf = sincos_pair(e, f)
    return sa, ca, sb, cb, sc, cc, sd, cd, se, ce, sf, cf
