"""The bench fused with its sensors and the anti-alias filter, kept at the output rate.

What the bench computes per DAC sample (:func:`rig.bench.advance`) is the bench state, then
the sensors read it, noise is added, the outputs are clipped and flagged, and the
acquisition's anti-alias filter runs over every sample before every ``q``-th is kept (``q =
acquisition.decimation``). Here the same chain runs in one compiled kernel per block that
writes only the kept instants, :data:`CHUNK_INTERVALS` intervals at a time (their
temporaries then stay in the core's cache).

- Linear model (:func:`advance_decimated`): the bench from the DAC to the sensors' three
  linear readings is lifted to the interval, ``z_{j+1} = Phi^q z_j + sum_i Phi^(q-1-i) Gamma
  V_{qj+i}`` at the kept instants and every sample's readings from ``z_j`` and the held
  inputs (:class:`Lifted`); then per sample what is not linear: the lever's exact geometry,
  the sensors' noise, clipping and flags, a row of samples at a time
  (:func:`rig.devices.accelerometer.accelerometer_row`,
  :func:`rig.devices.optical_lever.lever_row`).
- Nonlinear model (:func:`advance_decimated_nonlinear`): the bench state at every DAC sample
  (:func:`rig.bench.run.bench_states`), then the mirror's exact kinematics and the same rows.
- Both: the filter lifted to the interval (:func:`rig.sosfilt.lift_sections`,
  :func:`rig.sosfilt.lifted_sections_pass`, the three channels side by side).

The noise is drawn in compiled code from the per-sample path's generators, in its order, so
the noise, geometry, clipping and flags are the per-sample path's own arithmetic; the lifted
maps are the same exact linear maps with their sums in another order, so the kept volts and
truth equal the per-sample path's up to round-off that the stable bench and filter do not
amplify (the bound and what it was measured at: tests/rig/bench/test_fused.py). Any split of
a run into blocks of whole intervals gives the same bytes. The derivation, the cost per
interval and the measured figures: docs/bench_model.md and BENCHMARKS.md.

Kept: the filtered volts, the truth (``stage_accel_mps2``, ``theta_rad``, ``mirror_x_m``,
``mirror_rot_rad``, ``source_v``) and, per channel, whether its sensor saturated within the
kept instant's interval (:class:`rig.blocks.DecimatedBlock`).

Public API: :class:`Lifted`, :func:`lift`, :func:`advance_decimated`,
:func:`advance_decimated_nonlinear`, :func:`start_decimated`, :class:`DecimatedState`,
:func:`fused_model_info`, :data:`PER_SAMPLE`, :data:`PER_SAMPLE_NONLINEAR`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rig.jit import njit
from rig.blocks import DecimatedBlock
from rig.bench.estimates import linear_method
from rig.model_info import ModelInfo
from rig.bench.run import (SENSOR_STREAMS, bench_states, mirror_point, sensor_generators,
                           source_samples, state_after)
from rig.devices.accelerometer import accelerometer_row
from rig.devices.optical_lever import lever_row
from rig.devices.source import fill_standard_normal
from rig.errors import ConfigError, DivergenceError
from rig.sosfilt import LiftedSections, lifted_sections_pass

#: what the fused chain runs at every DAC sample and why (the run file's model info)
PER_SAMPLE = {
    "what": "the sensors' three linear readings (sensed acceleration, mirror translation and "
            "rotation) from the lifted state, the optical lever's exact geometry, the sensors' "
            "white noise (one draw per sample and channel), the clipping at the detector edge "
            "and the accelerometer's range with their flags, and the anti-alias filter; the "
            "bench state itself is stepped once per output sample (lifted: Phi^q, exact)",
    "why": "the bench from the DAC to the readings is linear, so it is lifted to the output "
           "rate; the rest is not linear and not lifted: the lever's second-order geometry is "
           "~0.4 % of the spot's rms in u (far above round-off), clipping and flags act on "
           "each sample, and the filter's input is the sum of those and the noise",
    "lifted": "bench state at the kept instants (rig.bench.fused)",
}


#: how the lifted chain steps the linear bench (the linear model's ``method`` text ends so)
LIFTED_STEP = ("lifted (rig.bench.fused): one exact step Phi^q per output sample, q = the "
               "decimation")


@dataclass(frozen=True, eq=False)
class Lifted:
    """The lifted matrices of one linear :class:`rig.bench.BenchModel` at decimation ``q``.

    Attributes
    ----------
    q : DAC samples per kept instant.
    phi_q : (nz, nz) ``Phi^q``.
    gamma_q : (q, nz) row i: ``Phi^(q-1-i) Gamma``.
    readings : (nz + q, 3 q): column ``3 i + r`` gives reading r (the sensed acceleration
        ``x0'' - w_c q``, the mirror translation ``w . theta``, its rotation) at sample i of an
        interval from ``(z_j, V_qj .. V_qj+q-1)``.
    accel_row : (nz,) x0'' = accel_row . z;  theta : (start, stop) of theta in z;
    mirror_w : (n,) mirror translation weights;  mirror_body : the mirror's body.
    """

    q: int
    phi_q: np.ndarray
    gamma_q: np.ndarray
    readings: np.ndarray
    accel_row: np.ndarray
    theta: tuple
    mirror_w: np.ndarray
    mirror_body: int

    def kernel_params(self) -> "_LiftedParams":
        """What the compiled kernel takes (``Phi^q`` transposed, the rows of the sums it
        runs side by side)."""
        return _LiftedParams(np.ascontiguousarray(self.phi_q.T), self.gamma_q, self.readings,
                             self.accel_row, int(self.theta[0]), self.mirror_w,
                             int(self.mirror_body))


class _LiftedParams(NamedTuple):
    """:class:`Lifted` as the kernel takes it (``phi_t`` = ``Phi^q`` transposed, ``th0`` the
    first angle's column)."""

    phi_t: np.ndarray
    gamma_q: np.ndarray
    readings: np.ndarray
    accel_row: np.ndarray
    th0: int
    mirror_w: np.ndarray
    body: int


class MirrorLayout(NamedTuple):
    """Where the nonlinear kernel finds the mirror and the accelerometer's state in the
    bench's states: the first angle's column ``th0``, the high-pass state's ``hp_col`` (-1:
    none), the links' ``lengths`` [m], the mirror's ``body`` and its position on it ``s_m``
    [m] (:func:`rig.bench.run.mirror_point`)."""

    th0: int
    hp_col: int
    lengths: np.ndarray
    body: int
    s_m: float


def lift(model, q: int) -> Lifted:
    """The :class:`Lifted` matrices of a linear bench model (``model.model == "linear"``) for
    ``q`` DAC samples per kept instant."""
    if model.model != "linear":
        raise ConfigError(f"the lifted chain needs the linear model, not {model.model!r}")
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or q < 1:
        raise ConfigError(f"decimation = {q!r} is invalid: expected an integer >= 1")
    q = int(q)
    phi, gamma = np.asarray(model.phi), np.asarray(model.gamma)
    nz = phi.shape[0]
    sl = model.slices
    th = sl["theta_rad"]
    scene = model.scene
    w = np.asarray(scene.mirror_weights(), float)
    rows = np.zeros((3, nz))
    rows[0] = model.accel_row
    if model.accelerometer.n_states:
        rows[0, sl["accel_highpass_q_mps"].start] -= model.accelerometer.corner_rad_s
    rows[1, th] = w
    rows[2, th.start + scene.mirror.body] = 1.0
    powers = [np.eye(nz)]
    for _ in range(q):
        powers.append(phi @ powers[-1])
    gamma_q = np.array([powers[q - 1 - i] @ gamma for i in range(q)])
    readings = np.zeros((nz + q, 3 * q))
    for i in range(q):
        readings[:nz, 3 * i:3 * i + 3] = (rows @ powers[i]).T
        for m in range(i):  # input of sample m reaches sample i through Phi^(i-1-m) Gamma
            readings[nz + m, 3 * i:3 * i + 3] = rows @ (powers[i - 1 - m] @ gamma)
    return Lifted(q=q, phi_q=np.ascontiguousarray(powers[q]),
                  gamma_q=np.ascontiguousarray(gamma_q), readings=np.ascontiguousarray(readings),
                  accel_row=np.ascontiguousarray(model.accel_row, dtype=float),
                  theta=(th.start, th.stop), mirror_w=np.ascontiguousarray(w),
                  mirror_body=int(scene.mirror.body))


@dataclass(frozen=True, eq=False)
class DecimatedState:
    """What the fused chain carries besides the bench's own :class:`rig.bench.BenchState`: the
    anti-alias filter's state of each channel (a, x, y) in the sections' coordinates (``zi``,
    (3, 2 x sections)) and, per channel, whether its sensor saturated after the last kept
    instant (``carry``, (3,) bool). ``generators``: a cache, the noise generators (accelerometer,
    psd_x, psd_y) left by the previous block, reused while their states are the bench state's
    (making them anew costs ~40 us a block)."""

    zi: np.ndarray
    carry: np.ndarray
    generators: tuple | None = None


def start_decimated(sos: np.ndarray) -> DecimatedState:
    """At rest: zero filter state, no saturation carried."""
    return DecimatedState(zi=np.zeros((3, 2 * np.asarray(sos).reshape(-1, 6).shape[0])),
                          carry=np.zeros(3, dtype=np.bool_))


def advance_decimated(model, lifted: Lifted, state, chain: DecimatedState, n: int,
                      sections: tuple, source_block=None):
    """Run ``n`` DAC samples (a whole number of intervals) from ``state`` (a
    :class:`rig.bench.BenchState` at a kept instant) through the fused chain of the linear
    model (module docstring). ``sections``: the anti-alias filter lifted to the decimation,
    :func:`rig.sosfilt.lift_sections` of its ``sos`` (rows ``[b0, b1, b2, 1, a1, a2]``;
    (0, 6): no filter). ``source_block`` as in :func:`rig.bench.advance`.

    Returns (:class:`rig.blocks.DecimatedBlock`, the bench state after it, the chain state
    after it).

    Raises
    ------
    ConfigError : ``n`` not a positive multiple of the decimation.
    DivergenceError : a non-finite state in the block.
    """
    q = lifted.q
    n = _whole_intervals(n, q)
    sections = _checked_sections(sections, q)
    fs = model.fs_hz
    v, src = source_samples(model, state, n, source_block)
    v = np.ascontiguousarray(v, dtype=float)
    z = np.array(state.z, dtype=float)
    z_start = z.copy()
    generators = chain.generators
    if generators is None or any(g.bit_generator.state != state.rng_states[k]
                                 for g, k in zip(generators, SENSOR_STREAMS)):
        generators = sensor_generators(state)
    j = n // q
    volts = np.empty((3, j))
    truth_out = (np.empty(j), np.empty((j, lifted.theta[1] - lifted.theta[0])), np.empty(j),
                 np.empty(j))
    sat = np.empty((3, j), dtype=np.bool_)
    s_aa = np.array(chain.zi, dtype=float)
    carry = np.array(chain.carry, dtype=np.bool_)
    _fused_kernel(lifted.kernel_params(), model.accelerometer.row_params(fs),
                  model.lever.row_params(fs), sections, v, z, *generators, s_aa, carry,
                  (volts, sat) + truth_out, CHUNK_INTERVALS)
    t0 = state.index / fs
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(volts))):
        raise DivergenceError(
            f"bench ({model.model}): a non-finite state in the block starting at t = {t0:.9g} s "
            f"({n} samples); the state at its start was {z_start.tolist()}", t0, z_start)
    accel, theta, mx, mrot = truth_out
    truth = {"stage_accel_mps2": accel, "theta_rad": theta, "mirror_x_m": mx,
             "mirror_rot_rad": mrot, "source_v": v[::q].copy()}
    new = state_after(state, n, z, src, generators)
    return (_kept_block(t0, fs, q, n, volts, truth, sat), new,
            DecimatedState(zi=s_aa, carry=carry, generators=generators))


def _checked_sections(sections, q: int) -> LiftedSections:
    """``sections`` as :func:`rig.sosfilt.lift_sections` makes them for decimation ``q`` (A,
    M^T, C, D), or ConfigError naming what was given (e.g. the ``sos`` rows themselves)."""
    ok = isinstance(sections, tuple) and len(sections) == 4
    if ok:
        aa, am_t, ac, ad = (np.asarray(a) for a in sections)
        ns = aa.shape[0] if aa.ndim == 2 else -1
        ok = (aa.shape == (ns, ns) and am_t.shape == (q, ns) and ac.shape == (ns,)
              and ad.shape == (1,))
    if not ok:
        got = (f"a tuple of {len(sections)}" if isinstance(sections, tuple) else
               f"{type(sections).__name__} of shape {np.shape(sections)}")
        raise ConfigError(f"sections = {got} is invalid: expected lift_sections(sos, {q}), "
                          f"the filter lifted to the decimation (A, M^T, C, D)")
    return LiftedSections(*sections)


def _whole_intervals(n, q: int) -> int:
    """``n`` as an int if it is a positive multiple of the decimation ``q``, else ConfigError."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < q or n % q:
        raise ConfigError(f"n_samples = {n!r} is invalid: expected a positive multiple of the "
                          f"decimation {q}")
    return int(n)


def _kept_block(t0, fs, q, n, volts, truth, sat) -> DecimatedBlock:
    """The :class:`DecimatedBlock` of the kept volts (3, J), truth and flags (3, J)."""
    return DecimatedBlock(t0_s=t0, fs_hz=fs, decimation=q, samples=n,
                          volts={"a": volts[0], "x": volts[1], "y": volts[2]}, truth=truth,
                          saturated={"a": sat[0], "x": sat[1], "y": sat[2]})


#: intervals the fused kernels take at a time: their temporaries (~160 doubles per interval
#: for the paper's bench, q = 10) then stay in the core's cache; the same values for any size
CHUNK_INTERVALS = 256


@njit(cache=True, nogil=True)
def _fused_kernel(lifted, acc, lever, sections, v, z, rng_a, rng_x, rng_y, s_aa, carry, out,
                  chunk):
    """The linear fused chain over ``J = v.size / q`` intervals (module docstring), ``chunk``
    intervals at a time (:func:`_fused_chunk`; every sum runs per interval and every noise
    stream is drawn in sample order, so the values do not depend on ``chunk``). ``lifted``:
    :class:`_LiftedParams`; ``acc``, ``lever``: the sensors' row parameters; ``sections``:
    :class:`rig.sosfilt.LiftedSections`. ``z`` (in/out) the state at the block's first kept
    instant, ends at the next block's; ``s_aa`` (3, ns) and ``carry`` (3,) (in/out) the filter
    states and the saturation carried (a, x, y); ``out`` = (volts (3, J), saturation flags
    (3, J), then the truth at the kept instants: accel (J,), theta (J, nth), mirror x (J,),
    mirror rotation (J,)), written."""
    q = lifted.gamma_q.shape[0]
    nj = v.shape[0] // q
    for j0 in range(0, nj, chunk):
        _fused_chunk(lifted, acc, lever, sections, v, z, rng_a, rng_x, rng_y, s_aa, carry, out,
                     j0, min(nj, j0 + chunk))


@njit(cache=True, nogil=True)
def _fused_chunk(lifted, acc, lever, sections, v, z, rng_a, rng_x, rng_y, s_aa, carry, out,
                 j0, j1):
    """Intervals ``j0 .. j1 - 1`` of :func:`_fused_kernel` in four passes: (1) the state at
    every kept instant, (2) the readings at every sample (loops over the intervals innermost:
    vectorised), (3) per sample the sensors, noise, clipping and flags, a row at a time, (4)
    the lifted anti-alias sections per channel."""
    phi_t, gamma_q, readings, accel_row, th0, mirror_w, body = lifted
    volts, sat, accel, theta, mx, mrot = out
    sd_a = acc.noise_sd_v
    sd_p = lever.noise_sd_m
    nz = z.shape[0]
    q = gamma_q.shape[0]
    nr = 3 * q
    nj = j1 - j0
    nth = theta.shape[1]
    # (1) inputs by interval, the input terms of the state, the states at the kept instants
    x = np.empty((nz + q, nj))  # z_j then the interval's inputs, one column per interval
    for i in range(q):
        for j in range(nj):
            x[nz + i, j] = v[(j0 + j) * q + i]
    u = np.zeros((nz, nj))
    for i in range(q):
        for m in range(nz):
            g = gamma_q[i, m]
            for j in range(nj):
                u[m, j] += g * x[nz + i, j]
    zc = z.copy()  # local: the compiler keeps it apart from x
    zn = np.empty(nz)
    for j in range(nj):
        for m in range(nz):
            x[m, j] = zc[m]
            zn[m] = u[m, j]
        for c in range(nz):  # the rows' sums side by side, each over c = 0 .. nz - 1 in order
            zj = zc[c]
            for m in range(nz):
                zn[m] += phi_t[c, m] * zj
        for m in range(nz):
            zc[m] = zn[m]
    for m in range(nz):
        z[m] = zc[m]
    # the truth at the kept instants
    for j in range(nj):
        s = 0.0
        for c in range(nz):
            s += accel_row[c] * x[c, j]
        accel[j0 + j] = s
        s = 0.0
        for b in range(nth):
            theta[j0 + j, b] = x[th0 + b, j]
            s += mirror_w[b] * x[th0 + b, j]
        mx[j0 + j] = s
        mrot[j0 + j] = x[th0 + body, j]
    # (2) the readings at every sample: r[3 i + k, j]
    r = np.zeros((nr, nj))
    for c in range(nz + q - 1):  # the last input reaches no sample of its interval
        for m in range(nr):
            w = readings[c, m]
            if w != 0.0:
                for j in range(nj):
                    r[m, j] += w * x[c, j]
    # (3) per sample: sensors, noise, clipping, flags -> the filter's inputs; the noise is
    # drawn first, in sample order (each stream as the per-sample path draws it)
    # (the draws of sample q j + i at [i, j], beside the readings they join)
    wa = np.zeros((q, nj if sd_a > 0.0 else 0))
    wx = np.zeros((q, nj if sd_p > 0.0 else 0))
    wy = np.zeros(wx.shape)
    for j in range(wa.shape[1]):
        for i in range(q):
            wa[i, j] = sd_a * rng_a.standard_normal()
    for j in range(wx.shape[1]):
        for i in range(q):
            wx[i, j] = sd_p * rng_x.standard_normal()
    for j in range(wy.shape[1]):
        for i in range(q):
            wy[i, j] = sd_p * rng_y.standard_normal()
    xin = np.empty((3, q, nj))
    flag = np.empty((2, q, nj), dtype=np.bool_)
    level = np.zeros(nj)  # the mirror's height: 0 (the linear bench has none)
    for i in range(q):
        accelerometer_row(r[3 * i], wa[i], acc, xin[0, i], flag[0, i])
        lever_row(r[3 * i + 1], level, r[3 * i + 2], wx[i], wy[i], lever, xin[1, i], xin[2, i],
                  flag[1, i])
    for f in range(2):  # the interval rule: since the previous kept instant, up to this one
        c = carry[f]
        for j in range(nj):
            sat[f, j0 + j] = c or flag[f, 0, j]
            c = False
            for i in range(1, q):
                c = c or flag[f, i, j]
        carry[f] = c
    for j in range(nj):
        sat[2, j0 + j] = sat[1, j0 + j]
    carry[2] = carry[1]
    # (4) the lifted anti-alias sections, per channel
    lifted_sections_pass(xin, sections, s_aa, volts, j0)


#: what the nonlinear model's fused chain runs at every DAC sample (the run file's model info)
PER_SAMPLE_NONLINEAR = {
    "what": "the whole bench state (the nonlinear bench integrated at every DAC sample), the "
            "mirror's exact kinematics, the optical lever's exact geometry, the sensors' white "
            "noise (one draw per sample and channel), the clipping at the detector edge and the "
            "accelerometer's range with their flags, into the anti-alias filter (itself lifted "
            "to the output rate)",
    "why": "not linear, so not lifted to the output rate (no Phi^q): the pendulum's large-angle "
           "terms and the lever's second-order geometry (~0.4 % of the spot's rms in u, far "
           "above round-off) act on each sample, clipping and flags too, and the filter's "
           "input is the sum of those and the noise",
    "fused": "the mirror's kinematics, the sensors, noise, clipping and flags in one compiled "
             "pass (the per-sample path's own arithmetic), then the anti-alias filter lifted to "
             "the output rate "
             "(its sections' exact linear map over each interval, computing only the kept "
             "instants; equal to filtering every sample up to round-off) (rig.bench.fused)",
}


def fused_model_info(model, info: ModelInfo) -> ModelInfo:
    """``info`` (:meth:`rig.bench.BenchSimulation.model_info` of ``model``) as the fused chain
    runs it: its ``per_sample`` (what runs at every DAC sample and why, with its ``rate_hz``)
    and, for the linear model, the ``method`` it steps the bench by (lifted)."""
    linear = model.model == "linear"
    per_sample = dict(PER_SAMPLE if linear else PER_SAMPLE_NONLINEAR, rate_hz=float(model.fs_hz))
    return dataclasses.replace(info, per_sample=per_sample,
                               method=linear_method(model, LIFTED_STEP) if linear
                               else info.method)


def advance_decimated_nonlinear(model, state, chain: DecimatedState, n: int, sections: tuple,
                                source_block=None):
    """The nonlinear model's ``n`` DAC samples (a whole number of intervals) from ``state`` (at
    a kept instant) through the sensors, the anti-alias filter and the decimation, keeping every
    ``q``-th sample. ``sections``: the filter lifted to the decimation,
    :func:`rig.sosfilt.lift_sections` of its ``sos`` (as :func:`advance_decimated` takes it).

    The bench state at every DAC sample is :func:`rig.bench.run.bench_states` (what
    :func:`rig.bench.advance` steps); then one compiled kernel (:func:`nonlinear_fused_kernel`):
    per sample the mirror's exact kinematics (:func:`rig.bench.run.mirror_point`), the
    accelerometer (:func:`rig.devices.accelerometer.accelerometer_row`) and the lever
    (:func:`rig.devices.optical_lever.lever_row`) with their noise, clipping and flags, then
    the filter lifted to the interval (:func:`rig.sosfilt.lifted_sections_pass`). The noise is
    the per-sample path's (each stream's draws in sample order), so the filter's inputs, the
    flags and the truth equal the per-sample path's bit for bit, and the kept volts equal
    :func:`rig.bench.advance` then daq's filter and decimation up to the lifted filter's
    round-off (the bound: tests/rig/bench/test_fused.py). The cost: docs/bench_model.md.

    Returns (:class:`rig.blocks.DecimatedBlock`, the bench state after it, the chain state).
    ``chain.zi`` (3, 2 x sections): the sections' state per channel, as
    :func:`start_decimated` makes it.

    Raises
    ------
    ConfigError : ``n`` not a positive multiple of the decimation, or a linear model.
    DivergenceError : a non-finite state in the block.
    """
    if model.model != "nonlinear":
        raise ConfigError(f"advance_decimated_nonlinear needs the nonlinear model, not "
                          f"{model.model!r}")
    q = model.decimation
    n = _whole_intervals(n, q)
    sections = _checked_sections(sections, q)
    fs = model.fs_hz
    v, src, z_out, z, accel, native, h_next = bench_states(model, state, n, source_block)
    sl = model.slices
    th = sl["theta_rad"]
    acc = model.accelerometer
    scene = model.scene
    layout = MirrorLayout(th.start, sl["accel_highpass_q_mps"].start if acc.n_states else -1,
                          np.asarray(scene.chain.length_m, dtype=float), scene.mirror.body,
                          float(scene.mirror.position_m))
    accel = np.ascontiguousarray(accel, dtype=float)
    generators = sensor_generators(state)
    s_aa = np.array(chain.zi, dtype=float)
    carry = np.array(chain.carry, dtype=np.bool_)
    j = n // q
    volts = np.empty((3, j))
    sat = np.empty((3, j), dtype=np.bool_)
    mx, mrot = np.empty(j), np.empty(j)
    nonlinear_fused_kernel(z_out, accel, layout, acc.row_params(fs), model.lever.row_params(fs),
                           *generators, sections, s_aa, carry, (volts, sat, mx, mrot), q,
                           CHUNK_INTERVALS)
    t0 = state.index / fs
    truth = {"stage_accel_mps2": accel[::q].copy(), "theta_rad": z_out[::q, th].copy(),
             "mirror_x_m": mx, "mirror_rot_rad": mrot, "source_v": v[::q].copy()}
    new = state_after(state, n, z, src, generators, native, h_next)
    return _kept_block(t0, fs, q, n, volts, truth, sat), new, DecimatedState(zi=s_aa, carry=carry)


@njit(cache=True, nogil=True)
def nonlinear_fused_kernel(z_out, accel, layout, acc, lever, rng_a, rng_x, rng_y, sections, s_aa,
                           carry, out, q, chunk):
    """Per DAC sample k of the bench states ``z_out`` (n, nz) and ``accel`` (n,) (``layout``:
    :class:`MirrorLayout`): the mirror's kinematics (:func:`rig.bench.run.mirror_point`), the
    accelerometer and the lever, a row of samples at a time
    (:func:`rig.devices.accelerometer.accelerometer_row`,
    :func:`rig.devices.optical_lever.lever_row`; ``acc``, ``lever``: their row parameters),
    into the filter inputs of ``chunk`` intervals at a time (3, q, chunk), with each chunk's
    noise drawn first in sample order per stream (a noise rms of 0: none drawn), and per
    channel whether its sensor saturated since the previous kept instant (``carry`` (3,)
    in/out: after the last kept instant); then those inputs through the lifted ``sections``
    (:func:`rig.sosfilt.lifted_sections_pass`; ``s_aa`` (3, ns) in/out). ``out`` = (volts
    (3, J), saturation flags (3, J), the mirror's translation and rotation at the kept
    instants (J,)), written."""
    th0, hp_col, lengths, body, s_m = layout
    volts, sat, mx, mrot = out
    wc = acc.corner_rad_s
    sd_a = acc.noise_sd_v
    sd_p = lever.noise_sd_m
    c_a = carry[0]
    c_p = carry[1]
    nj = accel.shape[0] // q
    for j0 in range(0, nj, chunk):
        nc = min(chunk, nj - j0)
        m = nc * q
        wa = np.empty(m if sd_a > 0.0 else 0)
        wx = np.empty(m if sd_p > 0.0 else 0)
        wy = np.empty(wx.shape[0])
        fill_standard_normal(rng_a, wa)
        fill_standard_normal(rng_x, wx)
        fill_standard_normal(rng_y, wy)
        xin = np.empty((3, q, nc))
        flag = np.empty((2, q, nc), dtype=np.bool_)
        # per sample: the sensed acceleration and the mirror's kinematics (sines and cosines of
        # the angles); the sensors then a row at a time (sample i of every interval), which
        # vectorises
        sa = np.empty((q, nc))
        nar = np.empty((q, nc if wa.shape[0] else 0))
        mxk = np.empty((q, nc))
        mzk = np.empty((q, nc))
        mrk = np.empty((q, nc))
        nxr = np.empty((q, nc if wx.shape[0] else 0))
        nyr = np.empty(nxr.shape)
        for j in range(nc):
            for i in range(q):
                k = (j0 + j) * q + i
                h = z_out[k, hp_col] if hp_col >= 0 else 0.0
                sa[i, j] = accel[k] - wc * h
                if wa.shape[0]:
                    nar[i, j] = sd_a * wa[j * q + i]
                mxk[i, j], mzk[i, j], mrk[i, j] = mirror_point(z_out, k, th0, lengths, body, s_m)
                if wx.shape[0]:
                    nxr[i, j] = sd_p * wx[j * q + i]
                    nyr[i, j] = sd_p * wy[j * q + i]
        for i in range(q):
            accelerometer_row(sa[i], nar[i], acc, xin[0, i], flag[0, i])
            lever_row(mxk[i], mzk[i], mrk[i], nxr[i], nyr[i], lever, xin[1, i], xin[2, i],
                      flag[1, i])
        for j in range(nc):  # the interval rule, in sample order
            mx[j0 + j] = mxk[0, j]
            mrot[j0 + j] = mrk[0, j]
            sat[0, j0 + j] = c_a or flag[0, 0, j]
            sat[1, j0 + j] = c_p or flag[1, 0, j]
            sat[2, j0 + j] = sat[1, j0 + j]
            c_a = False
            c_p = False
            for i in range(1, q):
                c_a = c_a or flag[0, i, j]
                c_p = c_p or flag[1, i, j]
        lifted_sections_pass(xin, sections, s_aa, volts, j0)
    carry[0] = c_a
    carry[1] = c_p
    carry[2] = c_p
