"""Simulate the chain on its base: held base input -> integrator -> trajectory + error estimate.

The true base acceleration (SPEC section 8)
-------------------------------------------
The analyzer's source is a DAC: :class:`BaseInput` holds its samples ``ax[k]`` (and optionally a
vertical ``ay[k]``) at ``t_k = k dt_s``, and the *held* continuous signal they define is, by
definition here, the stage's true acceleration x0''(t) (y0''(t)): with ``hold="zoh"`` the staircase
``x0''(t) = ax[k]`` on ``[t_k, t_{k+1})``, with ``hold="linear"`` the straight line between samples.
Everything downstream (the pendulum here; a stage model later) is continuous and sees that held
signal; the samples alone are not the acceleration. Holding versus interpolating the same samples
changes the response by ~1 % RMS (SPEC section 8), far more than integrator error, so the choice
is part of the model and is recorded with every trajectory. Every integrator steps exactly onto
each sample instant.

Public API: :class:`BaseInput`, :class:`SimState`, :class:`Trajectory`, :func:`simulate`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rig.validation import positive
from rig.chain import Chain
from rig.errors import ConfigError
from rig.readonly import readonly
from rig.solvers import HOLDS, PENDULUM, integrate, names_for, output_rows, solver_named
from rig.solvers.rhs import rhs_algorithm

STEPS_PER_PERIOD = 100  # default fixed-step resolution: steps per period of the fastest linear mode
_REL = 1e-9  # tolerance for "a whole number of" checks on times


def _whole(name: str, value: float, unit_name: str, unit: float) -> int:
    """value / unit as an integer >= 1, or ConfigError naming both."""
    r = value / unit
    k = int(round(r))
    if k < 1 or abs(r - k) > _REL * max(1.0, r):
        raise ConfigError(f"{name} = {value!r} s is invalid: expected a whole multiple (>= 1) of "
                          f"{unit_name} = {unit!r} s (the ratio is {r:.9g})")
    return k


def _divides(name: str, value: float, big_name: str, big: float) -> int:
    """big / value as an integer >= 1, or ConfigError saying value must divide big."""
    r = big / value
    k = int(round(r))
    if k < 1 or abs(r - k) > _REL * max(1.0, r):
        raise ConfigError(f"{name} = {value!r} s is invalid: it must divide {big_name} = {big!r} s "
                          f"a whole number of times (the ratio is {r:.9g}); integrator steps are "
                          "aligned to the input sample instants")
    return k


@dataclass(frozen=True, eq=False)
class BaseInput:
    """Base (stage) accelerations from a DAC, sampled at ``t_k = k dt_s`` and held.

    Parameters
    ----------
    ax_mps2 : (N,) horizontal base acceleration samples x0'' [m/s^2], positive toward +x.
    dt_s : sample interval [s], > 0.
    hold : ``"zoh"``: ``ax[k]`` held on ``[t_k, t_{k+1})`` (a DAC; N samples cover N intervals);
        ``"linear"``: straight lines between samples (N samples cover N - 1 intervals).
    ay_mps2 : optional (N,) vertical base acceleration y0'' [m/s^2], y up (``None``: zero).

    Notes
    -----
    The held continuous signal is the true base acceleration (module docstring). For block-wise
    runs, consecutive blocks of a ``linear`` input share their boundary sample (:meth:`block`).
    """

    ax_mps2: np.ndarray
    dt_s: float
    hold: str = "zoh"
    ay_mps2: np.ndarray | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "dt_s", positive("dt_s", self.dt_s))
        if self.hold not in HOLDS:
            raise ConfigError(f"hold = {self.hold!r} is invalid: expected one of "
                              f"{', '.join(HOLDS)}")
        set_(self, "ax_mps2", self._samples("ax_mps2", self.ax_mps2))
        if self.ay_mps2 is not None:
            ay = self._samples("ay_mps2", self.ay_mps2)
            if ay.shape != self.ax_mps2.shape:
                raise ConfigError(f"ay_mps2 has {ay.size} samples; expected {self.ax_mps2.size} "
                                  "(one per ax_mps2 sample)")
            set_(self, "ay_mps2", ay)

    def _samples(self, name, values) -> np.ndarray:
        try:
            a = np.array(values, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"{name} is invalid: expected a 1-D sequence of numbers") from None
        if a.ndim != 1:
            raise ConfigError(f"{name} has shape {a.shape}: expected a 1-D sequence of samples")
        need = 2 if self.hold == "linear" else 1
        if a.size < need:
            raise ConfigError(f"{name} has {a.size} samples: hold = {self.hold!r} needs >= {need}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ConfigError(f"{name}[{bad[0]}] = {a[bad[0]]} is invalid: every sample must be "
                              "finite")
        return readonly(a)

    @property
    def n_intervals(self) -> int:
        """Number of held intervals the samples define."""
        return self.ax_mps2.size - (1 if self.hold == "linear" else 0)

    @property
    def duration_s(self) -> float:
        """Time covered by the held signal [s]."""
        return self.n_intervals * self.dt_s

    def block(self, start: int, stop: int) -> "BaseInput":
        """The input over intervals ``start .. stop - 1`` (a ``linear`` block includes sample
        ``stop``, shared with the next block)."""
        if not 0 <= start < stop <= self.n_intervals:
            raise ConfigError(f"block({start}, {stop}) is invalid: expected 0 <= start < stop <= "
                              f"{self.n_intervals}")
        end = stop + (1 if self.hold == "linear" else 0)
        ay = None if self.ay_mps2 is None else self.ay_mps2[start:end]
        return BaseInput(self.ax_mps2[start:end], self.dt_s, self.hold, ay)


@dataclass(frozen=True, eq=False)
class SimState:
    """Everything a run hands to the next block (``simulate(..., start=state)``).

    Attributes
    ----------
    t_s : time [s].
    theta_rad, omega_rad_s : (n,) angles [rad] and angular velocities [rad/s].
    method : the method that produced it.
    native : (2n,) that method's own state (``theta, omega`` or ``theta, p`` [kg m^2/s]); used
        as is when the next block uses the same method, so blocks reproduce one-shot runs bit for
        bit.
    h_next_s : the adaptive method's proposed next step [s] (``nan`` if none).
    """

    t_s: float
    theta_rad: np.ndarray
    omega_rad_s: np.ndarray
    method: str
    native: np.ndarray
    h_next_s: float = float("nan")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulated run, sampled at the output instants.

    Attributes
    ----------
    t_s : (T,) output times [s].
    theta_rad, omega_rad_s : (T, n) angles [rad] and angular velocities [rad/s].
    chain : the simulated chain.
    energy_j : (T,) mechanical energy in the base frame, 1/2 w^T M w - g sum S cos th [J]
        (conserved for a fixed, undamped base); computed when first read.
    method : integrator name (:data:`rig.solvers.SOLVERS`).
    settings : the resolved settings (steps, tolerances, output and input intervals, hold;
        for the linear method ``linear_step``: whether it stepped once per output row).
    n_steps, n_rejected, n_fev : accepted steps, rejected steps, right-hand-side evaluations of
        the main run.
    n_newton : Gauss steps whose stage equations needed Newton (fixed-point iteration did not
        contract); 0 for other methods.
    wall_time_s : wall-clock time of the main run [s] (excluding the error estimate).
    error_estimate_rad, error_estimate_rad_s : (T, n) estimated absolute error of theta [rad] and
        omega [rad/s] accumulated since the start of this run, or ``None``.
    energy_error_estimate_j : (T,) the same estimate applied to the energy [J] (for a fixed,
        undamped base the energy is conserved, so this is the expected |E(t) - E(0)|), or
        ``None``.
    error_method : a sentence saying how the estimate was obtained.
    estimate_wall_time_s : wall-clock time spent on the estimate [s].
    final_state : :class:`SimState` at the end, to continue with.
    warnings : sentences saying why the result should not be trusted as it is
        (:func:`rig.sim_checks.simulation_warnings`; empty if none).
    """

    t_s: np.ndarray
    theta_rad: np.ndarray
    omega_rad_s: np.ndarray
    chain: Chain = field(repr=False)
    method: str
    settings: dict
    n_steps: int
    n_rejected: int
    n_fev: int
    n_newton: int
    wall_time_s: float
    error_estimate_rad: np.ndarray | None
    error_estimate_rad_s: np.ndarray | None
    energy_error_estimate_j: np.ndarray | None
    error_method: str
    estimate_wall_time_s: float
    final_state: SimState = field(repr=False)
    warnings: tuple = ()

    @functools.cached_property
    def energy_j(self) -> np.ndarray:
        """(T,) mechanical energy in the base frame [J] (computed on first use: for a long
        linear run it costs as much as the run itself)."""
        return readonly(np.asarray(self.chain.energy(self.theta_rad, self.omega_rad_s), float))

    @property
    def max_error_rad(self) -> float:
        """Largest estimated angle error over the run [rad] (``nan`` if not estimated)."""
        if self.error_estimate_rad is None:
            return float("nan")
        return float(np.max(self.error_estimate_rad))


@dataclass(frozen=True)
class _Segment:
    ax: np.ndarray
    ay: np.ndarray | None
    hold: str
    h_in: float
    n_int: int
    out_every: int
    substeps: int
    per_step: int = 1  # input intervals per step (etd3m; 1 for every other method)


def _vector(name: str, value, n: int) -> np.ndarray:
    try:
        v = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} = {value!r} is invalid: expected {n} numbers") from None
    if v.size == 1 and n > 1:
        v = np.full(n, v[0])
    if v.size != n:
        raise ConfigError(f"{name} has {v.size} entries; expected {n} (one per body)")
    if not np.all(np.isfinite(v)):
        raise ConfigError(f"{name} = {v.tolist()} is invalid: every entry must be finite")
    return v


def _default_substeps(chain: Chain, h: float) -> int:
    f_max = float(np.max(chain.natural_frequencies_hz()))
    return max(1, math.ceil(h * STEPS_PER_PERIOD * f_max - 1e-9))


def _samples_per_step(chain, dt_s, h_in, every, n_int, method="etd3m") -> int:
    """etd3m: input intervals per step, m (dt_s = m h_in), dividing the output interval and the
    run; default the largest such m with m h_in <= 1 / (STEPS_PER_PERIOD f_max)."""
    ok = [k for k in range(1, every + 1) if every % k == 0 and n_int % k == 0]
    if dt_s is None:
        f_max = float(np.max(chain.natural_frequencies_hz()))
        return max([k for k in ok if k * h_in * STEPS_PER_PERIOD * f_max <= 1.0 + _REL] or [1])
    r = dt_s / h_in
    m = int(round(r))
    if m < 1 or abs(r - m) > _REL * max(1.0, r) or m not in ok:
        raise ConfigError(
            f"dt_s = {dt_s!r} s is invalid for {method}: a step spans whole input samples, so dt_s "
            f"must be a whole multiple of base.dt_s = {h_in!r} s (the ratio is {r:.9g}) that "
            f"divides the output interval ({every} samples) and the run ({n_int} samples); "
            f"valid: {', '.join(f'{k * h_in:.6g}' for k in ok)} s")
    return m


def _plan(chain, duration, base, solver, dt_s, output_dt_s) -> tuple[list[_Segment], dict]:
    """Split the run into held-input segments the kernels step through."""
    multisample = solver.name if solver.multisample else ""
    if multisample and base is None:
        raise ConfigError(f"base = None is invalid for {multisample}: its steps span whole held "
                          "input samples; give a BaseInput, or use etd3 on a fixed base")
    if base is not None:
        h_in = base.dt_s
        n_int = _whole("duration_s", duration, "base.dt_s", h_in)
        if n_int > base.n_intervals:
            raise ConfigError(f"duration_s = {duration!r} s is invalid: the base input covers only "
                              f"{base.duration_s!r} s ({base.n_intervals} intervals of {h_in} s, "
                              f"hold = {base.hold!r})")
        if multisample:
            sub = 1
        elif dt_s is not None:
            sub = _divides("dt_s", dt_s, "the input interval base.dt_s", h_in)
        elif solver.fixed_step:
            sub = _default_substeps(chain, h_in)
        else:
            sub = 1
        if output_dt_s is not None:
            every = _whole("output_dt_s", output_dt_s, "base.dt_s", h_in)
        else:
            every = max(1, int(math.floor(1.0 / h_in + _REL)))
        m = (_samples_per_step(chain, dt_s, h_in, every, n_int, multisample) if multisample
             else 1)
        need = n_int + (1 if base.hold == "linear" else 0)
        ay = None if base.ay_mps2 is None else base.ay_mps2[:need]
        segs = [_Segment(base.ax_mps2[:need], ay, base.hold, h_in, n_int, every, sub, m)]
        info = dict(input_dt_s=h_in, hold=base.hold, output_dt_s=every * h_in,
                    dt_s=(h_in / sub if not solver.adaptive else None), substeps_per_input=sub)
        if multisample:
            info.update(dt_s=m * h_in, substeps_per_input=None, samples_per_step=m)
        return segs, info

    if solver.fixed_step or (not solver.adaptive and dt_s is not None):
        if dt_s is None:
            per_s = STEPS_PER_PERIOD * float(np.max(chain.natural_frequencies_hz()))
            out = 1.0 if output_dt_s is None else output_dt_s
            rows = round(duration / out)
            if rows >= 1 and abs(duration - rows * out) <= _REL * duration:
                # the output interval (default 1 s) split into equal steps: a sample lands on
                # every output instant (every whole second)
                dt = out / math.ceil(out * per_s - 1e-9)
            else:
                dt = duration / math.ceil(duration * per_s - 1e-9)
        else:
            dt = dt_s
        total = _divides("dt_s", dt, "duration_s", duration)
        if output_dt_s is not None:
            per_out = _whole("output_dt_s", output_dt_s, "dt_s", dt)
        else:
            per_out = max(1, int(math.floor(1.0 / dt + _REL)))
        n_full, rem = divmod(total, per_out)
        segs = []
        if n_full:
            segs.append(_Segment(np.zeros(n_full + 1), None, "zoh", per_out * dt, n_full, 1,
                                 per_out))
        if rem:
            segs.append(_Segment(np.zeros(2), None, "zoh", rem * dt, 1, 1, rem))
        return segs, dict(input_dt_s=None, hold=None, output_dt_s=per_out * dt, dt_s=dt,
                          substeps_per_input=None)

    out = 1.0 if output_dt_s is None else output_dt_s
    n_full = int(math.floor(duration / out + _REL))
    rem = duration - n_full * out
    segs = []
    if n_full:
        segs.append(_Segment(np.zeros(n_full + 1), None, "zoh", out, n_full, 1, 1))
    if rem > _REL * out:
        segs.append(_Segment(np.zeros(2), None, "zoh", rem, 1, 1, 1))
    return segs, dict(input_dt_s=None, hold=None, output_dt_s=out, dt_s=None,
                      substeps_per_input=None)


def _execute(chain, segs, solvers, native0, t0, h0):
    """Run the segments in turn, segment k with ``solvers[k]``; returns (y_out (T, 2n),
    native_end, h_next, counts, lifted) with ``lifted`` each segment's
    :attr:`rig.solvers.base.Run.lifted`."""
    y = native0
    h = h0
    rows = []
    lifted = []
    n_steps = n_rej = n_fev = n_newton = 0
    t = t0
    for k, (sg, solver) in enumerate(zip(segs, solvers)):
        run = integrate(chain, y, sg.ax, sg.ay, hold=sg.hold, h_in=sg.h_in, n_intervals=sg.n_int,
                        out_every=sg.out_every, solver=solver, h0_s=h, t0_s=t)
        rows.append(run.y_out if k == 0 else run.y_out[1:])
        y, h = run.native_end, run.h_next_s
        n_steps += run.n_steps
        n_rej += run.n_rejected
        n_fev += run.n_fev
        n_newton += run.n_newton
        lifted.append(run.lifted)
        t += sg.n_int * sg.h_in
    y_out = rows[0] if len(rows) == 1 else np.concatenate(rows)
    return y_out, y, h, (n_steps, n_rej, n_fev, n_newton), lifted


def _times(segs, t0, duration) -> np.ndarray:
    parts = []
    for k, sg in enumerate(segs):
        if k == 0:
            k0 = round(t0 / sg.h_in)
            if abs(k0 * sg.h_in - t0) <= _REL * sg.h_in:  # keep times exact multiples of h_in
                # (k0 + row) h_in, the whole numbers added exactly in floats, in place: one
                # array for a long run's rows, not three
                t = output_rows(sg.n_int, sg.out_every).astype(float)
                t += k0
                t *= sg.h_in
                parts.append(t)
            else:
                parts.append(t0 + output_rows(sg.n_int, sg.out_every) * sg.h_in)
        else:
            parts.append(np.array([t0 + duration]))
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def simulate(chain: Chain, duration_s: float, *, theta0=None, omega0=None,
             base: BaseInput | None = None, method: str = "dop853", rtol: float = 1e-10,
             atol: float = 1e-12, dt_s: float | None = None, output_dt_s: float | None = None,
             estimate_error: bool = True, start: SimState | None = None,
             algorithm: str = "auto") -> Trajectory:
    """Integrate the chain for ``duration_s`` seconds on a fixed or held-input moving base.

    Parameters
    ----------
    chain : the model (:class:`rig.chain.Chain`).
    duration_s : simulated time [s], finite > 0; with ``base`` a whole number of input intervals
        within the input; without ``base`` and a fixed-step method, a whole number of ``dt_s``.
    theta0, omega0 : initial angles [rad] and angular velocities [rad/s] (n each, or one number
        for every body; ``omega0`` defaults to 0). Give these or ``start``.
    base : held base acceleration (:class:`BaseInput`); ``None`` is a fixed base.
    method : ``"dop853"`` (default), ``"rk4"``, ``"gauss4"``, ``"midpoint"``, ``"linear"`` or
        ``"etd3"``, ``"etd3m"`` or ``"etd4m"`` (:data:`rig.solvers.SOLVERS`; etd3 for weakly
        nonlinear runs, e.g. the paper's pendulum on a random base: the linearised chain exactly,
        only the nonlinear remainder integrated; etd3m the same with steps spanning several held
        input samples, for a base input only; etd4m as etd3m with three nodes, order 4).
    rtol, atol : dop853 tolerances, rtol in (0, 1), atol > 0 [rad, rad/s per component].
    dt_s : step [s] of the fixed-step methods (rk4, gauss4, midpoint, etd3; linear substeps); must
        divide the input interval (on a fixed base: the duration). Default for those: the
        input interval split into equal steps of at most 1/(100 f_max), f_max the fastest linear
        mode (on a fixed base: the longest such step dividing the output interval, so a
        sample lands on every output instant, where the run is a whole number of output
        intervals; else dividing the duration); the linear method
        steps once per interval, composed into one step per output row where a row spans several
        (``settings["linear_step"]``; :func:`rig.solvers.exact.lift_linear`). Not accepted for
        dop853, which chooses its own steps. etd3m, etd4m: a whole multiple m of the input interval
        dividing the output interval and the run (the step spans m held samples; default: the
        largest such m with m base.dt_s <= 1/(100 f_max); ``settings["samples_per_step"]``).
    output_dt_s : output interval [s], a whole multiple of the input interval (of ``dt_s`` for a
        fixed-step method on a fixed base). Default: the largest multiple of the input interval
        not over 1 s (every input sample if that is over 1 s); on a fixed base 1 s (and the end).
        The last sample is always at the end of the run.
    estimate_error : run the cheap error estimate (below).
    start : continue from a previous run's :attr:`Trajectory.final_state` instead of
        ``theta0``/``omega0`` (same method: bit for bit as one longer run; the next block's input
        starts at this state's time).
    algorithm : right-hand side of rk4 and dop853: ``"auto"`` (default: scalar code for n = 2,
        the O(n) articulated-body recursion from
        :data:`rig.solvers.primitives.RECURSIVE_FROM_N` bodies),
        ``"dense"`` (mass-matrix Cholesky solve, O(n^3)) or ``"recursive"``; the same equations
        (tests: equal to round-off).

    Returns
    -------
    Trajectory, with an error estimate of the angles and angular velocities accumulated over this
    run: fixed-step methods: Richardson against the same run at dt_s / 2,
    ``err = |y_h - y_{h/2}| 2^p / (2^p - 1)``; dop853: ``|y - y_ref|`` against a run with
    rtol / 100, atol / 100 and at least two steps per input interval; linear: ``|y - y_ref|``
    against a run at dt_s / 2 (round-off only; the linearisation is a model error, not an
    integrator error, and is not included); etd3m (m samples per step): Richardson against
    m / 2 samples per step where m is even, against one sample per step (ratio m, scale
    m^p/(m^p - 1)) where m is odd, against etd3 at half a sample where m = 1 (etd4m at m = 1:
    against dop853 at rtol 1e-12; the sentence in ``error_method`` says which). The estimate
    costs one more run (at twice the steps for the half-step ones); ``energy_error_estimate_j``
    applies it to the energy.

    Raises
    ------
    ConfigError : an invalid argument (the message names it and the valid range).
    DivergenceError : the state became non-finite or the solver could not continue; it carries
        the time and the last finite state.
    """
    duration, rtol_f, atol_f, solver, dt_s, output_dt_s = _checked_arguments(
        chain, duration_s, base, method, rtol, atol, dt_s, output_dt_s, algorithm)
    t0, native0, h0 = _initial_state(chain, solver, method, theta0, omega0, start)
    segs, grid = _plan(chain, duration, base, solver, dt_s, output_dt_s)
    solvers = [solver.on_grid(sg.substeps, sg.per_step) for sg in segs]
    tic = time.perf_counter()
    y_out, native_end, h_next, (n_steps, n_rej, n_fev, n_newton), lifted = _execute(
        chain, segs, solvers, native0.copy(), t0, h0)
    wall = time.perf_counter() - tic
    tic = time.perf_counter()
    err_th, err_om, err_e, error_method = (
        _error_estimate(chain, segs, solvers, solver, y_out, native0, t0, h0) if estimate_error
        else (None, None, None, "not estimated (estimate_error=False)"))
    est_wall = time.perf_counter() - tic if estimate_error else 0.0
    n = chain.n
    t = _times(segs, t0, duration)
    y_out = readonly(y_out)
    theta, omega = y_out[:, :n], y_out[:, n:]  # read-only views (no copy of a long run)
    final = SimState(t_s=float(t[-1]), theta_rad=readonly(theta[-1].copy()),
                     omega_rad_s=readonly(omega[-1].copy()), method=method,
                     native=readonly(native_end.copy()), h_next_s=float(h_next))
    settings = _settings(chain, solver, method, algorithm, duration, t0, rtol_f, atol_f, grid,
                         solver.trajectory_settings(segs, lifted))
    traj = Trajectory(t_s=readonly(t), theta_rad=theta, omega_rad_s=omega, chain=chain,
                      method=method, settings=settings, n_steps=n_steps, n_rejected=n_rej,
                      n_fev=n_fev, n_newton=n_newton, wall_time_s=wall, error_estimate_rad=err_th,
                      error_estimate_rad_s=err_om, energy_error_estimate_j=err_e,
                      error_method=error_method,
                      estimate_wall_time_s=est_wall, final_state=final)
    from rig.sim_checks import simulation_warnings

    found = simulation_warnings(traj, fixed_base=base is None)
    return dataclasses.replace(traj, warnings=found) if found else traj


def _settings(chain, solver, method, algorithm, duration, t0, rtol, atol, grid,
              solver_settings) -> dict:
    """The trajectory's ``settings``: the method, its order and kind, the run, the tolerances
    (adaptive only), the right-hand side's algorithm, the grid and the solver's own."""
    rhs_name = (("n=2 scalar", "dense", "recursive")[rhs_algorithm(chain, algorithm)]
                if solver.selectable_rhs else None)
    settings = dict(method=method, order=solver.order, kind=solver.kind, duration_s=duration,
                    t0_s=t0, rtol=rtol if solver.adaptive else None,
                    atol=atol if solver.adaptive else None, rhs=rhs_name, **grid)
    settings.update(solver_settings)
    return settings


def _checked_arguments(chain, duration_s, base, method, rtol, atol, dt_s, output_dt_s,
                       algorithm):
    """:func:`simulate`'s arguments checked (a ConfigError naming the bad one); returns
    ``(duration, rtol, atol, solver, dt_s, output_dt_s)``."""
    if not isinstance(chain, Chain):
        raise ConfigError(f"chain = {chain!r} is invalid: expected a rig.chain.Chain")
    duration = positive("duration_s", duration_s)
    if method not in names_for(PENDULUM):
        raise ConfigError(f"method = {method!r} is invalid: expected one of "
                          f"{', '.join(names_for(PENDULUM))}")
    try:
        rtol_f = float(rtol)
    except (TypeError, ValueError):
        rtol_f = float("nan")
    if not 0.0 < rtol_f < 1.0:
        raise ConfigError(f"rtol = {rtol!r} is invalid: expected 0 < rtol < 1")
    atol_f = positive("atol", atol)
    rhs_algorithm(chain, algorithm)  # validate before running
    solver = solver_named(method, rtol=rtol_f, atol=atol_f, algorithm=algorithm)
    if dt_s is not None:
        if solver.adaptive:
            raise ConfigError(f"dt_s = {dt_s!r} is invalid for method {method!r}: it chooses its "
                              "own steps (set rtol, atol), dt_s must be None")
        dt_s = positive("dt_s", dt_s)
    if output_dt_s is not None:
        output_dt_s = positive("output_dt_s", output_dt_s)
    if base is not None and not isinstance(base, BaseInput):
        raise ConfigError(f"base = {base!r} is invalid: expected a BaseInput or None")
    return duration, rtol_f, atol_f, solver, dt_s, output_dt_s


def _initial_state(chain, solver, method, theta0, omega0, start):
    """``(t0, native0, h0)``: the start time [s], the solver's native state and its first step
    (NaN: its own choice), from ``theta0``/``omega0`` or a previous run's ``start``."""
    n = chain.n
    if start is not None:
        if theta0 is not None or omega0 is not None:
            raise ConfigError("theta0/omega0 and start are both given: expected one of them")
        if not isinstance(start, SimState):
            raise ConfigError(f"start = {start!r} is invalid: expected a SimState")
        th0 = _vector("start.theta_rad", start.theta_rad, n)
        om0 = _vector("start.omega_rad_s", start.omega_rad_s, n)
        same = start.method == method
        native0 = (np.array(start.native, float) if same else
                   solver.init(chain, np.concatenate([th0, om0])))
        return float(start.t_s), native0, float(start.h_next_s) if same else float("nan")
    if theta0 is None:
        raise ConfigError("theta0 is missing: expected n initial angles [rad] (or start)")
    th0 = _vector("theta0", theta0, n)
    om0 = np.zeros(n) if omega0 is None else _vector("omega0", omega0, n)
    return 0.0, solver.init(chain, np.concatenate([th0, om0])), float("nan")


def _error_estimate(chain, segs, solvers, solver, y_out, native0, t0, h0):
    """The run's error estimate against its solvers' refined reference (see :func:`simulate`):
    ``(angles [rad], angular velocities [rad/s], energy [J], how)``, per output row."""
    n = chain.n
    refs = [s.refined() for s in solvers]
    ref_start = refs[0].solver.start_from(chain, native0, solver)
    ref, *_ = _execute(chain, segs, [r.solver for r in refs], ref_start, t0,
                       h0 if refs[0].keep_h0 else float("nan"))
    scale = refs[0].scale
    diff = np.abs(y_out - ref) * scale
    e_main = chain.energy(y_out[:, :n], y_out[:, n:])
    e_ref = chain.energy(ref[:, :n], ref[:, n:])
    return (readonly(diff[:, :n].copy()), readonly(diff[:, n:].copy()),
            readonly(np.abs(e_main - e_ref) * scale), refs[0].how)
