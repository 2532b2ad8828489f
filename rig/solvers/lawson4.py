"""lawson4: integrating-factor (Lawson) Runge-Kutta 4 for the coupled bench, order 4.

The linear bench (its stiff coil, the reconstruction filter, the held source voltage) is
propagated exactly by ``e^{A h}`` and ``int e^{A s} B ds``, only the small nonlinear remainder
``f`` by the classical RK4 weights, ``substeps`` steps of ``h = 1 / (fs substeps)`` per DAC
interval: the error is fourth order *in the remainder* (~ theta^2 h^4), independent of the
electrical stiffness. Kernel and equations: :func:`rig.coupled.lawson4_kernel`. Cost ~ 4 O(n)
recursions and 2 dense + 4 thin mat-vecs per step. No state between blocks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.solvers.bench_base import BenchSolver


@dataclass(frozen=True)
class Lawson4(BenchSolver):
    """Lawson RK4 with ``substeps`` steps per DAC interval."""

    substeps: int = 1

    name: ClassVar[str] = "lawson4"
    order: ClassVar[int] = 4
    description: ClassVar[str] = ("Lawson (integrating-factor) RK4 on the coupled bench: the "
                                  "linear bench exact, the nonlinear remainder by RK4")

    def advance_bench(self, model, z, native, v):
        from rig import coupled

        self.check_model(model)
        z_out = np.empty((v.size, z.size))
        accel = np.empty(v.size)
        e_h, e_2, g_h, g_2 = model.lawson
        coupled.lawson4_kernel(*model.coupled.args(), e_h, e_2, g_h, g_2,
                               1.0 / (model.fs_hz * self.substeps), self.substeps, v, z, z_out,
                               accel)
        return z_out, accel, native
