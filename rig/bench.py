"""The whole bench, run continuously: source -> amplifier/coil -> stage -> pendulum -> sensors.

The state vector (named slices, :attr:`BenchModel.slices`)::

    z = (i [A], x0 [m], v0 [m/s], theta (n) [rad], omega (n) [rad/s], q [m/s], r [V])

``i`` the coil current, ``x0, v0`` the stage, ``theta, omega`` the pendulum, ``q`` the
accelerometer's charge-amplifier high-pass state (absent for a flat-to-DC accelerometer) and ``r``
the states of the source's reconstruction filter (absent when it is off). The input is the source
voltage, a DAC sample held for one sample interval ``h = 1 / simulation_rate_hz`` (SPEC section 8):
that held staircase is, by definition, the true DAC output; the source's analog reconstruction
filter smooths it (:mod:`rig.source`) and the stage acceleration ``x0''`` is whatever the
continuous amplifier, coil and stage make of that.

Models (``acquisition.model``)
------------------------------
``linear``
    The coil, stage, linearised pendulum (with its reaction on the stage if ``stage.reaction``)
    and the accelerometer's high-pass form one linear system ``z' = A z + B V``
    (:meth:`rig.stage.Stage.state_space`). It is discretised exactly for the held input with
    :func:`rig.integrators.discretise` (``z_{k+1} = Phi z_k + Gamma V_k``, Van Loan's matrix
    exponential) and stepped by a compiled loop: exact at the DAC instants up to round-off, ~0.1 us
    per sample for the Ishizaki pendulum. The sensors read the states at the instants.
``nonlinear``
    The stage (with the accelerometer state) is linear and, without the reaction, independent of
    the pendulum: it is discretised exactly at ``h / oversample`` (the source is constant there
    too) to give the exact stage acceleration at ``oversample`` instants per DAC interval. The
    pendulum's nonlinear equations are integrated through :func:`rig.integrators.integrate`
    (default ``rk4``, one step per sub-interval) with that acceleration linear between the
    sub-instants (``hold="linear"``, exact for a continuous input up to O((h/oversample)^2)).
    Error estimate (:meth:`BenchSimulation.model_info`): (1) the input interpolation, measured by
    driving the *linearised* pendulum through the same interpolated input with the integrators'
    exact ``linear`` method and comparing with the exact linear bench; (2) the integrator,
    Richardson against the same run with twice the steps. Both on a probe run of the scene.
    For ``ishizaki2009`` (reaction off, default drive, 20 s probe, oversample 8): interpolation
    3.0e-7 rad, 3.8e-5 of the largest angle (1.2e-6 rad at oversample 4: O((h/m)^2)),
    integrator 9e-14 rad, while the linearisation itself (nonlinear - linear) is 1.1e-6 rad.
    Cost ~8 us per DAC sample (the paper's run ~30 s).
    The pendulum's reaction on the stage is not supported with this model (ConfigError).

Outputs: :class:`rig.blocks.AnalogBlock` s at the simulation rate with volts ``a, x, y`` and the
truth beside them (:meth:`BenchSimulation.next_block`). Random streams: one
:class:`numpy.random.SeedSequence` per run, spawned into independent streams for the source, the
accelerometer noise and the two PSD axes; all generator states travel in :class:`BenchState`, so
any split into blocks reproduces a one-shot run bit for bit.

Numbers for the defaults (``ishizaki2009``, 0.1 V rms random source 0-12.5 Hz; see
:func:`stationary_levels`, :func:`signal_to_noise`, tests/test_bench.py): the paper's run (330 s
settle + 30 x 100 s, 3.33 million samples at 1 kHz) takes ~1.4 s of CPU with the linear model in
10 s blocks (source FIR, sensors and noise included; 1-3 s wall on a shared two-core machine);
levels and signal-to-noise ratios are listed in the docstrings of :mod:`rig.stage`,
:mod:`rig.accelerometer` and :mod:`rig.psd`.

Sampling at the DAC instants folds the DAC's images
---------------------------------------------------
The held source has images at ``m fs +- f``; sampling the outputs at the DAC instants folds what
passes of them back onto ``f``, coherent with the drive. The source's reconstruction filter
(:mod:`rig.source`, 100 Hz 4th-order Butterworth by default) removes them: the exact transfer
function of the simulated samples (:func:`expected_response` ``sampled=True``) then equals the
continuous chain (``sampled=False``: what a real bench with an ideally anti-aliased analyzer reads)
to better than 2e-5 over the band. With the filter off (``source.reconstruction_hz = 0``, the raw
staircase into the amplifier, whose coil corner is 318 Hz) they differ in ``a`` (hence in H_t and
Theta_2) by 1e-3 at 1 Hz, 1 % at 10 Hz and 4.8 % in the reaction's notch at 2.479 Hz, falling as
1 / fs^2.

Public API: :class:`BenchSimulation`, :class:`BenchModel`, :class:`BenchState`,
:class:`BenchResponse`, :func:`build_model`, :func:`start`, :func:`advance`, :func:`calibrations`,
:func:`expected_response`, :func:`stationary_levels`, :func:`signal_to_noise`, :func:`model_info`.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass
from typing import Iterator

import numba
import numpy as np

from rig.accelerometer import Accelerometer
from rig.blocks import AnalogBlock, Calibration
from rig.chain import Chain
from rig.errors import ConfigError, DivergenceError
from rig.integrators import METHODS, discretise, integrate, to_native
from rig.psd import OpticalLever
from rig.scene import Scene
from rig.source import NOISE_TYPES, Source, SourceState, generate, start_source
from rig.stage import Stage

MODELS = ("linear", "nonlinear")
NONLINEAR_METHODS = ("rk4", "gauss4", "dop853")
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
    model : "linear" or "nonlinear"; method, oversample, substeps, rtol, atol : the nonlinear
        path's integrator settings (method name, sub-instants per DAC interval, steps per
        sub-interval, dop853 tolerances).
    a, b : continuous bench ``z' = a z + b V``; phi, gamma : its exact ZOH step at 1 / fs.
    accel_row : x0'' = accel_row . z.  slices : named slices of z.
    stage_phi, stage_gamma, stage_accel_row : nonlinear path only: the stage + accelerometer
        (z_s = (i, x0, v0, q)) stepped exactly at 1 / (fs oversample).
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

    @property
    def chain(self) -> Chain:
        """The pendulum."""
        return self.scene.chain

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


def _acquisition_rates(acq: dict) -> tuple[float, int]:
    fs = acq["simulation_rate_hz"]
    rate = acq["rate_hz"]
    if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
        raise ConfigError(f"acquisition.simulation_rate_hz = {fs!r} is invalid: expected a finite "
                          "rate > 0 Hz")
    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
        raise ConfigError(f"acquisition.rate_hz = {rate!r} is invalid: expected a finite rate > 0 "
                          "Hz")
    r = fs / rate
    k = int(round(r))
    if k < 1 or abs(r - k) > _REL * max(1.0, r):
        raise ConfigError(f"acquisition.simulation_rate_hz = {fs!r} is invalid: expected a whole "
                          f"multiple (>= 1) of acquisition.rate_hz = {rate!r} Hz (e.g. "
                          f"{max(1, math.ceil(r)) * rate:g} Hz)")
    return float(fs), k


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


def build_model(scene: Scene, *, method: str = "rk4", oversample: int = 8, substeps: int = 1,
                rtol: float = 1e-10, atol: float = 1e-12) -> BenchModel:
    """Validate the scene's bench sections and build the :class:`BenchModel`.

    ``method``, ``oversample``, ``substeps``, ``rtol``, ``atol`` matter for the nonlinear model
    only (module docstring): ``oversample`` exact stage-acceleration instants per DAC interval
    (the pendulum sees them linearly interpolated), ``substeps`` integrator steps per
    sub-interval.

    Raises
    ------
    ConfigError : a bad value in ``source``, ``stage``, ``accelerometer``, ``psd`` or
        ``acquisition`` (naming the key, the value and what is valid), or the nonlinear model
        with the stage reaction.
    """
    if not isinstance(scene, Scene):
        raise ConfigError(f"scene = {scene!r} is invalid: expected a rig.scene.Scene")
    st = scene.settings
    acq = st["acquisition"]
    fs, decimation = _acquisition_rates(acq)
    source = Source.from_settings(st["source"], fs)
    stage = Stage.from_settings(st["stage"])
    acc = Accelerometer.from_settings(st["accelerometer"])
    lever = OpticalLever.from_settings(st["psd"])
    model = acq["model"]
    if model not in MODELS:
        raise ConfigError(f"acquisition.model = {model!r} is invalid: expected one of "
                          f"{', '.join(MODELS)}")
    if method not in NONLINEAR_METHODS:
        raise ConfigError(f"method = {method!r} is invalid: expected one of "
                          f"{', '.join(NONLINEAR_METHODS)}")
    for name, v in (("oversample", oversample), ("substeps", substeps)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"{name} = {v!r} is invalid: expected an integer >= 1")
    if model == "nonlinear" and stage.reaction:
        raise ConfigError(
            "acquisition.model = 'nonlinear' is not supported with stage.reaction = true: the "
            "nonlinear pendulum is integrated on a prescribed stage motion, so the pendulum "
            "cannot load the stage. Set stage.reaction = false (the stage then ignores the "
            "pendulum: its notches in a/V at the pendulum modes, -25 dB at 2.48 Hz for the "
            "ishizaki2009 defaults, disappear; x/a is unchanged) "
            "or acquisition.model = 'linear'")
    chain = scene.chain
    a, b, accel_row, slices = _bench_state_space(stage, chain, acc, with_chain=True,
                                                 source=source)
    h = 1.0 / fs
    phi, g0, _ = discretise(a, b, h, "zoh")
    kw = {}
    if model == "nonlinear":
        sa, sb, srow, _ = _bench_state_space(stage, chain, acc, with_chain=False, source=source)
        sphi, sg0, _ = discretise(sa, sb, h / oversample, "zoh")
        kw = dict(stage_phi=np.ascontiguousarray(sphi), stage_gamma=np.ascontiguousarray(sg0[:, 0]),
                  stage_accel_row=srow)
    return BenchModel(scene=scene, source=source, stage=stage, accelerometer=acc, lever=lever,
                      fs_hz=fs, decimation=decimation, model=model, method=method,
                      oversample=int(oversample), substeps=int(substeps), rtol=float(rtol),
                      atol=float(atol), a=a, b=b, phi=np.ascontiguousarray(phi),
                      gamma=np.ascontiguousarray(g0[:, 0]), accel_row=accel_row, slices=slices,
                      **kw)


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
    if model.model == "nonlinear":
        native = to_native(model.chain, model.method,
                           np.concatenate([sc.theta0_rad, sc.omega0_rad_s]))
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


@numba.njit(cache=True)
def linear_bench_kernel(phi, gamma, v, z, z_out):
    """z_out[k] = z_k, z_{k+1} = phi z_k + gamma v_k for k < len(v) (>= 1); z (in/out) ends at
    z_N. Each row is summed in the same order whatever the block split (bit-exact blocks)."""
    nz = z.shape[0]
    n = v.shape[0]
    for r in range(nz):
        z_out[0, r] = z[r]
    for k in range(n - 1):
        vk = v[k]
        for r in range(nz):
            acc = gamma[r] * vk
            for c in range(nz):
                acc += phi[r, c] * z_out[k, c]
            z_out[k + 1, r] = acc
    vk = v[n - 1]
    for r in range(nz):
        acc = gamma[r] * vk
        for c in range(nz):
            acc += phi[r, c] * z_out[n - 1, c]
        z[r] = acc


@numba.njit(cache=True)
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


def advance(model: BenchModel, state: BenchState, n: int) -> tuple[AnalogBlock, BenchState]:
    """Run ``n`` samples from ``state``: the block (volts and truth at the instants
    ``(state.index + k) / fs``, k < n) and the state after it.

    Raises
    ------
    DivergenceError : a non-finite state in the block (with the block's start time and state).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigError(f"n_samples = {n!r} is invalid: expected an integer >= 1")
    n = int(n)
    fs = model.fs_hz
    t0 = state.index / fs
    v, src = generate(model.source, state.source, n)
    sl = model.slices
    chain = model.chain
    z = np.array(state.z, dtype=float)
    native, h_next = state.native, state.h_next_s
    if model.model == "linear":
        z_out = np.empty((n, z.size))
        linear_bench_kernel(model.phi, model.gamma, v, z, z_out)
        _check_finite(model, state, z_out, z, t0, n)
        theta = z_out[:, sl["theta_rad"]]
        omega = z_out[:, sl["omega_rad_s"]]
        accel = z_out @ model.accel_row
    else:
        n2 = 2 * chain.n  # the stage-only system is z without theta, omega (same order)
        stage_idx = np.r_[0:3, 3 + n2:z.size]
        zs = z[stage_idx].copy()
        zs_out = np.empty((n, zs.size))
        m = model.oversample
        a_fine = np.empty(n * m + 1)
        stage_fine_kernel(model.stage_phi, model.stage_gamma, model.stage_accel_row, v, m, zs,
                          zs_out, a_fine)
        run = integrate(chain, native, a_fine, None, hold="linear", h_in=1.0 / (fs * m),
                        n_intervals=n * m, out_every=m, method=model.method,
                        substeps=model.substeps, rtol=model.rtol, atol=model.atol,
                        h0_s=h_next, t0_s=t0)
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
    if acc.n_states:
        sensed = acc.sensed(accel, z_out[:, sl["accel_highpass_q_mps"]][:, 0])
    else:
        sensed = accel.copy()
    rng_a = _rng(state.rng_states["accelerometer"])
    rng_x = _rng(state.rng_states["psd_x"])
    rng_y = _rng(state.rng_states["psd_y"])
    a_v, a_over = acc.output(sensed, fs, rng_a)
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

    ``next_block(n)`` returns the next n samples, ``blocks(block_s, duration_s)`` yields blocks of
    ``block_s`` seconds; both continue where the previous call stopped. ``state`` is the current
    :class:`BenchState` (assignable, e.g. to rewind).
    """

    def __init__(self, scene: Scene, seed=0, *, method: str = "rk4", oversample: int = 8,
                 substeps: int = 1, rtol: float = 1e-10, atol: float = 1e-12):
        self.model = build_model(scene, method=method, oversample=oversample, substeps=substeps,
                                 rtol=rtol, atol=atol)
        root, _ = _spawn(seed)
        self.seed = root  # seed=None draws OS entropy once; root.entropy is then the record
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
        r = block_s * fs if isinstance(block_s, (int, float)) and not isinstance(block_s, bool) \
            else float("nan")
        n = int(round(r)) if math.isfinite(r) else 0
        if n < 1 or abs(r - n) > _REL * max(1.0, r) or n % self.model.decimation:
            raise ConfigError(f"block_s = {block_s!r} s is invalid: expected a whole number (>= 1)"
                              f" of ADC samples at acquisition.rate_hz = "
                              f"{fs / self.model.decimation:g} Hz")
        if duration_s is None:
            while True:
                yield self.next_block(n)
        total = duration_s * fs if isinstance(duration_s, (int, float)) else float("nan")
        if not (math.isfinite(total) and total >= 1 and abs(total - round(total)) <= _REL * total):
            raise ConfigError(f"duration_s = {duration_s!r} s is invalid: expected a whole number "
                              f"(>= 1) of samples at {fs:g} Hz")
        left = int(round(total))
        while left > 0:
            k = min(n, left)
            left -= k
            yield self.next_block(k)

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
        """What runs and how accurate it is (:func:`model_info`; computed once, cached)."""
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
    st = scene.settings
    cal = {"a": Accelerometer.from_settings(st["accelerometer"]).calibration()}
    cal.update(OpticalLever.from_settings(st["psd"]).calibrations())
    return cal


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
        mirror_rot / stage_accel (:func:`rig.response.mirror_response`).
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


def expected_response(scene: Scene, freqs_hz, *, sampled: bool = False) -> BenchResponse:
    """The exact linear response of the whole chain source -> channels at ``freqs_hz`` [Hz].

    ``sampled=False`` (default) uses the closed forms of the parts (:meth:`Stage.
    frequency_response`, :meth:`Accelerometer.frequency_response`, :meth:`OpticalLever.
    frequency_response`) times the DAC hold; ``sampled=True`` the exact discrete-time transfer
    function of the simulated samples (:class:`BenchResponse`). Both use the linear pendulum and
    the linearised optical lever; both need ``0 <= f < fs / 2``.
    """
    model = build_model(scene) if scene.settings["acquisition"]["model"] == "linear" else \
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
    import dataclasses

    settings = copy.deepcopy(scene.settings)
    settings["acquisition"]["model"] = "linear"
    return dataclasses.replace(scene, settings=settings)


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
# model information and error estimates
# ================================================================================================

def model_info(scene: Scene, *, seed=0, probe_s: float = 20.0, method: str = "rk4",
               oversample: int = 8, substeps: int = 1) -> dict:
    """Which model runs, how, and its error estimate (measured on a ``probe_s`` run of the
    scene's own drive from rest); see :meth:`BenchSimulation.model_info`."""
    return _model_info(build_model(scene, method=method, oversample=oversample,
                                   substeps=substeps), probe_s=probe_s, seed=seed)


def _probe_theta(model: BenchModel, n: int, seed) -> np.ndarray:
    blk, _ = advance(model, start(model, seed), n)
    return blk.truth["theta_rad"]


def _model_info(model: BenchModel, *, probe_s: float, seed) -> dict:
    scene = model.scene
    fs = model.fs_hz
    n = max(1, int(round(probe_s * fs)))
    info = {
        "model": model.model,
        "fs_hz": fs,
        "hold": "zoh: the source DAC value is held for 1/fs; the stage acceleration it makes is "
                "continuous",
        "reaction": model.stage.reaction,
        "states": model.state_names(),
        "seed": model_seed(model, seed),
        "probe_s": probe_s,
    }
    lev = stationary_levels(scene)
    _, q = scene.chain.modes()
    qmax = float(np.max(q))
    th3 = 3 * max(lev["theta_rad"])
    shift = th3**2 / 16  # relative frequency shift of a pendulum at amplitude th3
    info["linearity"] = {
        "stationary_theta_rms_rad": lev["theta_rad"],
        "frequency_shift_at_3_sigma": shift,
        "half_bandwidth": 1 / (2 * qmax),
        "shift_over_half_bandwidth": shift * 2 * qmax,
        "how": "analytic stationary rms angles of the linear bench under the scene's source; a "
               "pendulum's frequency falls by ~A^2/16 at amplitude A (here 3 rms of the larger "
               "angle), compared with the highest-Q mode's half-power half-bandwidth 1/(2Q)",
    }
    tic = time.perf_counter()
    if model.model == "linear":
        info["method"] = ("exact discretisation (zero-order hold, matrix exponential) of the "
                          "coupled linear bench: coil, stage, linearised pendulum"
                          + (" with its reaction" if model.stage.reaction else "")
                          + ", accelerometer high-pass; compiled loop, one step per DAC sample")
        theta = _probe_theta(model, n, seed)
        # same system, two exact half steps per DAC sample
        half = _half_step_model(model)
        theta2 = _probe_theta(half, n, seed)
        err = float(np.max(np.abs(theta - theta2)))
        info["error_estimate"] = {
            "max_abs_theta_rad": err,
            "relative_to_max_theta": err / max(float(np.max(np.abs(theta))), 1e-300),
        }
        info["error_method"] = (
            f"|theta_h - theta_h/2| over a {probe_s:g} s probe of the scene's drive from rest, "
            "against the same exact discretisation with two half steps per DAC sample: round-off "
            "only (the linearisation is a model error, see 'linearity')")
    else:
        mi = METHODS[model.method]
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
        v, _ = generate(model.source, start(model, seed).source, n)
        a_fine = np.empty(n * m + 1)
        stage_fine_kernel(model.stage_phi, model.stage_gamma, model.stage_accel_row, v, m, zs,
                          np.empty((n, zs.size)), a_fine)
        y0 = np.concatenate([scene.theta0_rad, scene.omega0_rad_s])
        lin = integrate(scene.chain, y0, a_fine, None, hold="linear", h_in=1 / (fs * m),
                        n_intervals=n * m, out_every=m, method="linear")
        e_input = float(np.max(np.abs(lin.y_out[:n, :scene.chain.n] - theta_exact)))
        # (2) integrator: Richardson against twice the steps
        fine = build_model(scene, method=model.method, oversample=model.oversample,
                           substeps=2 * model.substeps, rtol=model.rtol / 100,
                           atol=model.atol / 100)
        theta_f = _probe_theta(fine, n, seed)
        if mi.order is not None and mi.kind != "adaptive":
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
            "nonlinear_minus_linear_max_abs_theta_rad": float(np.max(np.abs(theta - theta_exact))),
        }
        info["error_method"] = (
            f"on a {probe_s:g} s probe of the scene's drive from rest: (1) input interpolation: "
            "the linearised pendulum driven through the same sub-sampled, linearly interpolated "
            "stage acceleration (rig.integrators 'linear', exact for that input) against the "
            "exact linear bench; (2) integrator: " + how_int + "; the sum is the estimate. "
            "'nonlinear_minus_linear' is the model difference (the linearisation's error) on "
            "the probe")
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
           "model_info", "MODELS", "NONLINEAR_METHODS", "STREAMS"]
