"""gauss4 and midpoint: Gauss-Legendre collocation in (theta, p = M omega), fixed step.

gauss4 is the 2-stage method (order 4), midpoint the 1-stage one (implicit midpoint, order 2).
Both are symplectic: for undamped, unforced runs the energy error is O(h^p) and bounded (no
drift). The stage equations are solved to round-off by fixed-point iteration, then simplified
Newton where that stalls (:data:`rig.solvers._kernels.GAUSS_MAX_FIXED_POINT`); a step where
neither converges raises :class:`rig.errors.DivergenceError` naming dt_s. The native state is
(theta, p) [rad, kg m^2/s].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.solvers._kernels import (GAUSS4_A, GAUSS4_B, GAUSS4_C, MIDPOINT_A, MIDPOINT_B,
                                  MIDPOINT_C, gauss_kernel)
from rig.solvers.base import SubstepSolver


class _Gauss(SubstepSolver):
    symplectic: ClassVar[bool] = True
    native: ClassVar[str] = "theta,p"
    kind: ClassVar[str] = "implicit"
    tableau: ClassVar[tuple[np.ndarray, np.ndarray, np.ndarray]]

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, ay, sa, la = held.kernel_args
        sub = self.substeps
        status, nrow, i_done, s_fail, nfev, n_newton = gauss_kernel(
            chain.H, chain.S, chain.C, chain.g_mps2, ax, ay, sa, la, held.h_in, sub,
            held.n_intervals, held.out_every, y, y_out, *self.tableau)
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
