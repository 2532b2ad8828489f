"""The exact linear bench: ``z_{k+1} = Phi z_k + Gamma V_k`` per DAC interval (zero-order hold
of the source voltage, Van Loan's ``Phi = e^{A / fs}``), round-off only; what ``acquisition.model
= "linear"`` runs. Kernel: :func:`linear_bench_kernel` (bit-exact for any block split).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.jit import njit
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
        z_out = np.empty((v.size, z.size))
        linear_bench_kernel(np.ascontiguousarray(model.phi.T), model.gamma, v, z, z_out)
        return z_out, None, native  # x0'' = z_out @ model.accel_row, after the finiteness check


@njit(cache=True, nogil=True)
def linear_bench_kernel(phi_t, gamma, v, z, z_out):
    """z_out[k] = z_k, z_{k+1} = phi z_k + gamma v_k for k < len(v) (>= 1); z (in/out) ends at
    z_N; ``phi_t`` is phi transposed (C order).

    Row r of z_{k+1} is summed as ``gamma[r] v_k + phi[r, 0] z_k[0] + phi[r, 1] z_k[1] + ...`` in
    that order whatever the block split (bit-exact blocks); the loop runs over columns outside and
    rows inside, so the rows' independent sums proceed together in vector registers (faster than a
    row-by-row dot product, with the same rounding; docs/benchmarks/history.md)."""
    nz = z.shape[0]
    n = v.shape[0]
    for r in range(nz):
        z_out[0, r] = z[r]
    for k in range(n - 1):
        vk = v[k]
        for r in range(nz):
            z_out[k + 1, r] = gamma[r] * vk
        for c in range(nz):
            zc = z_out[k, c]
            for r in range(nz):
                z_out[k + 1, r] += phi_t[c, r] * zc
    vk = v[n - 1]
    for r in range(nz):
        z[r] = gamma[r] * vk
    for c in range(nz):
        zc = z_out[n - 1, c]
        for r in range(nz):
            z[r] += phi_t[c, r] * zc
