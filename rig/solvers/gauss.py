"""gauss4 and midpoint: Gauss-Legendre collocation in (theta, p = M omega), fixed step.

gauss4 is the 2-stage method (order 4), midpoint the 1-stage one (implicit midpoint, order 2).
Both are symplectic: for undamped, unforced runs the energy error is O(h^p) and bounded (no
drift). The stage equations are solved to round-off by fixed-point iteration, then simplified
Newton where that stalls (:data:`GAUSS_MAX_FIXED_POINT`); a step where
neither converges raises :class:`rig.errors.DivergenceError` naming dt_s. The native state is
(theta, p) [rad, kg m^2/s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.jit import njit
from rig.solvers.primitives import (NO_CONVERGENCE, NONFINITE, OK, all_finite, canon2, canon_n,
                                    chain_args, lu_factor, lu_solve, store)
from rig.solvers.base import SubstepSolver


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


class _Gauss(SubstepSolver):
    symplectic: ClassVar[bool] = True
    native: ClassVar[str] = "theta,p"
    kind: ClassVar[str] = "implicit"
    tableau: ClassVar[tuple[np.ndarray, np.ndarray, np.ndarray]]

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        sub = self.substeps
        status, nrow, i_done, s_fail, nfev, n_newton = gauss_kernel(
            chain_args(chain), held.kernel_args, held.h_in, sub, held.n_intervals,
            held.out_every, y, y_out, *self.tableau)
        return self.finish(chain, status, y, y_out, nrow, i_done, held, s_fail=s_fail,
                           substeps=sub, n_steps=i_done * sub, n_fev=nfev, n_newton=n_newton)


@dataclass(frozen=True)
class Gauss4(_Gauss):
    """2-stage Gauss-Legendre, ``substeps`` steps per input interval."""

    substeps: int = 1

    name: ClassVar[str] = "gauss4"
    order: ClassVar[int] = 4
    description: ClassVar[str] = ("2-stage Gauss-Legendre in (theta, p), symplectic, stages "
                                  "solved to round-off")
    tableau: ClassVar = (GAUSS4_A, GAUSS4_B, GAUSS4_C)


@dataclass(frozen=True)
class Midpoint(_Gauss):
    """Implicit midpoint (1-stage Gauss), ``substeps`` steps per input interval."""

    substeps: int = 1

    name: ClassVar[str] = "midpoint"
    order: ClassVar[int] = 2
    description: ClassVar[str] = "implicit midpoint (1-stage Gauss) in (theta, p), symplectic"
    tableau: ClassVar = (MIDPOINT_A, MIDPOINT_B, MIDPOINT_C)


# ================================================================================================
# compiled kernels
# ================================================================================================

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
def _gauss_newton(chain, y, h, s_loc, a0, da, b0, db, inv, ga, gc, scratch):
    """Solve the stage equations Z = h A F(y + Z) by simplified Newton,
    (I - h A (x) J) dZ = h A F(y + Z) - Z with J = dF/dy at y by forward differences.
    On success ff holds F(y + Z) at the solution. Returns (converged, rhs evaluations).
    (Any n; one call site per right-hand side keeps the compiled code small.)"""
    hc, s, cm, g = chain
    z, zold, ff, yt, work, jac, big, piv, rhs, fy = scratch
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
        canon_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, fy, min(col + 1, 1), work)
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
    if not lu_factor(big, piv):
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
            canon_n(hc, s, cm, g, yt, a0 + da * fri, b0 + db * fri, ff, i, work)
        nfev += ns
        if done:
            return True, nfev
        for i in range(ns):
            for c in range(n2):
                acc = 0.0
                for j in range(ns):
                    acc += ga[i, j] * ff[j, c]
                rhs[i * n2 + c] = h * acc - z[i, c]
        lu_solve(big, piv, rhs)
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
def _gauss_step(chain, y, h, s_loc, a0, da, b0, db, inv, ga, gb, gc, scratch):
    """One Gauss-Legendre step (stages ``ga``, ``gb``, ``gc``) of y = (theta, p) in place.

    Fixed-point iteration Z <- h A F(y + Z) from Z = 0 until :func:`_converged` (round-off); if
    that fails (h L too large, the iteration does not contract), simplified Newton
    (:func:`_gauss_newton`). Then y <- y + h sum_i b_i F(y + Z_i).
    Returns (status, rhs evaluations, used Newton).
    """
    hc, s, cm, g = chain
    z, zold, ff, yt, work, jac, big, piv, rhs, fy = scratch
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
                canon2(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, ff, i)
            else:
                canon_n(hc, s, cm, g, yt, a0 + da * fr, b0 + db * fr, ff, i, work)
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
        if not all_finite(y):
            return OK, nfev, False  # leave y non-finite: the next output check reports it
        used_newton = True
        ok, nf = _gauss_newton(chain, y, h, s_loc, a0, da, b0, db, inv, ga, gc, scratch)
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
def gauss_kernel(chain, inp, h_in, nsub, n_int, out_every, y, y_out, ga, gb, gc):
    """Gauss-Legendre collocation (tableau ga, gb, gc) in y = (theta, p), nsub steps per interval.

    ``chain``, ``inp``: as :func:`rig.solvers.rk4.rk4_kernel`'s. Returns (status, rows written,
    intervals done, local time reached, rhs evaluations, steps that needed Newton)."""
    hc, s, cm, g = chain
    ax, ay, sa, la = inp
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
    scratch = (z, zold, ff, yt, work, jac, big, piv, rhs, fy)
    h = h_in / nsub
    inv = 1.0 / h_in
    nfev = 0
    n_newton = 0
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
            s_loc = j * h
            status, nf, used = _gauss_step(chain, y, h, s_loc, a0, da, b0, db, inv, ga, gb, gc,
                                           scratch)
            nfev += nf
            if used:
                n_newton += 1
            if status != OK:
                return status, row, i, s_loc, nfev, n_newton
        left -= 1
        if left == 0 or i + 1 == n_int:
            left = out_every
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, i + 1, 0.0, nfev, n_newton
    return OK, row, n_int, 0.0, nfev, n_newton
