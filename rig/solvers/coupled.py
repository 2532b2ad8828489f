"""The nonlinear pendulum on the stage it loads: the whole bench's equations, which the coupled
bench's methods share (:mod:`rig.solvers.lawson4`, :mod:`rig.solvers.etdab`, and the linearisation
error's predictor of :mod:`rig.bench.selection`).

The bench state is the one of :mod:`rig.bench` (named slices there)::

    z = (i, x0, v0, theta (n), omega (n) [, q] [, r ...])

and its exact linear model is ``z' = A z + B V`` (:meth:`rig.devices.stage.Stage.state_space`
plus the source's reconstruction filter and the accelerometer's high-pass). The nonlinear bench
differs from it only in the mechanical accelerations: with ``F_ext = Kf i - k x0 - c v0`` the stage
and the chain obey::

    M x0'' = F_ext + F_chain(theta, omega, x0'')          (reaction on; without it F_chain = 0)
    theta'' = alpha(theta, omega, x0'')                    (the chain on a moving base, SPEC 2)

``F_chain`` is the horizontal force the chain exerts on its pivot (``rig.chain.Chain.base_force``)
and both it and ``alpha`` are *affine* in the base acceleration: the articulated-body recursion
(O(n), :func:`accelerations`) carries its bias terms in two parts, the one independent of ``x0''``
and the one per unit ``x0''``, so ``F_chain = F0 + F1 x0''`` and the stage equation is solved for
``x0'' = (F_ext + F0) / (M - F1)`` (``-F1 = m - S^T M(theta)^-1 S``-like effective mass of the
swinging chain, >= 0, so the denominator is >= M > 0) before the forward pass gives ``alpha``.
Linearised, this is exactly the coupled mass matrix ``[[M + m, S^T], [S, H]]`` of
:mod:`rig.devices.stage`.

Write ``z' = A z + B V + f(z)``; the *remainder* ``f`` is the nonlinear minus the linear
acceleration, non-zero only in the rows of ``v0``, ``omega`` (and ``q``, which integrates
``x0''``), and of relative size ~ theta^2. The kernels take the bench's parameters as one tuple,
:class:`CoupledArgs` (:meth:`CoupledParams.args`), and evaluate ``f`` with :func:`remainder_at`
(:func:`remainder_fast_at`: polynomial sines and one division for n = 2).

All kernels are ``numba.njit(cache=True, error_model="numpy")`` (a blow-up gives non-finite
numbers, checked once per block by the caller, not a ZeroDivisionError inside a step). They share
the solvers' polynomial sines (:func:`rig.solvers.primitives.sincos_poly`; cross-file calls are safe
with the keyed cache of :mod:`rig.jit`); their recursion (:func:`_accel`) carries the base-force
split the pendulum-only one (:func:`rig.solvers.primitives.rhs_rec`) does not, so it is its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rig.jit import njit
from rig.solvers.primitives import SINCOS_POLY_MAX, sincos_poly

if TYPE_CHECKING:
    from rig.chain import Chain
    from rig.devices.stage import Stage


class CoupledArgs(NamedTuple):
    """The coupled bench as every kernel here takes it, one argument (:meth:`CoupledParams.args`;
    the fields as :class:`CoupledParams`'s)."""

    mass: np.ndarray
    length: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    gamma: np.ndarray
    relative: bool
    g: float
    hc: np.ndarray
    s: np.ndarray
    cm: np.ndarray
    mtot: float
    kf: float
    k: float
    c: float
    m_stage: float
    reaction: bool
    th0: int
    q_idx: int
    wc: float
    rows: np.ndarray
    a_rows: np.ndarray


@dataclass(frozen=True, eq=False)
class CoupledParams:
    """Flat arrays and numbers for the kernels (build with :func:`coupled_params`).

    Attributes
    ----------
    mass, length, com, inertia, gamma : per body (SI); relative : joint damping; g : [m/s^2].
    hc, s, cm, mtot : H, S, C of :class:`rig.chain.Chain` and the chain's mass (the dense n = 2
        path).
    kf, k, c, m_stage : coil force constant [N/A], guide stiffness [N/m], damping [N s/m], moving
        mass without the pendulum [kg]; reaction : whether the chain loads the stage.
    n : bodies; th0, om0 : first index of theta and omega in z; q_idx : index of the
        accelerometer high-pass state (-1 if none); wc : its corner [rad/s].
    rows : (nf,) the rows of z where the remainder f is non-zero (v0, omega..., [q]).
    a_rows : (nf, nz) those rows of the linear A.
    """

    mass: np.ndarray
    length: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    gamma: np.ndarray
    relative: bool
    g: float
    hc: np.ndarray
    s: np.ndarray
    cm: np.ndarray
    mtot: float
    kf: float
    k: float
    c: float
    m_stage: float
    reaction: bool
    n: int
    th0: int
    om0: int
    q_idx: int
    wc: float
    rows: np.ndarray
    a_rows: np.ndarray

    def args(self) -> CoupledArgs:
        """The kernels' first argument."""
        return CoupledArgs(
            self.mass, self.length, self.com, self.inertia, self.gamma, self.relative, self.g,
            self.hc, self.s, self.cm, self.mtot, self.kf, self.k, self.c, self.m_stage,
            self.reaction, self.th0, self.q_idx, self.wc, self.rows, self.a_rows)


def coupled_params(chain: Chain, stage: Stage, a: np.ndarray, *, q_idx: int = -1,
                   wc: float = 0.0) -> CoupledParams:
    """Kernel parameters for the bench ``z' = a z + ...`` whose first ``3 + 2n`` states are
    ``(i, x0, v0, theta, omega)``; ``q_idx`` is the accelerometer high-pass state (or -1)."""
    n = chain.n
    rows = [2] + list(range(3 + n, 3 + 2 * n)) + ([q_idx] if q_idx >= 0 else [])
    rows = np.asarray(rows, dtype=np.int64)
    return CoupledParams(
        mass=np.asarray(chain.mass_kg, float), length=np.asarray(chain.length_m, float),
        com=np.asarray(chain.com_m, float), inertia=np.asarray(chain.inertia_kgm2, float),
        gamma=np.asarray(chain.damping_nms, float), relative=chain.damping_mode == "relative",
        g=float(chain.g_mps2), hc=np.ascontiguousarray(chain.H), s=np.ascontiguousarray(chain.S),
        cm=np.ascontiguousarray(chain.C), mtot=float(sum(chain.mass_kg)),
        kf=stage.force_constant_npa, k=stage.stiffness_npm,
        c=stage.damping_nspm, m_stage=stage.moving_mass_kg, reaction=bool(stage.reaction), n=n,
        th0=3, om0=3 + n, q_idx=int(q_idx), wc=float(wc), rows=rows,
        a_rows=np.ascontiguousarray(np.asarray(a, float)[rows]))


# ================================================================================================
# the nonlinear accelerations (the articulated-body recursion with the stage's base-force split)
# ================================================================================================

@njit(cache=True, error_model="numpy", inline="always")
def _accel(bodies, g, stage, th0, z, work, alpha):
    """Stage acceleration x0'' (returned) and alpha = theta'' of the coupled nonlinear bench at
    state z. ``work`` (n, 7) scratch. Backward pass: articulated inertia (c11, c12, c22) and the
    bias forces split into the part at x0'' = 0 (cb1, cb2; beta) and the part per unit x0''
    (ca1, ca2; beta_a: the inertial force -m x0'' of every body in the base frame). ``bodies``,
    ``stage``: :func:`arg_groups`."""
    mass, length, com, inertia, gamma, relative = bodies
    kf, k, c, m_stage, reaction = stage
    n = mass.shape[0]
    om0 = th0 + n
    c11 = 0.0
    c12 = 0.0
    c22 = 0.0
    cb1 = 0.0
    cb2 = 0.0
    ca1 = 0.0
    ca2 = 0.0
    for j in range(n - 1, -1, -1):
        st = math.sin(z[th0 + j])
        ct = math.cos(z[th0 + j])
        w = z[om0 + j]
        w2 = w * w
        m = mass[j]
        l = length[j]
        cj = com[j]
        if relative:
            wp = z[om0 + j - 1] if j > 0 else 0.0
            tau = -gamma[j] * (w - wp)
            if j + 1 < n:
                tau += gamma[j + 1] * (z[om0 + j + 1] - w)
        else:
            tau = -gamma[j] * w
        # e = (st, -ct) along the body, nn = (ct, st) across it
        an_x = c11 * ct + c12 * st
        an_y = c12 * ct + c22 * st
        ae_x = c11 * st - c12 * ct
        ae_y = c12 * st - c22 * ct
        bo_x = -l * w2 * ae_x + cb1
        bo_y = -l * w2 * ae_y + cb2
        bi_x = -m * cj * w2 * st + bo_x
        bi_y = m * cj * w2 * ct + bo_y + m * g
        # per unit x0'': the child's part, plus m (the inertial force -m x0'' enters as -m gx)
        oa_x = ca1
        oa_y = ca2
        ia_x = oa_x + m
        ia_y = oa_y
        ux = m * cj * ct + l * an_x
        uy = m * cj * st + l * an_y
        d = inertia[j] + m * cj * cj + l * l * (ct * an_x + st * an_y)
        beta = cj * (ct * bi_x + st * bi_y) + (l - cj) * (ct * bo_x + st * bo_y) - tau
        beta_a = cj * (ct * ia_x + st * ia_y) + (l - cj) * (ct * oa_x + st * oa_y)
        work[j, 0] = ux
        work[j, 1] = uy
        work[j, 2] = 1.0 / d
        work[j, 3] = beta
        work[j, 4] = beta_a
        work[j, 5] = st
        work[j, 6] = ct
        ud_x = ux / d
        ud_y = uy / d
        c11 = m + c11 - ux * ud_x
        c12 = c12 - uy * ud_x
        c22 = m + c22 - uy * ud_y
        cb1 = bi_x - beta * ud_x
        cb2 = bi_y - beta * ud_y
        ca1 = ia_x - beta_a * ud_x
        ca2 = ia_y - beta_a * ud_y
    fext = kf * z[0] - k * z[1] - c * z[2]
    if reaction:  # M ax = fext + F_chain, F_chain = -(cb1 + ca1 ax)
        ax = (fext - cb1) / (m_stage + ca1)
    else:
        ax = fext / m_stage
    apx = 0.0
    apy = 0.0
    for j in range(n):
        st = work[j, 5]
        ct = work[j, 6]
        a = -(work[j, 0] * apx + work[j, 1] * apy + work[j, 3] + ax * work[j, 4]) * work[j, 2]
        alpha[j] = a
        l = length[j]
        w2 = z[om0 + j] * z[om0 + j]
        apx += l * (ct * a - st * w2)
        apy += l * (st * a + ct * w2)
    return ax


@njit(cache=True, error_model="numpy", inline="always")
def _dense2_equations(g, hc, s, cm, mtot, stage, th0, z, s1, c1, s2, c2):
    """The dense n = 2 equations of :func:`_accel2` at state ``z``, given the angles' sines and
    cosines ``s1, c1, s2, c2``: ``(b0, r0, u1, u2, h11, h12, h22, r1, r2)`` of::

        b0 x0'' + u1 alpha1 + u2 alpha2 = r0           (reaction on; off: b0 x0'' = r0)
        u1 x0'' + h11 alpha1 + h12 alpha2 = r1
        u2 x0'' + h12 alpha1 + h22 alpha2 = r2

    with ``b0 = M + m, r0 = F_ext + S1 s1 w1^2 + S2 s2 w2^2`` (reaction) or ``b0 = M, r0 = F_ext``.
    The one set-up of :func:`_accel2` and :func:`remainder2_fast`, which solve it each their
    own way."""
    kf, k, c, m_stage, reaction = stage
    w1 = z[th0 + 2]
    w2 = z[th0 + 3]
    c12 = c1 * c2 + s1 * s2
    s12 = s1 * c2 - c1 * s2
    h12 = hc[0, 1] * c12
    hs = hc[0, 1] * s12
    u1 = s[0] * c1
    u2 = s[1] * c2
    r1 = -hs * w2 * w2 - g * s[0] * s1 - cm[0, 0] * w1 - cm[0, 1] * w2
    r2 = hs * w1 * w1 - g * s[1] * s2 - cm[1, 0] * w1 - cm[1, 1] * w2
    fext = kf * z[0] - k * z[1] - c * z[2]
    if reaction:
        b0 = m_stage + mtot
        r0 = fext + s[0] * s1 * w1 * w1 + s[1] * s2 * w2 * w2
    else:
        b0 = m_stage
        r0 = fext
    return b0, r0, u1, u2, hc[0, 0], h12, hc[1, 1], r1, r2


@njit(cache=True, error_model="numpy", inline="always")
def _accel2(g, hc, s, cm, mtot, stage, th0, z, alpha):
    """The same as :func:`_accel` for n = 2, from the dense equations (one division)::

        [[M + m, S1 c1, S2 c2], [S1 c1, H11, H12 c12], [S2 c2, H12 c12, H22]] (x0'', alpha)
          = (F_ext + S1 s1 w1^2 + S2 s2 w2^2, -H12 s12 w2^2 - g S1 s1 - (C w)_1,
             H12 s12 w1^2 - g S2 s2 - (C w)_2)

    (c_j = cos th_j, s12 = sin(th1 - th2); without the reaction the first row is M x0'' =
    F_ext), solved for alpha on the Schur complement of the stage entry."""
    b0, r0, u1, u2, h11, h12, h22, r1, r2 = _dense2_equations(
        g, hc, s, cm, mtot, stage, th0, z, math.sin(z[th0]), math.cos(z[th0]),
        math.sin(z[th0 + 1]), math.cos(z[th0 + 1]))
    if stage[4]:  # reaction
        h11 = h11 - u1 * u1 / b0
        h22 = h22 - u2 * u2 / b0
        h12 = h12 - u1 * u2 / b0
        r1 = r1 - u1 * r0 / b0
        r2 = r2 - u2 * r0 / b0
        det = h11 * h22 - h12 * h12
        a1 = (h22 * r1 - h12 * r2) / det
        a2 = (h11 * r2 - h12 * r1) / det
        ax = (r0 - u1 * a1 - u2 * a2) / b0
    else:
        ax = r0 / b0  # F_ext / M
        r1 = r1 - u1 * ax
        r2 = r2 - u2 * ax
        det = h11 * h22 - h12 * h12
        a1 = (h22 * r1 - h12 * r2) / det
        a2 = (h11 * r2 - h12 * r1) / det
    alpha[0] = a1
    alpha[1] = a2
    return ax


@njit(cache=True, error_model="numpy", inline="always")
def _rows_minus_linear(ax, alpha, z, q_idx, wc, a_rows, f):
    """f = (x0'', alpha, [x0'' - wc q]) - a_rows z."""
    n = alpha.shape[0]
    nf = a_rows.shape[0]
    nz = z.shape[0]
    f[0] = ax
    for j in range(n):
        f[1 + j] = alpha[j]
    if q_idx >= 0:
        f[n + 1] = ax - wc * z[q_idx]
    for r in range(nf):
        acc = 0.0
        for col in range(nz):
            acc += a_rows[r, col] * z[col]
        f[r] -= acc


@njit(cache=True, error_model="numpy", inline="always")
def _remainder2(g, hc, s, cm, mtot, stage, th0, q_idx, wc, a_rows, z, alpha, f):
    """The remainder f for n = 2 (dense accelerations); returns the nonlinear x0''."""
    ax = _accel2(g, hc, s, cm, mtot, stage, th0, z, alpha)
    _rows_minus_linear(ax, alpha, z, q_idx, wc, a_rows, f)
    return ax


@njit(cache=True, error_model="numpy")
def remainder_n(bodies, g, stage, th0, q_idx, wc, a_rows, z, work, alpha, f):
    """The remainder f for any n (O(n) recursion); returns the nonlinear x0''. Not inlined:
    kernels branch between it and :func:`_remainder2`, and inlining both into one loop makes
    the n = 2 path several times slower."""
    ax = _accel(bodies, g, stage, th0, z, work, alpha)
    _rows_minus_linear(ax, alpha, z, q_idx, wc, a_rows, f)
    return ax


@njit(cache=True, error_model="numpy", inline="always")
def arg_groups(prm):
    """``(dense, bodies, stage)``: the n = 2 equations' ``(g, hc, s, cm, mtot)``, the recursion's
    per-body arrays ``(mass, length, com, inertia, gamma, relative)`` and the stage's numbers
    ``(kf, k, c, m_stage, reaction)``, which a kernel takes out of its :class:`CoupledArgs` once. The helpers the
    kernels call in their loops take these and the few arrays they read, not the whole
    :class:`CoupledArgs`: numba reference-counts every array passed into a call, at each call,
    which for the whole tuple costs more than etdab's step itself."""
    return ((prm.g, prm.hc, prm.s, prm.cm, prm.mtot),
            (prm.mass, prm.length, prm.com, prm.inertia, prm.gamma, prm.relative),
            (prm.kf, prm.k, prm.c, prm.m_stage, prm.reaction))


@njit(cache=True, error_model="numpy", inline="always")
def kernel_scratch(prm, z):
    """``(n, two, nz, nf, work, alpha)``: the kernels' sizes (bodies, n = 2?, states, remainder
    rows) and the recursion's scratch ``work`` (n, 7) and ``alpha`` (n,)."""
    n = prm.mass.shape[0]
    return n, n == 2, z.shape[0], prm.rows.shape[0], np.empty((n, 7)), np.empty(n)


@njit(cache=True, error_model="numpy", inline="always")
def remainder_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, z, work, alpha, f):
    """The remainder f and the nonlinear x0'': :func:`_remainder2` where ``two`` (n = 2, inlined),
    else :func:`remainder_n` (a call); ``dense``, ``bodies``, ``stage``: :func:`arg_groups`."""
    g, hc, s, cm, mtot = dense
    if two:
        return _remainder2(g, hc, s, cm, mtot, stage, th0, q_idx, wc, a_rows, z, alpha, f)
    return remainder_n(bodies, g, stage, th0, q_idx, wc, a_rows, z, work, alpha, f)


@njit(cache=True, error_model="numpy", inline="always")
def remainder_fast_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, a_cols, z, work, alpha,
                      f):
    """:func:`remainder_at` with :func:`remainder2_fast` where ``two`` (polynomial sines, one
    division; ``a_rows`` read in its first ``a_cols`` columns), else :func:`remainder_n` (a
    call)."""
    g, hc, s, cm, mtot = dense
    if two:
        return remainder2_fast(g, hc, s, cm, mtot, stage, th0, q_idx, wc, a_rows, a_cols, z, f)
    return remainder_n(bodies, g, stage, th0, q_idx, wc, a_rows, z, work, alpha, f)


def accelerations(params: CoupledParams, z, *, recursive: bool = False
                  ) -> tuple[float, np.ndarray]:
    """Nonlinear stage acceleration x0'' [m/s^2] and theta'' (n,) [rad/s^2] at bench state z
    (the kernels' code: dense for n = 2 unless ``recursive``, the O(n) recursion otherwise)."""
    p = params
    z = np.ascontiguousarray(z, dtype=float)
    alpha = np.empty(p.n)
    _, bodies, stage = arg_groups(p.args())
    if p.n == 2 and not recursive:
        ax = _accel2(p.g, p.hc, p.s, p.cm, p.mtot, stage, p.th0, z, alpha)
    else:
        ax = _accel(bodies, p.g, stage, p.th0, z, np.empty((p.n, 7)), alpha)
    return float(ax), alpha


def remainder(params: CoupledParams, z) -> np.ndarray:
    """The remainder f(z) in the rows ``params.rows`` (nonlinear minus linear derivative)."""
    p = params
    z = np.ascontiguousarray(z, dtype=float)
    f = np.empty(p.rows.size)
    dense, bodies, stage = arg_groups(p.args())
    remainder_at(p.n == 2, dense, bodies, stage, p.th0, p.q_idx, p.wc, p.a_rows, z,
                 np.empty((p.n, 7)), np.empty(p.n), f)
    return f


@njit(cache=True, error_model="numpy", inline="always")
def remainder2_fast(g, hc, s, cm, mtot, stage, th0, q_idx, wc, a_rows, a_cols, z, f):
    """:func:`_remainder2` (n = 2) with polynomial sines where both angles are <= 0.8 rad and
    one division: the same equations, rounded differently (a few ulp); ``a_rows`` is read in
    its first ``a_cols`` columns (the others are zero). ``stage``: :func:`arg_groups`. Returns
    x0''."""
    t1 = z[th0]
    t2 = z[th0 + 1]
    if max(abs(t1), abs(t2)) <= SINCOS_POLY_MAX:
        s1, c1 = sincos_poly(t1)
        s2, c2 = sincos_poly(t2)
    else:
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    b0, r0, u1, u2, h11, h12, h22, r1, r2 = _dense2_equations(g, hc, s, cm, mtot, stage, th0, z,
                                                              s1, c1, s2, c2)
    if stage[4]:  # reaction
        # the Schur complement of the stage entry, det * b0 * b0 kept as one division
        h11b = h11 * b0 - u1 * u1
        h22b = h22 * b0 - u2 * u2
        h12b = h12 * b0 - u1 * u2
        r1b = r1 * b0 - u1 * r0
        r2b = r2 * b0 - u2 * r0
        inv = 1.0 / ((h11b * h22b - h12b * h12b) * b0)
        n1 = h22b * r1b - h12b * r2b
        n2 = h11b * r2b - h12b * r1b
        a1 = n1 * inv * b0
        a2 = n2 * inv * b0
        ax = (r0 * (h11b * h22b - h12b * h12b) - u1 * n1 - u2 * n2) * inv
    else:
        ax = r0 / b0  # F_ext / M
        r1 = r1 - u1 * ax
        r2 = r2 - u2 * ax
        inv = 1.0 / (h11 * h22 - h12 * h12)
        a1 = (h22 * r1 - h12 * r2) * inv
        a2 = (h11 * r2 - h12 * r1) * inv
    f[0] = ax
    f[1] = a1
    f[2] = a2
    if q_idx >= 0:
        f[3] = ax - wc * z[q_idx]
    for r in range(a_rows.shape[0]):
        acc = 0.0
        for col in range(a_cols):
            acc += a_rows[r, col] * z[col]
        f[r] -= acc
    return ax


# ================================================================================================
# bookkeeping (tests)
# ================================================================================================

def horizontal_momentum(chain: Chain, stage: Stage, theta, omega, v0) -> np.ndarray:
    """Horizontal momentum of stage + chain [kg m/s]: ``(M + m) v0 + sum_j S_j cos(th_j) w_j``
    (rows of theta, omega (T, n); v0 (T,))."""
    th = np.atleast_2d(np.asarray(theta, float))
    om = np.atleast_2d(np.asarray(omega, float))
    m = float(sum(chain.mass_kg))
    return (stage.moving_mass_kg + m) * np.asarray(v0, float) + np.sum(
        chain.S * np.cos(th) * om, axis=-1)


def energy(chain: Chain, stage: Stage, theta, omega, x0, v0, current=None) -> np.ndarray:
    """Total energy of stage + chain in the lab frame [J]: stage kinetic and spring energy,
    the chain's kinetic energy ``1/2 m v0^2 + v0 sum S_j cos th_j w_j + 1/2 w^T M(th) w``, its
    potential ``-g sum S_j cos th_j``, and the coil's ``1/2 L i^2`` if ``current`` is given."""
    th = np.atleast_2d(np.asarray(theta, float))
    om = np.atleast_2d(np.asarray(omega, float))
    v0 = np.asarray(v0, float)
    m = float(sum(chain.mass_kg))
    e = (0.5 * (stage.moving_mass_kg + m) * v0**2 + 0.5 * stage.stiffness_npm
         * np.asarray(x0, float)**2 + v0 * np.sum(chain.S * np.cos(th) * om, axis=-1)
         + chain.energy(th, om))
    if current is not None:
        e = e + 0.5 * stage.coil_inductance_h * np.asarray(current, float)**2
    return e


__all__ = ["CoupledArgs", "CoupledParams", "coupled_params", "accelerations", "remainder",
           "arg_groups", "kernel_scratch",
           "remainder_at", "remainder_fast_at", "remainder2_fast", "remainder_n",
           "horizontal_momentum", "energy"]
