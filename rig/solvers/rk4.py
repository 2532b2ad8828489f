"""rk4: the classic 4-stage Runge-Kutta method, fixed step (order 4).

Global error O(h^4); the energy drifts secularly (~ t h^4). ``substeps`` equal steps per input
interval; the right-hand side is the n = 2 scalar code, the dense solve or the O(n) recursion
(:func:`rig.solvers.rhs.rhs_algorithm`). Cost: 4 right-hand sides per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from rig.solvers._kernels import ALG_TWO, rk4_kernel, rk4_kernel2
from rig.solvers.base import SubstepSolver
from rig.solvers.rhs import bodies_array, rhs_algorithm


@dataclass(frozen=True)
class RK4(SubstepSolver):
    """Classic RK4 with ``substeps`` steps per input interval (``algorithm``: the right-hand side,
    ``"auto"``, ``"dense"`` or ``"recursive"``)."""

    substeps: int = 1
    algorithm: str = "auto"

    name: ClassVar[str] = "rk4"
    order: ClassVar[int] = 4
    kind: ClassVar[str] = "fixed"
    description: ClassVar[str] = "classic 4-stage Runge-Kutta, fixed step dt_s"
    selectable_rhs: ClassVar[bool] = True

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        alg = rhs_algorithm(chain, self.algorithm)
        ax, ay, sa, la = held.kernel_args
        hc, s, cm, g = chain.H, chain.S, chain.C, chain.g_mps2
        sub = self.substeps
        if alg == ALG_TWO:
            status, nrow, i_done = rk4_kernel2(hc, s, cm, g, ax, ay, sa, la, held.h_in, sub,
                                               held.n_intervals, held.out_every, y, y_out)
        else:
            status, nrow, i_done = rk4_kernel(hc, s, cm, g, bodies_array(chain), alg, ax, ay, sa,
                                              la, held.h_in, sub, held.n_intervals,
                                              held.out_every, y, y_out)
        return self.finish(chain, status, y, y_out, nrow, i_done, held, substeps=sub,
                           n_steps=i_done * sub, n_fev=4 * i_done * sub)
