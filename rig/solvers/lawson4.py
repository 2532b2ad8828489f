"""lawson4: integrating-factor (Lawson) Runge-Kutta 4 for the coupled bench, order 4.

The linear bench (its stiff coil, the reconstruction filter, the held source voltage) is
propagated exactly by ``e^{A h}`` and ``int e^{A s} B ds``, only the small nonlinear remainder
``f`` by the classical RK4 weights, ``substeps`` steps of ``h = 1 / (fs substeps)`` per DAC
interval: the error is fourth order *in the remainder* (~ theta^2 h^4), independent of the
electrical stiffness. Kernel: :func:`lawson4_kernel`; equations: :mod:`rig.solvers.coupled`.
Cost ~ 4 O(n) recursions and 2 dense + 4 thin mat-vecs per step. No state between blocks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.jit import njit
from rig.linear import van_loan
from rig.solvers.bench_base import BenchSolver
from rig.solvers.coupled import arg_groups, kernel_scratch, remainder_at


@dataclass(frozen=True)
class Lawson4(BenchSolver):
    """Lawson RK4 with ``substeps`` steps per DAC interval."""

    substeps: int = 1

    name: ClassVar[str] = "lawson4"
    order: ClassVar[int] = 4
    description: ClassVar[str] = ("Lawson (integrating-factor) RK4 on the coupled bench: the "
                                  "linear bench exact, the nonlinear remainder by RK4")

    def advance_bench(self, model, z, native, v):
        self.check_model(model)
        z_out = np.empty((v.size, z.size))
        accel = np.empty(v.size)
        e_h, e_2, g_h, g_2 = model.lawson
        lawson4_kernel(model.coupled.args(), e_h, e_2, g_h, g_2,
                       1.0 / (model.fs_hz * self.substeps), self.substeps, v, z, z_out, accel)
        return z_out, accel, native


# ================================================================================================
# compiled kernels
# ================================================================================================

def lawson_matrices(a: np.ndarray, b: np.ndarray, h: float):
    """(E_h, E_{h/2}, G_h, G_{h/2}): ``e^{A t}`` and ``int_0^t e^{A s} ds B`` (B one column) at
    t = h and h / 2, from one Van Loan exponential each."""
    nz = a.shape[0]
    out = []
    for t in (h, h / 2):
        e = van_loan(a, np.asarray(b, float)[:, :1], t, ramp=False)
        out.append((np.ascontiguousarray(e[:nz, :nz]), np.ascontiguousarray(e[:nz, nz])))
    (e_h, g_h), (e_2, g_2) = out
    return e_h, e_2, g_h, g_2


@njit(cache=True, nogil=True, error_model="numpy")
def lawson4_kernel(prm, e_h, e_2, g_h, g_2, h, nsub, v, z, z_out, ax_out):
    """Lawson RK4 (module docstring) over len(v) DAC intervals, ``nsub`` steps of ``h`` each.

    z_out[k] = z and ax_out[k] = x0'' at DAC instant k (k < len(v)); ``z`` (in/out) ends at the
    instant len(v). Every row is summed in a fixed order, so block splits reproduce one-shot runs
    bit for bit. ``prm``: :class:`rig.solvers.coupled.CoupledArgs`."""
    n, two, nz, nf, work, alpha = kernel_scratch(prm, z)
    dense, bodies, stage = arg_groups(prm)
    th0, q_idx, wc, a_rows, rows = prm.th0, prm.q_idx, prm.wc, prm.a_rows, prm.rows
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
            ax = remainder_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, z, work,
                              alpha, f1)
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
            ax = remainder_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, zt, work,
                              alpha, f2)
            # stage 3
            for r in range(nz):
                zt[r] = p2[r]
            for i in range(nf):
                zt[rows[i]] += 0.5 * h * f2[i]
            ax = remainder_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, zt, work,
                              alpha, f3)
            # stage 4
            for r in range(nz):
                acc = 0.0
                for i in range(nf):
                    acc += e_2[r, rows[i]] * f3[i]
                zt[r] = ph[r] + h * acc
            ax = remainder_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, zt, work,
                              alpha, f4)
            # the step
            for r in range(nz):
                acc = 0.0
                for i in range(nf):
                    acc += e_h[r, rows[i]] * f1[i] + 2.0 * e_2[r, rows[i]] * (f2[i] + f3[i])
                z[r] = ph[r] + (h / 6.0) * acc
            for i in range(nf):
                z[rows[i]] += (h / 6.0) * f4[i]
