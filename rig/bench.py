"""The whole bench, run continuously: source -> amplifier/coil -> stage -> pendulum -> sensors.

The state vector (named slices, :attr:`BenchModel.slices`)::

    z = (i [A], x0 [m], v0 [m/s], theta (n) [rad], omega (n) [rad/s], q [m/s], r [V])

``i`` the coil current, ``x0, v0`` the stage, ``theta, omega`` the pendulum, ``q`` the
accelerometer's charge-amplifier high-pass state (absent for a flat-to-DC accelerometer) and ``r``
the states of the source's reconstruction filter (absent when it is off). The input is the source
voltage, a DAC sample held for one sample interval ``h = 1 / simulation_rate_hz`` (SPEC section 8):
that held staircase is, by definition, the true DAC output; the source's analog reconstruction
filter smooths it (:mod:`rig.devices.source`) and the stage acceleration ``x0''`` is whatever the
continuous amplifier, coil and stage make of that.

Models (``acquisition.model``, ``acquisition.error_budget``)
------------------------------------------------------------
``linear``
    The coil, stage, linearised pendulum (with its reaction on the stage if ``stage.reaction``)
    and the accelerometer's high-pass form one linear system ``z' = A z + B V``
    (:meth:`rig.devices.stage.Stage.state_space`). It is discretised exactly for the held input with
    :func:`rig.solvers.exact.discretise` (``z_{k+1} = Phi z_k + Gamma V_k``, Van Loan's matrix
    exponential) and stepped by a compiled loop: exact at the DAC instants up to round-off, ~0.1 us
    per sample for the Ishizaki pendulum. The sensors read the states at the instants. Its error
    is the linearisation (a model error, predicted by :func:`predict_linearisation_error`).
``nonlinear``
    ``method="etdab"`` (default): the whole bench, nonlinear pendulum *and* its reaction on the
    stage (or without it), integrated as one system by :mod:`rig.coupled`: the linear bench is
    propagated exactly (the matrix exponential of the exact linear model) and only the nonlinear
    remainder (relative size ~theta^2) is integrated, by exponential Adams-Bashforth of order 4
    (:func:`rig.coupled.etd_ab_kernel`: the remainder's integral over a step from the
    polynomial through its values at the last 4 steps; one evaluation per step, at the step's
    own state), ``substeps`` steps per DAC interval. Error estimate: Richardson (x 16/15)
    against twice the steps on a probe run of the scene's drive. The per-sample cost is the
    exact linear step plus one remainder evaluation and its weights (docs: BENCHMARKS.md).
    Where the motion is far from linear (a double rod swinging at 1 rad) its error constant is
    larger than lawson4's at the same step (the estimate says so).
    ``method="lawson4"``: the same split, the remainder by Lawson's RK4 (four evaluations per
    step). For ``ishizaki2009`` with one step per DAC sample: 4e-12 relative RMS at the default
    drive (round-off), 1e-10 at 1 V (theta1 ~ 0.06 rad); halving the step divides it by 25-50.
    ``method="rk4" | "gauss4" | "dop853"`` (``stage.reaction = false`` only): the stage is
    discretised exactly at ``h / oversample`` and the pendulum's nonlinear equations are
    integrated through :func:`rig.solvers.integrate` on that prescribed stage acceleration,
    linear between the sub-instants (``hold="linear"``, O((h/oversample)^2)); its error estimate
    adds the input interpolation (the linearised pendulum through the same interpolated input
    against the exact linear bench) to the integrator's (Richardson). For ``ishizaki2009``
    (reaction off, default drive, 20 s probe, oversample 8): interpolation 3.0e-7 rad, 3.8e-5 of
    the largest angle, integrator 9e-14 rad. Cost ~8 us per DAC sample.
``auto`` (default)
    The cheapest model that meets ``acquisition.error_budget`` (the allowed relative RMS error of
    the simulated angles over the records, max over the bodies; default 1e-2): :func:`select_model`
    predicts the linear model's error (:func:`predict_linearisation_error`) and takes ``linear``
    if even its upper estimate is inside the budget, ``nonlinear`` otherwise. The choice, the
    prediction, the reason and how it was predicted are in :meth:`BenchSimulation.model_info`
    (``selection``, ``reason``), which the run file stores; a forced model records the same
    prediction and whether the budget is met (``budget_met``).

Why the budget is 1 % by default: a lightly damped mode turns a tiny amplitude-dependent
frequency shift into a large time-domain difference. For the paper's pendulum (Q1 = 530, tau =
Q1 / (pi f1) = 68 s) the linear model's relative RMS angle error grows as the drive level squared
and with the run length up to a few tau: at the default 0.1 V (theta1 ~ 6e-3 rad rms, a
frequency shift ~theta^2/4 ~ 1e-5, 1 % of the half-bandwidth) it is ~0.5 % over the paper's
records, ~2e-3 over 100 s from rest and ~3e-4 over 20 s. For the paper's run the choice flips at
0.127 V (budget 1e-2) or 0.040 V (budget 1e-3); 0.3 V needs the nonlinear model for the paper's
run but not for 10 s from rest (tests/rig/test_model_selection.py).

The predictor: first-order perturbation
---------------------------------------
``z_nl = z_lin + d + O(theta^2 d)`` with ``d' = A d + f(z_lin(t))``, ``f`` the nonlinear
remainder of the accelerations (:mod:`rig.coupled`): the linearisation error to first order is
the linear bench's response to the remainder evaluated along the *linear* trajectory (on the
same drive it equals nonlinear - linear to 2 %, tests/rig/test_bench.py). It is computed for the
scene's own source type, level, initial state and run length on a surrogate drive: the scene's
source regenerated at a reduced rate (>= 8 times the highest source or pendulum frequency, 100 Hz
for ``ishizaki2009``; its own random stream, so the choice is a property of the scene, not of
the run's seed), the coil + stage + pendulum (no reconstruction filter) discretised exactly with
a first-order hold of the voltage and of ``f``. The relative RMS error of every angle over the
recorded span is estimated from 8 values: for a run of >= 16 amplitude time constants ``tau =
Q / (pi f)`` one realisation cut into 8 batches (pooled ratio; uncertainty from the batches'
jackknife x 1.5, calibrated on 30 predictor streams, after which it matches their scatter within
20 %; for a run longer than 24 tau a probe of 5 tau settling + 24 tau of records, stationary and
conservative if the run settles less), for a shorter run 8 independent realisations of it (their
mean and standard deviation). Spread of the actual run's value: that scaled to the run's length;
decision on ``upper = estimate + t sqrt(spread^2 + uncertainty^2)`` (t = 2.36, Student's 97.5 %
quantile for 7 degrees of freedom). The first order must hold all along: if the predicted error
anywhere in the run (settling included) exceeds 0.1 of the largest angle (e.g. a pendulum
released far from rest) the prediction is flagged ``first_order_valid = False`` and ``auto``
takes the nonlinear model. Clear cases stop early (every realisation so far over 10 x the
budget, or two under a tenth of it). Cost ~0.3-
0.5 us per reduced sample on a shared machine (paper's run: 197,000 samples, ~0.15 s).

Accuracy against the nonlinear bench on independent drives (measured error, mean +- std over
seeds, vs prediction +- its stated single-run spread): 0.1 V, 100 s from rest: 2.0e-3 +- 0.9e-3
(12 seeds) vs 2.3e-3 +- 1.2e-3; 0.03 V: 1.8e-4 +- 0.8e-4 vs 2.1e-4 +- 1.1e-4; 0.1 V, 20 s:
2.8e-4 +- 2.0e-4 vs 2.2e-4 +- 1.3e-4; 0.05 V, 300 s + 1000 s: 1.2e-3 +- 0.3e-3 (4 seeds) vs
1.4e-3 +- 0.3e-3; the paper's run (0.1 V, 300 s + 3000 s): 4.3e-3 +- 0.9e-3 (3 seeds, the
largest 5.3e-3) and 6.6e-3 (a fourth) vs 4.5e-3 +- 0.5e-3 (upper 6.5e-3). The first-order term
underestimates once the error itself is large (0.3 V, 300 s + 1000 s: 7.0e-2 measured vs 4.9e-2;
1 V: 0.60 vs 0.54, and there the first order is flagged invalid), far above any sensible budget,
where the decision is the same.

Outputs: :class:`rig.blocks.AnalogBlock` s at the simulation rate with volts ``a, x, y`` and the
truth beside them (:meth:`BenchSimulation.next_block`). Random streams: one
:class:`numpy.random.SeedSequence` per run, spawned into independent streams for the source, the
accelerometer noise and the two PSD axes; all generator states travel in :class:`BenchState`, so
any split into blocks reproduces a one-shot run bit for bit.

Numbers for the defaults (``ishizaki2009``, 0.1 V rms random source 0-12.5 Hz; see
:func:`stationary_levels`, :func:`signal_to_noise`, tests/rig/test_bench.py): the paper's run (330 s
settle + 30 x 100 s, 3.33 million samples at 1 kHz) takes ~1.4 s of CPU with the linear model in
10 s blocks (source FIR, sensors and noise included; 1-3 s wall on a shared two-core machine),
plus ~0.15 s for the model choice;
levels and signal-to-noise ratios are listed in the docstrings of :mod:`rig.devices.stage`,
:mod:`rig.devices.accelerometer` and :mod:`rig.devices.optical_lever`.

Sampling at the DAC instants folds the DAC's images
---------------------------------------------------
The held source has images at ``m fs +- f``; sampling the outputs at the DAC instants folds what
passes of them back onto ``f``, coherent with the drive. The source's reconstruction filter
(:mod:`rig.devices.source`, 100 Hz 4th-order Butterworth by default) removes them: the exact transfer
function of the simulated samples (:func:`expected_response` ``sampled=True``) then equals the
continuous chain (``sampled=False``: what a real bench with an ideally anti-aliased analyzer reads)
to better than 2e-5 over the band. With the filter off (``source.reconstruction_hz = 0``, the raw
staircase into the amplifier, whose coil corner is 318 Hz) they differ in ``a`` (hence in H_t and
Theta_2) by 1e-3 at 1 Hz, 1 % at 10 Hz and 4.8 % in the reaction's notch at 2.479 Hz, falling as
1 / fs^2.

Public API: :class:`BenchSimulation`, :class:`BenchModel`, :class:`BenchState`,
:class:`BenchResponse`, :func:`build_model`, :func:`start`, :func:`advance`, :func:`calibrations`,
:func:`expected_response`, :func:`stationary_levels`, :func:`signal_to_noise`, :func:`model_info`,
:func:`select_model`, :func:`predict_linearisation_error`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from rig.devices.accelerometer import Accelerometer
from rig.blocks import AnalogBlock, Calibration
from rig import coupled as rcoupled
from rig.chain import Chain
from rig.errors import ConfigError, DivergenceError
from rig.solvers import COUPLED_BENCH, Exact, ExactBench, integrate, solver_named
from rig.solvers.etdab import ETDAB_ORDER
from rig.solvers.exact import discretise
from rig._jit import njit
from rig._threads import Prefetch
from rig.devices.optical_lever import OpticalLever
from rig.linear import FrequencyResponse
from rig.scene import Scene
from rig.devices.source import NOISE_TYPES, Source, SourceState, generate, start_source
from rig.devices.stage import Stage

MODELS = ("auto", "linear", "nonlinear")  # acquisition.model; "auto" resolves to one of the others
NONLINEAR_METHODS = ("lawson4", "etdab", "rk4", "gauss4", "dop853")
COUPLED_METHODS = ("lawson4", "etdab")  # rig.coupled: the whole bench as one system
DEFAULT_METHOD = "etdab"
PRESCRIBED_STAGE_METHODS = ("rk4", "gauss4", "dop853")  # rig.solvers on a given stage motion
PREDICTOR_ENTROPY = 20090005  # the predictor's own random stream (the choice is the scene's)
PREDICTOR_BATCHES = 8
SPREAD_CALIBRATION = 1.5  # jackknife std of 8 batches -> measured run-to-run scatter (see how)
FIRST_ORDER_LIMIT = 0.1  # largest |d theta| / largest |theta| for the first order to hold
_T975 = {1: 12.71, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
         9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131}
STREAMS = ("source", "accelerometer", "psd_x", "psd_y")
_REL = 1e-9


# ================================================================================================
# the model
# ================================================================================================

@dataclass(frozen=True, eq=False)
class BenchModel:
    """Everything fixed about a bench run (no state). Build with :func:`build_model`.

    Attributes
    ----------
    scene, source, stage, accelerometer, lever : the parts.
    fs_hz : simulation (DAC) rate [Hz]; decimation : simulation_rate_hz / rate_hz.
    model : "linear" or "nonlinear" (what runs; ``acquisition.model`` may say "auto");
    method, oversample, substeps, rtol, atol : the nonlinear path's integrator settings (method
        name, sub-instants per DAC interval (prescribed-stage methods), steps per DAC interval
        (lawson4) or per sub-interval, dop853 tolerances).
    selection : the model choice of ``acquisition.model = "auto"`` (:func:`select_model`), else
        None (computed on demand by :meth:`BenchSimulation.model_info`).
    a, b : continuous bench ``z' = a z + b V``; phi, gamma : its exact ZOH step at 1 / fs.
    accel_row : x0'' = accel_row . z.  slices : named slices of z.
    stage_phi, stage_gamma, stage_accel_row : prescribed-stage nonlinear path only: the stage +
        accelerometer (z_s = (i, x0, v0, q)) stepped exactly at 1 / (fs oversample).
    coupled, lawson : lawson4 and etdab paths: the kernels' parameters (:class:`rig.coupled.
        CoupledParams`); lawson4: (E_h, E_h/2, G_h, G_h/2) at h = 1 / (fs substeps).
    etdab : etdab path only: (Phi^T, Gamma, W) at h = 1 / (fs substeps)
        (:func:`rig.coupled.etd_ab_weights`) and their sparsity (:func:`rig.coupled.
        etd_ab_sparsity`): the kernel's arguments after ``coupled``'s.
    """

    scene: Scene
    source: Source
    stage: Stage
    accelerometer: Accelerometer
    lever: OpticalLever
    fs_hz: float
    decimation: int
    model: str
    method: str
    oversample: int
    substeps: int
    rtol: float
    atol: float
    a: np.ndarray
    b: np.ndarray
    phi: np.ndarray
    gamma: np.ndarray
    accel_row: np.ndarray
    slices: dict
    stage_phi: np.ndarray | None = None
    stage_gamma: np.ndarray | None = None
    stage_accel_row: np.ndarray | None = None
    coupled: rcoupled.CoupledParams | None = None
    lawson: tuple | None = None
    selection: dict | None = None
    etdab: tuple | None = None

    @property
    def chain(self) -> Chain:
        """The pendulum."""
        return self.scene.chain

    @functools.cached_property
    def solver(self):
        """The solver this model runs (:mod:`rig.solvers`): the exact linear bench for the linear
        model, else ``method`` at ``substeps`` steps per DAC interval (lawson4, etdab: the
        coupled bench) or per sub-interval (the prescribed-stage methods; dop853 at ``rtol``,
        ``atol``)."""
        if self.model == "linear":
            return ExactBench()
        return solver_named(self.method, substeps=self.substeps, rtol=self.rtol, atol=self.atol)

    @property
    def n_states(self) -> int:
        """Length of the bench state vector z."""
        return self.a.shape[0]

    def state_names(self) -> list[str]:
        """Names (with units) of the entries of z."""
        n = self.chain.n
        names = (["coil_current_a", "stage_disp_m", "stage_vel_mps"]
                 + [f"theta{j + 1}_rad" for j in range(n)]
                 + [f"omega{j + 1}_rad_s" for j in range(n)])
        if self.accelerometer.n_states:
            names.append("accel_highpass_q_mps")
        nr = self.n_states - len(names)
        names += [f"reconstruction{k + 1}_v" for k in range(nr)]
        return names


def _bench_state_space(stage: Stage, chain: Chain, acc: Accelerometer, with_chain: bool,
                       source: Source):
    """Continuous (a, b, accel_row, slices) of the source's reconstruction filter + stage
    [+ pendulum] + accelerometer high-pass, input the DAC voltage."""
    ss = stage.state_space(chain if with_chain else None)
    recon = source.reconstruction_state_space()
    nz0 = ss.a.shape[0]
    nq = acc.n_states
    nr = 0 if recon is None else recon[0].shape[0]
    nz = nz0 + nq + nr
    a = np.zeros((nz, nz))
    b = np.zeros((nz, 1))
    a[:nz0, :nz0] = ss.a
    if recon is None:
        b[:nz0] = ss.b
    else:  # the amplifier sees the filter's output c . r; the DAC feeds the filter
        ra, rb, rc = recon
        r = slice(nz0 + nq, nz)
        a[r, r] = ra
        b[r, 0] = rb
        a[:nz0, r] = np.outer(ss.b[:, 0], rc)
    accel_row = np.zeros(nz)
    accel_row[:nz0] = ss.accel_row
    if nq:
        a[nz0, :] = accel_row  # q' = x0'' - w_c q
        a[nz0, nz0] = -acc.corner_rad_s
    slices = {"coil_current_a": slice(0, 1), "stage_disp_m": slice(1, 2),
              "stage_vel_mps": slice(2, 3)}
    if with_chain:
        n = chain.n
        slices["theta_rad"] = slice(3, 3 + n)
        slices["omega_rad_s"] = slice(3 + n, 3 + 2 * n)
    if nq:
        slices["accel_highpass_q_mps"] = slice(nz0, nz0 + 1)
    if nr:
        slices["reconstruction_v"] = slice(nz0 + nq, nz)
    return a, b, accel_row, slices


def build_model(scene: Scene, *, method: str | None = None, oversample: int = 8,
                substeps: int = 1, rtol: float = 1e-10, atol: float = 1e-12,
                selection: dict | None = None) -> BenchModel:
    """Validate the scene's bench sections and build the :class:`BenchModel`.

    ``acquisition.model = "auto"`` runs :func:`select_model` (or takes ``selection``, its
    result for this scene). ``method`` (default ``"etdab"``), ``oversample``, ``substeps``,
    ``rtol``, ``atol`` matter for the nonlinear model only (module docstring): ``substeps``
    Lawson steps per DAC interval, or for the prescribed-stage methods ``oversample`` exact
    stage-acceleration instants per DAC interval (the pendulum sees them linearly interpolated)
    and ``substeps`` integrator steps per sub-interval.

    Raises
    ------
    ConfigError : a bad value in ``source``, ``stage``, ``accelerometer``, ``psd`` or
        ``acquisition`` (naming the key, the value and what is valid), or a prescribed-stage
        method with the stage reaction.
    """
    if not isinstance(scene, Scene):
        raise ConfigError(f"scene = {scene!r} is invalid: expected a rig.scene.Scene")
    acq = scene.acquisition
    fs, decimation = acq.simulation_rate_hz, acq.decimation
    source, stage, acc, lever = scene.source, scene.stage, scene.accelerometer, scene.lever
    model = acq.model
    if method is None:
        method = DEFAULT_METHOD
    if method not in NONLINEAR_METHODS:
        raise ConfigError(f"method = {method!r} is invalid: expected one of "
                          f"{', '.join(NONLINEAR_METHODS)}")
    for name, v in (("oversample", oversample), ("substeps", substeps)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"{name} = {v!r} is invalid: expected an integer >= 1")
    if model == "auto":
        if selection is None:
            selection = select_model(scene)
        model = selection["chosen"]
    else:
        selection = None
    if model == "nonlinear" and stage.reaction and method in PRESCRIBED_STAGE_METHODS:
        raise ConfigError(
            f"method = {method!r} is not supported with stage.reaction = true: it integrates the "
            "nonlinear pendulum on a prescribed stage motion, so the pendulum cannot load the "
            "stage. Use method 'lawson4' (the coupled nonlinear bench) or set "
            "stage.reaction = false")
    chain = scene.chain
    a, b, accel_row, slices = _bench_state_space(stage, chain, acc, with_chain=True,
                                                 source=source)
    h = 1.0 / fs
    phi, g0, _ = discretise(a, b, h, "zoh")
    kw = {}
    if model == "nonlinear" and method in COUPLED_METHODS:
        q_idx = slices["accel_highpass_q_mps"].start if acc.n_states else -1
        prm = rcoupled.coupled_params(chain, stage, a, q_idx=q_idx,
                                      wc=acc.corner_rad_s if acc.n_states else 0.0)
        if method == "lawson4":
            kw = dict(coupled=prm, lawson=rcoupled.lawson_matrices(a, b, h / substeps))
        else:
            hs = h / substeps
            phi_s, g_s, _ = discretise(a, b, hs, "zoh")
            phi_t = np.ascontiguousarray(phi_s.T)
            w = rcoupled.etd_ab_weights(a, prm.rows, hs, ETDAB_ORDER)
            kw = dict(coupled=prm, etdab=(phi_t, np.ascontiguousarray(g_s[:, 0]), w)
                      + rcoupled.etd_ab_sparsity(w, prm.a_rows))
    elif model == "nonlinear":
        sa, sb, srow, _ = _bench_state_space(stage, chain, acc, with_chain=False, source=source)
        sphi, sg0, _ = discretise(sa, sb, h / oversample, "zoh")
        kw = dict(stage_phi=np.ascontiguousarray(sphi), stage_gamma=np.ascontiguousarray(sg0[:, 0]),
                  stage_accel_row=srow)
    return BenchModel(scene=scene, source=source, stage=stage, accelerometer=acc, lever=lever,
                      fs_hz=fs, decimation=decimation, model=model, method=method,
                      oversample=int(oversample), substeps=int(substeps), rtol=float(rtol),
                      atol=float(atol), a=a, b=b, phi=np.ascontiguousarray(phi),
                      gamma=np.ascontiguousarray(g0[:, 0]), accel_row=accel_row, slices=slices,
                      selection=selection, **kw)


# ================================================================================================
# the state and one step
# ================================================================================================

@dataclass(frozen=True, eq=False)
class BenchState:
    """Everything carried from one block to the next.

    Attributes
    ----------
    index : samples produced so far (the next block starts at ``index / fs``).
    z : (n_states,) bench state at that instant (:attr:`BenchModel.slices`).
    source : the source's state.
    rng_states : ``bit_generator.state`` of the accelerometer and PSD noise streams.
    native : nonlinear path: the integrator's own state (``theta, omega`` or ``theta, p``).
    h_next_s : nonlinear dop853: its proposed next step [s].
    seed_entropy : the root SeedSequence's entropy (for the record).
    """

    index: int
    z: np.ndarray
    source: SourceState
    rng_states: dict
    native: np.ndarray | None = None
    h_next_s: float = float("nan")
    seed_entropy: int | None = None


def _spawn(seed) -> tuple[np.random.SeedSequence, list[np.random.SeedSequence]]:
    """The root sequence and one child per stream. A SeedSequence argument is copied first (its
    own ``spawn`` counter is not advanced), so the same seed always gives the same streams."""
    if isinstance(seed, np.random.SeedSequence):
        ss = np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key,
                                    pool_size=seed.pool_size)
    else:
        ss = np.random.SeedSequence(seed)
    return ss, ss.spawn(len(STREAMS))


def start(model: BenchModel, seed=0) -> BenchState:
    """The state at t = 0: stage at rest, pendulum at the scene's initial state, fresh streams
    spawned from ``seed`` (an int or a SeedSequence)."""
    root, children = _spawn(seed)
    sc = model.scene
    z = np.zeros(model.n_states)
    z[model.slices["theta_rad"]] = sc.theta0_rad
    z[model.slices["omega_rad_s"]] = sc.omega0_rad_s
    src = start_source(model.source, children[0])
    rngs = {name: np.random.PCG64(child).state  # a fresh dict of ints, owned by the state
            for name, child in zip(STREAMS[1:], children[1:])}
    native = None
    if model.model == "nonlinear" and model.method not in COUPLED_METHODS:
        native = model.solver.init(model.chain, np.concatenate([sc.theta0_rad, sc.omega0_rad_s]))
    entropy = root.entropy if isinstance(root.entropy, int) else None
    return BenchState(index=0, z=_readonly(z), source=src, rng_states=rngs, native=native,
                      seed_entropy=entropy)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _rng(state: dict) -> np.random.Generator:
    """A generator continuing from ``state`` (the dict is read, not kept)."""
    bg = np.random.PCG64(0)  # a fixed seed: cheaper than OS entropy, overwritten at once
    bg.state = state
    return np.random.Generator(bg)


@njit(cache=True, nogil=True)
def stage_fine_kernel(phi, gamma, row, v, m, z, z_out, a_fine):
    """Stage-only exact steps at h/m: z_out[k] = z at DAC instant k, a_fine[k m + j] = x0'' at
    sub-instant j of interval k (and a_fine[N m] at the end); z (in/out) ends at instant N."""
    nz = z.shape[0]
    tmp = np.empty(nz)
    n = v.shape[0]
    for k in range(n):
        vk = v[k]
        for r in range(nz):
            z_out[k, r] = z[r]
        for j in range(m):
            acc = 0.0
            for c in range(nz):
                acc += row[c] * z[c]
            a_fine[k * m + j] = acc
            for r in range(nz):
                s = gamma[r] * vk
                for c in range(nz):
                    s += phi[r, c] * z[c]
                tmp[r] = s
            for r in range(nz):
                z[r] = tmp[r]
    acc = 0.0
    for c in range(nz):
        acc += row[c] * z[c]
    a_fine[n * m] = acc


def _mirror_kinematics(scene: Scene, theta: np.ndarray, exact: bool):
    """Mirror-centre displacement relative to the stage (x along +x, z up) and rotation."""
    chain = scene.chain
    j, s = scene.mirror.body, scene.mirror.position_m
    lengths = np.asarray(chain.length_m)
    if not exact:
        return theta @ scene.mirror_weights(), np.zeros(theta.shape[0]), theta[:, j].copy()
    x = np.sin(theta[:, :j]) @ lengths[:j] + s * np.sin(theta[:, j])
    z = (1 - np.cos(theta[:, :j])) @ lengths[:j] + s * (1 - np.cos(theta[:, j]))
    return x, z, theta[:, j].copy()


def _check_finite(model, state, z_out, z, t0, n):
    """Once per block: every state finite, or DivergenceError with the block's start."""
    if not (np.all(np.isfinite(z_out)) and np.all(np.isfinite(z))):
        raise DivergenceError(
            f"bench ({model.model}): a non-finite state in the block starting at t = {t0:.9g} s "
            f"({n} samples); the state at its start was {np.asarray(state.z).tolist()}", t0,
            np.asarray(state.z))


def advance(model: BenchModel, state: BenchState, n: int, source_block=None
            ) -> tuple[AnalogBlock, BenchState]:
    """Run ``n`` samples from ``state``: the block (volts and truth at the instants
    ``(state.index + k) / fs``, k < n) and the state after it.

    ``source_block``: the source's next ``n`` samples and state, ``generate(model.source,
    state.source, n)``, when already computed (e.g. ahead, in another thread); checked to start at
    this block.

    Raises
    ------
    DivergenceError : a non-finite state in the block (with the block's start time and state).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigError(f"n_samples = {n!r} is invalid: expected an integer >= 1")
    n = int(n)
    fs = model.fs_hz
    t0 = state.index / fs
    if source_block is None:
        v, src = generate(model.source, state.source, n)
    else:
        v, src = source_block
        if v.shape != (n,) or src.index != state.source.index + n:
            raise ValueError(f"source_block covers samples up to {src.index} ({v.shape[0]}); "
                             f"expected {n} samples from {state.source.index}")
    sl = model.slices
    chain = model.chain
    z = np.array(state.z, dtype=float)
    native, h_next = state.native, state.h_next_s
    solver = model.solver
    if COUPLED_BENCH in solver.systems:  # the whole bench as one system
        z_out, accel, native = solver.advance_bench(model, z, native, v)
        _check_finite(model, state, z_out, z, t0, n)
        theta = z_out[:, sl["theta_rad"]]
        omega = z_out[:, sl["omega_rad_s"]]
        if accel is None:
            accel = z_out @ model.accel_row
    else:  # the pendulum on the exactly stepped stage's motion
        n2 = 2 * chain.n  # the stage-only system is z without theta, omega (same order)
        stage_idx = np.r_[0:3, 3 + n2:z.size]
        zs = z[stage_idx].copy()
        zs_out = np.empty((n, zs.size))
        m = model.oversample
        a_fine = np.empty(n * m + 1)
        stage_fine_kernel(model.stage_phi, model.stage_gamma, model.stage_accel_row, v, m, zs,
                          zs_out, a_fine)
        run = integrate(chain, native, a_fine, None, hold="linear", h_in=1.0 / (fs * m),
                        n_intervals=n * m, out_every=m, solver=solver, h0_s=h_next, t0_s=t0)
        native, h_next = run.native_end, run.h_next_s
        y = run.y_out  # (n + 1, 2n): theta, omega at the DAC instants
        z_out = np.empty((n, z.size))
        z_out[:, stage_idx] = zs_out
        z_out[:, sl["theta_rad"]] = y[:n, :chain.n]
        z_out[:, sl["omega_rad_s"]] = y[:n, chain.n:]
        z = np.empty(z.size)
        z[stage_idx] = zs
        z[sl["theta_rad"]] = y[n, :chain.n]
        z[sl["omega_rad_s"]] = y[n, chain.n:]
        _check_finite(model, state, z_out, z, t0, n)
        theta = z_out[:, sl["theta_rad"]]
        omega = z_out[:, sl["omega_rad_s"]]
        accel = a_fine[:n * m:m].copy()

    # sensors
    acc = model.accelerometer
    q = z_out[:, sl["accel_highpass_q_mps"]][:, 0] if acc.n_states else None
    rng_a = _rng(state.rng_states["accelerometer"])
    rng_x = _rng(state.rng_states["psd_x"])
    rng_y = _rng(state.rng_states["psd_y"])
    sensed, a_v, a_over = acc.sense_and_output(accel, q, fs, rng_a)
    mx, mz, mrot = _mirror_kinematics(model.scene, theta, exact=model.model == "nonlinear")
    reading = model.lever.measure(mx, mrot, fs, rng_x, rng_y, mirror_z_m=mz)
    rng_states = {"accelerometer": rng_a.bit_generator.state,  # fresh dicts (snapshots)
                  "psd_x": rng_x.bit_generator.state,
                  "psd_y": rng_y.bit_generator.state}

    truth = {
        "source_v": v,
        "stage_accel_mps2": accel,
        "stage_disp_m": z_out[:, 1].copy(),
        "stage_vel_mps": z_out[:, 2].copy(),
        "coil_current_a": z_out[:, 0].copy(),
        "theta_rad": np.ascontiguousarray(theta),
        "omega_rad_s": np.ascontiguousarray(omega),
        "mirror_x_m": mx,
        "mirror_z_m": mz,
        "mirror_rot_rad": mrot,
        "accel_sensed_mps2": sensed,
        "spot_u_m": reading.spot_u_m,
        "spot_v_m": reading.spot_v_m,
        "a_overrange": a_over,
        "psd_off_detector": reading.off_detector,
    }
    block = AnalogBlock(t0_s=t0, fs_hz=fs, volts={"a": a_v, "x": reading.x_v, "y": reading.y_v},
                        truth=truth)
    new = BenchState(index=state.index + n, z=_readonly(z), source=src, rng_states=rng_states,
                     native=None if native is None else _readonly(np.array(native)),
                     h_next_s=float(h_next), seed_entropy=state.seed_entropy)
    return block, new


def _block_sizes(fs: float, decimation: int, block_s, duration_s) -> list[int]:
    """Samples per block for :meth:`BenchSimulation.blocks` (one block if ``duration_s`` is
    None), or :class:`ConfigError` naming the bad value."""
    r = block_s * fs if isinstance(block_s, (int, float)) and not isinstance(block_s, bool) \
        else float("nan")
    n = int(round(r)) if math.isfinite(r) else 0
    if n < 1 or abs(r - n) > _REL * max(1.0, r) or n % decimation:
        raise ConfigError(f"block_s = {block_s!r} s is invalid: expected a whole number (>= 1)"
                          f" of ADC samples at acquisition.rate_hz = {fs / decimation:g} Hz")
    if duration_s is None:
        return [n]
    total = duration_s * fs if isinstance(duration_s, (int, float)) else float("nan")
    if not (math.isfinite(total) and total >= 1 and abs(total - round(total)) <= _REL * total):
        raise ConfigError(f"duration_s = {duration_s!r} s is invalid: expected a whole number "
                          f"(>= 1) of samples at {fs:g} Hz")
    left = int(round(total))
    sizes = []
    while left > 0:
        sizes.append(min(n, left))
        left -= sizes[-1]
    return sizes


def _source_blocks(source, state, sizes):
    """``generate(source, ., k)`` for each k of ``sizes`` in turn, from ``state``."""
    for k in sizes:
        v, state = generate(source, state, k)
        yield v, state


# ================================================================================================
# the stateful wrapper
# ================================================================================================

class BenchSimulation:
    """A running bench: :func:`build_model` + :func:`start` + repeated :func:`advance`.

    Parameters
    ----------
    scene : the scene (its ``source``, ``stage``, ``accelerometer``, ``psd`` and ``acquisition``
        sections).
    seed : int or SeedSequence for every random stream of the run.
    method, oversample, substeps, rtol, atol : nonlinear-model settings (:func:`build_model`).

    ahead : ``(block_s, duration_s)`` of the first :meth:`blocks` call to come: its source is
        made from now on in another thread (the source does not depend on the model; numpy's
        FFTs release the GIL), while the model is chosen and the compiled kernels load. A later
        call with other arguments, or after other steps, makes its own.

    With ``acquisition.model = "auto"`` the model is chosen at construction (:func:`select_model`).
    ``next_block(n)`` returns the next n samples, ``blocks(block_s, duration_s)`` yields blocks of
    ``block_s`` seconds; both continue where the previous call stopped. ``state`` is the current
    :class:`BenchState` (assignable, e.g. to rewind).
    """

    #: source blocks made ahead at most (10 s blocks at 1 kHz: 64 x 80 kB)
    AHEAD_BLOCKS = 64

    def __init__(self, scene: Scene, seed=0, *, method: str | None = None, oversample: int = 8,
                 substeps: int = 1, rtol: float = 1e-10, atol: float = 1e-12,
                 ahead: tuple[float, float] | None = None):
        root, children = _spawn(seed)
        self.seed = root  # seed=None draws OS entropy once; root.entropy is then the record
        self._ahead = None
        if ahead is not None:
            acq, source = scene.acquisition, scene.source
            sizes = _block_sizes(acq.simulation_rate_hz, acq.decimation, *ahead)
            made = Prefetch(_source_blocks(source, start_source(source, children[0]), sizes),
                            self.AHEAD_BLOCKS)
            self._ahead = (tuple(ahead), sizes, made)
        self.model = build_model(scene, method=method, oversample=oversample, substeps=substeps,
                                 rtol=rtol, atol=atol)
        self.state = start(self.model, root)
        self._info = None

    @property
    def fs_hz(self) -> float:
        """Simulation rate [Hz]."""
        return self.model.fs_hz

    @property
    def time_s(self) -> float:
        """Time of the next sample [s]."""
        return self.state.index / self.model.fs_hz

    def next_block(self, n_samples: int) -> AnalogBlock:
        """The next ``n_samples`` samples as an :class:`AnalogBlock`."""
        block, self.state = advance(self.model, self.state, n_samples)
        return block

    def blocks(self, block_s: float, duration_s: float | None = None) -> Iterator[AnalogBlock]:
        """Blocks of ``block_s`` seconds (a whole number of samples, and of ADC samples), for
        ``duration_s`` seconds (a whole number of blocks' worth; the last block may be shorter)
        or for ever (None)."""
        fs = self.model.fs_hz
        if duration_s is None:
            n = _block_sizes(fs, self.model.decimation, block_s, None)[0]
            while True:
                yield self.next_block(n)
        sizes = _block_sizes(fs, self.model.decimation, block_s, duration_s)
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead[0] == (block_s, duration_s) and self.state.index == 0:
            made = ahead[2]
        else:
            if ahead is not None:
                ahead[2].close()
            # the source does not depend on the bench: its blocks are made ahead in a thread
            made = Prefetch(_source_blocks(self.model.source, self.state.source, sizes), 2)
        try:
            for k, src in zip(sizes, made):
                block, self.state = advance(self.model, self.state, k, src)
                yield block
        finally:
            made.close()

    def run(self, duration_s: float) -> AnalogBlock:
        """The next ``duration_s`` seconds as one block."""
        r = duration_s * self.model.fs_hz
        n = int(round(r))
        if n < 1 or abs(r - n) > _REL * max(1.0, r):
            raise ConfigError(f"duration_s = {duration_s!r} s is invalid: expected a whole number "
                              f"(>= 1) of samples at {self.model.fs_hz:g} Hz")
        return self.next_block(n)

    def calibrations(self) -> dict[str, Calibration]:
        """Per-channel calibrations (:func:`calibrations`)."""
        return _calibrations(self.model)

    def model_info(self, *, probe_s: float = 20.0) -> dict:
        """What runs, why, and how accurate it is (computed once, cached; JSON-ready).

        Keys: ``model`` ("linear" or "nonlinear": what runs), ``requested_model``
        (``acquisition.model``), ``error_budget``, ``reason`` (a sentence: the choice and the
        numbers behind it), ``budget_met`` (the estimated error of the model that runs is within
        the budget), ``selection`` (:func:`select_model`, with the predictor's ``how``),
        ``method`` (how it is integrated), ``error_estimate`` (``max_abs_theta_rad`` first,
        ``relative_rms_theta``: the total relative RMS angle error, and its parts),
        ``error_method``, ``linearity`` (rms angles and the frequency-shift rule of thumb),
        ``states``, ``seed``, ``probe_s``, ``fs_hz``, ``hold``, ``reaction``,
        ``estimate_wall_time_s``. The error of the nonlinear model's integrator and the linear
        model's round-off are measured on a ``probe_s`` run of the scene's drive from rest.
        """
        if self._info is None or self._info["probe_s"] != probe_s:
            self._info = _model_info(self.model, probe_s=probe_s, seed=self.seed)
        return self._info


# ================================================================================================
# calibrations and analytic responses
# ================================================================================================

def _calibrations(model: BenchModel) -> dict[str, Calibration]:
    cal = {"a": model.accelerometer.calibration()}
    cal.update(model.lever.calibrations())
    return cal


def calibrations(scene: Scene) -> dict[str, Calibration]:
    """Channel calibrations: ``a`` [V per m/s^2] (pass band, polarity included), ``x`` [V per m of
    mirror translation relative to the stage], ``y`` [V per rad of mirror rotation]."""
    return {"a": scene.accelerometer.calibration(), **scene.lever.calibrations()}


@dataclass(frozen=True, eq=False)
class BenchResponse:
    """Exact linear responses of the bench, per source volt unless stated (complex, (nf,)).

    Attributes
    ----------
    freqs_hz : (nf,) [Hz].
    a, x, y : channel volts per source volt [V/V] (sensor responses included, noise excluded).
    stage_accel : [(m/s^2)/V];  stage_disp : [m/V];  theta : (nf, n) [rad/V].
    mirror_x : [m/V] translation relative to the stage;  mirror_rot : [rad/V].
    h_t, theta_2 : what the analyzer shows in engineering units with the calibrations undone:
        (x / cal_x) / (a / cal_a) [m per m/s^2] and (y / cal_y) / (a / cal_a) [rad per m/s^2];
        the accelerometer's high-pass is in the denominator (at 0.1 Hz +0.97 dB, -26.6 deg for
        the default 0.05 Hz corner).
    h_t_pendulum, theta_2_pendulum : the pendulum alone, mirror_x / stage_accel and
        mirror_rot / stage_accel (:func:`rig.describe.mirror_response`).
    sampled : False: continuous-time chain times the DAC's hold ``(1 - e^{-i w h}) / (i w h)``
        (what an ideally anti-aliased measurement sees); True: the exact transfer function from
        the DAC samples to the simulated samples, ``C (e^{i w h} I - Phi)^-1 Gamma``, which also
        contains the hold's images folded back by sampling at the DAC rate.
    """

    freqs_hz: np.ndarray
    a: np.ndarray
    x: np.ndarray
    y: np.ndarray
    stage_accel: np.ndarray
    stage_disp: np.ndarray
    theta: np.ndarray
    mirror_x: np.ndarray
    mirror_rot: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    h_t_pendulum: np.ndarray
    theta_2_pendulum: np.ndarray
    sampled: bool

    def response(self, *names: str) -> FrequencyResponse:
        """The named fields (default ``"h_t", "theta_2"``) as one
        :class:`rig.linear.FrequencyResponse`, one column per name."""
        names = names or ("h_t", "theta_2")
        bad = [n for n in names if n not in _RESPONSE_FIELDS]
        if bad:
            raise ConfigError(f"fields {bad} are invalid: expected some of {_RESPONSE_FIELDS}")
        return FrequencyResponse(self.freqs_hz, np.stack([getattr(self, n) for n in names], -1),
                                 tuple(names))


_RESPONSE_FIELDS = ("a", "x", "y", "stage_accel", "stage_disp", "mirror_x", "mirror_rot", "h_t",
                    "theta_2", "h_t_pendulum", "theta_2_pendulum")


def expected_response(scene: Scene, freqs_hz, *, sampled: bool = False) -> BenchResponse:
    """The exact linear response of the whole chain source -> channels at ``freqs_hz`` [Hz].

    ``sampled=False`` (default) uses the closed forms of the parts (:meth:`Stage.
    frequency_response`, :meth:`Accelerometer.frequency_response`, :meth:`OpticalLever.
    frequency_response`) times the DAC hold; ``sampled=True`` the exact discrete-time transfer
    function of the simulated samples (:class:`BenchResponse`). Both use the linear pendulum and
    the linearised optical lever; both need ``0 <= f < fs / 2``.
    """
    model = build_model(scene) if scene.acquisition.model == "linear" else \
        build_model(_as_linear(scene))
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    fs = model.fs_hz
    if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f >= fs / 2):
        raise ConfigError(f"freqs_hz must lie in [0, {fs / 2:g}) Hz (half the simulation rate)")
    chain = scene.chain
    acc, lever = model.accelerometer, model.lever
    h = 1.0 / fs
    w = 2 * np.pi * f
    if sampled:
        zf = np.exp(1j * w * h)
        nz = model.n_states
        mats = zf[:, None, None] * np.eye(nz)[None] - model.phi[None]
        resp = np.linalg.solve(mats, np.broadcast_to(model.gamma.astype(complex), (f.size, nz))
                               [..., None])[..., 0]  # (nf, nz): state per source volt
        sl = model.slices
        stage_accel = resp @ model.accel_row
        stage_disp = resp[:, 1]
        theta = resp[:, sl["theta_rad"]]
        if acc.n_states:
            sensed = stage_accel - acc.corner_rad_s * resp[:, sl["accel_highpass_q_mps"]][:, 0]
        else:
            sensed = stage_accel
        a = acc.volts_per_mps2 * sensed
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            zoh = np.where(w > 0, (1 - np.exp(-1j * w * h)) / (1j * w * h), 1.0)
        st = model.stage.frequency_response(f, chain)
        drive = zoh * model.source.reconstruction_response(f)
        stage_accel = st.accel * drive
        stage_disp = st.disp * drive
        theta = st.theta * drive[:, None]
        a = acc.frequency_response(f) * stage_accel
    mirror_x = theta @ scene.mirror_weights()
    mirror_rot = theta[:, scene.mirror.body]
    cal = _calibrations(model)
    x = cal["x"].volts_per_unit * mirror_x
    y = cal["y"].volts_per_unit * mirror_rot
    a_eng = a / cal["a"].volts_per_unit
    with np.errstate(invalid="ignore", divide="ignore"):
        h_t = (x / cal["x"].volts_per_unit) / a_eng
        theta_2 = (y / cal["y"].volts_per_unit) / a_eng
        h_t_p = mirror_x / stage_accel
        th2_p = mirror_rot / stage_accel
    return BenchResponse(freqs_hz=f, a=a, x=x, y=y, stage_accel=stage_accel,
                         stage_disp=stage_disp, theta=theta, mirror_x=mirror_x,
                         mirror_rot=mirror_rot, h_t=h_t, theta_2=theta_2, h_t_pendulum=h_t_p,
                         theta_2_pendulum=th2_p, sampled=bool(sampled))


def _as_linear(scene: Scene) -> Scene:
    return scene.with_acquisition(model="linear")


def _source_psd(source: Source, f: np.ndarray) -> np.ndarray:
    """One-sided PSD of the source [V^2/Hz] used for level estimates: the design PSD of the
    noise types (burst random scaled by its on-fraction), a flat band of the same power for the
    chirp; None for a sine (a line)."""
    if source.type in NOISE_TYPES:
        p = source.design_psd(f)
        if source.type == "burst-random":
            p = p * source.burst_samples / source.period_samples
        return p
    if source.type == "periodic-chirp":
        inband = (f >= source.fmin_hz) & (f <= source.fmax_hz)
        return np.where(inband, source.level_vrms**2 / (source.fmax_hz - source.fmin_hz), 0.0)
    return None


def stationary_levels(scene: Scene, *, points: int = 100_001) -> dict:
    """Analytic stationary rms levels of the default drive (linear model, reaction as set):
    stage acceleration, stroke, angles, mirror translation and spot positions, from the
    source PSD and :func:`expected_response` (``sampled=False``) integrated over 0..fmax.
    For a sine source the rms of the steady-state line."""
    model = build_model(_as_linear(scene))
    src = model.source
    if src.type == "sine":
        f = np.array([src.frequency_hz])
        r = expected_response(scene, f)
        amp2 = np.full(1, src.level_vrms**2)  # rms^2 of the line

        def rms(hh):
            return float(np.sqrt(np.sum(np.abs(hh) ** 2 * amp2)))
    else:
        f = np.linspace(0.0, src.fmax_hz * (1 + 1e-9), points)
        f = f[f < model.fs_hz / 2]
        r = expected_response(scene, f)
        p = _source_psd(src, f)
        df = f[1] - f[0]

        def rms(hh):
            return float(np.sqrt(np.sum(np.abs(hh) ** 2 * p) * df))
    lever = model.lever
    return {
        "stage_accel_mps2": rms(r.stage_accel),
        "stage_disp_m": rms(r.stage_disp),
        "theta_rad": [rms(r.theta[:, j]) for j in range(scene.chain.n)],
        "mirror_x_m": rms(r.mirror_x),
        "mirror_rot_rad": rms(r.mirror_rot),
        "spot_u_m": rms(r.mirror_x * lever.spot_per_translation),
        "spot_v_m": rms(r.mirror_rot * lever.spot_per_rotation_m),
        "a_v": rms(r.a),
        "x_v": rms(r.x),
        "y_v": rms(r.y),
    }


def signal_to_noise(scene: Scene, freqs_hz) -> dict[str, np.ndarray]:
    """Analytic signal-to-noise ratio of each channel [dB] at ``freqs_hz``: the channel's PSD
    under the scene's (noise-type) source over its sensor's white noise PSD."""
    model = build_model(_as_linear(scene))
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    p = _source_psd(model.source, f)
    if p is None:
        raise ConfigError("signal_to_noise needs a broadband source (not source.type = 'sine')")
    r = expected_response(scene, f)
    acc, lever = model.accelerometer, model.lever
    noise_a = (acc.sensitivity_vpmps2 * acc.noise_mps2_rthz) ** 2
    noise_x = (lever.gain_vpm * lever.noise_m_rthz) ** 2
    with np.errstate(divide="ignore"):
        return {
            "a": 10 * np.log10(np.abs(r.a) ** 2 * p / noise_a),
            "x": 10 * np.log10(np.abs(r.x) ** 2 * p / noise_x),
            "y": 10 * np.log10(np.abs(r.y) ** 2 * p / noise_x),
        }


# ================================================================================================
# the linearisation error, the model choice
# ================================================================================================

def _predictor_rate(scene: Scene, fs: float) -> float:
    """The predictor's reduced rate: the lowest fs / k >= 8 x (the highest source or pendulum
    frequency) at which the scene's source is valid (whole-sample periods)."""
    src = scene.source
    f_src = src.frequency_hz if src.type == "sine" else src.fmax_hz
    f_modes = scene.chain.modes()[0]
    f_top = max(float(f_src), float(np.max(f_modes)) if f_modes.size else 0.0)
    k_max = max(1, int(fs // (8.0 * f_top))) if f_top > 0 else 1
    for k in range(k_max, 0, -1):
        try:
            dataclasses.replace(src, reconstruction_hz=0.0, fs_hz=fs / k)
        except ConfigError:
            continue
        return fs / k
    return fs


def _amplitude_time_constant_s(chain: Chain) -> float:
    """The longest modal amplitude time constant tau = Q / (pi f) [s] (inf if undamped)."""
    f, q = chain.modes()
    if f.size == 0:
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(np.isfinite(q), q / (np.pi * f), np.inf)
    return float(np.max(tau))


def predict_linearisation_error(scene: Scene, *, decide_at: float | None = None) -> dict:
    """Predicted error of the exact linear model against the nonlinear bench (module docstring,
    "The predictor"): relative RMS of ``theta_lin - theta_nl`` over the recorded span per body.

    Returns a dict (JSON-ready): ``relative_rms_theta`` (n,) the estimate (pooled over the
    batches); ``spread_relative_rms_theta`` (n,) the standard deviation of a single run's value
    about it (the run's own drive is another realisation); ``uncertainty_relative_rms_theta``
    (n,) the standard deviation of the estimate itself; ``upper_relative_rms_theta`` (n,) =
    estimate + t sqrt(spread^2 + uncertainty^2) (t the 97.5 % Student-t quantile for the
    batches' degrees of freedom, 2.36 for 8 batches); ``max`` / ``upper`` (the largest over the
    bodies); ``max_abs_theta_rad`` (largest |theta_lin - theta_nl| seen); ``theta_rms_rad`` (n,)
    of the linear bench; ``rate_hz``, ``realisations``, ``batches``, ``tau_s``,
    ``probe_settle_s``, ``probe_recorded_s`` (per realisation), ``simulated_s``, ``how``.

    ``first_order_valid``: the largest |d_theta| anywhere in the run (settling included) stays
    below ``FIRST_ORDER_LIMIT`` (0.1) of the largest |theta|; otherwise the prediction is only
    an order of magnitude. ``decide_at``: a budget; stop after the realisations done so far
    once every one of them is over 10 x ``decide_at`` (one suffices), under ``decide_at`` / 10
    (two needed) or the first order fails: the decision is then not in doubt (e.g. a pendulum
    released far from rest, or a tiny drive on an expensive chain); the statistics come from
    those realisations (``stopped_early``: "under" or "over", else "").
    """
    acq = scene.acquisition
    fs = acq.simulation_rate_hz
    chain = scene.chain
    n = chain.n
    stage = scene.stage
    fr = _predictor_rate(scene, fs)
    src = dataclasses.replace(scene.source, reconstruction_hz=0.0, fs_hz=fr)
    ss = stage.state_space(chain)
    a = ss.a
    nz = a.shape[0]
    hr = 1.0 / fr
    phi, g0, g1 = discretise(a, ss.b, hr, "linear")
    prm = rcoupled.coupled_params(chain, stage, a)
    nf = prm.rows.size
    bf = np.zeros((nz, nf))
    bf[prm.rows, np.arange(nf)] = 1.0
    _, gf0, gf1 = discretise(a, bf, hr, "linear")
    settle, t_rec = float(acq.settle_s), float(acq.records * acq.record_s)
    tau = _amplitude_time_constant_s(chain)
    nb_all = PREDICTOR_BATCHES
    if math.isfinite(tau) and t_rec >= 2 * nb_all * tau:
        # a long run: one realisation cut into 8 batches of >= 2 tau; longer than 24 tau, its
        # records are stationary after 5 tau and a probe of 5 tau + 24 tau estimates them
        # (conservatively: a shorter settle only lowers the error)
        k_runs, batches = 1, nb_all
        if t_rec > 3 * nb_all * tau:
            settle_p, rec_p = 5 * tau, 3 * nb_all * tau
        else:
            settle_p, rec_p = settle, t_rec
    else:  # a short run: 8 independent realisations of it
        k_runs, batches = nb_all, 1
        settle_p, rec_p = settle, t_rec
    n_tot = max(1, int(round((settle_p + rec_p) * fr)))
    k_rec = min(int(round(settle_p * fr)), n_tot - 1)
    sums = np.zeros((k_runs, batches, 3, n))
    z0 = np.zeros(nz)
    z0[3:3 + n] = scene.theta0_rad
    z0[3 + n:3 + 2 * n] = scene.omega0_rad_s
    g0c, g1c = np.ascontiguousarray(g0[:, 0]), np.ascontiguousarray(g1[:, 0])
    gf0, gf1 = np.ascontiguousarray(gf0), np.ascontiguousarray(gf1)
    stopped_early = ""
    peaks = np.zeros((k_runs, 2, n))
    for r, child in enumerate(np.random.SeedSequence(PREDICTOR_ENTROPY).spawn(k_runs)):
        v, _ = generate(src, start_source(src, child), n_tot + 1)
        z, d = z0.copy(), np.zeros(nz)
        rcoupled.first_order_kernel(*prm.args(), phi, g0c, g1c, gf0, gf1, v, z, d, k_rec,
                                    batches, sums[r], peaks[r])
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(d))):
            raise DivergenceError("the linearisation-error predictor diverged (is the linear "
                                  "bench unstable?)", 0.0, z)
        if decide_at is not None and k_runs > 1 and r + 1 < k_runs:
            with np.errstate(divide="ignore", invalid="ignore"):
                e_r = np.nan_to_num(np.sqrt(sums[:r + 1, 0, 1, :] / sums[:r + 1, 0, 0, :]))
            e_r = e_r.max(axis=1)  # (runs so far,): the worst body of each
            invalid = np.max(peaks[:r + 1, 1]) > FIRST_ORDER_LIMIT * np.max(peaks[:r + 1, 0])
            under = r >= 1 and np.all(e_r < decide_at / 10)
            if invalid or np.all(e_r > 10 * decide_at) or under:
                stopped_early = "under" if under else "over"
                k_runs = r + 1
                sums, peaks = sums[:k_runs], peaks[:k_runs]
                break
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = float(np.nan_to_num(np.max(peaks[:, 1, :]) / np.max(peaks[:, 0, :])))
    first_order_valid = ratio <= FIRST_ORDER_LIMIT
    t2 = sums[:, :, 0, :].reshape(-1, n)
    d2 = sums[:, :, 1, :].reshape(-1, n)
    nb = t2.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        if k_runs == 1:  # pooled ratio; delete-one-batch jackknife for its uncertainty
            pooled = np.where(t2.sum(0) > 0, np.sqrt(d2.sum(0) / t2.sum(0)), 0.0)
            loo_t = t2.sum(0) - t2
            e_loo = np.where(loo_t > 0, np.sqrt((d2.sum(0) - d2) / loo_t), 0.0)
            unc = SPREAD_CALIBRATION * np.sqrt(
                (nb - 1) / nb * np.sum((e_loo - e_loo.mean(0)) ** 2, axis=0))
            spread = unc * math.sqrt(rec_p / t_rec)  # the variance shrinks as 1 / length
        else:  # the runs' own values: their mean, their scatter
            e_k = np.where(t2 > 0, np.sqrt(d2 / t2), 0.0)
            pooled = e_k.mean(0)
            spread = e_k.std(0, ddof=1) if nb > 1 else pooled.copy()
            unc = spread / math.sqrt(nb)
    t975 = _T975.get(nb - 1, 2.0)  # Student-t: the spread is itself estimated from nb values
    upper = pooled + t975 * np.sqrt(spread**2 + unc**2)
    n_rec = n_tot + 1 - k_rec
    theta_rms = np.sqrt(t2.sum(0) / (k_runs * n_rec))
    how = (f"first-order perturbation: the linear bench (coil, stage, pendulum"
           f"{' with its reaction' if stage.reaction else ''}) and its first-order linearisation "
           "error d' = A d + f(z_lin) (f: nonlinear minus linear accelerations along the linear "
           f"trajectory), both discretised exactly at {fr:g} Hz (first-order hold) and driven by "
           f"the scene's source regenerated at that rate (own random stream); {k_runs} run(s) of "
           f"{settle_p:g} s settle + {rec_p:g} s recorded from the scene's initial state (the "
           f"run: {settle:g} s + {t_rec:g} s; longest amplitude time constant tau = {tau:.3g} s), "
           f"each recorded span in {batches} batch(es); one run: estimate = pooled RMS ratio, "
           "its uncertainty = the delete-one-batch jackknife standard deviation times "
           f"{SPREAD_CALIBRATION:g} (the jackknife of 8 batches underestimates the scatter by "
           "20-35 %, measured over 30 predictor streams), spread of the actual run = that times "
           "sqrt(probe records / run records); several runs: estimate = their mean, spread = "
           "their standard deviation, uncertainty = spread / sqrt(runs); "
           "upper = estimate + t sqrt(spread^2 + "
           f"uncertainty^2), t = {t975:.3g} the two-sided 95 % Student-t quantile for "
           f"{nb - 1} degrees of freedom. Exact to first order: the neglected term is O(e^2) "
           "relative")
    return {
        "relative_rms_theta": pooled.tolist(),
        "spread_relative_rms_theta": spread.tolist(),
        "uncertainty_relative_rms_theta": unc.tolist(),
        "upper_relative_rms_theta": upper.tolist(),
        "max": float(np.max(pooled)),
        "upper": float(np.max(upper)),
        "max_abs_theta_rad": float(np.max(sums[:, :, 2, :])),
        "theta_rms_rad": theta_rms.tolist(),
        "rate_hz": fr,
        "realisations": k_runs,
        "batches": batches,
        "tau_s": tau,
        "probe_settle_s": settle_p,
        "probe_recorded_s": rec_p,
        "simulated_s": k_runs * n_tot / fr,
        "stopped_early": stopped_early,
        "first_order_valid": first_order_valid,
        "peak_error_over_peak_theta": ratio,
        "how": how + (f"; stopped after {k_runs} run(s), the decision at {decide_at:g} being "
                      "clear" if stopped_early else ""),
    }


def select_model(scene: Scene) -> dict:
    """The model for ``acquisition.model`` and ``acquisition.error_budget``, and why.

    ``auto``: ``linear`` if the upper predicted linearisation error
    (:func:`predict_linearisation_error`) is within the budget, else ``nonlinear``; a forced
    model is kept and the same prediction says whether the linear model meets the budget.
    Returns a dict (JSON-ready): ``requested``, ``chosen``, ``error_budget``,
    ``linear_meets_budget``, ``predicted_linear_error`` (the max over bodies), its ``upper``,
    ``reason`` (a sentence), ``prediction`` (the predictor's dict, with ``how``).
    """
    requested = scene.acquisition.model
    budget = scene.acquisition.error_budget
    tic = time.perf_counter()
    pred = predict_linearisation_error(scene, decide_at=budget)
    e, up = pred["max"], pred["upper"]
    # (a prediction stopped early as clearly under the budget is under it, whatever the
    # Student-t factor of two runs makes of their scatter)
    ok = (up <= budget or pred["stopped_early"] == "under") and pred["first_order_valid"]
    th = ", ".join(f"{x:.2g}" for x in pred["theta_rms_rad"])
    told = (f"the predicted linearisation error (relative RMS of the angles over the records) "
            f"is {e:.2g} (upper {up:.2g}) at {th} rad rms")
    if not pred["first_order_valid"]:
        told += (f", and that is only an order of magnitude: the first-order error reaches "
                 f"{pred['peak_error_over_peak_theta']:.2g} of the largest angle during the run")
    if requested == "auto":
        chosen = "linear" if ok else "nonlinear"
        if ok:
            reason = (f"auto: {told}, within the error budget {budget:g}: the exact linear model "
                      "(round-off only) is the cheapest that meets it")
        else:
            reason = (f"auto: {told}, over the error budget {budget:g}: the linear model is not "
                      "enough, the nonlinear model runs")
    else:
        chosen = requested
        if requested == "linear":
            reason = (f"forced by acquisition.model = 'linear'; {told}, "
                      + (f"within the error budget {budget:g}" if ok else
                         f"OVER the error budget {budget:g} ('auto' would run the nonlinear "
                         "model)"))
        else:
            reason = (f"forced by acquisition.model = 'nonlinear'; {told}, "
                      + (f"so the linear model would have met the budget {budget:g} ('auto' "
                         "would run it)" if ok else f"over the budget {budget:g}"))
    return {"requested": requested, "chosen": chosen, "error_budget": budget,
            "linear_meets_budget": bool(ok), "predicted_linear_error": e,
            "predicted_linear_error_upper": up, "reason": reason, "prediction": pred,
            "predict_wall_time_s": time.perf_counter() - tic}


# ================================================================================================
# model information and error estimates
# ================================================================================================

def model_info(scene: Scene, *, seed=0, probe_s: float = 20.0, method: str | None = None,
               oversample: int = 8, substeps: int = 1) -> dict:
    """Which model runs, why, how, and its error estimate (measured on a ``probe_s`` run of the
    scene's own drive from rest); see :meth:`BenchSimulation.model_info`."""
    return _model_info(build_model(scene, method=method, oversample=oversample,
                                   substeps=substeps), probe_s=probe_s, seed=seed)


def _probe_theta(model: BenchModel, n: int, seed) -> np.ndarray:
    """Angles of an n-sample run from rest through the full bench (sensors included)."""
    blk, _ = advance(model, start(model, seed), n)
    return blk.truth["theta_rad"]


def _kernel_theta(model: BenchModel, v: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Angles at the DAC instants of the linear, lawson4 or etdab kernel alone (no sensors)."""
    z_out, _, _ = model.solver.advance_bench(model, z0.copy(), None, v)
    return z_out[:, model.slices["theta_rad"]]


def _richardson_estimate(scene, model: BenchModel, v: np.ndarray, z0: np.ndarray,
                         order: int) -> dict:
    """Error estimate of a coupled-bench method of ``order`` on the probe input ``v``: Richardson
    against the same method with twice the steps per DAC sample, ``|theta - theta_fine| 2^p /
    (2^p - 1)`` [rad], and the nonlinear-minus-linear model difference on the probe."""
    theta = _kernel_theta(model, v, z0)
    fine = build_model(scene, method=model.method, substeps=2 * model.substeps,
                       selection=model.selection)
    diff = (theta - _kernel_theta(fine, v, z0)) * (2.0**order / (2.0**order - 1.0))
    lin = _kernel_theta(build_model(_as_linear(scene)), v, z0)
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


def _model_info(model: BenchModel, *, probe_s: float, seed) -> dict:
    scene = model.scene
    acq = scene.acquisition
    fs = model.fs_hz
    n = max(1, int(round(probe_s * fs)))
    tic = time.perf_counter()
    sel = model.selection if model.selection is not None else select_model(scene)
    budget = sel["error_budget"]
    info = {
        "model": model.model,
        "requested_model": acq.model,
        "error_budget": budget,
        "reason": sel["reason"],
        "fs_hz": fs,
        "hold": "zoh: the source DAC value is held for 1/fs; the stage acceleration it makes is "
                "continuous",
        "reaction": model.stage.reaction,
        "states": model.state_names(),
        "seed": model_seed(model, seed),
        "probe_s": probe_s,
        "selection": sel,
    }
    info["per_sample"] = {
        "rate_hz": fs,
        "what": "the bench state (one exact step per DAC sample), the optical lever's exact "
                "geometry, the sensors' white noise (one draw per sample and channel), the "
                "clipping at the detector edge and the accelerometer's range with their flags, "
                "and the anti-alias filter",
        "why": "not linear, so not lifted to the output rate: the lever's second-order "
               "geometry is ~0.4 % of the spot's rms in u (far above round-off), clipping and "
               "flags act on each sample, and the filter's input is the sum of those and the "
               "noise",
    }
    pred = sel["prediction"]
    _, q = scene.chain.modes()
    qmax = float(np.max(q)) if q.size else math.inf
    th3 = 3 * max(pred["theta_rms_rad"])
    shift = th3**2 / 16  # relative frequency shift of a pendulum at amplitude th3
    info["linearity"] = {
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
    root, children = _spawn(seed)
    v, _ = generate(model.source, start_source(model.source, children[0]), n)
    z0 = np.array(start(model, root).z)
    if model.model == "linear":
        info["method"] = ("exact discretisation (zero-order hold, matrix exponential) of the "
                          "coupled linear bench: coil, stage, linearised pendulum"
                          + (" with its reaction" if model.stage.reaction else "")
                          + ", accelerometer high-pass; compiled loop, one step per DAC sample")
        theta = _kernel_theta(model, v, z0)
        theta2 = _kernel_theta(_half_step_model(model), v, z0)
        e_disc = float(np.max(np.abs(theta - theta2)))
        rel_disc = _rel_rms(theta - theta2, theta)
        e_lin = pred["max"]
        info["error_estimate"] = {
            "max_abs_theta_rad": pred["max_abs_theta_rad"] + e_disc,
            "relative_rms_theta": e_lin + rel_disc,
            "linearisation_relative_rms_theta": e_lin,
            "linearisation_upper_relative_rms_theta": pred["upper"],
            "discretisation_max_abs_theta_rad": e_disc,
            "discretisation_relative_rms_theta": rel_disc,
        }
        info["error_method"] = (
            "linearisation (the model error, against the nonlinear bench): predicted, see "
            "selection.prediction.how; discretisation: |theta_h - theta_h/2| over a "
            f"{probe_s:g} s probe of the scene's drive from rest against the same exact "
            "discretisation with two half steps per DAC sample (round-off only)")
    elif model.method == "etdab":
        loads = " that it loads (reaction)" if model.stage.reaction else ""
        info["method"] = (
            f"nonlinear pendulum on the stage{loads}, the whole bench as one system "
            "(rig.coupled): the linear bench propagated exactly (matrix exponential, zero-order "
            "hold), the nonlinear remainder by exponential Adams-Bashforth of order "
            f"{ETDAB_ORDER} (its integral over a step from the polynomial through its last "
            f"{ETDAB_ORDER} values, one evaluation per step), {model.substeps} step(s) per DAC "
            "sample")
        info["error_estimate"] = _richardson_estimate(scene, model, v, z0, ETDAB_ORDER)
        info["error_method"] = (
            f"Richardson on a {probe_s:g} s probe of the scene's drive from rest: |theta - "
            f"theta(2x steps)| 2^{ETDAB_ORDER}/(2^{ETDAB_ORDER} - 1) (the error is that of the "
            "small nonlinear remainder: the linear part is exact). "
            "'probe_nonlinear_minus_linear' is the model difference on the probe (the run's is "
            "predicted in 'selection')")
    elif model.method == "lawson4":
        loads = " that it loads (reaction)" if model.stage.reaction else ""
        info["method"] = (f"nonlinear pendulum on the stage{loads}, the whole bench as one "
                          "system (rig.coupled): the linear bench propagated exactly (matrix "
                          "exponential, zero-order hold), the nonlinear remainder by Lawson's "
                          f"RK4, {model.substeps} step(s) per DAC sample")
        info["error_estimate"] = _richardson_estimate(scene, model, v, z0, 4)
        info["error_method"] = (
            f"Richardson on a {probe_s:g} s probe of the scene's drive from rest: |theta - "
            "theta(2x steps)| 16/15 (order 4; the error is that of the small nonlinear "
            "remainder: the linear part is exact). 'probe_nonlinear_minus_linear' is the model "
            "difference on the probe (the run's is predicted in 'selection')")
    else:
        mi = model.solver
        info["method"] = (f"nonlinear pendulum via rig.integrators {model.method} "
                          f"({mi.description}), {model.substeps} step(s) per sub-interval; stage "
                          f"and accelerometer exact (ZOH) at {model.oversample} sub-instants per "
                          "DAC sample, the stage acceleration linear between them")
        theta = _probe_theta(model, n, seed)
        scale = max(float(np.max(np.abs(theta))), 1e-300)
        # (1) input interpolation: linearised pendulum, interpolated input vs exact linear bench
        lin_model = build_model(_as_linear(scene))
        theta_exact = _probe_theta(lin_model, n, seed)
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
        # (2) integrator: Richardson against twice the steps
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
        info["error_estimate"] = {
            "input_interpolation_max_abs_theta_rad": e_input,
            "integrator_max_abs_theta_rad": e_int,
            "max_abs_theta_rad": e_input + e_int,
            "relative_to_max_theta": (e_input + e_int) / scale,
            "relative_rms_theta": _rel_rms(d_input, theta) + _rel_rms((theta - theta_f) * factor,
                                                                       theta),
            "nonlinear_minus_linear_max_abs_theta_rad": float(np.max(np.abs(theta - theta_exact))),
        }
        info["error_method"] = (
            f"on a {probe_s:g} s probe of the scene's drive from rest: (1) input interpolation: "
            "the linearised pendulum driven through the same sub-sampled, linearly interpolated "
            "stage acceleration (rig.integrators 'linear', exact for that input) against the "
            "exact linear bench; (2) integrator: " + how_int + "; the sum is the estimate. "
            "'nonlinear_minus_linear' is the model difference (the linearisation's error) on "
            "the probe")
    info["budget_met"] = bool(info["error_estimate"]["relative_rms_theta"] <= budget)
    if not info["budget_met"]:
        info["reason"] += (f". The estimated error of the model that runs, "
                           f"{info['error_estimate']['relative_rms_theta']:.2g}, is OVER the "
                           f"budget {budget:g}")
    info["estimate_wall_time_s"] = time.perf_counter() - tic
    return info


def model_seed(model: BenchModel, seed) -> object:
    """The seed as recorded: the root SeedSequence's entropy (an int, or a list of ints)."""
    root, _ = _spawn(seed)
    return root.entropy


def _half_step_model(model: BenchModel) -> BenchModel:
    """The same linear bench stepped as two exact half steps per DAC sample (round-off check)."""
    import dataclasses

    phi_h, g_h, _ = discretise(model.a, model.b, 0.5 / model.fs_hz, "zoh")
    phi = phi_h @ phi_h
    gamma = phi_h @ g_h[:, 0] + g_h[:, 0]
    return dataclasses.replace(model, phi=np.ascontiguousarray(phi),
                               gamma=np.ascontiguousarray(gamma))


__all__ = ["BenchSimulation", "BenchModel", "BenchState", "BenchResponse", "build_model", "start",
           "advance", "calibrations", "expected_response", "stationary_levels", "signal_to_noise",
           "model_info", "select_model", "predict_linearisation_error", "MODELS",
           "NONLINEAR_METHODS", "STREAMS"]
