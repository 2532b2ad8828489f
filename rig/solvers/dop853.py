"""dop853: Dormand-Prince 8(5,3) with Hairer's (scipy's) step-size control (order 8).

The local error is kept near ``rtol |y| + atol`` per step (Hairer's 5th/3rd order blend); the global
error is roughly proportional to the tolerance. The method never steps across an input sample
instant: it splits what is left of an interval into equal steps no longer than its proposal (and
at least ``substeps``), and carries its proposed step over to the next interval and the next block
(:attr:`rig.solvers.base.Run.h_next_s`). ``adaptive=False`` drives the tableau with ``substeps``
fixed steps per interval (order checks). Cost: 12 right-hand sides per step (+1 per rejection).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.errors import ConfigError
from rig.jit import njit
from rig.solvers.primitives import (NONFINITE, OK, STEP_TOO_SMALL, chain_args, rhs2, rhs_alg,
                                    rhs_n, rhs_rec, store)
from rig.solvers.base import Refinement, SubstepSolver
from rig.solvers.rhs import bodies_array, rhs_algorithm


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


@dataclass(frozen=True)
class Dop853(SubstepSolver):
    """DOP853 at tolerances ``rtol`` (relative) and ``atol`` (absolute per component [rad,
    rad/s]); ``substeps`` the least number of steps per input interval (the fixed number with
    ``adaptive=False``); ``algorithm`` the right-hand side (as :class:`rig.solvers.rk4.RK4`)."""

    rtol: float = 1e-10
    atol: float = 1e-12
    substeps: int = 1
    adaptive_steps: bool = True
    algorithm: str = "auto"

    name: ClassVar[str] = "dop853"
    order: ClassVar[int] = 8
    kind: ClassVar[str] = "adaptive"
    description: ClassVar[str] = ("Dormand-Prince 8(5,3) with Hairer/scipy step-size control "
                                  "(rtol, atol)")
    adaptive: ClassVar[bool] = True
    fixed_step: ClassVar[bool] = False
    selectable_rhs: ClassVar[bool] = True

    def __post_init__(self):
        super().__post_init__()
        if not (0.0 < float(self.rtol) < 1.0) or not float(self.atol) > 0.0:
            raise ConfigError(f"rtol = {self.rtol!r}, atol = {self.atol!r} are invalid: expected "
                              "0 < rtol < 1 and atol > 0")

    def refined(self) -> Refinement:
        # 100 times tighter, and at least two steps per input interval: where the sample grid,
        # not the tolerance, sets the step (one step per sample), a tighter tolerance alone would
        # repeat the same steps and report zero
        r_ref, a_ref = max(self.rtol / 100.0, 1e-14), self.atol / 100.0
        ref = dataclasses.replace(self, rtol=r_ref, atol=a_ref, substeps=2 * self.substeps)
        return Refinement(ref, 1.0, (
            f"|y - y_ref| against the same run with rtol = {r_ref:.3g}, atol = {a_ref:.3g} "
            "(100 times tighter) and at least two steps per input interval, from the same "
            "start state"))

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        alg = rhs_algorithm(chain, self.algorithm)
        n_int, h_in = held.n_intervals, held.h_in
        min_step = 10.0 * np.spacing(max(abs(held.t0_s) + n_int * h_in, h_in))
        (status, nrow, i_done, s_fail, h_next, n_steps, n_rej,
         nfev) = dop853_kernel(chain_args(chain), bodies_array(chain), alg, held.kernel_args, h_in,
                               n_int, held.out_every, y, y_out, self.rtol, self.atol, h0_s,
                               min_step, self.adaptive_steps, self.substeps)
        if not self.adaptive_steps:
            h_next = float("nan")
        return self.finish(chain, status, y, y_out, nrow, i_done, held, s_fail=s_fail,
                           substeps=self.substeps, h_next=h_next, n_steps=n_steps,
                           n_rejected=n_rej, n_fev=nfev)


# ================================================================================================
# compiled kernels
# ================================================================================================

@njit(cache=True)
def _dop_step(chain, bod, alg, y, h, s_loc, a0, da, b0, db, inv, kk, yt, work, st0):
    """One DOP853 step of size h from local time s_loc.

    Evaluates kk[0] = f(s_loc, y) if st0 = 0 (else kk[0] must hold it), the stages kk[1..11],
    yt = y_new = y + h sum_j b_j k_j (DOP_A[12] = b) and kk[12] = f(s_loc + h, y_new)."""
    hc, s, cm, g = chain
    n2 = y.shape[0]
    for st in range(st0, 13):
        for c in range(n2):
            acc = 0.0
            for j in range(st):
                acc += DOP_A[st, j] * kk[j, c]
            yt[c] = y[c] + h * acc
        fr = (s_loc + DOP_C[st] * h) * inv
        if alg == 0:
            rhs2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st)
        elif alg == 1:
            rhs_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)
        else:
            rhs_rec(bod, g, yt, a0 + da * fr, b0 + db * fr, kk, st, work)


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
def dop853_kernel(chain, bod, alg, inp, h_in, n_int, out_every, y, y_out, rtol, atol, h_prop,
                  min_step, adaptive, nsub):
    """Dormand-Prince 8(5,3) over ``n_int`` input intervals.

    Adaptive (``adaptive=True``): steps never cross a sample instant; the rest of an interval is
    split into equal steps no longer than the proposal ``h_prop`` (computed by Hairer's initial
    step algorithm if it is not > 0) nor than ``h_in / nsub``; the proposal is carried over to the
    next interval. Fixed (``adaptive=False``): ``nsub`` equal steps per interval, no error control
    (used to measure the order of the tableau). ``chain``, ``bod``, ``alg``, ``inp``: as
    :func:`rig.solvers.rk4.rk4_kernel`'s.

    Returns (status, rows written, intervals done, local time reached in that interval,
    next proposed step, accepted steps, rejected steps, rhs evaluations).
    """
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
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
        # the input may jump at the sample instant: f at the interval start is always fresh
        fresh = True
        s_loc = 0.0
        if adaptive and not h_prop > 0.0:
            rhs_alg(hc, s, cm, g, bod, alg, y, a0, b0, kk, zero, work)
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
            rhs_alg(hc, s, cm, g, bod, alg, yt, a0 + da * fr, b0 + db * fr, kk, one, work)
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
                _dop_step(chain, bod, alg, y, h, s_loc, a0, da, b0, db, inv, kk, y_new, work,
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
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, 0.0, h_prop, n_acc, n_rej, nfev
    return OK, row, n_int, 0.0, h_prop, n_acc, n_rej, nfev
