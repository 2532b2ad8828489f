"""The nonlinear pendulum on the stage it loads: the whole bench integrated as one system.

The bench state is the one of :mod:`rig.bench` (named slices there)::

    z = (i, x0, v0, theta (n), omega (n) [, q] [, r ...])

and its exact linear model is ``z' = A z + B V`` (:meth:`rig.devices.stage.Stage.state_space` plus the
source's reconstruction filter and the accelerometer's high-pass). The nonlinear bench differs from
it only in the mechanical accelerations: with ``F_ext = Kf i - k x0 - c v0`` the stage and the
chain obey::

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
``x0''``), and of relative size ~ theta^2.

``lawson4`` (:func:`lawson4_kernel`)
    Integrating-factor (Lawson) Runge-Kutta 4 on ``w = e^{-A t} (z - z_forced)``: the linear
    bench, including its stiff coil (R/L = 2000 1/s) and reconstruction-filter poles and the held
    source voltage, is propagated *exactly* (``e^{A h}``, ``int e^{A s} B ds``: the same Van Loan
    matrices as the exact linear model), and only the small remainder ``f`` is integrated by the
    classical RK4 weights. Per step of ``h = 1 / (fs substeps)``::

        P_h = E_h z + G_h V,   P_2 = E_{h/2} z + G_{h/2} V
        k1 = f(z)
        k2 = f(P_2 + h/2 E_{h/2} k1)
        k3 = f(P_2 + h/2 k2)
        k4 = f(P_h + h E_{h/2} k3)
        z+ = P_h + h/6 (E_h k1 + 2 E_{h/2} (k2 + k3) + k4)

    With ``f = 0`` this *is* the exact linear bench (round-off only), so its error is a fourth-
    order error *in the remainder*: it vanishes with the amplitude like theta^2 h^4 and does not
    depend on the stiffness of the electrical parts. Steps end on the DAC instants (the source
    is constant inside every step). Cost ~ 4 evaluations of the O(n) recursion plus two dense
    and four thin (nz x (n + 2)) matrix-vector products per step.

``first_order_kernel``
    The linear bench and its first-order linearisation error ``d`` together:
    ``d' = A d + f(z_lin(t))`` (``z_nl = z_lin + d + O(theta^2 d)``), both discretised exactly
    for a linearly interpolated input (first-order hold of ``V`` and of ``f``). This is the
    predictor of the linearisation error used by :func:`rig.bench.select_model`.

All kernels are ``numba.njit(cache=True, error_model="numpy")`` (a blow-up gives non-finite
numbers, checked once per block by the caller, not a ZeroDivisionError inside a step). They share
the solvers' polynomial sines (:func:`rig.solvers._kernels._sincos_poly`; cross-file calls are safe
with the keyed cache of :mod:`rig._jit`); their recursion (:func:`_accel`) carries the base-force
split the pendulum-only one (:func:`rig.solvers._kernels._rhs_rec`) does not, so it is its own.
The drivers are :mod:`rig.solvers.lawson4` and :mod:`rig.solvers.etdab`.

Public API: :class:`CoupledParams`, :func:`coupled_params`, :func:`accelerations`,
:func:`remainder`, :func:`lawson_matrices`, :func:`lawson4_kernel`, :func:`etd_ab_weights`,
:func:`etd_ab_phase_weights`, :func:`etd_ab_sparsity`, :func:`etd_ab_kernel`,
:func:`first_order_kernel`, :func:`horizontal_momentum`, :func:`energy`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rig.chain import Chain
from rig._jit import njit
from rig.solvers._kernels import SINCOS_POLY_MAX, _sincos_poly
from rig.devices.stage import Stage


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

    def args(self) -> tuple:
        """The leading kernel arguments, in kernel order."""
        return (self.mass, self.length, self.com, self.inertia, self.gamma, self.relative,
                self.g, self.hc, self.s, self.cm, self.mtot, self.kf, self.k, self.c,
                self.m_stage, self.reaction, self.th0, self.q_idx, self.wc, self.rows,
                self.a_rows)


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
def _accel(mass, length, com, inertia, gamma, relative, g, kf, k, c, m_stage, reaction, th0,
           z, work, alpha):
    """Stage acceleration x0'' (returned) and alpha = theta'' of the coupled nonlinear bench at
    state z. ``work`` (n, 7) scratch. Backward pass: articulated inertia (c11, c12, c22) and the
    bias forces split into the part at x0'' = 0 (cb1, cb2; beta) and the part per unit x0''
    (ca1, ca2; beta_a: the inertial force -m x0'' of every body in the base frame)."""
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
def _dense2_equations(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, z, s1, c1, s2, c2):
    """The dense n = 2 equations of :func:`_accel2` at state ``z``, given the angles' sines and
    cosines ``s1, c1, s2, c2``: ``(b0, r0, u1, u2, h11, h12, h22, r1, r2)`` of::

        b0 x0'' + u1 alpha1 + u2 alpha2 = r0           (reaction on; off: b0 x0'' = r0)
        u1 x0'' + h11 alpha1 + h12 alpha2 = r1
        u2 x0'' + h12 alpha1 + h22 alpha2 = r2

    with ``b0 = M + m, r0 = F_ext + S1 s1 w1^2 + S2 s2 w2^2`` (reaction) or ``b0 = M, r0 = F_ext``.
    The one set-up of :func:`_accel2` and :func:`_remainder2_fast`, which solve it each their
    own way."""
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
def _accel2(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, z, alpha):
    """The same as :func:`_accel` for n = 2, from the dense equations (one division)::

        [[M + m, S1 c1, S2 c2], [S1 c1, H11, H12 c12], [S2 c2, H12 c12, H22]] (x0'', alpha)
          = (F_ext + S1 s1 w1^2 + S2 s2 w2^2, -H12 s12 w2^2 - g S1 s1 - (C w)_1,
             H12 s12 w1^2 - g S2 s2 - (C w)_2)

    (c_j = cos th_j, s12 = sin(th1 - th2); without the reaction the first row is M x0'' =
    F_ext), solved for alpha on the Schur complement of the stage entry."""
    b0, r0, u1, u2, h11, h12, h22, r1, r2 = _dense2_equations(
        g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, z, math.sin(z[th0]),
        math.cos(z[th0]), math.sin(z[th0 + 1]), math.cos(z[th0 + 1]))
    if reaction:
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
def _remainder2(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, q_idx, wc, a_rows, z,
                alpha, f):
    """The remainder f for n = 2 (dense accelerations); returns the nonlinear x0''."""
    ax = _accel2(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, z, alpha)
    _rows_minus_linear(ax, alpha, z, q_idx, wc, a_rows, f)
    return ax


@njit(cache=True, error_model="numpy")
def _remainder_n(mass, length, com, inertia, gamma, relative, g, kf, k, c, m_stage, reaction,
                 th0, q_idx, wc, a_rows, z, work, alpha, f):
    """The remainder f for any n (O(n) recursion); returns the nonlinear x0''. Not inlined:
    kernels branch between it and :func:`_remainder2`, and inlining both into one loop makes
    the n = 2 path several times slower."""
    ax = _accel(mass, length, com, inertia, gamma, relative, g, kf, k, c, m_stage, reaction, th0,
                z, work, alpha)
    _rows_minus_linear(ax, alpha, z, q_idx, wc, a_rows, f)
    return ax


@njit(cache=True, error_model="numpy", inline="always")
def _kernel_scratch(mass, rows, z):
    """``(n, two, nz, nf, work, alpha)``: the kernels' sizes (bodies, n = 2?, states, remainder
    rows) and the recursion's scratch ``work`` (n, 7) and ``alpha`` (n,)."""
    n = mass.shape[0]
    return n, n == 2, z.shape[0], rows.shape[0], np.empty((n, 7)), np.empty(n)


@njit(cache=True, error_model="numpy", inline="always")
def _remainder(two, prm, z, work, alpha, f):
    """The remainder f and the nonlinear x0'': :func:`_remainder2` where ``two`` (n = 2, inlined),
    else :func:`_remainder_n` (a call). ``prm`` is the kernels' leading arguments as one tuple
    (:meth:`CoupledParams.args`), which a kernel packs from its own arguments: the kernels keep
    them as separate arguments (taken out of a tuple *argument* the arrays made etdab's step
    slower)."""
    (mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c, m_stage,
     reaction, th0, q_idx, wc, rows, a_rows) = prm
    if two:
        return _remainder2(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, q_idx, wc,
                           a_rows, z, alpha, f)
    return _remainder_n(mass, length, com, inertia, gamma, relative, g, kf, k, c, m_stage,
                        reaction, th0, q_idx, wc, a_rows, z, work, alpha, f)


@njit(cache=True, error_model="numpy", inline="always")
def _remainder_fast(two, prm, a_cols, z, work, alpha, f):
    """:func:`_remainder` with :func:`_remainder2_fast` where ``two`` (polynomial sines, one
    division; ``a_rows`` read in its first ``a_cols`` columns), else :func:`_remainder_n` (a
    call)."""
    (mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c, m_stage,
     reaction, th0, q_idx, wc, rows, a_rows) = prm
    if two:
        return _remainder2_fast(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, q_idx, wc,
                                a_rows, a_cols, z, f)
    return _remainder_n(mass, length, com, inertia, gamma, relative, g, kf, k, c, m_stage,
                        reaction, th0, q_idx, wc, a_rows, z, work, alpha, f)


def accelerations(params: CoupledParams, z, *, recursive: bool = False
                  ) -> tuple[float, np.ndarray]:
    """Nonlinear stage acceleration x0'' [m/s^2] and theta'' (n,) [rad/s^2] at bench state z
    (the kernels' code: dense for n = 2 unless ``recursive``, the O(n) recursion otherwise)."""
    p = params
    z = np.ascontiguousarray(z, dtype=float)
    alpha = np.empty(p.n)
    if p.n == 2 and not recursive:
        ax = _accel2(p.g, p.hc, p.s, p.cm, p.mtot, p.kf, p.k, p.c, p.m_stage, p.reaction, p.th0, z,
                     alpha)
    else:
        ax = _accel(p.mass, p.length, p.com, p.inertia, p.gamma, p.relative, p.g, p.kf, p.k, p.c,
                    p.m_stage, p.reaction, p.th0, z, np.empty((p.n, 7)), alpha)
    return float(ax), alpha


def remainder(params: CoupledParams, z) -> np.ndarray:
    """The remainder f(z) in the rows ``params.rows`` (nonlinear minus linear derivative)."""
    p = params
    z = np.ascontiguousarray(z, dtype=float)
    f = np.empty(p.rows.size)
    _remainder(p.n == 2, p.args(), z, np.empty((p.n, 7)), np.empty(p.n), f)
    return f


# ================================================================================================
# Lawson RK4
# ================================================================================================

def lawson_matrices(a: np.ndarray, b: np.ndarray, h: float):
    """(E_h, E_{h/2}, G_h, G_{h/2}): ``e^{A t}`` and ``int_0^t e^{A s} ds B`` (B one column) at
    t = h and h / 2, from one Van Loan exponential each."""
    nz = a.shape[0]
    out = []
    for t in (h, h / 2):
        big = np.zeros((nz + 1, nz + 1))
        big[:nz, :nz] = a * t
        big[:nz, nz] = b[:, 0] * t
        e = scipy.linalg.expm(big)
        out.append((np.ascontiguousarray(e[:nz, :nz]), np.ascontiguousarray(e[:nz, nz])))
    (e_h, g_h), (e_2, g_2) = out
    return e_h, e_2, g_h, g_2


@njit(cache=True, nogil=True, error_model="numpy")
def lawson4_kernel(mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c,
                   m_stage, reaction, th0, q_idx, wc, rows, a_rows, e_h, e_2, g_h, g_2, h, nsub,
                   v, z, z_out, ax_out):
    """Lawson RK4 (module docstring) over len(v) DAC intervals, ``nsub`` steps of ``h`` each.

    z_out[k] = z and ax_out[k] = x0'' at DAC instant k (k < len(v)); ``z`` (in/out) ends at the
    instant len(v). Every row is summed in a fixed order, so block splits reproduce one-shot runs
    bit for bit."""
    n, two, nz, nf, work, alpha = _kernel_scratch(mass, rows, z)
    prm = (mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c, m_stage,
           reaction, th0, q_idx, wc, rows, a_rows)
    f1 = np.empty(nf)
    f2 = np.empty(nf)
    f3 = np.empty(nf)
    f4 = np.empty(nf)
    ph = np.empty(nz)
    p2 = np.empty(nz)
    zt = np.empty(nz)
    for kk in range(v.shape[0]):
        vk = v[kk]
        for col in range(nz):
            z_out[kk, col] = z[col]
        for sub in range(nsub):
            ax = _remainder(two, prm, z, work, alpha, f1)
            if sub == 0:
                ax_out[kk] = ax
            for r in range(nz):
                acc_h = g_h[r] * vk
                acc_2 = g_2[r] * vk
                for col in range(nz):
                    acc_h += e_h[r, col] * z[col]
                    acc_2 += e_2[r, col] * z[col]
                ph[r] = acc_h
                p2[r] = acc_2
            # stage 2
            for r in range(nz):
                acc = 0.0
                for i in range(nf):
                    acc += e_2[r, rows[i]] * f1[i]
                zt[r] = p2[r] + 0.5 * h * acc
            ax = _remainder(two, prm, zt, work, alpha, f2)
            # stage 3
            for r in range(nz):
                zt[r] = p2[r]
            for i in range(nf):
                zt[rows[i]] += 0.5 * h * f2[i]
            ax = _remainder(two, prm, zt, work, alpha, f3)
            # stage 4
            for r in range(nz):
                acc = 0.0
                for i in range(nf):
                    acc += e_2[r, rows[i]] * f3[i]
                zt[r] = ph[r] + h * acc
            ax = _remainder(two, prm, zt, work, alpha, f4)
            # the step
            for r in range(nz):
                acc = 0.0
                for i in range(nf):
                    acc += e_h[r, rows[i]] * f1[i] + 2.0 * e_2[r, rows[i]] * (f2[i] + f3[i])
                z[r] = ph[r] + (h / 6.0) * acc
            for i in range(nf):
                z[rows[i]] += (h / 6.0) * f4[i]


# ================================================================================================
# exponential Adams-Bashforth: one remainder evaluation per DAC sample
# ================================================================================================

def etd_ab_weights(a: np.ndarray, rows: np.ndarray, h: float, order: int, lag: int = 0
                   ) -> np.ndarray:
    """Weights of :func:`etd_ab_kernel` with the remainder at every step:
    ``etd_ab_phase_weights(a, rows, h, order, 1, lag)[0][0]``, (order, nf, nz)."""
    return etd_ab_phase_weights(a, rows, h, order, 1, lag)[0][0]


def etd_ab_phase_weights(a: np.ndarray, rows: np.ndarray, h: float, order: int, every: int,
                         lag: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Weights of :func:`etd_ab_kernel` for a remainder evaluated at every ``every``-th step
    (its nodes ``H = every h`` apart): ``(w, lagv)``.

    ``w`` (every, order, nf, nz) (transposed for the kernel's loop): for the step that starts
    ``i`` steps after the newest node, ``W^(i)_j = int_0^h e^{A(h-s)} P L_j((i h + s) / H) ds``,
    where ``P`` puts the remainder's ``nf`` rows into z and ``L_j`` is the Lagrange polynomial
    through the nodes ``x = -lag, .., -(lag + order - 1)`` (in units of H) that is 1 at ``x =
    -(lag + j)``. ``lagv`` (every, order): ``L_j(i / every)``, the remainder at that step's start.
    Read off one matrix exponential of the system augmented by the monomials (Van Loan): block m
    of its first block row is ``int_0^h e^{A(h-s)} P (s/h)^m ds / m!``; ``L_j(i / every + u /
    every)`` is expanded in powers of ``u = s / h`` (``every`` = 1: the powers of ``L_j``'s own
    coefficients, exactly)."""
    a = np.asarray(a, float)
    nz = a.shape[0]
    nf = rows.size
    size = nz + order * nf
    big = np.zeros((size, size))
    big[:nz, :nz] = a * h
    big[rows, nz + np.arange(nf)] = h
    for m in range(order - 1):
        r0 = nz + m * nf
        big[r0:r0 + nf, r0 + nf:r0 + 2 * nf] = np.eye(nf)
    e = scipy.linalg.expm(big)
    ks = [math.factorial(m) * e[:nz, nz + m * nf:nz + (m + 1) * nf] for m in range(order)]
    nodes = -(lag + np.arange(order, dtype=float))
    poly = np.polynomial.polynomial
    w = np.zeros((every, order, nz, nf))
    lagv = np.zeros((every, order))
    for j in range(order):
        others = np.delete(nodes, j)
        coef = poly.polyfromroots(others) / np.prod(nodes[j] - others)
        for i in range(every):
            if every == 1:
                comp = coef
            else:
                comp = np.zeros(1)
                for m, cm in enumerate(coef):
                    comp = poly.polyadd(comp, cm * poly.polypow([i / every, 1.0 / every], m))
            lagv[i, j] = poly.polyval(i / every, coef)
            for m in range(min(order, comp.size)):
                w[i, j] += comp[m] * ks[m]
    return np.ascontiguousarray(w.transpose(0, 1, 3, 2)), lagv


@njit(cache=True, error_model="numpy", inline="always")
def _remainder2_fast(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, q_idx, wc, a_rows,
                     a_cols, z, f):
    """:func:`_remainder2` (n = 2) with polynomial sines where both angles are <= 0.8 rad and
    one division: the same equations, rounded differently (a few ulp); ``a_rows`` is read in
    its first ``a_cols`` columns (the others are zero). Returns x0''."""
    t1 = z[th0]
    t2 = z[th0 + 1]
    if max(abs(t1), abs(t2)) <= SINCOS_POLY_MAX:
        s1, c1 = _sincos_poly(t1)
        s2, c2 = _sincos_poly(t2)
    else:
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    b0, r0, u1, u2, h11, h12, h22, r1, r2 = _dense2_equations(
        g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0, z, s1, c1, s2, c2)
    if reaction:
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


def etd_ab_sparsity(w: np.ndarray, a_rows: np.ndarray) -> tuple[int, int]:
    """Where :func:`etd_ab_kernel`'s products are not identically zero: ``w_rows``, the rows of
    z the weights reach (a prefix: the source's reconstruction filter, last in z, never sees the
    remainder), and ``a_cols``, the columns of ``a_rows`` in use (a prefix). Skipping exact zeros
    leaves every sum's value unchanged (finite states); it saves ~5 % of a step (skipping
    Phi's zero blocks by ranges per column cost more than it saved: the loops no longer
    vectorise)."""
    rows = np.flatnonzero(np.abs(w).reshape(-1, w.shape[-1]).sum(axis=0))
    cols = np.flatnonzero(np.abs(a_rows).sum(axis=0))
    return int(rows[-1] + 1 if rows.size else 0), int(cols[-1] + 1 if cols.size else 0)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def etd_ab_kernel(mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c,
                  m_stage, reaction, th0, q_idx, wc, rows, a_rows, phi_t, gam, w, lagv, w_rows,
                  a_cols, nsub, have, hist, phase, v, z, z_out, ax_out):
    """Exponential Adams-Bashforth over len(v) DAC intervals, ``nsub`` steps of h each::

        z_{k+1} = Phi z_k + Gamma v + sum_j W^(i)_j f(z at node n - lag - j),  j = 0 .. order - 1

    (``phi_t`` = Phi transposed and ``gam`` over h; ``w``, ``lagv`` from
    :func:`etd_ab_phase_weights`, ``every`` = len(w), lag = len(hist) - order): the linear
    bench and the held source exactly, the remainder's integral over the step by the polynomial
    through its values at ``order`` past nodes, which are every ``every``-th step; ``i`` is the
    step's place after the newest node (``phase[0]``, in/out: 0 .. every - 1 at the block's
    start). At a node, one evaluation of f at the step's own state, which also gives the
    nonlinear x0''; between nodes x0'' is the linear row plus f's first row interpolated
    (``lagv``). ``ax_out[k]`` = x0'' and ``z_out[k]`` = z at DAC instant k. ``every`` = 1: f at
    every step (with lag >= 1 the step does not wait for the newest evaluation); the
    acquisition's default is :func:`rig.bench.model.remainder_every`.

    ``w_rows, a_cols`` (:func:`etd_ab_sparsity`) skip exact zeros of the products. ``hist``
    (lag + order, nf) holds f at the last nodes (newest first) and is updated; ``have`` False:
    none yet (a start, which is a node: every entry is taken as f(z_0)). ``z`` (in/out) ends at
    the instant len(v). The rows are summed in a fixed order, so block splits reproduce one-shot
    runs bit for bit. Compiled with FMA contraction (``fastmath={"contract"}``, no reordering):
    the acquisition runs the same arithmetic unrolled for the matrices' zero pattern
    (:func:`rig.unrolled.etdab_kernel`, the same values), this loop is its reference and the
    path of benches too large to unroll."""
    n, two, nz, nf, work, alpha = _kernel_scratch(mass, rows, z)
    every = w.shape[0]
    order = w.shape[1]
    nh = hist.shape[0]
    lag = nh - order
    f = np.empty(nf)
    zn = np.empty(nz)
    zw = np.empty(nz)
    first = not have
    ph = phase[0]
    ax = 0.0
    for kk in range(v.shape[0]):
        vk = v[kk]
        for sub in range(nsub):
            if ph == 0:
                if two:
                    ax = _remainder2_fast(g, hc, s, cm, mtot, kf, k, c, m_stage, reaction, th0,
                                          q_idx, wc, a_rows, a_cols, z, f)
                else:
                    ax = _remainder_n(mass, length, com, inertia, gamma, relative, g, kf, k, c,
                                      m_stage, reaction, th0, q_idx, wc, a_rows, z, work, alpha,
                                      f)
                if first:
                    first = False
                    for j in range(nh):
                        for i in range(nf):
                            hist[j, i] = f[i]
                else:
                    for j in range(nh - 1, 0, -1):
                        for i in range(nf):
                            hist[j, i] = hist[j - 1, i]
                    for i in range(nf):
                        hist[0, i] = f[i]
            elif sub == 0:
                ax = 0.0
                for col in range(a_cols):
                    ax += a_rows[0, col] * z[col]
                for j in range(order):
                    ax += lagv[ph, j] * hist[lag + j, 0]
            if sub == 0:
                ax_out[kk] = ax
                for r in range(nz):
                    z_out[kk, r] = z[r]
            for r in range(nz):
                zn[r] = gam[r] * vk
                zw[r] = 0.0
            for col in range(nz):
                zc = z[col]
                for r in range(nz):
                    zn[r] += phi_t[col, r] * zc
            for j in range(order - 1, -1, -1):
                for i in range(nf):
                    x = hist[lag + j, i]
                    for r in range(w_rows):
                        zw[r] += w[ph, j, i, r] * x
            for r in range(nz):
                z[r] = zn[r] + zw[r]
            ph += 1
            if ph == every:
                ph = 0
    phase[0] = ph


# ================================================================================================
# first-order linearisation error (the predictor)
# ================================================================================================

@njit(cache=True, nogil=True, error_model="numpy")
def first_order_kernel(mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c,
                       m_stage, reaction, th0, q_idx, wc, rows, a_rows, phi, g0, g1, gf0, gf1, v,
                       z, d, k_rec, n_batches, sums, peaks):
    """Linear bench z and its first-order linearisation error d over len(v) - 1 intervals.

    z_{k+1} = Phi z_k + G0 v_k + G1 (v_{k+1} - v_k);  d_{k+1} = Phi d_k + GF0 f_k + GF1 (f_{k+1}
    - f_k) with f_k = f(z_k) in ``rows`` (first-order hold of both inputs). From sample ``k_rec``
    on, the samples are split into ``n_batches`` equal consecutive batches and
    ``sums[b, 0, j] += theta_j^2``, ``sums[b, 1, j] += d_theta_j^2``,
    ``sums[b, 2, j] = max |d_theta_j|``; over every sample ``peaks[0, j] = max |theta_j|``,
    ``peaks[1, j] = max |d_theta_j|`` (is the first order valid all along?). ``z``, ``d``
    (in/out) end at the last sample.

    For n = 2, f is :func:`_remainder2_fast`'s (polynomial sines, one division: the dense
    equations rounded differently, a few ulp), as etdab's; the state products run row beside
    row (each row's sum over the columns in order, as a loop per row would form it)."""
    n, two, nz, nf, work, alpha = _kernel_scratch(mass, rows, z)
    prm = (mass, length, com, inertia, gamma, relative, g, hc, s, cm, mtot, kf, k, c, m_stage,
           reaction, th0, q_idx, wc, rows, a_rows)
    f = np.empty(nf)
    fn = np.empty(nf)
    zt = np.empty(nz)
    dt = np.empty(nz)
    phi_t = np.ascontiguousarray(phi.T)  # rows side by side: row r's terms in column order
    gf0_t = np.ascontiguousarray(gf0.T)
    gf1_t = np.ascontiguousarray(gf1.T)
    a_cols = a_rows.shape[1]
    n_s = v.shape[0]
    n_rec = n_s - k_rec
    ax = _remainder_fast(two, prm, a_cols, z, work, alpha, f)
    for kk in range(n_s):
        for j in range(n):
            if abs(z[th0 + j]) > peaks[0, j]:
                peaks[0, j] = abs(z[th0 + j])
            if abs(d[th0 + j]) > peaks[1, j]:
                peaks[1, j] = abs(d[th0 + j])
        if kk >= k_rec:
            b = ((kk - k_rec) * n_batches) // n_rec
            for j in range(n):
                t = z[th0 + j]
                e = d[th0 + j]
                sums[b, 0, j] += t * t
                sums[b, 1, j] += e * e
                if abs(e) > sums[b, 2, j]:
                    sums[b, 2, j] = abs(e)
        if kk + 1 == n_s:
            break
        v0 = v[kk]
        dv = v[kk + 1] - v0
        for r in range(nz):
            zt[r] = g0[r] * v0 + g1[r] * dv
        for col in range(nz):
            zc = z[col]
            for r in range(nz):
                zt[r] += phi_t[col, r] * zc
        for r in range(nz):
            z[r] = zt[r]
        ax = _remainder_fast(two, prm, a_cols, z, work, alpha, fn)
        for r in range(nz):
            dt[r] = 0.0
        for col in range(nz):
            dc = d[col]
            for r in range(nz):
                dt[r] += phi_t[col, r] * dc
        for i in range(nf):
            fi = f[i]
            dfi = fn[i] - fi
            for r in range(nz):
                dt[r] += gf0_t[i, r] * fi + gf1_t[i, r] * dfi
        for r in range(nz):
            d[r] = dt[r]
        for i in range(nf):
            f[i] = fn[i]


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


__all__ = ["CoupledParams", "coupled_params", "accelerations", "remainder", "lawson_matrices",
           "lawson4_kernel", "etd_ab_weights", "etd_ab_phase_weights", "etd_ab_sparsity",
           "etd_ab_kernel", "first_order_kernel", "horizontal_momentum", "energy"]
