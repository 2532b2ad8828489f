"""Every compiled kernel of the pendulum solvers, in one file (:mod:`rig.solvers` drives them).

Each method's stepping loop and the primitives they share: the right-hand side of
``M(th) th'' + N(th) th'^2 + C th' + diag(S)[(g + y0'') sin th + x0'' cos th] = 0``
(:mod:`rig.chain`) as scalar code for n = 2 (:func:`_rhs2`, :func:`_acc2`), a dense mass-matrix
Cholesky solve, O(n^3) (:func:`_rhs_n`, :func:`_cholesky_solve`), and the articulated-body
recursion, O(n) (:func:`_rhs_rec`); the canonical (theta, p) form of the Gauss methods; the
exponential methods' split of the remainder off the linearised chain (:func:`_nsplit2`,
:func:`_nsplit_n`); the sines and cosines (:func:`_sincos_poly`: inlined polynomials within 2 ulp
of libm for angles up to :data:`SINCOS_POLY_MAX`, which lets several of them overlap in the
pipeline).

The kernels are ``numba.njit(cache=True)`` (releasing the GIL in the loops); they run a whole block
(many input intervals) per call into caller-owned output arrays, the state goes in and comes out.
Non-finite values are looked for once per output sample (not per step); a kernel returns a status
(:data:`OK`, :data:`NONFINITE`, :data:`STEP_TOO_SMALL`, :data:`NO_CONVERGENCE`) that the driver
turns into :class:`rig.errors.DivergenceError`. Some are compiled with ``fastmath={"contract"}``
(fused multiply-adds only: no reassociation, the same results for any block split).

The shared primitives here are also called from :mod:`rig.chain` (the Cholesky solve) and
:mod:`rig.coupled` (the polynomial sines); numba's on-disk cache would not see a change here from
there (numba/numba#1833), so :mod:`rig._jit` keys the cache directory by a hash of every kernel
file. Tests hold the right-hand sides to :func:`rig.chain.accel_kernel`.

References
----------
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I: Nonstiff
Problems*, 2nd ed., Springer 1993, sections II.4 (step size control, initial step) and II.5 (the
Dormand-Prince 8(5,3) pair, code DOP853). E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical
Integration*, 2nd ed., Springer 2006, sections II.1.3, VI.4, VIII.6 (Gauss methods, fixed-point
iteration of the stage equations). M. Hochbruck, A. Ostermann, Exponential integrators, *Acta
Numerica* 19 (2010) 209-286. R. Featherstone, *Rigid Body Dynamics Algorithms*, Springer 2008,
ch. 7 (articulated-body algorithm).
"""

from __future__ import annotations

import math

import numpy as np

from rig._jit import njit

# Kernel status codes
OK, NONFINITE, STEP_TOO_SMALL, NO_CONVERGENCE = 0, 1, 2, 3

# _NOTE_LITERALS: numba compiles a separate copy of a jitted function for every integer *literal*
# it is called with (f(x, 0) and f(x, 1) are two compilations, each inlined where called); the
# kernels therefore pass run-time integers (e.g. ``zero = n - n``) to their helpers, which keeps the
# first (cold-cache) compilation several seconds shorter.

# -- Dormand-Prince 8(5,3) coefficients -----------------------------------------------------------
# Copied from Hairer's DOP853 (Hairer, Norsett & Wanner 1993, via scipy's
# scipy/integrate/_ivp/dop853_coefficients.py); only the 12 stages of the step and the error
# estimators (not the dense-output extension) are needed.
DOP_C = np.array([
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    0.333333333333333333333333333333,
    0.25,
    0.307692307692307692307692307692,
    0.651282051282051282051282051282,
    0.6,
    0.857142857142857142857142857142,
    1.0,
    1.0])  # the 13th entry is the end of the step, where f(t + h, y_new) is evaluated

DOP_A = np.zeros((13, 12))
DOP_A[1, 0] = 5.26001519587677318785587544488e-2
DOP_A[2, :2] = [1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2]
DOP_A[3, 0] = 2.95875854768068491816892993775e-2
DOP_A[3, 2] = 8.87627564304205475450678981324e-2
DOP_A[4, 0] = 2.41365134159266685502369798665e-1
DOP_A[4, 2] = -8.84549479328286085344864962717e-1
DOP_A[4, 3] = 9.24834003261792003115737966543e-1
DOP_A[5, 0] = 3.7037037037037037037037037037e-2
DOP_A[5, 3] = 1.70828608729473871279604482173e-1
DOP_A[5, 4] = 1.25467687566822425016691814123e-1
DOP_A[6, 0] = 3.7109375e-2
DOP_A[6, 3] = 1.70252211019544039314978060272e-1
DOP_A[6, 4] = 6.02165389804559606850219397283e-2
DOP_A[6, 5] = -1.7578125e-2
DOP_A[7, 0] = 3.70920001185047927108779319836e-2
DOP_A[7, 3] = 1.70383925712239993810214054705e-1
DOP_A[7, 4] = 1.07262030446373284651809199168e-1
DOP_A[7, 5] = -1.53194377486244017527936158236e-2
DOP_A[7, 6] = 8.27378916381402288758473766002e-3
DOP_A[8, 0] = 6.24110958716075717114429577812e-1
DOP_A[8, 3] = -3.36089262944694129406857109825
DOP_A[8, 4] = -8.68219346841726006818189891453e-1
DOP_A[8, 5] = 2.75920996994467083049415600797e1
DOP_A[8, 6] = 2.01540675504778934086186788979e1
DOP_A[8, 7] = -4.34898841810699588477366255144e1
DOP_A[9, 0] = 4.77662536438264365890433908527e-1
DOP_A[9, 3] = -2.48811461997166764192642586468
DOP_A[9, 4] = -5.90290826836842996371446475743e-1
DOP_A[9, 5] = 2.12300514481811942347288949897e1
DOP_A[9, 6] = 1.52792336328824235832596922938e1
DOP_A[9, 7] = -3.32882109689848629194453265587e1
DOP_A[9, 8] = -2.03312017085086261358222928593e-2
DOP_A[10, 0] = -9.3714243008598732571704021658e-1
DOP_A[10, 3] = 5.18637242884406370830023853209
DOP_A[10, 4] = 1.09143734899672957818500254654
DOP_A[10, 5] = -8.14978701074692612513997267357
DOP_A[10, 6] = -1.85200656599969598641566180701e1
DOP_A[10, 7] = 2.27394870993505042818970056734e1
DOP_A[10, 8] = 2.49360555267965238987089396762
DOP_A[10, 9] = -3.0467644718982195003823669022
DOP_A[11, 0] = 2.27331014751653820792359768449
DOP_A[11, 3] = -1.05344954667372501984066689879e1
DOP_A[11, 4] = -2.00087205822486249909675718444
DOP_A[11, 5] = -1.79589318631187989172765950534e1
DOP_A[11, 6] = 2.79488845294199600508499808837e1
DOP_A[11, 7] = -2.85899827713502369474065508674
DOP_A[11, 8] = -8.87285693353062954433549289258
DOP_A[11, 9] = 1.23605671757943030647266201528e1
DOP_A[11, 10] = 6.43392746015763530355970484046e-1
# Row 12 holds the 8th-order weights b (the solution is y + h sum_j b_j k_j).
DOP_A[12, 0] = 5.42937341165687622380535766363e-2
DOP_A[12, 5] = 4.45031289275240888144113950566
DOP_A[12, 6] = 1.89151789931450038304281599044
DOP_A[12, 7] = -5.8012039600105847814672114227
DOP_A[12, 8] = 3.1116436695781989440891606237e-1
DOP_A[12, 9] = -1.52160949662516078556178806805e-1
DOP_A[12, 10] = 2.01365400804030348374776537501e-1
DOP_A[12, 11] = 4.47106157277725905176885569043e-2
DOP_B = DOP_A[12].copy()

# Error estimators over the 12 stages plus f(t + h, y_new) (13 entries).
DOP_E3 = np.zeros(13)
DOP_E3[:12] = DOP_B
DOP_E3[0] -= 0.244094488188976377952755905512
DOP_E3[8] -= 0.733846688281611857341361741547
DOP_E3[11] -= 0.220588235294117647058823529412e-1
DOP_E5 = np.zeros(13)
DOP_E5[0] = 0.1312004499419488073250102996e-1
DOP_E5[5] = -0.1225156446376204440720569753e+1
DOP_E5[6] = -0.4957589496572501915214079952
DOP_E5[7] = 0.1664377182454986536961530415e+1
DOP_E5[8] = -0.3503288487499736816886487290
DOP_E5[9] = 0.3341791187130174790297318841
DOP_E5[10] = 0.8192320648511571246570742613e-1
DOP_E5[11] = -0.2235530786388629525884427845e-1

# Step-size controller (scipy.integrate's RungeKutta, after Hairer II.4): accept if err <= 1,
# h_new = h * min(MAX, max(MIN, SAFETY * err^(-1/8))); no growth right after a rejection.
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
DOP_ERROR_EXPONENT = -1.0 / 8.0

# -- Gauss-Legendre coefficients ----------------------------------------------------------------
_R3 = math.sqrt(3.0)
GAUSS4_A = np.array([[0.25, 0.25 - _R3 / 6.0], [0.25 + _R3 / 6.0, 0.25]])
GAUSS4_B = np.array([0.5, 0.5])
GAUSS4_C = np.array([0.5 - _R3 / 6.0, 0.5 + _R3 / 6.0])
MIDPOINT_A = np.array([[0.5]])
MIDPOINT_B = np.array([1.0])
MIDPOINT_C = np.array([0.5])
GAUSS_MAX_FIXED_POINT = 40   # fixed-point sweeps before switching to simplified Newton
GAUSS_MAX_NEWTON = 60
GAUSS_ROUNDOFF_FLOOR = 1e-13  # a stagnating iteration below this relative change is at round-off


# ================================================================================================
# compiled helpers
# ================================================================================================

@njit(cache=True)
def _cholesky_solve(w, f, r, off, n):
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
# here). ``_rhs2``/``_canon2`` are branch-free scalar code for n = 2 (the paper's pendulum), which
# LLVM inlines into the kernels; ``_rhs_n``/``_canon_n`` take any n with one sin/cos per body,
# cos(th_j - th_k) = c_j c_k + s_j s_k and sin(th_j - th_k) = s_j c_k - c_j s_k (O(n) transcendental
# calls instead of O(n^2)), and a Cholesky solve; ``w`` is their scratch of shape (n, n + 2).
# Kernels choose between them once per call site (``if two: ... else: ...``).

@njit(cache=True)
def _rhs2(hc, s, cm, g, y, ax, ay, f, r):
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
def _rhs_n(hc, s, cm, g, y, ax, ay, f, r, w):
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
    _cholesky_solve(w, f, r, n, n)


@njit(cache=True)
def _canon2(hc, s, cm, g, y, ax, ay, f, r):
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
def _canon_n(hc, s, cm, g, y, ax, ay, f, r, w):
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
    _cholesky_solve(w, f, r, n - n, n)  # f[r, :n] = omega (n - n: see _NOTE_LITERALS)
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
def _sincos_poly(x):
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
def _sincos(x):
    """(sin x, cos x): the polynomial for |x| <= SINCOS_POLY_MAX, libm otherwise."""
    if abs(x) <= SINCOS_POLY_MAX:
        return _sincos_poly(x)
    return math.sin(x), math.cos(x)


@njit(cache=True, fastmath={"contract"})
def _rhs_rec(bod, g, y, ax, ay, f, r, w):
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
        st, ct = _sincos(y[j])
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
def _rhs(hc, s, cm, g, bod, alg, y, ax, ay, f, r, w):
    """f[r] = (omega, th'') by the algorithm ``alg`` (ALG_TWO, ALG_DENSE or ALG_RECURSIVE); ``w``
    is scratch of shape (n, max(n + 2, 6)). (Outside the hot loops: there the kernels branch
    themselves, which measured 3 times faster for n = 2 than calling through this function.)"""
    if alg == 0:
        _rhs2(hc, s, cm, g, y, ax, ay, f, r)
    elif alg == 2:
        _rhs_rec(bod, g, y, ax, ay, f, r, w)
    else:
        _rhs_n(hc, s, cm, g, y, ax, ay, f, r, w)


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
        _cholesky_solve(m, b, zero, zero, n)
        for j in range(n):
            omega[t, j] = b[0, j]


@njit(cache=True)
def _all_finite(y):
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return True


@njit(cache=True)
def _store(y, y_out, row):
    """y_out[row] = y; returns whether y is finite (the once-per-output divergence check)."""
    ok = True
    for c in range(y.shape[0]):
        y_out[row, c] = y[c]
        if not math.isfinite(y[c]):
            ok = False
    return ok


# Output rows are kept with a countdown (``left``), not ``i % out_every``: an integer division
# per input interval costs as much as the linear method's whole step.


# ================================================================================================
# rk4
# ================================================================================================

@njit(cache=True, nogil=True)
def rk4_kernel(hc, s, cm, g, bod, alg, ax, ay, sa, la, h_in, nsub, n_int, out_every, y, y_out):
    """Classic RK4, ``nsub`` equal steps per input interval, over ``n_int`` intervals.

    Input (all kernels): interval i holds ``ax[i] + (ax[i + la] - ax[i]) s / h_in`` (la = 1 for
    linear hold, 0 for zoh) and likewise ``ay[i sa]`` (sa = 0 with ay = [0.]: no vertical input);
    written with indices rather than branches so LLVM does not unswitch (duplicate) the loops.

    ``y`` (2n,) is the state at the start and is overwritten with the state at the end. Rows of
    ``y_out`` receive the state at interval counts 0, out_every, 2 out_every, ..., n_int.
    ``bod``, ``alg``: the right-hand side's body table and algorithm (:func:`_rhs`).
    Returns (status, rows written, intervals done).
    """
    n2 = y.shape[0]
    n = n2 // 2
    kk = np.zeros((4, n2))
    yt = np.empty(n2)
    work = np.empty((n, max(n + 2, 6)))
    h = h_in / nsub
    inv = 1.0 / h_in
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
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
                    _rhs2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st)
                elif alg == 1:
                    _rhs_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
                else:
                    _rhs_rec(bod, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
            for c in range(n2):
                y[c] += h / 6.0 * (kk[0, c] + 2.0 * (kk[1, c] + kk[2, c]) + kk[3, c])
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1
    return OK, row, n_int


@njit(cache=True, inline="always")
def _sincos2(a, b):
    """sin and cos of two angles, (sa, ca, sb, cb): the polynomial when both |angles| <=
    SINCOS_POLY_MAX (one branch), libm otherwise."""
    if max(abs(a), abs(b)) <= SINCOS_POLY_MAX:
        sa, ca = _sincos_poly(a)
        sb, cb = _sincos_poly(b)
        return sa, ca, sb, cb
    return math.sin(a), math.cos(a), math.sin(b), math.cos(b)


@njit(cache=True, inline="always")
def _acc2(hc, s, cm, g, th0, th1, w0, w1, ax, ay):
    """th'' of the n = 2 chain as two numbers (the arithmetic of :func:`_rhs2`)."""
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
def rk4_kernel2(hc, s, cm, g, ax, ay, sa, la, h_in, nsub, n_int, out_every, y, y_out):
    """:func:`rk4_kernel` for n = 2 in scalar code (the state in registers, the sines and
    cosines from the inlined polynomial, fused multiply-adds). Same arguments (without the body
    table) and returns."""
    z0 = y[0]
    z1 = y[1]
    z2 = y[2]
    z3 = y[3]
    h = h_in / nsub
    hh = 0.5 * h
    h6 = h / 6.0
    inv = 1.0 / h_in
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    return OK, row, n_int


# ================================================================================================
# dop853
# ================================================================================================

@njit(cache=True)
def _dop_step(hc, s, cm, g, bod, alg, y, h, s_loc, a0, da, b0, db, inv, kk, yt, work, st0):
    """One DOP853 step of size h from local time s_loc.

    Evaluates kk[0] = f(s_loc, y) if st0 = 0 (else kk[0] must hold it), the stages kk[1..11],
    yt = y_new = y + h sum_j b_j k_j (DOP_A[12] = b) and kk[12] = f(s_loc + h, y_new)."""
    n2 = y.shape[0]
    for st in range(st0, 13):
        for c in range(n2):
            acc = 0.0
            for j in range(st):
                acc += DOP_A[st, j] * kk[j, c]
            yt[c] = y[c] + h * acc
        fr = (s_loc + DOP_C[st] * h) * inv
        if alg == 0:
            _rhs2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st)
        elif alg == 1:
            _rhs_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
        else:
            _rhs_rec(bod, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)


@njit(cache=True)
def _dop_error_norm(kk, h, y, y_new, rtol, atol):
    """Hairer's DOP853 error norm (scipy's _estimate_error_norm): <= 1 means accept."""
    n2 = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for c in range(n2):
        sc = atol + max(abs(y[c]), abs(y_new[c])) * rtol
        a5 = 0.0
        a3 = 0.0
        for j in range(13):
            a5 += DOP_E5[j] * kk[j, c]
            a3 += DOP_E3[j] * kk[j, c]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n2)


@njit(cache=True)
def _rms_scaled(v, r, y, rtol, atol):
    """RMS of v[r] / (atol + |y| rtol)."""
    n2 = y.shape[0]
    acc = 0.0
    for c in range(n2):
        x = v[r, c] / (atol + abs(y[c]) * rtol)
        acc += x * x
    return math.sqrt(acc / n2)


@njit(cache=True, nogil=True)
def dop853_kernel(hc, s, cm, g, bod, alg, ax, ay, sa, la, h_in, n_int, out_every, y, y_out,
                  rtol, atol, h_prop, min_step, adaptive, nsub):
    """Dormand-Prince 8(5,3) over ``n_int`` input intervals.

    Adaptive (``adaptive=True``): steps never cross a sample instant; the rest of an interval is
    split into equal steps no longer than the proposal ``h_prop`` (computed by Hairer's initial
    step algorithm if it is not > 0) nor than ``h_in / nsub``; the proposal is carried over to the
    next interval. Fixed (``adaptive=False``): ``nsub`` equal steps per interval, no error control
    (used to measure the order of the tableau).

    Returns (status, rows written, intervals done, local time reached in that interval,
    next proposed step, accepted steps, rejected steps, rhs evaluations).
    """
    n2 = y.shape[0]
    n = n2 // 2
    kk = np.zeros((13, n2))
    yt = np.empty(n2)
    y_new = np.empty(n2)
    work = np.empty((n, max(n + 2, 6)))
    inv = 1.0 / h_in
    h_cap = h_in / nsub
    n_acc = 0
    n_rej = 0
    nfev = 0
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        b0 = ay[i * sa]
        db = ay[(i + la) * sa] - b0
        # the input may jump at the sample instant: f at the interval start is always fresh
        fresh = True
        s_loc = 0.0
        if adaptive and not h_prop > 0.0:
            _rhs(hc, s, cm, g, bod, alg, y, a0, b0, kk, zero, work)
            nfev += 1
            # Hairer's initial step (scipy select_initial_step, error estimator order 7)
            d0 = 0.0
            for c in range(n2):
                d0 += (y[c] / (atol + abs(y[c]) * rtol)) ** 2
            d0 = math.sqrt(d0 / n2)
            d1 = _rms_scaled(kk, zero, y, rtol, atol)
            h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
            h0 = min(h0, h_in)
            for c in range(n2):
                yt[c] = y[c] + h0 * kk[0, c]
            fr = h0 * inv
            _rhs(hc, s, cm, g, bod, alg, yt, a0 + da * fr, b0 + db * fr, kk, one, work)
            nfev += 1
            for c in range(n2):
                kk[1, c] -= kk[0, c]
            d2 = _rms_scaled(kk, one, y, rtol, atol) / h0
            if d1 <= 1e-15 and d2 <= 1e-15:
                h1 = max(1e-6, h0 * 1e-3)
            else:
                h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
            h_prop = min(100.0 * h0, h1)
        done = False
        while not done:
            rem = h_in - s_loc
            rejected = False
            while True:
                if adaptive:
                    # as scipy: a proposal below 10 ulp of t is raised to it; only a rejected
                    # step that must shrink below it is a failure
                    if h_prop < min_step:
                        if rejected:
                            return STEP_TOO_SMALL, row, i, s_loc, h_prop, n_acc, n_rej, nfev
                        h_prop = min_step
                    h_try = min(h_prop, h_cap)
                    if h_try >= rem:
                        m = 1
                    else:
                        m = int(math.ceil(rem / h_try))
                else:
                    m = nsub - int(round(s_loc * nsub * inv))
                h = rem if m == 1 else rem / m
                _dop_step(hc, s, cm, g, bod, alg, y, h, s_loc, a0, da, b0, db, inv, kk, y_new, work,
                          0 if fresh else 1)
                nfev += 13 if fresh else 12
                fresh = False
                if not adaptive:
                    break
                err = _dop_error_norm(kk, h, y, y_new, rtol, atol)
                if err < 1.0:
                    if err == 0.0:
                        factor = MAX_FACTOR
                    else:
                        factor = min(MAX_FACTOR, SAFETY * err ** DOP_ERROR_EXPONENT)
                    if rejected:
                        factor = min(1.0, factor)
                    # the error model err ~ h^8 makes h * factor independent of h, so a step
                    # shortened to land on a sample instant still gives the proposal, unless
                    # MAX_FACTOR capped it: then it says nothing against the longer one
                    if h < h_prop and factor == MAX_FACTOR:
                        h_prop = max(h * factor, h_prop)
                    else:
                        h_prop = h * factor
                    break
                n_rej += 1
                rejected = True
                if math.isfinite(err):
                    h_prop = h * max(MIN_FACTOR, SAFETY * err ** DOP_ERROR_EXPONENT)
                else:
                    h_prop = h * MIN_FACTOR
            n_acc += 1
            for c in range(n2):
                y[c] = y_new[c]
            if m == 1:
                done = True
            else:
                s_loc += h
                for c in range(n2):
                    kk[0, c] = kk[12, c]
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, 0.0, h_prop, n_acc, n_rej, nfev
    return OK, row, n_int, 0.0, h_prop, n_acc, n_rej, nfev


# ================================================================================================
# Gauss-Legendre (implicit midpoint, gauss4) in canonical coordinates
# ================================================================================================

@njit(cache=True)
def _lu_factor(a, piv):
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
def _lu_solve(a, piv, b):
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


@njit(cache=True)
def _stage_change(znew, zold, y):
    """max over stages and components of |dZ| / (|y| + |Z|); the relative change of the stages."""
    ns, n2 = znew.shape
    big = 0.0
    for c in range(n2):
        sc = abs(y[c])
        for i in range(ns):
            sc = max(sc, abs(znew[i, c]))
        if sc == 0.0:
            sc = 1e-300
        for i in range(ns):
            d = abs(znew[i, c] - zold[i, c]) / sc
            if d != d:
                return d
            if d > big:
                big = d
    return big


@njit(cache=True)
def _converged(d, old):
    """Stopping rule for the stage iterations, from the last two relative changes d, old.

    Returns 1 (solved to round-off), 0 (go on) or -1 (not converging). Solved when the change is
    zero, when the geometric tail d rho / (1 - rho), rho = d / old, is below the unit round-off
    (Hairer & Wanner IV.8), or when the change stops decreasing at round-off level
    (<= GAUSS_ROUNDOFF_FLOOR). A change that stops decreasing above that level is a failure.
    """
    if d != d:
        return -1
    if d == 0.0:
        return 1
    if old == np.inf:
        return 0
    rho = d / old
    if rho < 1.0:
        if d * rho / (1.0 - rho) <= 1.1102230246251565e-16:
            return 1
        return 0
    if old <= GAUSS_ROUNDOFF_FLOOR:
        return 1
    return -1


@njit(cache=True)
def _gauss_newton(hc, s, cm, g, y, h, s_loc, a0, da, b0, db, inv, ga, gc, z, zold, ff, yt, work,
                  jac, big, piv, rhs, fy):
    """Solve the stage equations Z = h A F(y + Z) by simplified Newton,
    (I - h A (x) J) dZ = h A F(y + Z) - Z with J = dF/dy at y by forward differences.
    On success ff holds F(y + Z) at the solution. Returns (converged, rhs evaluations).
    (Any n; one call site per right-hand side keeps the compiled code small.)"""
    ns, n2 = z.shape
    nfev = 0
    fr = (s_loc + 0.5 * h) * inv
    for col in range(-1, n2):  # col = -1: F(y); then F(y + dlt e_col)
        dlt = 0.0
        for k in range(n2):
            yt[k] = y[k]
        if col >= 0:
            dlt = 1.4901161193847656e-08 * max(abs(y[col]), 1e-6)
            yt[col] += dlt
        _canon_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, fy, min(col + 1, 1), work)
        nfev += 1
        if col >= 0:
            for k in range(n2):
                jac[k, col] = (fy[1, k] - fy[0, k]) / dlt
    m = ns * n2
    for i in range(ns):
        for j in range(ns):
            for k in range(n2):
                for c in range(n2):
                    big[i * n2 + k, j * n2 + c] = -h * ga[i, j] * jac[k, c]
    for r in range(m):
        big[r, r] += 1.0
    if not _lu_factor(big, piv):
        return False, nfev
    for i in range(ns):
        for c in range(n2):
            z[i, c] = 0.0
    old = np.inf
    done = False
    for it in range(GAUSS_MAX_NEWTON + 1):
        for i in range(ns):  # ff = F(y + Z) at the stage times
            for c in range(n2):
                yt[c] = y[c] + z[i, c]
            fri = (s_loc + gc[i] * h) * inv
            _canon_n(hc, s, cm, g, yt, a0 + da * fri, b0 + db * fri, ff, i, work)
        nfev += ns
        if done:
            return True, nfev
        for i in range(ns):
            for c in range(n2):
                acc = 0.0
                for j in range(ns):
                    acc += ga[i, j] * ff[j, c]
                rhs[i * n2 + c] = h * acc - z[i, c]
        _lu_solve(big, piv, rhs)
        for i in range(ns):
            for c in range(n2):
                zold[i, c] = z[i, c]
                z[i, c] += rhs[i * n2 + c]
        d = _stage_change(z, zold, y)
        state = _converged(d, old)
        if state == 1:
            done = True
        elif state == -1 and (it >= 3 or d != d):
            return False, nfev
        old = d
    return False, nfev


@njit(cache=True)
def _gauss_step(hc, s, cm, g, y, h, s_loc, a0, da, b0, db, inv, ga, gb, gc, z, zold, ff, yt,
                work, jac, big, piv, rhs, fy):
    """One Gauss-Legendre step (stages ``ga``, ``gb``, ``gc``) of y = (theta, p) in place.

    Fixed-point iteration Z <- h A F(y + Z) from Z = 0 until :func:`_converged` (round-off); if
    that fails (h L too large, the iteration does not contract), simplified Newton
    (:func:`_gauss_newton`). Then y <- y + h sum_i b_i F(y + Z_i).
    Returns (status, rhs evaluations, used Newton).
    """
    ns, n2 = z.shape
    two = hc.shape[0] == 2
    nfev = 0
    for i in range(ns):
        for c in range(n2):
            z[i, c] = 0.0
    converged = False
    old = np.inf
    for it in range(GAUSS_MAX_FIXED_POINT):
        for i in range(ns):
            for c in range(n2):
                yt[c] = y[c] + z[i, c]
            fr = (s_loc + gc[i] * h) * inv
            if two:
                _canon2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, ff, i)
            else:
                _canon_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, ff, i, work)
        nfev += ns
        for i in range(ns):
            for c in range(n2):
                zold[i, c] = z[i, c]
                acc = 0.0
                for j in range(ns):
                    acc += ga[i, j] * ff[j, c]
                z[i, c] = h * acc
        d = _stage_change(z, zold, y)
        state = _converged(d, old)
        if state == 1:
            converged = True
            break
        if state == -1 and (it >= 3 or d != d):
            break
        old = d
    used_newton = False
    if not converged:
        if not _all_finite(y):
            return OK, nfev, False  # leave y non-finite: the next output check reports it
        used_newton = True
        ok, nf = _gauss_newton(hc, s, cm, g, y, h, s_loc, a0, da, b0, db, inv, ga, gc, z, zold,
                               ff, yt, work, jac, big, piv, rhs, fy)
        nfev += nf
        if not ok:
            return NO_CONVERGENCE, nfev, True
    # y_new = y + h sum_i b_i F(y + Z_i), F from the last (converged) sweep
    for c in range(n2):
        acc = 0.0
        for i in range(ns):
            acc += gb[i] * ff[i, c]
        y[c] += h * acc
    return OK, nfev, used_newton


@njit(cache=True, nogil=True)
def gauss_kernel(hc, s, cm, g, ax, ay, sa, la, h_in, nsub, n_int, out_every, y, y_out,
                 ga, gb, gc):
    """Gauss-Legendre collocation (tableau ga, gb, gc) in y = (theta, p), nsub steps per interval.

    Returns (status, rows written, intervals done, local time reached, rhs evaluations,
    steps that needed Newton)."""
    n2 = y.shape[0]
    n = n2 // 2
    ns = gb.shape[0]
    z = np.empty((ns, n2))
    zold = np.empty((ns, n2))
    ff = np.empty((ns, n2))
    yt = np.empty(n2)
    fy = np.empty((2, n2))
    work = np.empty((n, n + 2))
    jac = np.empty((n2, n2))
    big = np.empty((ns * n2, ns * n2))
    piv = np.empty(ns * n2, dtype=np.int64)
    rhs = np.empty(ns * n2)
    h = h_in / nsub
    inv = 1.0 / h_in
    nfev = 0
    n_newton = 0
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        b0 = ay[i * sa]
        db = ay[(i + la) * sa] - b0
        for j in range(nsub):
            s_loc = j * h
            status, nf, used = _gauss_step(hc, s, cm, g, y, h, s_loc, a0, da, b0, db, inv, ga, gb,
                                           gc, z, zold, ff, yt, work, jac, big, piv, rhs, fy)
            nfev += nf
            if used:
                n_newton += 1
            if status != OK:
                return status, row, i, s_loc, nfev, n_newton
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, 0.0, nfev, n_newton
    return OK, row, n_int, 0.0, nfev, n_newton


@njit(cache=True, nogil=True)
def linear_kernel(phi, g0, g1, ax, la, nsub, n_int, out_every, y, y_out):
    """z <- Phi z + Gamma0 u_a + Gamma1 (u_b - u_a) per substep (single input x0'').

    ``phi``, ``g0``, ``g1`` are for the substep h_in / nsub; inside interval i the substep j sees
    the held input at its ends, u_a = u(j/nsub), u_b = u((j+1)/nsub). Returns (status, rows,
    intervals done)."""
    n2 = y.shape[0]
    yt = np.empty(n2)
    frac = 1.0 / nsub
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
    row = one
    left = out_every
    for i in range(n_int):
        a0 = ax[i]
        da = ax[i + la] - a0
        for j in range(nsub):
            ua = a0 + da * (j * frac)
            du = a0 + da * ((j + 1) * frac) - ua
            for r in range(n2):
                acc = g0[r, 0] * ua + g1[r, 0] * du
                for c in range(n2):
                    acc += phi[r, c] * y[c]
                yt[r] = acc
            for r in range(n2):
                y[r] = yt[r]
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1
    return OK, row, n_int


@njit(cache=True, nogil=True)
def _lift_taps(phi, p_i, g0, g1, la, nsub, m, taps):
    """taps[q] += P_I^(m-1-q) a_I (and taps[q+1] += P_I^(m-1-q) b_I with la = 1) for
    :func:`lift_linear`.

    Inside one interval substep j sees u_a = u_q (1 - j f) + u_{q+1} j f and u_b - u_a =
    (u_{q+1} - u_q) f (f = 1/nsub; linear hold), u_a = u_q (zoh), so by Horner
    a_I = sum_j Phi^(nsub-1-j) (Gamma0 (1 - j f) - Gamma1 f) and
    b_I = sum_j Phi^(nsub-1-j) (Gamma0 j f + Gamma1 f) (zoh: Gamma0 alone, b_I = 0)."""
    n2 = phi.shape[0]
    a = np.zeros(n2)
    b = np.zeros(n2)
    t = np.empty(n2)
    f = 1.0 / nsub
    for j in range(nsub):
        _matvec(phi, a, t)
        for r in range(n2):
            a[r] = t[r] + (g0[r] * (1.0 - j * f) - g1[r] * f if la else g0[r])
        if la:
            _matvec(phi, b, t)
            for r in range(n2):
                b[r] = t[r] + (g0[r] * (j * f) + g1[r] * f)
    for q in range(m - 1, -1, -1):
        for r in range(n2):
            taps[q, r] += a[r]
        _matvec(p_i, a, t)
        a[:] = t
        if la:
            for r in range(n2):
                taps[q + 1, r] += b[r]
            _matvec(p_i, b, t)
            b[:] = t


@njit(cache=True)
def _matvec(a, x, out):
    """out = a @ x, each row summed in column order."""
    for r in range(a.shape[0]):
        acc = 0.0
        for c in range(a.shape[1]):
            acc += a[r, c] * x[c]
        out[r] = acc


@njit(cache=True, nogil=True)
def lifted_kernel(p, taps, ax, m, n_rows, y, y_out):
    """z <- P z + sum_q taps[q] ax[k m + q] once per output row k (see :func:`lift_linear`).

    Stores the start and each of the ``n_rows`` rows into ``y_out[0 .. n_rows]``. Returns
    (status, rows, intervals done) like :func:`linear_kernel`. A row's input sum and matrix
    product are taken in a fixed order, so a row's result does not depend on where it sits in the
    run (blocks that end on output rows reproduce a one-shot run bit for bit)."""
    n2 = y.shape[0]
    nt = taps.shape[0]
    yt = np.empty(n2)
    w = np.empty(n2)
    zero = n_rows - n_rows  # see _NOTE_LITERALS
    _store(y, y_out, zero)
    for k in range(n_rows):
        i0 = k * m
        for r in range(n2):
            w[r] = 0.0
        for q in range(nt):
            u = ax[i0 + q]
            for r in range(n2):
                w[r] += taps[q, r] * u
        for r in range(n2):
            acc = w[r]
            for c in range(n2):
                acc += p[r, c] * y[c]
            yt[r] = acc
        for r in range(n2):
            y[r] = yt[r]
        if not _store(y, y_out, k + 1):
            return NONFINITE, k + 2, (k + 1) * m
    return OK, n_rows + 1, n_rows * m


@njit(cache=True, nogil=True, fastmath={"contract"})
def lifted_kernel2(p, taps, ax, m, n_rows, y, y_out):
    """:func:`lifted_kernel` for the 4-state (n = 2) chain, the state in scalars (the generic
    loops keep it in memory, ~3 times slower); fused multiply-adds, no reassociation."""
    nt = taps.shape[0]
    p00, p01, p02, p03 = p[0, 0], p[0, 1], p[0, 2], p[0, 3]
    p10, p11, p12, p13 = p[1, 0], p[1, 1], p[1, 2], p[1, 3]
    p20, p21, p22, p23 = p[2, 0], p[2, 1], p[2, 2], p[2, 3]
    p30, p31, p32, p33 = p[3, 0], p[3, 1], p[3, 2], p[3, 3]
    y0, y1, y2, y3 = y[0], y[1], y[2], y[3]
    y_out[0, 0], y_out[0, 1], y_out[0, 2], y_out[0, 3] = y0, y1, y2, y3
    for k in range(n_rows):
        i0 = k * m
        w0 = w1 = w2 = w3 = 0.0
        for q in range(nt):
            u = ax[i0 + q]
            w0 += taps[q, 0] * u
            w1 += taps[q, 1] * u
            w2 += taps[q, 2] * u
            w3 += taps[q, 3] * u
        z0 = w0 + p00 * y0 + p01 * y1 + p02 * y2 + p03 * y3
        z1 = w1 + p10 * y0 + p11 * y1 + p12 * y2 + p13 * y3
        z2 = w2 + p20 * y0 + p21 * y1 + p22 * y2 + p23 * y3
        z3 = w3 + p30 * y0 + p31 * y1 + p32 * y2 + p33 * y3
        y0, y1, y2, y3 = z0, z1, z2, z3
        y_out[k + 1, 0], y_out[k + 1, 1], y_out[k + 1, 2], y_out[k + 1, 3] = y0, y1, y2, y3
        if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2)
                and math.isfinite(y3)):
            y[0], y[1], y[2], y[3] = y0, y1, y2, y3
            return NONFINITE, k + 2, (k + 1) * m
    y[0], y[1], y[2], y[3] = y0, y1, y2, y3
    return OK, n_rows + 1, n_rows * m


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

ETD3_NODES = (0.5 - _R3 / 6.0, 0.5 + _R3 / 6.0)


@njit(cache=True, inline="always")
def _sincos4(a, b, c, d):
    """sin and cos of four angles: (sa, ca, sb, cb, sc, cc, sd, cd). One branch for all four: the
    polynomial when every |angle| <= SINCOS_POLY_MAX (straight-line code whose four evaluations
    overlap in the pipeline), libm otherwise (a branch per angle, or libm calls queued one
    after the other, measured 1.3 to 2.6 times slower per etd3 step)."""
    if max(max(abs(a), abs(b)), max(abs(c), abs(d))) <= SINCOS_POLY_MAX:
        sa, ca = _sincos_poly(a)
        sb, cb = _sincos_poly(b)
        sc, cc = _sincos_poly(c)
        sd, cd = _sincos_poly(d)
        return sa, ca, sb, cb, sc, cc, sd, cd
    return (math.sin(a), math.cos(a), math.sin(b), math.cos(b), math.sin(c), math.cos(c),
            math.sin(d), math.cos(d))


@njit(cache=True, inline="always")
def _nsplit2(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0, s1, c1):
    """(N0, N1, N2) of the n = 2 chain at (theta, omega), as six numbers (N0_0, N0_1, N1_0, ...);
    s0, c0, s1, c1 are sin and cos of th0 and th1."""
    n00, n01, n10, n11, m01, idet = _nsplit2h(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0,
                                              s1, c1)
    n20, n21 = _n2_two(hc, s, s0, s1, m01, idet)
    return n00, n01, n10, n11, n20, n21


@njit(cache=True, inline="always")
def _mass2(hc, s0, c0, s1, c1):
    """The n = 2 mass matrix's coupling m01 = H01 cos(th0 - th1), H01 sin(th0 - th1) and
    1 / det M."""
    h01 = hc[0, 1]
    m01 = h01 * (c0 * c1 + s0 * s1)
    hs = h01 * (s0 * c1 - c0 * s1)
    idet = 1.0 / (hc[0, 0] * hc[1, 1] - m01 * m01)
    return m01, hs, idet


@njit(cache=True, inline="always")
def _nsplit2h(hc, s, cm, g, p, q, bw, th0, th1, w0, w1, s0, c0, s1, c1):
    """(N0, N1) of the n = 2 chain at (theta, omega), and m01, 1 / det M for the vertical gain
    (:func:`_n2_two`); :func:`_nsplit2` without N2."""
    m01, hs, idet = _mass2(hc, s0, c0, s1, c1)
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
def _n2_two(hc, s, s0, s1, m01, idet):
    """The vertical gain N2 of the n = 2 chain from sin th0, sin th1, m01 and 1 / det M."""
    e0 = -s[0] * s0
    e1 = -s[1] * s1
    return (hc[1, 1] * e0 - m01 * e1) * idet, (hc[0, 0] * e1 - m01 * e0) * idet


@njit(cache=True)
def _nsplit_n(hc, s, cm, g, p, q, bw, z, rz, out, ro, w):
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


@njit(cache=True)
def _sincos_pair(a, b):
    sa, ca, sb, cb, _, _, _, _ = _sincos4(a, b, 0.0, 0.0)
    return sa, ca, sb, cb


@njit(cache=True, inline="always")
def _sincos6(a, b, c, d, e, f):
    """``_sincos4(a, b, c, d)`` and ``_sincos_pair(e, f)``, the same twelve numbers: the six
    polynomials as one straight line where every |angle| <= SINCOS_POLY_MAX (no call, no
    polynomials of the pair's padding zeros), else those two calls."""
    if max(max(max(abs(a), abs(b)), max(abs(c), abs(d))), max(abs(e), abs(f))) <= SINCOS_POLY_MAX:
        sa, ca = _sincos_poly(a)
        sb, cb = _sincos_poly(b)
        sc, cc = _sincos_poly(c)
        sd, cd = _sincos_poly(d)
        se, ce = _sincos_poly(e)
        sf, cf = _sincos_poly(f)
        return sa, ca, sb, cb, sc, cc, sd, cd, se, ce, sf, cf
    sa, ca, sb, cb, sc, cc, sd, cd = _sincos4(a, b, c, d)
    se, ce, sf, cf = _sincos_pair(e, f)
    return sa, ca, sb, cb, sc, cc, sd, cd, se, ce, sf, cf


@njit(cache=True, nogil=True)
def etd3_kernel(hc, s, cm, g, p, q, bw, phi, g0, g1, phic, g0c, g1c, pc, wq, xp, ax, ay, sa, la,
                h_in, nsub, n_int, out_every, y, y_out, hist, have):
    """etd3 (see the section comment above), ``nsub`` steps per input interval, any n.

    ``hist`` (2, 3n) holds (N0, N1, N2) at the previous step's two stages and is updated in place;
    ``have`` says whether it is valid (else the first step predicts with N(y), which costs one
    more evaluation). ``y`` (2n,) is overwritten with the end state. Returns (status, rows
    written, intervals done, remainder evaluations).
    """
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
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    two = one + 1
    if not have:
        for c in range(n2):
            zs[two, c] = y[c]
        _nsplit_n(hc, s, cm, g, p, q, bw, zs, two, hist, zero, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
        nev += 1
    _store(y, y_out, zero)
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
                _nsplit_n(hc, s, cm, g, p, q, bw, zs, st, hist, st, w)
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, nev
    return OK, row, n_int, nev


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3_kernel2(hc, s, cm, g, p, q, bw, phi, g0, g1, phic, g0c, g1c, pc, wq, xp, ax, ay, sa, la,
                 h_in, nsub, n_int, out_every, y, y_out, hist, have):
    """:func:`etd3_kernel` for n = 2 in scalar code (the same arithmetic up to the order of the
    sums; the state and history stay in registers). Same arguments and returns."""
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
        sa0, ca0, sa1, ca1, _, _, _, _ = _sincos4(z0, z1, 0.0, 0.0)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, sa0, ca0,
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
    zero = n_int - n_int  # a run-time 0 and 1: see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
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
            sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1 = _sincos4(p0, p1, q0, q1)
            a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                    cp0, sp1, cp1)
            b00, b01, b10, b11, b20, b21 = _nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                _etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
                return NONFINITE, row, i + 1, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    _etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
    return OK, row, n_int, nev


@njit(cache=True)
def _etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21):
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


@njit(cache=True, inline="always")
def _etd3m_fir(u, i0, stride, wt, widths, acc):
    """acc = sum_q u[(i0 + q) stride] wt[q], skipping the rows' zero suffixes (``widths``)."""
    for r in range(widths[2]):
        acc[r] = 0.0
    lo = 0
    for seg in range(3):
        hi = widths[seg] if seg < 2 else wt.shape[0]
        width = widths[2 + seg]
        for qq in range(lo, hi):
            x = u[(i0 + qq) * stride]
            for r in range(width):
                acc[r] += x * wt[qq, r]
        lo = hi


@njit(cache=True)
def _etd3m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w):
    """hn[i] = (N0, N1, N2) at the state zs[i] (the n = 2 scalar code where n = 2)."""
    if zs.shape[1] == 4:
        s0, c0, s1, c1 = _sincos_pair(zs[i, 0], zs[i, 1])
        (hn[i, 0], hn[i, 1], hn[i, 2], hn[i, 3], hn[i, 4],
         hn[i, 5]) = _nsplit2(hc, s, cm, g, p, q, bw, zs[i, 0], zs[i, 1], zs[i, 2], zs[i, 3], s0,
                              c0, s1, c1)
    else:
        _nsplit_n(hc, s, cm, g, p, q, bw, zs, i, hn, i, w)


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3m_kernel(hc, s, cm, g, p, q, bw, phi, phic, wt, wq, pc, xp, ck, lohi, widths, ax, ay,
                 sa, m, n_steps, out_steps, y, y_out, hist, have):
    """etd3m (see the section comment above): ``n_steps`` steps of ``m`` input samples, any n.

    ``ax``, ``ay`` hold the samples (``ay`` read with stride ``sa``: 0 for none), ``wt`` the
    per-sample weights (:class:`Etd3mCoefficients`); a row is stored every ``out_steps`` steps
    and at the end. ``hist`` (2, 3n) and ``have`` as :func:`etd3_kernel`. ``y`` (2n,) is
    overwritten with the end state. Returns (status, rows written, input intervals done,
    remainder evaluations)."""
    n2 = y.shape[0]
    n = n2 // 2
    nw = n2 * n
    kw = wt.shape[1]
    acc = np.empty(kw)
    accv = np.zeros(kw)
    zs = np.empty((2, n2))
    hn = np.empty((2, 3 * n))
    gg = np.empty((2, n))
    nh = np.empty((2, 3 * n))
    zt = np.empty(n2)
    w = np.empty((n, n + 5))
    nev = 0
    zero = n_steps - n_steps  # see _NOTE_LITERALS
    one = zero + 1
    if not have:
        for c in range(n2):
            zs[zero, c] = y[c]
        _etd3m_eval(hc, s, cm, g, p, q, bw, zs, zero, hist, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
        nev += 1
    _store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        # the FIR: acc = sum_q u_q wt[q] (all four weight sets), accv the same for ay
        _etd3m_fir(ax, i0, 1, wt, widths, acc)
        if sa:
            _etd3m_fir(ay, i0, sa, wt, widths, accv)
        # predicted stages
        for i in range(2):
            x0 = xp[i, 0]
            x1 = xp[i, 1]
            for c in range(3 * n):
                nh[i, c] = x0 * hist[0, c] + x1 * hist[1, c]
            for j in range(n):
                gg[i, j] = bw[j] + nh[i, n + j]
            du = ck[i] * (ax[i0 + lohi[i, 1]] - ax[i0 + lohi[i, 0]])
            dv = ck[i] * (ay[(i0 + lohi[i, 1]) * sa] - ay[(i0 + lohi[i, 0]) * sa])
            base = (3 - i) * nw
            for r in range(n2):
                t = 0.0
                for c in range(n2):
                    t += phic[i, r, c] * y[c]
                for j in range(n):
                    t += (acc[base + r * n + j] * gg[i, j]
                          + accv[base + r * n + j] * nh[i, 2 * n + j]
                          + pc[i, r, j] * nh[i, j])
                zs[i, r] = t
            for j in range(n):
                zs[i, n + j] += du * gg[i, j] + dv * nh[i, 2 * n + j]
        for i in range(2):
            _etd3m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w)
        nev += 2
        # the step
        for r in range(n2):
            t = 0.0
            for c in range(n2):
                t += phi[r, c] * y[c]
            for i in range(2):
                base = i * nw
                for j in range(n):
                    t += (acc[base + r * n + j] * (bw[j] + hn[i, n + j])
                          + accv[base + r * n + j] * hn[i, 2 * n + j] + wq[i, r, j] * hn[i, j])
            zt[r] = t
        for r in range(n2):
            y[r] = zt[r]
        for i in range(2):
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
def _etd3m_w2(r, acc, accv, base, pc, ip, e0, e1, g0, g1, v0, v1):
    """Row r of pc[ip] @ e + the (4, 2) blocks at ``base`` of acc @ g and accv @ v (n = 2)."""
    k = base + 2 * r
    return (((acc[k] * g0 + acc[k + 1] * g1) + (pc[ip, r, 0] * e0 + pc[ip, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, inline="always")
def _etd3m_row2(mat, i, r, z0, z1, z2, z3, acc, accv, base, pc, ip, e0, e1, g0, g1, v0, v1):
    """Row r of mat[i] @ z + pc[ip] @ e + the (4, 2) blocks at ``base`` of acc @ g and accv @ v
    (n = 2)."""
    k = base + 2 * r
    return (((mat[i, r, 0] * z0 + mat[i, r, 1] * z1) + (mat[i, r, 2] * z2 + mat[i, r, 3] * z3))
            + ((acc[k] * g0 + acc[k + 1] * g1) + (pc[ip, r, 0] * e0 + pc[ip, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3m_kernel2(hc, s, cm, g, p, q, bw, phi, phic, wt, wq, pc, xp, ck, lohi, widths, ax, ay,
                  sa, m, n_steps, out_steps, y, y_out, hist, have):
    """:func:`etd3m_kernel` for the n = 2 chain: the state, the stages and the remainder parts in
    scalars, the four stage angles' sin and cos in one branch (:func:`_sincos4`)."""
    kw = wt.shape[1]
    acc = np.empty(kw)
    accv = np.zeros(kw)
    phi3 = phi.reshape((1, 4, 4))
    nev = 0
    z0, z1, z2, z3 = y[0], y[1], y[2], y[3]
    if not have:
        s0, c0, s1, c1 = _sincos_pair(z0, z1)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0,
                                                s1, c1)
        b00, b01, b10, b11, b20, b21 = a00, a01, a10, a11, a20, a21
        nev += 1
    else:
        a00, a01, a10, a11, a20, a21 = (hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3],
                                        hist[0, 4], hist[0, 5])
        b00, b01, b10, b11, b20, b21 = (hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3],
                                        hist[1, 4], hist[1, 5])
    bw0 = bw[0]
    bw1 = bw[1]
    zero = n_steps - n_steps  # see _NOTE_LITERALS
    one = zero + 1
    _store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        _etd3m_fir(ax, i0, 1, wt, widths, acc)
        if sa:
            _etd3m_fir(ay, i0, sa, wt, widths, accv)
        # stage 0: predicted parts, then the exact step to c0 H with the staircase against b + N1^
        x0 = xp[0, 0]
        x1 = xp[0, 1]
        e0 = x0 * a00 + x1 * b00
        e1 = x0 * a01 + x1 * b01
        g0 = bw0 + (x0 * a10 + x1 * b10)
        g1 = bw1 + (x0 * a11 + x1 * b11)
        v0 = x0 * a20 + x1 * b20
        v1 = x0 * a21 + x1 * b21
        du = ck[0] * (ax[i0 + lohi[0, 1]] - ax[i0 + lohi[0, 0]])
        dv = ck[0] * (ay[(i0 + lohi[0, 1]) * sa] - ay[(i0 + lohi[0, 0]) * sa])
        p0 = _etd3m_row2(phic, 0, 0, z0, z1, z2, z3, acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p1 = _etd3m_row2(phic, 0, 1, z0, z1, z2, z3, acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p2 = _etd3m_row2(phic, 0, 2, z0, z1, z2, z3, acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p3 = _etd3m_row2(phic, 0, 3, z0, z1, z2, z3, acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p2 += du * g0 + dv * v0
        p3 += du * g1 + dv * v1
        # stage 1
        x0 = xp[1, 0]
        x1 = xp[1, 1]
        e0 = x0 * a00 + x1 * b00
        e1 = x0 * a01 + x1 * b01
        g0 = bw0 + (x0 * a10 + x1 * b10)
        g1 = bw1 + (x0 * a11 + x1 * b11)
        v0 = x0 * a20 + x1 * b20
        v1 = x0 * a21 + x1 * b21
        du = ck[1] * (ax[i0 + lohi[1, 1]] - ax[i0 + lohi[1, 0]])
        dv = ck[1] * (ay[(i0 + lohi[1, 1]) * sa] - ay[(i0 + lohi[1, 0]) * sa])
        q0 = _etd3m_row2(phic, 1, 0, z0, z1, z2, z3, acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q1 = _etd3m_row2(phic, 1, 1, z0, z1, z2, z3, acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q2 = _etd3m_row2(phic, 1, 2, z0, z1, z2, z3, acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q3 = _etd3m_row2(phic, 1, 3, z0, z1, z2, z3, acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q2 += du * g0 + dv * v0
        q3 += du * g1 + dv * v1
        sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1 = _sincos4(p0, p1, q0, q1)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                cp0, sp1, cp1)
        b00, b01, b10, b11, b20, b21 = _nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                cq0, sq1, cq1)
        nev += 2
        # the step: e^{AH} z + node 0's and node 1's weights
        n0 = (_etd3m_row2(phi3, 0, 0, z0, z1, z2, z3, acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(0, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n1 = (_etd3m_row2(phi3, 0, 1, z0, z1, z2, z3, acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(1, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n2 = (_etd3m_row2(phi3, 0, 2, z0, z1, z2, z3, acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(2, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n3 = (_etd3m_row2(phi3, 0, 3, z0, z1, z2, z3, acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(3, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
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
                _etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
                return NONFINITE, row, (k + 1) * m, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    _etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
    return OK, row, n_steps * m, nev


# ================================================================================================
# etd4m (rig.solvers.etd4m)
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
        _etd4m_eval(hc, s, cm, g, p, q, bw, zs, zero, hist, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
            hist[one + one, c] = hist[zero, c]
        nev += 1
    _store(y, y_out, zero)
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
            ok = _store(y, y_out, row)
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
         cr1) = _sincos6(p0, p1, q0, q1, r0, r1)
        a00, a01, a10, a11, a20, a21 = _nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                cp0, sp1, cp1)
        b00, b01, b10, b11, b20, b21 = _nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                cq0, sq1, cq1)
        d00, d01, d10, d11, d20, d21 = _nsplit2(hc, s, cm, g, p, q, bw, r0, r1, r2, r3, sr0,
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
            ok = _store(y, y_out, row)
            row += 1
            if not ok:
                _etd4m_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21,
                             d00, d01, d10, d11, d20, d21)
                return NONFINITE, row, (k + 1) * m, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    _etd4m_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00, d01, d10,
                 d11, d20, d21)
    return OK, row, n_steps * m, nev


@njit(cache=True)
def _etd4m_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00, d01, d10,
                 d11, d20, d21):
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
def _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, i, z0, z1, z2, z3, bw0, bw1, a00, a01,
                   a10, a11, b00, b01, b10, b11, d00, d01, d10, d11):
    """Stage i of :func:`etd4m_kernel2h` (n = 2): its four numbers."""
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
def etd4m_kernel2h(hc, s, cm, g, p, q, bw, phi, phic, wt, wq, pn, xp, ck, lohi, ax, m, n_steps,
                   out_steps, y, y_out, hist, have, fir_chunk):
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
        s0, c0, s1, c1 = _sincos_pair(z0, z1)
        a00, a01, a10, a11, _, _ = _nsplit2h(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0, s1,
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
    _store(y, y_out, zero)
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
        p0, p1, p2, p3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, zero, z0, z1, z2,
                                        z3, bw0, bw1, a00, a01, a10, a11, b00, b01, b10, b11,
                                        d00, d01, d10, d11)
        q0, q1, q2, q3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, one, z0, z1, z2,
                                        z3, bw0, bw1, a00, a01, a10, a11, b00, b01, b10, b11,
                                        d00, d01, d10, d11)
        r0, r1, r2, r3 = _etd4m_stage2h(phic, pn, xp, ck, lohi, ax, i0, acc, one + one, z0, z1,
                                        z2, z3, bw0, bw1, a00, a01, a10, a11, b00, b01, b10, b11,
                                        d00, d01, d10, d11)
        (sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1, sr0, cr0, sr1,
         cr1) = _sincos6(p0, p1, q0, q1, r0, r1)
        a00, a01, a10, a11, _, _ = _nsplit2h(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0, cp0,
                                             sp1, cp1)
        b00, b01, b10, b11, _, _ = _nsplit2h(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0, cq0,
                                             sq1, cq1)
        d00, d01, d10, d11, _, _ = _nsplit2h(hc, s, cm, g, p, q, bw, r0, r1, r2, r3, sr0, cr0,
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
         cr1) = _sincos6(p0, p1, q0, q1, r0, r1)
        a20, a21 = _n2_at(hc, s, sp0, cp0, sp1, cp1)
        b20, b21 = _n2_at(hc, s, sq0, cq0, sq1, cq1)
        d20, d21 = _n2_at(hc, s, sr0, cr0, sr1, cr1)
    elif have:
        a20, a21, b20, b21 = hist[0, 4], hist[0, 5], hist[1, 4], hist[1, 5]
        d20, d21 = hist[2, 4], hist[2, 5]
    else:
        s0, c0, s1, c1 = _sincos_pair(z0, z1)
        a20, a21 = _n2_at(hc, s, s0, c0, s1, c1)
        b20, b21, d20, d21 = a20, a21, a20, a21
    _etd4m_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21, d00, d01, d10,
                 d11, d20, d21)
    return status, row, done * m, nev


@njit(cache=True, inline="always")
def _n2_at(hc, s, s0, c0, s1, c1):
    """The vertical gain N2 of the n = 2 chain at the angles with these sines and cosines."""
    m01, _, idet = _mass2(hc, s0, c0, s1, c1)
    return _n2_two(hc, s, s0, s1, m01, idet)


@njit(cache=True, inline="always")
def _store4(y, y_out, row, z0, z1, z2, z3):
    """y = z (n = 2), stored as :func:`_store` does; returns whether it is finite."""
    y[0], y[1], y[2], y[3] = z0, z1, z2, z3
    return _store(y, y_out, row)
