"""The bench run in blocks: the state carried between blocks, its start and one block's step.

:func:`advance` ``(model, state, n) -> (block, state)`` is a pure block stepper: the bench state
at the DAC instants (the exact linear step, the coupled nonlinear bench, or the pendulum on the
exactly stepped stage's motion, :mod:`rig.bench.model`), then the sensors (accelerometer, optical
lever) read it with their noise. Outputs: :class:`rig.blocks.AnalogBlock` s at the simulation
rate with volts ``a, x, y`` and the truth beside them. Random streams: one
:class:`numpy.random.SeedSequence` per run, spawned into independent streams for the source,
the accelerometer noise and the two PSD axes (:data:`STREAMS`); all generator states travel in
:class:`BenchState`, so any split into blocks reproduces a one-shot run bit for bit. Cost: linear
in the block's samples (the measured figures are in BENCHMARKS.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.blocks import AnalogBlock
from rig.errors import ConfigError, DivergenceError
from rig.solvers import COUPLED_BENCH, integrate
from rig.jit import njit
from rig.readonly import readonly
from rig.scene import Scene
from rig.devices.source import SourceState, generate, start_source
from rig.bench.model import COUPLED_METHODS, BenchModel

STREAMS = ("source", "accelerometer", "psd_x", "psd_y")


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


def spawn_streams(seed) -> tuple[np.random.SeedSequence, list[np.random.SeedSequence]]:
    """The root sequence and one child per stream. A SeedSequence argument is copied first (its
    own ``spawn`` counter is not advanced), so the same seed always gives the same streams."""
    if isinstance(seed, np.random.SeedSequence):
        ss = np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key,
                                    pool_size=seed.pool_size)
    else:
        ss = np.random.SeedSequence(seed)
    return ss, ss.spawn(len(STREAMS))


def source_seed(seed) -> np.random.SeedSequence:
    """The seed of the source's stream in a run of seed ``seed`` (what :func:`start` gives the
    source): a reader of a run file can rebuild what the source drew, e.g. a multisine's
    phases."""
    return spawn_streams(seed)[1][STREAMS.index("source")]


def start(model: BenchModel, seed=0) -> BenchState:
    """The state at t = 0: stage at rest, pendulum at the scene's initial state, fresh streams
    spawned from ``seed`` (an int or a SeedSequence)."""
    root, children = spawn_streams(seed)
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
    return BenchState(index=0, z=readonly(z), source=src, rng_states=rngs, native=native,
                      seed_entropy=entropy)


def _rng(state: dict) -> np.random.Generator:
    """A generator continuing from ``state`` (the dict is read, not kept)."""
    bg = np.random.PCG64(0)  # a fixed seed: cheaper than OS entropy, overwritten at once
    bg.state = state
    return np.random.Generator(bg)


#: the sensors' noise streams, in the order their generators are handed around
SENSOR_STREAMS = ("accelerometer", "psd_x", "psd_y")


def sensor_generators(state: BenchState) -> tuple[np.random.Generator, ...]:
    """The noise generators of :data:`SENSOR_STREAMS` continuing from ``state``."""
    return tuple(_rng(state.rng_states[k]) for k in SENSOR_STREAMS)


def state_after(state: BenchState, n: int, z: np.ndarray, source: SourceState, generators,
                native=None, h_next_s: float = float("nan")) -> BenchState:
    """The :class:`BenchState` ``n`` samples after ``state``: the bench state ``z`` (kept,
    read-only), the source's state, the sensors' generators' states (:data:`SENSOR_STREAMS`
    order; fresh snapshots) and a nonlinear integrator's ``native`` state (copied) and next
    step."""
    rng_states = {k: g.bit_generator.state for k, g in zip(SENSOR_STREAMS, generators)}
    return BenchState(index=state.index + n, z=readonly(z), source=source,
                      rng_states=rng_states,
                      native=None if native is None else readonly(np.array(native)),
                      h_next_s=float(h_next_s), seed_entropy=state.seed_entropy)


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


def mirror_kinematics(scene: Scene, theta: np.ndarray, exact: bool):
    """Mirror-centre displacement relative to the stage (x along +x, z up) and rotation, each
    (n,), from the angles ``theta`` (n, bodies) [rad]; ``exact``: the chain's geometry
    (:func:`mirror_kinematics_kernel`), else its linearisation ``theta @ mirror_weights``."""
    chain = scene.chain
    j, s = scene.mirror.body, scene.mirror.position_m
    if not exact:
        return theta @ scene.mirror_weights(), np.zeros(theta.shape[0]), theta[:, j].copy()
    n = theta.shape[0]
    x, z, rot = np.empty(n), np.empty(n), np.empty(n)
    mirror_kinematics_kernel(theta, np.asarray(chain.length_m, dtype=float), j, float(s),
                             x, z, rot)
    return x, z, rot


@njit(cache=True, nogil=True)
def mirror_kinematics_kernel(theta, lengths, j, s, x, z, rot):
    """Per sample k: ``x = sum_{b<j} l_b sin th_b + s sin th_j``, ``z = sum_{b<j} l_b (1 -
    cos th_b) + s (1 - cos th_j)`` (the terms added in that order, no fused multiply-add; ``s =
    0``: the mirror at its body's pivot, no such term) and ``rot = th_j``, with libm's cos and
    sin, in one pass without temporaries (:func:`mirror_point`): the values of the numpy
    expression it replaced (``np.sin(theta[:, :j]) @ l[:j]`` ...) where numpy's sin and cos
    are libm's and the sum has one term (the mirror on the second body), else equal up to the
    order of the sum's rounding (tests/rig/test_bench.py)."""
    for k in range(theta.shape[0]):
        x[k], z[k], rot[k] = mirror_point(theta, k, 0, lengths, j, s)


@njit(cache=True, inline="always")
def mirror_point(theta, k, th0, lengths, j, s):
    """:func:`mirror_kinematics_kernel` at sample ``k``, the angles at ``theta[k, th0 + b]``
    (a bench state row, or a row of angles with ``th0`` = 0): ``(x, z, rot)``."""
    xk = 0.0
    zk = 0.0
    for b in range(j):
        c, sn = math.cos(theta[k, th0 + b]), math.sin(theta[k, th0 + b])
        if b == 0:
            xk = lengths[b] * sn
            zk = lengths[b] * (1.0 - c)
        else:
            xk += lengths[b] * sn
            zk += lengths[b] * (1.0 - c)
    th = theta[k, th0 + j]
    if s != 0.0:
        c, sn = math.cos(th), math.sin(th)
        xk = xk + s * sn
        zk = zk + s * (1.0 - c)
    return xk, zk, th


def _check_finite(model, state, z_out, z, t0, n):
    """Once per block: every state finite, or DivergenceError with the block's start. (A sum
    with a NaN or an infinite term is not finite, so a finite sum of ``z_out`` proves every
    state finite at a fraction of the elementwise test's cost; that test runs only when it
    is not.)"""
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(np.sum(z_out)) + float(np.sum(z))
    if math.isfinite(total):
        return
    if not (np.all(np.isfinite(z_out)) and np.all(np.isfinite(z))):
        raise DivergenceError(
            f"bench ({model.model}): a non-finite state in the block starting at t = {t0:.9g} s "
            f"({n} samples); the state at its start was {np.asarray(state.z).tolist()}", t0,
            np.asarray(state.z))


def source_samples(model: BenchModel, state: BenchState, n: int, source_block=None):
    """The source's next ``n`` samples and state from ``state``: ``source_block`` (made ahead,
    checked to start at ``state``) or generated now."""
    if source_block is None:
        return generate(model.source, state.source, n)
    v, src = source_block
    if v.shape != (n,) or src.index != state.source.index + n:
        raise ValueError(f"source_block covers samples up to {src.index} ({v.shape[0]}); "
                         f"expected {n} samples from {state.source.index}")
    return v, src


def bench_states(model: BenchModel, state: BenchState, n: int, source_block=None):
    """The bench's part of :func:`advance` (``n`` a checked int >= 1): the source samples and
    the bench state at the block's ``n`` DAC instants, before any sensor reads them.

    Returns ``(v, source state, z_out (n, nz), z after the block, x0'' (n,), native,
    h_next)``; raises DivergenceError as :func:`advance` does."""
    fs = model.fs_hz
    t0 = state.index / fs
    v, src = source_samples(model, state, n, source_block)
    sl = model.slices
    chain = model.chain
    z = np.array(state.z, dtype=float)
    native, h_next = state.native, state.h_next_s
    solver = model.solver
    if COUPLED_BENCH in solver.systems:  # the whole bench as one system
        z_out, accel, native = solver.advance_bench(model, z, native, v)
        _check_finite(model, state, z_out, z, t0, n)
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
        accel = a_fine[:n * m:m].copy()
    return v, src, z_out, z, accel, native, h_next


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
    v, src, z_out, z, accel, native, h_next = bench_states(model, state, n, source_block)
    sl = model.slices
    theta = z_out[:, sl["theta_rad"]]
    omega = z_out[:, sl["omega_rad_s"]]

    # sensors
    acc = model.accelerometer
    q = z_out[:, sl["accel_highpass_q_mps"]][:, 0] if acc.n_states else None
    rng_a, rng_x, rng_y = sensor_generators(state)
    sensed, a_v, a_over = acc.sense_and_output(accel, q, fs, rng_a)
    mx, mz, mrot = mirror_kinematics(model.scene, theta, exact=model.model == "nonlinear")
    reading = model.lever.measure(mx, mrot, fs, rng_x, rng_y, mirror_z_m=mz)

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
    return block, state_after(state, n, z, src, (rng_a, rng_x, rng_y), native, h_next)
