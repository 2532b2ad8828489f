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
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.errors import ConfigError
from rig.solvers._kernels import dop853_kernel
from rig.solvers.base import Refinement, SubstepSolver
from rig.solvers.rhs import bodies_array, rhs_algorithm


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
        ax, ay, sa, la = held.kernel_args
        n_int, h_in = held.n_intervals, held.h_in
        min_step = 10.0 * np.spacing(max(abs(held.t0_s) + n_int * h_in, h_in))
        (status, nrow, i_done, s_fail, h_next, n_steps, n_rej,
         nfev) = dop853_kernel(chain.H, chain.S, chain.C, chain.g_mps2, bodies_array(chain), alg,
                               ax, ay, sa, la, h_in, n_int, held.out_every, y, y_out, self.rtol,
                               self.atol, h0_s, min_step, self.adaptive_steps, self.substeps)
        if not self.adaptive_steps:
            h_next = float("nan")
        return self.finish(chain, status, y, y_out, nrow, i_done, held, s_fail=s_fail,
                           substeps=self.substeps, h_next=h_next, n_steps=n_steps,
                           n_rejected=n_rej, n_fev=nfev)
