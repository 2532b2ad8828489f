"""What the coupled bench's solvers share: the whole rig (source filter, coil, stage, pendulum,
accelerometer high-pass) stepped as one system ``z' = A z + B V + f(z)`` through the held source
voltage ``V`` (one DAC sample per interval of ``1 / fs``).

A bench solver steps a :class:`rig.bench.BenchModel`, whose build precomputed its matrices at the
model's ``substeps`` (:func:`rig.bench.build_model`), so the solver's ``substeps`` must be the
model's: :meth:`BenchSolver.advance_bench` checks it. ``advance_bench(model, z, native, v)``
steps ``z`` (in place, to the end of the block) over ``len(v)`` DAC intervals and returns
``(z_out, accel, native)``: the states at the DAC instants, the stage acceleration x0'' [m/s^2]
at them (``None`` for the linear bench: ``z_out @ model.accel_row``) and the method's state for
the next block (``None`` where it keeps none).

The rest of the :class:`rig.solvers.base.Solver` protocol is shared: the class attributes
(``order``, ``kind``, ``systems`` = ``(COUPLED_BENCH,)``, ...), ``from_options``, ``on_grid``
and ``refined`` (the Richardson reference that :func:`rig.bench.model_info` uses). ``init`` /
``advance`` are not: they step the pendulum's native state through a :class:`rig.solvers.base.
HeldInput` of base accelerations and return a :class:`rig.solvers.base.Run` of ``(theta,
omega)`` rows, while a bench solver steps the whole bench state ``z`` through held *voltages*
and also returns the stage acceleration; one signature for both would fold ``z`` into the
native state or voltages into the held input, and no caller drives both kinds (``integrate``
the pendulum solvers, :func:`rig.bench.advance` the bench solvers, told apart by ``systems``).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

from rig.errors import ConfigError
from rig.solvers.base import COUPLED_BENCH, Refinement, whole_number


class BenchSolver:
    """Shared behaviour of the coupled-bench solvers."""

    order: ClassVar[int | None] = None
    kind: ClassVar[str] = "exponential"
    symplectic: ClassVar[bool] = False
    native: ClassVar[str] = "none"
    adaptive: ClassVar[bool] = False
    fixed_step: ClassVar[bool] = True
    multisample: ClassVar[bool] = False
    selectable_rhs: ClassVar[bool] = False
    systems: ClassVar[tuple[str, ...]] = (COUPLED_BENCH,)

    def __post_init__(self):
        whole_number("substeps", self.substeps)

    @classmethod
    def from_options(cls, **options):
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in options.items() if k in names})

    def on_grid(self, substeps: int, samples_per_step: int = 1):
        return dataclasses.replace(self, substeps=substeps)

    def refined(self) -> Refinement:
        """The same method at twice the steps per DAC interval (Richardson, order p)."""
        p = self.order
        return Refinement(self.on_grid(2 * self.substeps), 2.0**p / (2.0**p - 1.0),
                          f"Richardson: |theta - theta(2x steps)| 2^{p}/(2^{p} - 1)")

    def check_model(self, model) -> None:
        if model.substeps != self.substeps:
            raise ConfigError(f"{self.name}: the model was built for substeps = "
                              f"{model.substeps}, the solver has {self.substeps}; build the "
                              "model with the solver's substeps (rig.bench.build_model)")
