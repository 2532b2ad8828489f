"""linear: the exact discretisation of the *linearised* chain for the held input.

``z_{k+1} = Phi z_k + Gamma0 u_k + Gamma1 (u_{k+1} - u_k)`` per substep (:func:`discretise`, Van
Loan's block exponential); only round-off error (the linearisation is a model error, ~ theta^3;
the vertical input y0'' drops out of it at first order). Where an output row spans L > 1
substeps the recursion is composed into one step per row (Phi^L and a FIR of the row's input
samples, :func:`lift_linear`). Cost: one (2n x 2n) mat-vec per substep, or per output row lifted.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.solvers._kernels import OK, _lift_taps, lifted_kernel, lifted_kernel2, linear_kernel
from rig.solvers.base import Refinement, SubstepSolver


# ================================================================================================
# exact discretisation of the linear model
# ================================================================================================

def discretise(a, b, h, hold="zoh"):
    """Exact discretisation of z' = A z + B u over one step h for a held input (Van Loan).

    With ``u(t_k + s) = u_k + (u_{k+1} - u_k) s / h`` (``linear``; ``zoh`` drops the second term)::

        z_{k+1} = Phi z_k + Gamma0 u_k + Gamma1 (u_{k+1} - u_k)
        Phi = e^{A h},  Gamma0 = int_0^h e^{A r} dr B,  Gamma1 = int_0^h e^{A (h - r)} B r / h dr

    all read off ``expm([[A h, B h, 0], [0, 0, I], [0, 0, 0]]) = [[Phi, Gamma0, Gamma1], ...]``.
    No one-sample delay and no start-up transient are introduced (unlike ``zpk2sos`` of a hold
    model or ``dlsim`` with first-order hold from a zero state).

    Returns (Phi (N, N), Gamma0 (N, m), Gamma1 (N, m)); Gamma1 is zero for ``zoh``.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    nz, m = b.shape
    big = np.zeros((nz + 2 * m, nz + 2 * m))
    big[:nz, :nz] = a * h
    big[:nz, nz:nz + m] = b * h
    big[nz:nz + m, nz + m:] = np.eye(m)
    import scipy.linalg

    e = scipy.linalg.expm(big)
    phi = e[:nz, :nz].copy()
    g0 = e[:nz, nz:nz + m].copy()
    g1 = e[:nz, nz + m:].copy() if hold == "linear" else np.zeros_like(g0)
    return phi, g0, g1


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
