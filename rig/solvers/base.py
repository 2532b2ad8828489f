"""The solver interface: what every method of :mod:`rig.solvers` provides, its input and result.

A solver steps the chain on a prescribed, *held* base input (:class:`HeldInput`): input interval
``k`` is ``[k h_in, (k+1) h_in)`` and inside it the base accelerations are ``u(t_k + s) = u_k``
(``hold="zoh"``) or ``u_k + (u_{k+1} - u_k) s / h_in`` (``hold="linear"``). The input is smooth
inside an interval and may jump at its ends, so every method steps *exactly onto* each sample
instant: fixed-step methods take ``substeps`` equal steps per interval, the adaptive method never
steps across an instant, the multi-sample methods take steps of whole samples. Stage times are
local to the interval, so the result does not depend on the absolute time: block-wise runs
reproduce one-shot runs bit for bit (for the linear method, which steps once per output row, blocks
that end on output rows).

A solver is a frozen dataclass of its settings (step, tolerances); the state it carries between
calls is its *native* state, a flat float vector whose layout :attr:`Solver.native` names
(``theta,omega``; ``theta,p`` with ``p = M(theta) omega`` [kg m^2/s] for the Gauss methods;
``theta,omega,history`` for the exponential methods: theta, omega, a valid flag, the step the
history belongs to [s], then the nonlinear remainder's parts at the previous step's stages).
:meth:`Solver.init` makes it from ``(theta, omega)``, :meth:`Solver.advance` runs one block and
returns it in :attr:`Run.native_end` for the next block, :meth:`Solver.readout` turns native rows
back into ``(theta, omega)``. :meth:`Solver.refined` is the solver the error estimate of
:func:`rig.simulate.simulate` compares with (half the step, a tighter tolerance, ...) and how.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol, runtime_checkable

import numpy as np

from rig.errors import ConfigError, DivergenceError
from rig.solvers.primitives import (NONFINITE, STEP_TOO_SMALL, HeldArgs, momentum_to_omega,
                                    omega_to_momentum)

if TYPE_CHECKING:
    from rig.chain import Chain

HOLDS = ("zoh", "linear")

#: what a solver can step: the pendulum on a prescribed base (rig.solvers), the coupled bench
#: (stage, reaction and pendulum as one system: rig.solvers.coupled, stepped by rig.bench)
PENDULUM, COUPLED_BENCH = "pendulum on a prescribed base", "coupled bench"


@dataclass(frozen=True, eq=False)
class HeldInput:
    """One block of held base input: ``n_intervals`` intervals of ``h_in`` seconds.

    Attributes
    ----------
    ax, ay : base accelerations x0'', y0'' [m/s^2] at the sample instants, C-contiguous float
        arrays of at least ``n_intervals`` (+1 for ``hold="linear"``) samples; ``ay`` is ``None``
        for no vertical input.
    hold : ``"zoh"`` or ``"linear"``.
    h_in : input sample interval [s].
    n_intervals : intervals to step through.
    out_every : output every this many intervals (and at the end).
    t0_s : absolute time of the start [s], only used to report where a divergence happened.
    """

    ax: np.ndarray
    ay: np.ndarray | None
    hold: str
    h_in: float
    n_intervals: int
    out_every: int
    t0_s: float = 0.0

    @classmethod
    def of(cls, ax, ay, *, hold: str, h_in: float, n_intervals: int, out_every: int,
           t0_s: float = 0.0) -> "HeldInput":
        """Check the samples against the block and make them contiguous float arrays."""
        if hold not in HOLDS:
            raise ConfigError(f"hold = {hold!r} is invalid: expected one of {', '.join(HOLDS)}")
        need = n_intervals + (1 if hold == "linear" else 0)
        ax = np.ascontiguousarray(ax, dtype=float)
        if ax.shape[0] < need:
            raise ConfigError(f"ax has {ax.shape[0]} samples; {n_intervals} intervals with hold = "
                              f"{hold!r} need {need}")
        if ay is not None:
            ay = np.ascontiguousarray(ay, dtype=float)
            if ay.shape[0] < need:
                raise ConfigError(f"ay has {ay.shape[0]} samples; {need} are needed")
        return cls(ax, ay, hold, h_in, n_intervals, out_every, t0_s)

    @property
    def kernel_args(self) -> HeldArgs:
        """(ax, ay, sa, la) as the kernels take them: ay a 1-sample dummy with sa = 0 where there
        is no vertical input, la = 1 for the linear hold."""
        use_ay = self.ay is not None
        ay = self.ay if use_ay else np.zeros(1)
        return HeldArgs(self.ax, ay, int(use_ay), int(self.hold == "linear"))

    @property
    def rows(self) -> np.ndarray:
        return output_rows(self.n_intervals, self.out_every)


@dataclass(frozen=True, eq=False)
class Run:
    """Result of one :meth:`Solver.advance` (one :func:`rig.solvers.integrate` call).

    Attributes
    ----------
    y_out : (T, 2n) states (theta [rad], omega [rad/s]) at the output instants (interval counts
        0, out_every, ..., n_intervals).
    native_end : the solver's native state at the end; pass it back as the next block's start to
        continue bit for bit.
    h_next_s : proposed next step of an adaptive method [s] (``nan`` otherwise).
    n_steps, n_rejected, n_fev, n_newton : accepted steps, rejected steps, right-hand-side
        evaluations, Gauss steps that needed Newton (the linear method counts its substeps, also
        where it took them composed, one output row at a time).
    lifted : the linear method's substeps per kernel step where it stepped once per output row
        (:func:`rig.solvers.exact.lift_linear`; out_every * substeps), 0 where it stepped every
        substep.
    """

    y_out: np.ndarray
    native_end: np.ndarray
    h_next_s: float
    n_steps: int
    n_rejected: int
    n_fev: int
    n_newton: int
    lifted: int = 0


@dataclass(frozen=True)
class Refinement:
    """What a solver's error estimate compares with: ``err = |y - y_ref| * scale``.

    Attributes
    ----------
    solver : the reference solver, run over the same segments from the same start state.
    scale : 1 for a reference far more accurate than the run; ``r^p / (r^p - 1)`` for Richardson
        with step ratio r and order p.
    how : one sentence for the trajectory's ``error_method``.
    keep_h0 : start the reference with the run's proposed first step (else it chooses its own).
    """

    solver: "Solver"
    scale: float
    how: str
    keep_h0: bool = False


@runtime_checkable
class Solver(Protocol):
    """One integration method (module docstring). Class attributes describe the method; instance
    fields are its settings."""

    name: ClassVar[str]            # registry key (rig.solvers.SOLVERS)
    order: ClassVar[int | None]    # global order p (error ~ h^p); None for the exact linear map
    kind: ClassVar[str]            # "fixed", "adaptive", "implicit", "exact" or "exponential"
    description: ClassVar[str]
    symplectic: ClassVar[bool]     # symplectic for undamped, unforced chains (bounded energy error)
    native: ClassVar[str]          # layout of the native state (module docstring)
    adaptive: ClassVar[bool]       # chooses its own steps (tolerances, no dt_s)
    fixed_step: ClassVar[bool]     # steps a fixed dt_s that divides the input interval
    multisample: ClassVar[bool]    # a step spans whole input samples (dt_s = m h_in)
    selectable_rhs: ClassVar[bool]  # takes the right-hand-side algorithm (auto/dense/recursive)
    systems: ClassVar[tuple[str, ...]]  # what it steps (PENDULUM, COUPLED_BENCH)

    def init(self, chain: Chain, y) -> np.ndarray:
        """(theta, omega) (2n,) -> the native start state."""

    def advance(self, chain: Chain, native: np.ndarray, held: HeldInput, *,
                h0_s: float = float("nan")) -> Run:
        """Step ``native`` through the block (``h0_s``: an adaptive method's proposed first step,
        ``nan`` to choose it); raises DivergenceError on a non-finite state or a failed step."""

    def readout(self, chain: Chain, rows) -> np.ndarray:
        """Native states (T, >= 2n) -> (theta, omega) (T, 2n)."""

    def on_grid(self, substeps: int, samples_per_step: int) -> "Solver":
        """This solver at ``substeps`` steps per input interval (or ``samples_per_step`` input
        intervals per step for a multi-sample method), as a run's plan sets them."""

    def refined(self) -> Refinement:
        """The reference of the error estimate, for this solver on its grid."""

    def trajectory_settings(self, segs, lifted) -> dict:
        """Method-specific entries of a trajectory's ``settings`` (e.g. how ``linear`` stepped)."""


class PendulumSolver:
    """Shared behaviour of the pendulum solvers (``theta,omega`` or history native states)."""

    order: ClassVar[int | None] = None
    symplectic: ClassVar[bool] = False
    native: ClassVar[str] = "theta,omega"
    adaptive: ClassVar[bool] = False
    fixed_step: ClassVar[bool] = True
    multisample: ClassVar[bool] = False
    selectable_rhs: ClassVar[bool] = False
    systems: ClassVar[tuple[str, ...]] = (PENDULUM,)
    history_rows: ClassVar[int] = 0  # rows of 3n remainder parts in the native history

    @classmethod
    def from_options(cls, **options) -> "PendulumSolver":
        """The solver with those of ``options`` that are its settings (the others ignored)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in options.items() if k in names})

    def init(self, chain: Chain, y) -> np.ndarray:
        y = np.array(y, dtype=float)
        if self.native == "theta,p":
            n = chain.n
            p = np.empty((1, n))
            omega_to_momentum(chain.H, y[None, :n], y[None, n:], p)
            return np.concatenate([y[:n], p[0]])
        if self.history_rows:
            return np.concatenate([y[:2 * chain.n], np.zeros(2 + 3 * self.history_rows * chain.n)])
        return y

    def readout(self, chain: Chain, rows) -> np.ndarray:
        rows = np.asarray(rows, float)
        if self.native != "theta,p":
            return rows[:, :2 * chain.n]
        n = chain.n
        out = rows.copy()
        momentum_to_omega(chain.H, np.ascontiguousarray(rows[:, :n]),
                          np.ascontiguousarray(rows[:, n:]), out[:, n:])
        return out

    def trajectory_settings(self, segs, lifted) -> dict:
        return {}

    def start_from(self, chain: Chain, native, other: "Solver") -> np.ndarray:
        """``other``'s native state as this solver's start (a copy where the layouts agree)."""
        native = np.asarray(native, float)
        if other.native == self.native:
            return native.copy()
        return self.init(chain, other.readout(chain, native[None, :])[0])

    def split_history(self, chain: Chain, y, step_s: float):
        """(z, hist, have) of a history native state: the (theta, omega) part, the remainder
        history (rows, 3n) and whether it belongs to a step of ``step_s`` seconds."""
        n, k = chain.n, self.history_rows
        z = np.ascontiguousarray(y[:2 * n])
        full = y.size == (2 + 3 * k) * n + 2
        meta = y[2 * n:2 * n + 2] if full else np.zeros(2)
        hist = (np.ascontiguousarray(y[2 * n + 2:].reshape(k, 3 * n)) if full
                else np.zeros((k, 3 * n)))
        have = bool(meta[0] == 1.0 and abs(meta[1] - step_s) <= 1e-12 * step_s)
        return z, hist, have

    def out_rows(self, chain: Chain, native: np.ndarray, held: HeldInput) -> np.ndarray:
        """The kernel's output array: native rows, or (theta, omega) for history states."""
        width = 2 * chain.n if self.history_rows else native.size
        return np.empty((output_count(held.n_intervals, held.out_every), width))

    def finish(self, chain: Chain, status: int, y, y_out, nrow: int, i_done: int,
               held: HeldInput, *, s_fail: float = 0.0, substeps: int = 1,
               h_next: float = float("nan"), n_steps: int = 0, n_rejected: int = 0,
               n_fev: int = 0, n_newton: int = 0, lifted: int = 0) -> Run:
        """The kernel's result as a :class:`Run`, or DivergenceError for a failed status."""
        if status != 0:
            raise_divergence(chain, self, status, y, y_out, held.rows, nrow, i_done, s_fail,
                             held.h_in, held.t0_s, substeps)
        return Run(y_out=self.readout(chain, y_out), native_end=y, h_next_s=float(h_next),
                   n_steps=int(n_steps), n_rejected=int(n_rejected), n_fev=int(n_fev),
                   n_newton=int(n_newton), lifted=lifted)


def halved(solver, how: str) -> Refinement:
    """Richardson against ``solver`` at half the step: scale 2^p / (2^p - 1) (p = its order)."""
    p = solver.order
    return Refinement(solver, 2.0**p / (2.0**p - 1.0), how, keep_h0=True)


def multisample_refinement(solver, m: int, halve_one) -> Refinement:
    """The Richardson reference of a multi-sample method at m samples per step: the same method
    at m / 2 (m even, ratio 2) or at one sample per step (m odd, ratio m); ``halve_one()``
    returns the reference for m = 1 (a solver that can take half a sample)."""
    if m == 1:
        return halve_one()
    if m % 2 == 0:
        ref, r, what = (solver.on_grid(1, m // 2), 2,
                        f"the same method at dt_s / 2 ({m // 2} input intervals per step)")
    else:
        ref, r, what = (solver.on_grid(1, 1), m,
                        f"the same method at dt_s / {m} (one input interval per step: m = {m} is "
                        "odd, so dt_s / 2 is not a whole number of samples)")
    return richardson(ref, r, what, solver.order)


def richardson(ref, r: int, what: str, p: int) -> Refinement:
    """Richardson: |y - y_ref| r^p / (r^p - 1) against ``ref`` (``what``) at 1/r of the step."""
    return Refinement(ref, r**p / (r**p - 1.0),
                      f"Richardson: |y - y_ref| * {r}^{p}/({r}^{p} - 1) against {what} (order "
                      f"p = {p}); valid while the error is in its asymptotic range")


def fixed_step_refinement(solver) -> Refinement:
    """The fixed-step methods' estimate: the same run at dt_s / 2."""
    p = solver.order
    return halved(solver.on_grid(2 * solver.substeps, 1),
                  f"Richardson: |y_h - y_h/2| * 2^{p}/(2^{p} - 1) against the same run at "
                  f"dt_s / 2 (order p = {p}); valid while the error is in its asymptotic range")


class SubstepSolver(PendulumSolver):
    """A pendulum solver set by ``substeps`` whole steps per input interval: the count is
    validated, :meth:`on_grid` sets it, and :meth:`refined` is the same run at dt_s / 2
    (:func:`fixed_step_refinement`; a subclass with another estimate overrides it)."""

    substeps: int

    def __post_init__(self):
        whole_number("substeps", self.substeps)

    def on_grid(self, substeps: int, samples_per_step: int = 1):
        return dataclasses.replace(self, substeps=substeps)

    def refined(self) -> Refinement:
        return fixed_step_refinement(self)


def output_count(n_intervals: int, out_every: int) -> int:
    """len(output_rows(n_intervals, out_every)), without forming the rows."""
    return n_intervals // out_every + 1 + (1 if n_intervals % out_every else 0)


def output_rows(n_intervals: int, out_every: int) -> np.ndarray:
    """Interval counts at which states are output: 0, out_every, 2 out_every, ..., and the end."""
    idx = np.arange(0, n_intervals + 1, out_every)
    if idx[-1] != n_intervals:
        idx = np.append(idx, n_intervals)
    return idx


def raise_divergence(chain, solver, status, y, y_out, rows, nrow, i_done, s_fail, h_in, t0_s,
                     substeps):
    """A kernel's failed status as :class:`rig.errors.DivergenceError` with time and state."""
    method = solver.name
    if status == NONFINITE:
        last = nrow - 2  # the row just written is the first non-finite one
        state = solver.readout(chain, y_out[last:last + 1])[0]
        t = t0_s + rows[last] * h_in
        t_bad = t0_s + rows[nrow - 1] * h_in
        raise DivergenceError(
            f"{method}: the state became non-finite between t = {t:.9g} s and {t_bad:.9g} s "
            f"(last finite state at t = {t:.9g} s: theta = {state[:chain.n]}, omega = "
            f"{state[chain.n:]}); reduce the step (dt_s, rtol) or check the input", t, state)
    state = solver.readout(chain, y[None, :])[0]
    t = t0_s + i_done * h_in + s_fail
    if status == STEP_TOO_SMALL:
        raise DivergenceError(
            f"dop853: the step size fell below 10 ulp of the time at t = {t:.9g} s (the solution "
            f"is singular or non-finite there); last accepted state {state}", t, state)
    raise DivergenceError(
        f"{method}: the implicit stage equations did not converge at t = {t:.9g} s with "
        f"dt_s = {h_in / substeps:.6g} s (neither fixed-point iteration nor simplified Newton); "
        f"reduce dt_s. Last state {state}", t, state)


def whole_number(name: str, value, low: int = 1) -> int:
    """An int >= low, or ConfigError naming the value."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ConfigError(f"{name} = {value!r} is invalid: expected a whole number >= {low}")
    return int(value)

