"""The exact linear bench: ``z_{k+1} = Phi z_k + Gamma V_k`` per DAC interval (zero-order hold
of the source voltage, Van Loan's ``Phi = e^{A / fs}``), round-off only; what ``acquisition.model
= "linear"`` runs. Kernel: :func:`rig.bench.linear_bench_kernel` (bit-exact for any block split).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.solvers.bench_base import BenchSolver


@dataclass(frozen=True)
class ExactBench(BenchSolver):
    """The exact ZOH step of the linear bench, once per DAC interval."""

    substeps: int = 1

    name: ClassVar[str] = "exact-bench"
    kind: ClassVar[str] = "exact"
    fixed_step: ClassVar[bool] = False
    description: ClassVar[str] = "exact discretisation (ZOH) of the linear bench"

    def check_model(self, model) -> None:  # one step per DAC interval whatever model.substeps
        pass

    def advance_bench(self, model, z, native, v):
        from rig.bench import linear_bench_kernel

        z_out = np.empty((v.size, z.size))
        linear_bench_kernel(np.ascontiguousarray(model.phi.T), model.gamma, v, z, z_out)
        return z_out, None, native  # x0'' = z_out @ model.accel_row, after the finiteness check
