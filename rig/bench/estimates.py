"""What runs, why, and how accurate it is: the bench's model information and error estimates.

:func:`model_info` (and :meth:`rig.bench.BenchSimulation.model_info`, stored in the run file):
the model choice (:func:`rig.bench.selection.select_model`), the method, and the error estimate
of the model that runs, measured on a ``probe_s`` run of the scene's own drive from rest:

- ``linear``: the predicted linearisation error plus the discretisation's (one exact step
  against two exact half steps per DAC sample: round-off only);
- ``etdab`` / ``lawson4`` (the coupled bench, :mod:`rig.solvers.coupled`): Richardson against twice
  the steps per DAC sample, ``|theta - theta_fine| 2^p / (2^p - 1)`` with the method's order ``p``
  (the error is the small nonlinear remainder's: the linear part is exact), and the
  nonlinear-minus-linear difference on the probe;
- ``rk4`` / ``gauss4`` / ``dop853`` (reaction off, the pendulum on the prescribed stage
  acceleration, linear between ``oversample`` sub-instants, O((h/oversample)^2)): the input
  interpolation (the linearised pendulum through the same interpolated input against the exact
  linear bench) plus the integrator's (Richardson, or tolerances / 100 for dop853).

Cost: two to three probe runs of ``probe_s`` (docs/bench_model.md has the measured accuracies).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from rig.solvers import Exact, integrate
from rig.solvers.etdab import ETDAB_ORDER
from rig.linear import discretise
from rig.scene import Scene
from rig.devices.source import generate, start_source
from rig.model_info import ModelInfo
from rig.bench.model import BenchModel, build_model, linear_scene
from rig.bench.run import spawn_streams, advance, stage_fine_kernel, start
from rig.bench.selection import select_model


def model_info(scene: Scene, *, seed=0, probe_s: float = 20.0, method: str | None = None,
               oversample: int = 8, substeps: int = 1, every: int | None = None) -> ModelInfo:
    """Which model runs, why, how, and its error estimate (measured on a ``probe_s`` run of the
    scene's own drive from rest); see :meth:`BenchSimulation.model_info`."""
    return model_info_of(build_model(scene, method=method, oversample=oversample,
                                     substeps=substeps, every=every), probe_s=probe_s,
                         seed=seed)


def _probe_theta(model: BenchModel, n: int, seed) -> np.ndarray:
    """Angles of an n-sample run from rest through the full bench (sensors included)."""
    blk, _ = advance(model, start(model, seed), n)
    return blk.truth["theta_rad"]


def kernel_theta(model: BenchModel, v: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Angles at the DAC instants of the linear, lawson4 or etdab kernel alone (no sensors)."""
    z_out, _, _ = model.solver.advance_bench(model, z0.copy(), None, v)
    return z_out[:, model.slices["theta_rad"]]


def _richardson_estimate(scene, model: BenchModel, v: np.ndarray, z0: np.ndarray) -> dict:
    """Error estimate of a coupled-bench method on the probe input ``v``: against the reference
    of its solver's :meth:`~rig.solvers.bench_base.BenchSolver.refined` (Richardson: the same
    method with twice the steps per DAC sample, ``|theta - theta_fine| 2^p / (2^p - 1)`` [rad],
    p its order), and the nonlinear-minus-linear model difference on the probe."""
    theta = kernel_theta(model, v, z0)
    ref = model.solver.refined()
    fine = build_model(scene, method=ref.solver.name, substeps=ref.solver.substeps,
                       every=model.every, selection=model.selection)
    diff = (theta - kernel_theta(fine, v, z0)) * ref.scale
    lin = kernel_theta(build_model(linear_scene(scene)), v, z0)
    return {
        "max_abs_theta_rad": float(np.max(np.abs(diff))),
        "relative_rms_theta": _rel_rms(diff, theta),
        "integrator_max_abs_theta_rad": float(np.max(np.abs(diff))),
        "probe_nonlinear_minus_linear_relative_rms_theta": _rel_rms(theta - lin, theta),
    }


def _rel_rms(diff: np.ndarray, ref: np.ndarray) -> float:
    """max over bodies of rms(diff_j) / rms(ref_j) (0 where nothing moves)."""
    num = np.sqrt(np.mean(diff**2, axis=0))
    den = np.sqrt(np.mean(ref**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(den > 0, num / den, 0.0)
    return float(np.max(r))


#: how the linear bench is stepped by the per-sample path (rig.bench.advance)
PER_SAMPLE_STEP = "compiled loop, one step per DAC sample"


def linear_method(model: BenchModel, step: str = PER_SAMPLE_STEP) -> str:
    """The linear model's ``method`` text: its discretisation, then how it is stepped."""
    return ("exact discretisation (zero-order hold, matrix exponential) of the coupled linear "
            "bench: coil, stage, linearised pendulum"
            + (" with its reaction" if model.stage.reaction else "")
            + f", accelerometer high-pass; {step}")


#: what the per-sample path runs at every DAC sample and why (the fused chain says its own)
PER_SAMPLE_STEPPED = {
    "what": "the bench state (one exact step per DAC sample), the optical lever's exact "
            "geometry, the sensors' white noise (one draw per sample and channel), the "
            "clipping at the detector edge and the accelerometer's range with their flags, "
            "and the anti-alias filter",
    "why": "not linear, so not lifted to the output rate: the lever's second-order "
           "geometry is ~0.4 % of the spot's rms in u (far above round-off), clipping and "
           "flags act on each sample, and the filter's input is the sum of those and the "
           "noise",
}

#: how the source's DAC value is held (the model info's ``hold``)
HOLD = "zoh: the source DAC value is held for 1/fs; the stage acceleration it makes is continuous"


@dataclass(frozen=True)
class _Estimate:
    """How a model is integrated and its measured error (the model-specific part of the info)."""

    method: str
    error_estimate: dict
    error_method: str
    remainder_every_steps: int | None = None


def model_info_of(model: BenchModel, *, probe_s: float, seed, probe_v=None) -> ModelInfo:
    scene = model.scene
    fs = model.fs_hz
    n = max(1, int(round(probe_s * fs)))
    tic = time.perf_counter()
    sel = model.selection if model.selection is not None else select_model(scene)
    budget = sel["error_budget"]
    root, children = spawn_streams(seed)
    if probe_v is not None and probe_v.shape == (n,):  # the run's own first samples, made ahead
        v = probe_v
    else:
        v, _ = generate(model.source, start_source(model.source, children[0]), n)
    z0 = np.array(start(model, root).z)
    if model.model == "linear":
        est = _linear_estimate(model, v, z0, sel["prediction"], probe_s)
    elif model.method in ("etdab", "lawson4"):
        est = _coupled_estimate(model, v, z0, probe_s)
    else:
        est = _prescribed_stage_estimate(model, v, n, seed, probe_s)
    met = bool(est.error_estimate["relative_rms_theta"] <= budget)
    reason = sel["reason"] if met else (
        sel["reason"] + f". The estimated error of the model that runs, "
        f"{est.error_estimate['relative_rms_theta']:.2g}, is OVER the budget {budget:g}")
    return ModelInfo(
        model=model.model, requested_model=scene.acquisition.model, error_budget=budget,
        reason=reason, fs_hz=fs, hold=HOLD, reaction=model.stage.reaction,
        states=model.state_names(), seed=model_seed(model, seed), probe_s=probe_s,
        selection=sel, per_sample={"rate_hz": fs, **PER_SAMPLE_STEPPED},
        linearity=_linearity(scene, sel["prediction"]), method=est.method,
        remainder_every_steps=est.remainder_every_steps, error_estimate=est.error_estimate,
        error_method=est.error_method, budget_met=met,
        estimate_wall_time_s=time.perf_counter() - tic)


def _linearity(scene: Scene, pred: dict) -> dict:
    """The rms angles and the frequency-shift rule of thumb (the info's ``linearity``)."""
    _, q = scene.chain.modes()
    qmax = float(np.max(q)) if q.size else math.inf
    th3 = 3 * max(pred["theta_rms_rad"])
    shift = th3**2 / 16  # relative frequency shift of a pendulum at amplitude th3
    return {
        "theta_rms_rad": pred["theta_rms_rad"],
        "frequency_shift_at_3_sigma": shift,
        "half_bandwidth": 1 / (2 * qmax),
        "shift_over_half_bandwidth": shift * 2 * qmax,
        "predicted_linear_error": pred["max"],
        "how": "rms angles of the linear bench under the scene's source (the predictor's runs); "
               "a pendulum's frequency falls by ~A^2/16 at amplitude A (here 3 rms of the larger "
               "angle), compared with the highest-Q mode's half-power half-bandwidth 1/(2Q). The "
               "decision uses the predicted error ('selection'), not this rule of thumb",
    }


def _linear_estimate(model: BenchModel, v: np.ndarray, z0: np.ndarray, pred: dict,
                     probe_s: float) -> _Estimate:
    """The linear model: the predicted linearisation error plus the discretisation's (one
    exact step against two exact half steps per DAC sample: round-off only)."""
    theta = kernel_theta(model, v, z0)
    theta2 = kernel_theta(_half_step_model(model), v, z0)
    e_disc = float(np.max(np.abs(theta - theta2)))
    rel_disc = _rel_rms(theta - theta2, theta)
    e_lin = pred["max"]
    return _Estimate(
        method=linear_method(model),
        error_estimate={
            "max_abs_theta_rad": pred["max_abs_theta_rad"] + e_disc,
            "relative_rms_theta": e_lin + rel_disc,
            "linearisation_relative_rms_theta": e_lin,
            "linearisation_upper_relative_rms_theta": pred["upper"],
            "discretisation_max_abs_theta_rad": e_disc,
            "discretisation_relative_rms_theta": rel_disc,
        },
        error_method=(
            "linearisation (the model error, against the nonlinear bench): predicted, see "
            "selection.prediction.how; discretisation: |theta_h - theta_h/2| over a "
            f"{probe_s:g} s probe of the scene's drive from rest against the same exact "
            "discretisation with two half steps per DAC sample (round-off only)"))


def _coupled_estimate(model: BenchModel, v: np.ndarray, z0: np.ndarray,
                      probe_s: float) -> _Estimate:
    """The coupled bench (etdab, lawson4): Richardson on the probe (:func:`_richardson_estimate`)."""
    loads = " that it loads (reaction)" if model.stage.reaction else ""
    est = _richardson_estimate(model.scene, model, v, z0)
    if model.method == "lawson4":
        return _Estimate(
            method=(f"nonlinear pendulum on the stage{loads}, the whole bench as one system "
                    "(rig.solvers.coupled): the linear bench propagated exactly (matrix "
                    "exponential, zero-order hold), the nonlinear remainder by Lawson's RK4, "
                    f"{model.substeps} step(s) per DAC sample"),
            error_estimate=est,
            error_method=(
                f"Richardson on a {probe_s:g} s probe of the scene's drive from rest: |theta - "
                "theta(2x steps)| 16/15 (order 4; the error is that of the small nonlinear "
                "remainder: the linear part is exact). 'probe_nonlinear_minus_linear' is the "
                "model difference on the probe (the run's is predicted in 'selection')"))
    return _Estimate(
        method=(
            f"nonlinear pendulum on the stage{loads}, the whole bench as one system "
            "(rig.solvers.coupled): the linear bench propagated exactly (matrix exponential, "
            "zero-order hold), the nonlinear remainder by exponential Adams-Bashforth of order "
            f"{ETDAB_ORDER} (its integral over a step from the polynomial through its last "
            f"{ETDAB_ORDER} values, "
            + ("one evaluation per step" if model.every == 1 else
               f"evaluated every {model.every} steps and extrapolated between") +
            f"), {model.substeps} step(s) per DAC sample"),
        remainder_every_steps=model.every,
        error_estimate=est,
        error_method=(
            f"Richardson on a {probe_s:g} s probe of the scene's drive from rest: |theta - "
            f"theta(2x steps)| 2^{ETDAB_ORDER}/(2^{ETDAB_ORDER} - 1) (the remainder's nodes "
            "every the same number of steps, so half as far apart; the error is that of the "
            "small nonlinear remainder: the linear part is exact). "
            "'probe_nonlinear_minus_linear' is the model difference on the probe (the run's is "
            "predicted in 'selection')"))


def _prescribed_stage_estimate(model: BenchModel, v: np.ndarray, n: int, seed,
                               probe_s: float) -> _Estimate:
    """rk4 / gauss4 / dop853 on the prescribed stage acceleration: the input interpolation
    (the linearised pendulum through the same interpolated input against the exact linear
    bench) plus the integrator's (Richardson, or tolerances / 100 for dop853)."""
    scene, mi, fs = model.scene, model.solver, model.fs_hz
    theta = _probe_theta(model, n, seed)
    scale = max(float(np.max(np.abs(theta))), 1e-300)
    # (1) input interpolation: linearised pendulum, interpolated input vs exact linear bench
    theta_exact = _probe_theta(build_model(linear_scene(scene)), n, seed)
    m = model.oversample
    zs = np.zeros(model.n_states - 2 * scene.chain.n)
    a_fine = np.empty(n * m + 1)
    stage_fine_kernel(model.stage_phi, model.stage_gamma, model.stage_accel_row, v, m, zs,
                      np.empty((n, zs.size)), a_fine)
    y0 = np.concatenate([scene.theta0_rad, scene.omega0_rad_s])
    lin = integrate(scene.chain, y0, a_fine, None, hold="linear", h_in=1 / (fs * m),
                    n_intervals=n * m, out_every=m, solver=Exact())
    d_input = lin.y_out[:n, :scene.chain.n] - theta_exact
    e_input = float(np.max(np.abs(d_input)))
    # (2) integrator: Richardson against twice the steps (built here, not by mi.refined():
    # dop853's refinement floors rtol at 1e-14, this one keeps rtol / 100 as run files have)
    fine = build_model(scene, method=model.method, oversample=model.oversample,
                       substeps=2 * model.substeps, rtol=model.rtol / 100,
                       atol=model.atol / 100, selection=model.selection)
    theta_f = _probe_theta(fine, n, seed)
    if mi.order is not None and not mi.adaptive:
        factor = 2.0**mi.order / (2.0**mi.order - 1.0)
        how_int = (f"Richardson |theta - theta(2x steps)| 2^{mi.order}/(2^{mi.order} - 1)")
    else:
        factor = 1.0
        how_int = "|theta - theta(rtol, atol / 100)|"
    e_int = float(np.max(np.abs(theta - theta_f))) * factor
    return _Estimate(
        method=(f"nonlinear pendulum via rig.solvers {model.method} ({mi.description}), "
                f"{model.substeps} step(s) per sub-interval; stage and accelerometer exact (ZOH) "
                f"at {model.oversample} sub-instants per DAC sample, the stage acceleration "
                "linear between them"),
        error_estimate={
            "input_interpolation_max_abs_theta_rad": e_input,
            "integrator_max_abs_theta_rad": e_int,
            "max_abs_theta_rad": e_input + e_int,
            "relative_to_max_theta": (e_input + e_int) / scale,
            "relative_rms_theta": _rel_rms(d_input, theta) + _rel_rms((theta - theta_f) * factor,
                                                                       theta),
            "nonlinear_minus_linear_max_abs_theta_rad": float(np.max(np.abs(theta - theta_exact))),
        },
        error_method=(
            f"on a {probe_s:g} s probe of the scene's drive from rest: (1) input interpolation: "
            "the linearised pendulum driven through the same sub-sampled, linearly interpolated "
            "stage acceleration (rig.solvers 'linear', exact for that input) against the "
            "exact linear bench; (2) integrator: " + how_int + "; the sum is the estimate. "
            "'nonlinear_minus_linear' is the model difference (the linearisation's error) on "
            "the probe"))


def model_seed(model: BenchModel, seed) -> object:
    """The seed as recorded: the root SeedSequence's entropy (an int, or a list of ints)."""
    root, _ = spawn_streams(seed)
    return root.entropy


def _half_step_model(model: BenchModel) -> BenchModel:
    """The same linear bench stepped as two exact half steps per DAC sample (round-off check)."""
    import dataclasses

    phi_h, g_h, _ = discretise(model.a, model.b, 0.5 / model.fs_hz, "zoh")
    phi = phi_h @ phi_h
    gamma = phi_h @ g_h[:, 0] + g_h[:, 0]
    return dataclasses.replace(model, phi=np.ascontiguousarray(phi),
                               gamma=np.ascontiguousarray(gamma))
