"""etdab: exponential Adams-Bashforth for the coupled bench, order 4 (the acquisition's default).

The linear bench exactly (``Phi``, ``Gamma`` at ``h = 1 / (fs substeps)``), the nonlinear remainder
``f`` by the polynomial through its values at the last four steps integrated against ``e^{A s}``
(weights :func:`rig.coupled.etd_ab_weights`): one remainder evaluation per step. The native state
is those four past remainder values (``(4, rows)``), so blocks continue bit for bit; the first
steps after a start build it up. Kernel and equations: :func:`rig.coupled.etd_ab_kernel`, run
unrolled for the matrices' exact-zero pattern (:func:`rig.unrolled.etdab_kernel`: the same values).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.solvers.bench_base import BenchSolver

ETDAB_ORDER = 4  # past remainder values per step (the order of the method)


@dataclass(frozen=True)
class Etdab(BenchSolver):
    """Exponential Adams-Bashforth 4 with ``substeps`` steps per DAC interval."""

    substeps: int = 1

    name: ClassVar[str] = "etdab"
    order: ClassVar[int] = ETDAB_ORDER
    description: ClassVar[str] = ("exponential Adams-Bashforth 4 on the coupled bench: the linear "
                                  "bench exact, the remainder by its last four values")
    native: ClassVar[str] = "history"

    def advance_bench(self, model, z, native, v):
        from rig import unrolled

        self.check_model(model)
        z_out = np.empty((v.size, z.size))
        accel = np.empty(v.size)
        hist = (np.zeros((ETDAB_ORDER, model.coupled.rows.size)) if native is None
                else np.array(native, dtype=float))
        kernel = unrolled.etdab_kernel(*model.etdab[:3], hist.shape[0], model.coupled.n)
        kernel(*model.coupled.args(), *model.etdab, self.substeps, native is not None, hist, v, z,
               z_out, accel)
        return z_out, accel, hist
