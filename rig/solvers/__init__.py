"""Integration methods for the chain on a held base input, one module per method.

Every method is a :class:`rig.solvers.base.Solver`: a frozen dataclass of its settings (step,
tolerances) with its order, what it steps, its native state, ``advance`` over a block of held
input and ``refined`` (the reference of its error estimate). :data:`SOLVERS` maps the method names
(``daq simulate --method``, :func:`rig.simulate.simulate`, the bench's prescribed-stage methods,
the benchmarks) to their classes; :func:`integrate` runs one block with any of them.

=========  =====  ===========  ============================================================
name       order  module       what
=========  =====  ===========  ============================================================
rk4        4      rk4          classic Runge-Kutta, fixed step
dop853     8      dop853       Dormand-Prince 8(5,3), adaptive (rtol, atol)
gauss4     4      gauss        2-stage Gauss-Legendre in (theta, p), symplectic
midpoint   2      gauss        implicit midpoint in (theta, p), symplectic
linear     exact  exact        exact discretisation of the linearised chain
etd3       3      etd3         exponential: linear part exact, remainder by Gauss quadrature
etd3m      3      etd3m        etd3 with steps of m whole input samples
etd4m      4      etd4m        etd3m with three Gauss nodes
lawson4    4      lawson4      coupled bench: Lawson RK4, the linear bench exact
etdab      4      etdab        coupled bench: exponential Adams-Bashforth 4 (the default)
=========  =====  ===========  ============================================================

The last two step the coupled bench (:mod:`rig.bench`; its equations in
:mod:`rig.solvers.coupled`), as does
:class:`ExactBench` (the exact linear bench, ``acquisition.model = "linear"``, not a method name);
the others the pendulum on a prescribed base.

Each method's compiled kernels are in its module, the primitives they share in
:mod:`rig.solvers.primitives`; measured accuracies and costs are in
docs/solvers.md.
"""

from __future__ import annotations

import numpy as np

from rig.errors import ConfigError
from rig.solvers.base import (COUPLED_BENCH, HOLDS, PENDULUM, HeldInput, Refinement, Run, Solver,
                              output_rows)
from rig.solvers.dop853 import Dop853
from rig.solvers.etd3 import Etd3
from rig.solvers.etd3m import Etd3m
from rig.solvers.etd4m import Etd4m
from rig.solvers.etdab import Etdab
from rig.solvers.exact import Exact
from rig.solvers.exact_bench import ExactBench
from rig.solvers.gauss import Gauss4, Midpoint
from rig.solvers.lawson4 import Lawson4
from rig.solvers.rk4 import RK4

#: method name -> solver class, in the order the CLI and the documentation list them; a class's
#: ``systems`` says what it steps (PENDULUM: integrate / simulate; COUPLED_BENCH: rig.bench)
SOLVERS: dict[str, type] = {cls.name: cls for cls in (RK4, Dop853, Gauss4, Midpoint, Exact,
                                                      Etd3, Etd3m, Etd4m, Lawson4, Etdab)}


def names_for(system: str) -> list[str]:
    """The registered methods that step ``system`` (PENDULUM or COUPLED_BENCH)."""
    return [name for name, cls in SOLVERS.items() if system in cls.systems]


def solver_named(method: str, **options) -> Solver:
    """``SOLVERS[method]`` with those of ``options`` that are its settings, or ConfigError."""
    if method not in SOLVERS:
        raise ConfigError(f"method = {method!r} is invalid: expected one of {', '.join(SOLVERS)}")
    return SOLVERS[method].from_options(**options)


def integrate(chain, native0, ax, ay, *, hold: str, h_in: float, n_intervals: int,
              out_every: int, solver: Solver, t0_s: float = 0.0,
              h0_s: float = float("nan")) -> Run:
    """Run ``solver`` over ``n_intervals`` held-input intervals of ``h_in`` seconds.

    Parameters
    ----------
    chain : the model (:class:`rig.chain.Chain`).
    native0 : start state in the solver's native form (``solver.init(chain, (theta, omega))``,
        or a previous :attr:`Run.native_end`).
    ax, ay : base accelerations x0'', y0'' [m/s^2] at the sample instants, at least
        ``n_intervals`` (+1 for ``hold="linear"``) samples; ``ay`` may be ``None`` (zero).
    hold : ``"zoh"`` or ``"linear"``.
    h_in : input sample interval [s].
    out_every : output every this many intervals (and at the end).
    solver : a :class:`rig.solvers.base.Solver` (e.g. ``RK4(substeps=4)``).
    t0_s : absolute time of the start [s], only used to report where a divergence happened.
    h0_s : an adaptive solver's proposed first step [s]; ``nan`` selects it.

    Raises
    ------
    ConfigError : too few input samples, a bad hold or a solver setting that does not fit the
        block.
    DivergenceError : a non-finite state at an output instant (reports the last finite output),
        a dop853 step below 10 ulp of the time, or Gauss stage equations that did not converge.
    """
    if not isinstance(solver, Solver) or PENDULUM not in solver.systems:
        raise ConfigError(f"solver = {solver!r} is invalid: expected a rig.solvers solver "
                          f"({', '.join(SOLVERS[m].__name__ for m in names_for(PENDULUM))})")
    held = HeldInput.of(ax, ay, hold=hold, h_in=h_in, n_intervals=n_intervals,
                        out_every=out_every, t0_s=t0_s)
    return solver.advance(chain, np.array(native0, dtype=float), held, h0_s=h0_s)


__all__ = ["SOLVERS", "COUPLED_BENCH", "PENDULUM", "names_for", "HOLDS", "HeldInput", "Refinement",
           "Run", "Solver", "integrate",
           "output_rows", "solver_named", "RK4", "Dop853", "Gauss4", "Midpoint", "Exact", "Etd3",
           "Etd3m", "Etd4m", "Lawson4", "Etdab", "ExactBench"]


from rig.lazy_exports import submodule_getattr  # noqa: E402

__getattr__ = submodule_getattr('rig.solvers')  # a public submodule is an attribute on first use
