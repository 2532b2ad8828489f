"""etdab: exponential Adams-Bashforth for the coupled bench, order 4 (the acquisition's default).

The linear bench exactly (``Phi``, ``Gamma`` at ``h = 1 / (fs substeps)``), the nonlinear remainder
``f`` by the polynomial through its values at the last four nodes integrated against ``e^{A s}``
(weights :func:`rig.coupled.etd_ab_phase_weights`). The nodes are every ``every`` steps: at
every step (``every`` = 1), or, by default where the nonlinearity is weak and the drive's band
allows, every 5 (:func:`rig.bench.model.remainder_every`: the remainder carries the drive's band,
so four nodes 5 ms apart resolve it), the polynomial extrapolated over the steps between. The
native state is those four remainder values (``(4, rows)``; with ``every`` > 1 one more row: the
steps since the newest node), so blocks continue bit for bit; the first steps after a start
build it up. Kernel and equations: :func:`rig.coupled.etd_ab_kernel`, run unrolled for the
matrices' exact-zero pattern (:func:`rig.unrolled.etdab_kernel`: the same values).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.errors import ConfigError
from rig.solvers.base import whole_number
from rig.solvers.bench_base import BenchSolver

ETDAB_ORDER = 4  # past remainder values per step (the order of the method)


@dataclass(frozen=True)
class Etdab(BenchSolver):
    """Exponential Adams-Bashforth 4 with ``substeps`` steps per DAC interval and the remainder
    evaluated at every ``every``-th step (1: every step)."""

    substeps: int = 1
    every: int = 1

    name: ClassVar[str] = "etdab"
    order: ClassVar[int] = ETDAB_ORDER
    description: ClassVar[str] = ("exponential Adams-Bashforth 4 on the coupled bench: the linear "
                                  "bench exact, the remainder by its last four values")
    native: ClassVar[str] = "history"

    def __post_init__(self):
        super().__post_init__()
        whole_number("every", self.every)

    def check_model(self, model) -> None:
        super().check_model(model)
        if model.every != self.every:
            raise ConfigError(f"{self.name}: the model was built for every = {model.every}, the "
                              f"solver has {self.every}; build the model with the solver's every "
                              "(rig.bench.build_model)")

    def advance_bench(self, model, z, native, v):
        """The native state: the remainder at the last ``ETDAB_ORDER`` nodes (newest first,
        one row each); with ``every`` > 1 one more row, the steps since the newest node."""
        from rig import unrolled

        self.check_model(model)
        z_out = np.empty((v.size, z.size))
        accel = np.empty(v.size)
        nf = model.coupled.rows.size
        phase = np.zeros(1, dtype=np.int64)
        if native is None:
            hist = np.zeros((ETDAB_ORDER, nf))
        else:
            native = np.array(native, dtype=float)
            hist = np.ascontiguousarray(native[:ETDAB_ORDER])
            if self.every > 1:
                phase[0] = int(native[ETDAB_ORDER, 0])
        kernel = unrolled.etdab_kernel(*model.etdab[:3], hist.shape[0], model.coupled.n)
        kernel(*model.coupled.args(), *model.etdab, self.substeps, native is not None, hist,
               phase, v, z, z_out, accel)
        if self.every > 1:
            hist = np.vstack([hist, np.full((1, nf), float(phase[0]))])
        return z_out, accel, hist
