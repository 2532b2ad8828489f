"""linear: the exact discretisation of the *linearised* chain for the held input.

``z_{k+1} = Phi z_k + Gamma0 u_k + Gamma1 (u_{k+1} - u_k)`` per substep (:func:`discretise`, Van
Loan's block exponential); only round-off error (the linearisation is a model error, ~ theta^3;
the vertical input y0'' drops out of it at first order). Where an output row spans L > 1
substeps the recursion is composed into one step per row (Phi^L and a FIR of the row's input
samples, :func:`lift_linear`). Cost: one (2n x 2n) mat-vec per substep, or per output row lifted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.jit import njit
from rig.linear import discretise
from rig.solvers.primitives import NONFINITE, OK, store
from rig.solvers.base import Refinement, SubstepSolver


# ================================================================================================
# exact discretisation of the linear model
# ================================================================================================

# -- lifted to the output rate --------------------------------------------------------------------
#
# When each output row spans L = out_every * substeps substeps, the per-substep recursion composes
# into one step per row, z_{k+1} = Phi^L z_k + sum_q c_q u_{k m + q}: a FIR of the row's
# m = out_every input samples (m + 1 with the linear hold: rows share their boundary sample). With
# the interval's map ``z <- P_I z + a_I u_q + b_I u_{q+1}`` (P_I = Phi^substeps; a_I, b_I the
# substeps' Gamma0, Gamma1 terms carried to the interval's end, b_I = 0 for zoh) the taps are
# ``c_q = P_I^{m-1-q} a_I + P_I^{m-q} b_I`` (each term where its exponent is >= 0). They come from
# the discretised Phi itself (repeated products, Phi^L by squaring), so the lifted run follows the
# per-substep run to round-off (a few ulp per row), not merely the exact solution.


def _matrix_power(a: np.ndarray, k: int) -> np.ndarray:
    """a^k by repeated squaring (k >= 0; relative error ~ log2(k) ulp)."""
    out = np.eye(a.shape[0])
    sq = a.copy()
    while k:
        if k & 1:
            out = sq @ out
        k >>= 1
        if k:
            sq = sq @ sq
    return out


def lift_linear(phi, g0, g1, hold: str, substeps: int, out_every: int):
    """The linear method over one output row of ``out_every`` input intervals at once.

    Parameters
    ----------
    phi, g0, g1 : the substep's exact discretisation (:func:`discretise`; (N, N), (N, 1), (N, 1)).
    hold : ``"zoh"`` or ``"linear"`` (the input inside an interval, as in :func:`linear_kernel`).
    substeps : substeps per input interval.
    out_every : input intervals per output row, m.

    Returns
    -------
    p : (N, N) Phi^(m substeps).
    taps : (m, N) for ``zoh``, (m + 1, N) for ``linear``: the row's state is
        ``z_{k+1} = p z_k + taps.T @ u[k m : k m + len(taps)]``, the same map as
        :func:`linear_kernel` over the row's m intervals (equal to round-off).
    """
    phi = np.ascontiguousarray(phi, dtype=float)
    n2 = phi.shape[0]
    g0 = np.ascontiguousarray(g0, dtype=float).reshape(n2)
    g1 = np.ascontiguousarray(g1, dtype=float).reshape(n2)
    la = int(hold == "linear")
    p_i = _matrix_power(phi, substeps)
    taps = np.zeros((out_every + la, n2))
    _lift_taps(phi, p_i, g0, g1, la, substeps, out_every, taps)
    return _matrix_power(p_i, out_every), taps


@dataclass(frozen=True)
class Exact(SubstepSolver):
    """The exact linear map, ``substeps`` per input interval; ``lift``: step once per output row
    where a row spans more than one substep (the partial last row, if any, per substep);
    ``False`` steps every substep (the same map to round-off, ~out_every times slower)."""

    substeps: int = 1
    lift: bool = True

    name: ClassVar[str] = "linear"
    order: ClassVar[None] = None
    kind: ClassVar[str] = "exact"
    description: ClassVar[str] = ("exact discretisation (matrix exponential) of the linearised "
                                  "model")
    fixed_step: ClassVar[bool] = False

    def refined(self) -> Refinement:
        return Refinement(self.on_grid(2 * self.substeps), 1.0, (
            "|y - y_ref| against the same exact discretisation at dt_s / 2: round-off only; the "
            "linearisation (relative error ~ theta^2) is a model error, not an integrator error, "
            "and is not included"), keep_h0=True)

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, _, _, la = held.kernel_args
        sub, out_every, n_intervals = self.substeps, held.out_every, held.n_intervals
        a, b = chain.state_space()
        phi, g0, g1 = discretise(a, b, held.h_in / sub, held.hold)
        n_full = n_intervals // out_every if self.lift and out_every * sub > 1 else 0
        lifted = 0
        if n_full:
            p_row, taps = lift_linear(phi, g0, g1, held.hold, sub, out_every)
            kernel = lifted_kernel2 if y.size == 4 else lifted_kernel
            status, nrow, i_done = kernel(p_row, taps, ax, out_every, n_full, y, y_out)
            lifted = out_every * sub
            tail = n_intervals - i_done
            if status == OK and tail:  # the partial last output interval, per substep
                part = np.empty((2, y.size))
                status, k, di = linear_kernel(phi, g0, g1, ax[i_done:], la, sub, tail, tail, y,
                                              part)
                y_out[nrow] = part[1]
                nrow, i_done = nrow + k - 1, i_done + di
        else:
            status, nrow, i_done = linear_kernel(phi, g0, g1, ax, la, sub, n_intervals,
                                                 out_every, y, y_out)
        return self.finish(chain, status, y, y_out, nrow, i_done, held, substeps=sub,
                           n_steps=i_done * sub, lifted=lifted)

    def trajectory_settings(self, segs, lifted) -> dict:
        """``linear_step``: how the method stepped (``lifted``: each segment's
        :attr:`rig.solvers.base.Run.lifted`)."""
        if not any(lifted):
            return {"linear_step": "every substep"}
        what = (f"lifted to the output rate: one step of Phi^{max(lifted)} and a FIR of the held "
                "input per output row, Phi the substep's exact discretisation")
        if any(k and sg.n_int % sg.out_every for k, sg in zip(lifted, segs)):
            what += "; the partial last output interval every substep"
        return {"linear_step": what}


# ================================================================================================
# compiled kernels
# ================================================================================================

@njit(cache=True, nogil=True)
def linear_kernel(phi, g0, g1, ax, la, nsub, n_int, out_every, y, y_out):
    """z <- Phi z + Gamma0 u_a + Gamma1 (u_b - u_a) per substep (single input x0'').

    ``phi``, ``g0``, ``g1`` are for the substep h_in / nsub; inside interval i the substep j sees
    the held input at its ends, u_a = u(j/nsub), u_b = u((j+1)/nsub). Returns (status, rows,
    intervals done)."""
    n2 = y.shape[0]
    yt = np.empty(n2)
    frac = 1.0 / nsub
    zero = n_int - n_int  # run-time 0, 1: _NOTE_LITERALS, rig.solvers.primitives
    one = zero + 1
    store(y, y_out, zero)
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
            ok = store(y, y_out, row)
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
    zero = n_rows - n_rows  # see _NOTE_LITERALS (rig.solvers.primitives)
    store(y, y_out, zero)
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
        if not store(y, y_out, k + 1):
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
