"""The bench fused with its sensors and the anti-alias filter (the linear one lifted).

What ``acquisition.model = "linear"`` computes per DAC sample (:func:`rig.bench.advance`) is
``z_{k+1} = Phi z_k + Gamma V_k`` (the exact zero-order-hold step), then the sensors read the
state, noise is added, the outputs are clipped and flagged, and the acquisition's anti-alias
filter runs over every sample before every ``q``-th is kept (``q = acquisition.decimation``).
Only the kept instants are stored. Here the same chain runs per *decimation interval* of ``q``
DAC samples, in one compiled kernel (:func:`_fused_kernel`) that writes only what is kept, in
four passes over each :data:`CHUNK_INTERVALS` intervals of a block (their temporaries then stay
in the core's cache; measured in BENCHMARKS.md):

1. the bench state only at the kept instants ``k = q j`` (lifting)::

       z_{j+1} = Phi^q z_j + sum_{i<q} Phi^(q-1-i) Gamma V_{qj+i}

2. the three linear readings the sensors need at every sample ``qj + i`` (the sensed
   acceleration ``x0'' - w_c q``, the mirror translation ``w . theta`` and rotation
   ``theta_mirror``), straight from ``z_j`` and the interval's held inputs::

       r(qj+i) = R Phi^i z_j + sum_{l<i} R Phi^(i-1-l) Gamma V_{qj+l}

   (``R`` the (3, nz) reading rows; one (nz + q, 3q) matrix, :attr:`Lifted.readings`);

3. per sample, what is not linear and so is not lifted: the optical lever's exact geometry
   (:func:`rig.devices.optical_lever._spot`, second order in the angles: ~0.4 % of the spot's
   rms, far above round-off), the white noise of the accelerometer and of both PSD axes (drawn
   inside the kernel from the same numpy generators, the same values in the same order as
   :meth:`Accelerometer.sense_and_output` and :meth:`OpticalLever.measure` draw them), the
   clipping at the accelerometer's range and at the detector's edge with their flags; a row at
   a time (sample ``i`` of every interval: :func:`_accelerometer_row`, :func:`_lever_row`),
   loops that vectorise (the lever's where every tilt of the row is within the small-angle
   polynomial's range, as a mirror's microradians are), the same arithmetic as per sample;

4. the anti-alias filter (the acquisition's sections, passed in as plain arrays: rig does not
   import daq), linear in its input, that clipped noisy sum: lifted to the interval in the
   sections' own state coordinates (:func:`lift_sections`, ``s_{j+1} = A s_j + M x_j``, ``y_j
   = C s_j + D x_qj``; ``A`` is block lower triangular, as a cascade is), the three channels'
   recursions side by side.

Kept: the filtered volts, the truth (``stage_accel_mps2``, ``theta_rad``, ``mirror_x_m``,
``mirror_rot_rad``, ``source_v``) and, per channel, whether its sensor saturated within the kept
instant's interval (the acquisition's interval rule, :class:`rig.blocks.DecimatedBlock`).

Equal to the per-sample path up to round-off: steps 1, 2 and 4 are the same exact linear maps
with their products formed once and summed in another order, so the values differ by rounding
that the stable bench and filter do not amplify (the bound and what it was measured at:
tests/rig/test_lifted.py); the noise, the geometry and the clipping are the per-sample path's
own arithmetic. Any split of a run into blocks of whole intervals gives the same bytes (every
sum runs per interval, in a fixed order). Valid for the linear model only (the nonlinear bench
has no Phi^q: :func:`advance_decimated_nonlinear` steps it per sample and fuses what follows
the bench, the per-sample path's own arithmetic up to the filter, which is step 4's lifted one:
equal to the per-sample path up to the filter's round-off). Cost per
interval and channel set: ``nz (nz + q)`` multiply-adds for the state, ``3 q (nz + q)`` for
the readings (vectorised over the intervals), ``q`` spot geometries and ``3 q`` normal draws,
and per channel ``q ns`` (vectorised) plus ``ns (ns + 2) / 2 + ns`` for the filter (``ns = 2 x
sections``); measured in BENCHMARKS.md.

Public API: :class:`Lifted`, :func:`lift`, :func:`lift_sections`, :func:`advance_decimated`,
:func:`advance_decimated_nonlinear`, :func:`start_decimated`, :class:`DecimatedState`,
:data:`PER_SAMPLE`, :data:`PER_SAMPLE_NONLINEAR`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig._jit import njit
from rig._sosfilt import sos_sample
from rig.blocks import DecimatedBlock
from rig.bench.run import mirror_point
from rig.devices.optical_lever import SMALL_ANGLE_RAD, _spot, _spot_small
from rig.devices.source import _fill_standard_normal
from rig.errors import ConfigError, DivergenceError

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
    "lifted": "bench state at the kept instants (rig.lifted)",
}


#: how the lifted chain steps the linear bench (the linear model's ``method`` text ends so)
LIFTED_STEP = "lifted (rig.lifted): one exact step Phi^q per output sample, q = the decimation"


@dataclass(frozen=True, eq=False)
class Lifted:
    """The lifted matrices of one linear :class:`rig.bench.BenchModel` at decimation ``q``.

    Attributes
    ----------
    q : DAC samples per kept instant.
    phi_q : (nz, nz) ``Phi^q``.
    gamma_q : (q, nz) row i: ``Phi^(q-1-i) Gamma``.
    readings : (nz + q, 3 q): column ``3 i + r`` gives reading r at sample i of an interval
        from ``(z_j, V_qj .. V_qj+q-1)`` (module docstring, step 2).
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
    :class:`rig.bench.BenchState` at a kept instant) through the fused chain (module
    docstring). ``sections``: the anti-alias filter lifted to the decimation,
    :func:`lift_sections` of its ``sos`` (rows ``[b0, b1, b2, 1, a1, a2]``; (0, 6): no
    filter). ``source_block`` as in :func:`rig.bench.advance`.

    Returns (:class:`rig.blocks.DecimatedBlock`, the bench state after it, the chain state
    after it).

    Raises
    ------
    ConfigError : ``n`` not a positive multiple of the decimation.
    DivergenceError : a non-finite state in the block.
    """
    from rig.bench.run import BenchState, _readonly, _rng, source_samples

    q = lifted.q
    n = _whole_intervals(n, q)
    fs = model.fs_hz
    v, src = source_samples(model, state, n, source_block)
    v = np.ascontiguousarray(v, dtype=float)
    z = np.array(state.z, dtype=float)
    z_start = z.copy()
    acc, lever = model.accelerometer, model.lever
    keys = ("accelerometer", "psd_x", "psd_y")
    generators = chain.generators
    if generators is None or any(g.bit_generator.state != state.rng_states[k]
                                 for g, k in zip(generators, keys)):
        generators = tuple(_rng(state.rng_states[k]) for k in keys)
    rng_a, rng_x, rng_y = generators
    sd_a = acc.noise_rms_v(fs) if acc.noise_mps2_rthz > 0 else 0.0
    sd_p = lever.noise_rms_m(fs) if lever.noise_m_rthz > 0 else 0.0
    j = n // q
    nth = lifted.theta[1] - lifted.theta[0]
    volts = np.empty((3, j))
    accel = np.empty(j)
    theta = np.empty((j, nth))
    mx = np.empty(j)
    mrot = np.empty(j)
    sat = np.empty((3, j), dtype=np.bool_)
    s_aa = np.array(chain.zi, dtype=float)
    carry = np.array(chain.carry, dtype=np.bool_)
    phi_rad = lever.phi_rad
    aa, am_t, ac, ad = _checked_sections(sections, q)
    _fused_kernel(lifted.phi_q, lifted.gamma_q, lifted.readings, lifted.accel_row,
                  lifted.theta[0], lifted.mirror_w, lifted.mirror_body, v, z,
                  rng_a, rng_x, rng_y, sd_a, sd_p,
                  acc.volts_per_mps2, acc.sensitivity_vpmps2 * acc.range_mps2,
                  np.cos(phi_rad), np.sin(phi_rad), lever.distance_m, lever.half_size_m,
                  lever.sign_x * lever.gain_vpm, lever.sign_y * lever.gain_vpm,
                  aa, am_t, ac, ad, s_aa, carry, volts, accel, theta, mx, mrot, sat,
                  CHUNK_INTERVALS)
    t0 = state.index / fs
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(volts))):
        raise DivergenceError(
            f"bench ({model.model}): a non-finite state in the block starting at t = {t0:.9g} s "
            f"({n} samples); the state at its start was {z_start.tolist()}", t0, z_start)
    truth = {"stage_accel_mps2": accel, "theta_rad": theta, "mirror_x_m": mx,
             "mirror_rot_rad": mrot, "source_v": v[::q].copy()}
    block, rng_states = _kept_block(t0, fs, q, n, volts, truth, sat, (rng_a, rng_x, rng_y))
    new = BenchState(index=state.index + n, z=_readonly(z), source=src, rng_states=rng_states,
                     seed_entropy=state.seed_entropy)
    return block, new, DecimatedState(zi=s_aa, carry=carry, generators=generators)


def _checked_sections(sections, q: int) -> tuple:
    """``sections`` as :func:`lift_sections` makes them for decimation ``q`` (A, M^T, C, D), or
    ConfigError naming what was given (e.g. the ``sos`` rows themselves)."""
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
    return sections


def _whole_intervals(n, q: int) -> int:
    """``n`` as an int if it is a positive multiple of the decimation ``q``, else ConfigError."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < q or n % q:
        raise ConfigError(f"n_samples = {n!r} is invalid: expected a positive multiple of the "
                          f"decimation {q}")
    return int(n)


def _kept_block(t0, fs, q, n, volts, truth, sat, generators):
    """The :class:`DecimatedBlock` of the kept volts (3, J), truth and flags (3, J), and the
    noise generators' states after it (accelerometer, psd_x, psd_y)."""
    block = DecimatedBlock(t0_s=t0, fs_hz=fs, decimation=q, samples=n,
                           volts={"a": volts[0], "x": volts[1], "y": volts[2]}, truth=truth,
                           saturated={"a": sat[0], "x": sat[1], "y": sat[2]})
    rng_states = {k: g.bit_generator.state
                  for k, g in zip(("accelerometer", "psd_x", "psd_y"), generators)}
    return block, rng_states


def lift_sections(sos: np.ndarray, q: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
    """The anti-alias sections ``sos`` lifted to ``q`` samples, in their own state coordinates
    (``zi`` of every section, ``2 x sections`` states ``s``): ``s_{j+1} = A s_j + M x_j`` over
    an interval's q inputs ``x_j`` and the kept output ``y_j = C s_j + D x_j[0]`` (the filtered
    sample at the interval's first instant). Returns ``(A, M^T, C, D)`` as (ns, ns), (q, ns),
    (ns,), (1,); built by running the sections (:func:`rig._sosfilt.sos_sample`) on unit
    states and inputs, so they are the sections' own linear map."""
    sos = np.ascontiguousarray(sos, dtype=float).reshape(-1, 6)
    ns = 2 * sos.shape[0]

    def run(s0, x):
        zi = s0.reshape(-1, 1, 2).copy()
        ys = [sos_sample(sos, zi, 0, xi) for xi in x]
        return zi.reshape(-1), ys[0]

    a, c = np.zeros((ns, ns)), np.zeros(ns)
    for k in range(ns):
        e = np.zeros(ns)
        e[k] = 1.0
        a[:, k], c[k] = run(e, np.zeros(q))
    m = np.zeros((ns, q))
    for i in range(q):
        x = np.zeros(q)
        x[i] = 1.0
        m[:, i], y0 = run(np.zeros(ns), x)
        if i == 0:
            d = np.array([y0])
    band = np.arange(ns)[None, :] >= 2 * (np.arange(ns)[:, None] // 2) + 2
    if np.any(a[band] != 0):  # what the kernel skips: a cascade cannot feed back
        raise ValueError("the lifted sections are not block lower triangular")
    return (np.ascontiguousarray(a), np.ascontiguousarray(m.T), c, d)


#: intervals the fused kernel takes at a time: its temporaries (~160 doubles per interval for
#: the paper's bench, q = 10) then stay in the core's cache; the same values for any size
CHUNK_INTERVALS = 256


@njit(cache=True, nogil=True)
def _fused_kernel(phi_q, gamma_q, readings, accel_row, th0, mirror_w, body, v, z,
                  rng_a, rng_x, rng_y, sd_a, sd_p, gain_a, lim_a, cphi, sphi, dist, half,
                  gain_x, gain_y, aa, am_t, ac, ad, s_aa, carry, volts, accel, theta, mx,
                  mrot, sat, chunk):
    """The fused chain over ``J = v.size / q`` intervals (module docstring), ``chunk``
    intervals at a time (:func:`_fused_chunk`: the four passes; every sum runs per interval
    and every noise stream is drawn in sample order, so the values do not depend on
    ``chunk``). ``z`` (in/out) the state at the block's first kept instant, ends at the next
    block's; ``s_aa`` (3, ns) and ``carry`` (3,) (in/out) the filter states and the
    saturation carried (a, x, y); writes the kept volts (3, J), truth and saturation flags
    (3, J)."""
    q = gamma_q.shape[0]
    nj = v.shape[0] // q
    phi_t = phi_q.T.copy()
    for j0 in range(0, nj, chunk):
        _fused_chunk(phi_t, gamma_q, readings, accel_row, th0, mirror_w, body, v, z,
                     rng_a, rng_x, rng_y, sd_a, sd_p, gain_a, lim_a, cphi, sphi, dist, half,
                     gain_x, gain_y, aa, am_t, ac, ad, s_aa, carry, volts, accel, theta, mx,
                     mrot, sat, j0, min(nj, j0 + chunk))


@njit(cache=True, nogil=True)
def _fused_chunk(phi_t, gamma_q, readings, accel_row, th0, mirror_w, body, v, z,
                 rng_a, rng_x, rng_y, sd_a, sd_p, gain_a, lim_a, cphi, sphi, dist, half,
                 gain_x, gain_y, aa, am_t, ac, ad, s_aa, carry, volts, accel, theta, mx,
                 mrot, sat, j0, j1):
    """Intervals ``j0 .. j1 - 1`` of :func:`_fused_kernel` (``phi_t`` = ``Phi^q`` transposed)
    in four passes: (1) the state at every kept instant, (2) the readings at every sample
    (loops over the intervals innermost: vectorised), (3) per sample the sensors, noise,
    clipping and flags, (4) the lifted anti-alias sections (:func:`lift_sections`: ``aa`` = A,
    ``am_t`` = M^T, ``ac``, ``ad``) per channel."""
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
    acc = np.empty(nz)
    for j in range(nj):
        for m in range(nz):
            x[m, j] = zc[m]
            acc[m] = u[m, j]
        for c in range(nz):  # the rows' sums side by side, each over c = 0 .. nz - 1 in order
            zj = zc[c]
            for m in range(nz):
                acc[m] += phi_t[c, m] * zj
        for m in range(nz):
            zc[m] = acc[m]
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
        _accelerometer_row(r[3 * i], wa[i], gain_a, lim_a, xin[0, i], flag[0, i])
        _lever_row(r[3 * i + 1], level, r[3 * i + 2], wx[i], wy[i], cphi, sphi, dist, half,
                   gain_x, gain_y, xin[1, i], xin[2, i], flag[1, i])
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
    _lifted_sections_pass(xin, aa, am_t, ac, ad, s_aa, volts, j0)


@njit(cache=True, nogil=True)
def _accelerometer_row(r, w, gain, lim, out, flag):
    """One sample of every interval of a chunk: the sensed acceleration readings ``r`` times
    the gain, plus the noise ``w`` (empty: none), clipped at ``+-lim`` into ``out`` and flagged
    beyond it (:meth:`Accelerometer.sense_and_output`'s arithmetic; a loop that vectorises)."""
    if w.shape[0]:
        for j in range(r.shape[0]):
            va = gain * r[j] + w[j]
            flag[j] = abs(va) > lim
            out[j] = min(max(va, -lim), lim)
    else:
        for j in range(r.shape[0]):
            va = gain * r[j]
            flag[j] = abs(va) > lim
            out[j] = min(max(va, -lim), lim)


@njit(cache=True, nogil=True, error_model="numpy")
def _lever_row(dx, dz, th, wx, wy, cphi, sphi, dist, half, gain_x, gain_y, out_x, out_y,
               flag):
    """One sample of every interval of a chunk: the optical lever's exact spot of the mirror's
    translations ``dx``, heights ``dz`` and rotations ``th``
    (:func:`rig.devices.optical_lever._spot`), plus the noise ``wx``, ``wy`` (empty: none),
    clipped at the detector's edge ``+-half`` times the signed gains into ``out_x``, ``out_y``
    and flagged beyond it (:meth:`OpticalLever.measure`'s arithmetic). Where every tilt is
    within the small-angle polynomial's range (a mirror's tilts are microradians) and there is
    noise, the spot is :func:`_spot_small`, the same arithmetic without a branch or a call, so
    the loop vectorises."""
    n = dx.shape[0]
    small = wx.shape[0] > 0
    for j in range(n):
        small = small & (abs(th[j]) <= SMALL_ANGLE_RAD)
    if small:
        for j in range(n):
            uk, vk = _spot_small(dx[j], dz[j], th[j], cphi, sphi, dist)
            flag[j], out_x[j], out_y[j] = _lever_out(uk + wx[j], vk + wy[j], half, gain_x,
                                                     gain_y)
    else:
        for j in range(n):
            uk, vk = _spot(dx[j], dz[j], th[j], cphi, sphi, dist)
            if wx.shape[0]:
                uk = uk + wx[j]
                vk = vk + wy[j]
            flag[j], out_x[j], out_y[j] = _lever_out(uk, vk, half, gain_x, gain_y)


@njit(cache=True, nogil=True)
def _lever_out(uk, vk, half, gain_x, gain_y):
    """The detector's flag (the spot beyond its edge ``+-half``) and its two outputs, the spot
    clipped at the edge times the signed gains."""
    return ((abs(uk) > half) | (abs(vk) > half), gain_x * min(max(uk, -half), half),
            gain_y * min(max(vk, -half), half))


@njit(cache=True, nogil=True)
def _lifted_sections_pass(xin, aa, am_t, ac, ad, s_aa, volts, j0):
    """The anti-alias sections lifted to the interval (:func:`lift_sections`: ``aa`` = A,
    ``am_t`` = M^T, ``ac``, ``ad``; ns = 0: no filter) over the filter inputs ``xin`` (3, q,
    nj) of intervals ``j0 .. j0 + nj - 1``: writes their kept volts (3, J) at those columns;
    ``s_aa`` (3, ns) in/out the sections' states per channel (a, x, y). Every sum runs per
    interval in a fixed order."""
    q = xin.shape[1]
    nj = xin.shape[2]
    ns = s_aa.shape[1]
    if ns == 0:
        for ch in range(3):
            for j in range(nj):
                volts[ch, j0 + j] = xin[ch, 0, j]
        return
    ua = np.zeros((3, ns, nj))
    for ch in range(3):
        for i in range(q):
            for k in range(ns):
                g = am_t[i, k]
                for j in range(nj):
                    ua[ch, k, j] += g * xin[ch, i, j]
    # the three channels' recursions side by side (independent sums in flight together)
    sn = np.empty((ns, 3))
    sk = np.empty((ns, 3))
    for k in range(ns):
        for ch in range(3):
            sn[k, ch] = s_aa[ch, k]
    d = ad[0]
    for j in range(nj):
        y0 = d * xin[0, 0, j]
        y1 = d * xin[1, 0, j]
        y2 = d * xin[2, 0, j]
        for k in range(ns):
            ck = ac[k]
            y0 += ck * sn[k, 0]
            y1 += ck * sn[k, 1]
            y2 += ck * sn[k, 2]
        volts[0, j0 + j] = y0
        volts[1, j0 + j] = y1
        volts[2, j0 + j] = y2
        for k in range(ns):
            s0 = ua[0, k, j]
            s1 = ua[1, k, j]
            s2 = ua[2, k, j]
            # a cascade: section k // 2 depends on itself and the sections before it only
            # (A is block lower triangular, exact zeros beyond)
            for c in range(2 * (k // 2) + 2):
                akc = aa[k, c]
                s0 += akc * sn[c, 0]
                s1 += akc * sn[c, 1]
                s2 += akc * sn[c, 2]
            sk[k, 0] = s0
            sk[k, 1] = s1
            sk[k, 2] = s2
        for k in range(ns):
            for ch in range(3):
                sn[k, ch] = sk[k, ch]
    for k in range(ns):
        for ch in range(3):
            s_aa[ch, k] = sn[k, ch]


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
             "instants; equal to filtering every sample up to round-off) (rig.lifted)",
}


def advance_decimated_nonlinear(model, state, chain: DecimatedState, n: int, sections: tuple,
                                source_block=None):
    """The nonlinear model's ``n`` DAC samples (a whole number of intervals) from ``state`` (at
    a kept instant) through the sensors, the anti-alias filter and the decimation, keeping every
    ``q``-th sample. ``sections``: the filter lifted to the decimation, :func:`lift_sections`
    of its ``sos`` (as :func:`advance_decimated` takes it).

    The bench state at every DAC sample is :func:`rig.bench.run.bench_states` (what
    :func:`rig.bench.advance` steps); then one compiled kernel (:func:`_nonlinear_kernel`),
    :data:`CHUNK_INTERVALS` intervals at a time: per sample the mirror's exact kinematics
    (:func:`rig.bench.run.mirror_point`, what ``_mirror_kinematics(exact=True)`` computes), the
    accelerometer (``x0'' - w_c q``, gain, noise, clip, flag:
    :meth:`Accelerometer.sense_and_output`'s arithmetic), the lever
    (:func:`rig.devices.optical_lever._spot`, noise, clip, flag: :meth:`OpticalLever.measure`'s)
    and the interval rule's flags, then the filter lifted to the interval
    (:func:`_lifted_sections_pass`, the linear chain's step 4). The noise is the per-sample
    path's (each stream's ``standard_normal`` draws in sample order, from numpy's generators in
    compiled code: the same values and generator states as one ``standard_normal(n)`` per stream
    and block). So the filter's inputs, the flags and the truth equal the per-sample path's bit
    for bit, and the kept volts equal :func:`rig.bench.advance` then daq's filter and
    decimation up to the lifted filter's round-off (its sums in another order; the bound:
    tests/rig/test_lifted.py); the per-sample kinematics, noise, spot positions and sensed
    acceleration are never stored. Cost: the bench's own, plus per sample ``2 nth`` sines and
    cosines, one spot geometry and three normal draws, and per interval and channel the lifted
    filter's ``q ns`` (vectorised) plus ``ns (ns + 2) / 2 + ns`` multiply-adds.

    Returns (:class:`rig.blocks.DecimatedBlock`, the bench state after it, the chain state).
    ``chain.zi`` (3, 2 x sections): the sections' state per channel, as
    :func:`start_decimated` makes it.

    Raises
    ------
    ConfigError : ``n`` not a positive multiple of the decimation, or a linear model.
    DivergenceError : a non-finite state in the block.
    """
    from rig.bench.run import BenchState, _readonly, _rng, bench_states

    if model.model != "nonlinear":
        raise ConfigError(f"advance_decimated_nonlinear needs the nonlinear model, not "
                          f"{model.model!r}")
    q = model.decimation
    n = _whole_intervals(n, q)
    fs = model.fs_hz
    v, src, z_out, z, accel, native, h_next = bench_states(model, state, n, source_block)
    sl = model.slices
    th = sl["theta_rad"]
    acc, lever = model.accelerometer, model.lever
    hp_col = sl["accel_highpass_q_mps"].start if acc.n_states else -1
    accel = np.ascontiguousarray(accel, dtype=float)
    rng_a = _rng(state.rng_states["accelerometer"])
    rng_x = _rng(state.rng_states["psd_x"])
    rng_y = _rng(state.rng_states["psd_y"])
    sd_a = acc.noise_rms_v(fs) if acc.noise_mps2_rthz > 0 else 0.0
    sd_p = lever.noise_rms_m(fs) if lever.noise_m_rthz > 0 else 0.0
    scene = model.scene
    s_aa = np.array(chain.zi, dtype=float)
    carry = np.array(chain.carry, dtype=np.bool_)
    j = n // q
    volts = np.empty((3, j))
    sat = np.empty((3, j), dtype=np.bool_)
    mx, mrot = np.empty(j), np.empty(j)
    phi_rad = lever.phi_rad
    aa, am_t, ac, ad = _checked_sections(sections, q)
    _nonlinear_kernel(z_out, accel, th.start, hp_col, acc.corner_rad_s, acc.volts_per_mps2,
                      rng_a, sd_a, acc.sensitivity_vpmps2 * acc.range_mps2,
                      np.asarray(scene.chain.length_m, dtype=float), scene.mirror.body,
                      float(scene.mirror.position_m), math.cos(phi_rad), math.sin(phi_rad),
                      lever.distance_m, rng_x, rng_y, sd_p, lever.half_size_m,
                      lever.sign_x * lever.gain_vpm, lever.sign_y * lever.gain_vpm,
                      aa, am_t, ac, ad, s_aa, q, carry, volts, sat, mx, mrot, CHUNK_INTERVALS)
    t0 = state.index / fs
    truth = {"stage_accel_mps2": accel[::q].copy(), "theta_rad": z_out[::q, th].copy(),
             "mirror_x_m": mx, "mirror_rot_rad": mrot, "source_v": v[::q].copy()}
    block, rng_states = _kept_block(t0, fs, q, n, volts, truth, sat, (rng_a, rng_x, rng_y))
    new = BenchState(index=state.index + n, z=_readonly(z), source=src, rng_states=rng_states,
                     native=None if native is None else _readonly(np.array(native)),
                     h_next_s=float(h_next), seed_entropy=state.seed_entropy)
    return block, new, DecimatedState(zi=s_aa, carry=carry)


@njit(cache=True, nogil=True)
def _nonlinear_kernel(z_out, accel, th0, hp_col, wc, gain_a, rng_a, sd_a, lim_a, lengths, body,
                      s_m, cphi, sphi, dist, rng_x, rng_y, sd_p, half, gain_x, gain_y, aa, am_t,
                      ac, ad, s_aa, q, carry, volts, sat, mx, mrot, chunk):
    """Per DAC sample k of the bench states ``z_out`` (n, nz) (angles from column ``th0``, the
    accelerometer's high-pass state at ``hp_col``, -1: none) and ``accel`` (n,): the mirror's
    kinematics (:func:`rig.bench.run.mirror_point`), the accelerometer
    (``_sense_output_kernel``'s arithmetic) and the lever (``_measure_kernel``'s, a row of
    samples at a time: :func:`_lever_row`) into the filter
    inputs of ``chunk`` intervals at a time (3, q, chunk), with each chunk's noise drawn first
    in sample order per stream (``sd_a`` / ``sd_p`` = 0: none drawn), and per channel whether
    its sensor saturated since the previous kept instant (``sat`` (3, J); ``carry`` (3,) in/out:
    after the last kept instant); then those inputs through the lifted sections
    (:func:`_lifted_sections_pass`; ``s_aa`` (3, ns) in/out), which write the kept volts (3, J).
    Writes the mirror's translation and rotation at the kept instants (``mx``, ``mrot``, (J,)).
    Measured against the path with the kinematics, noise and filter apart: BENCHMARKS.md."""
    c_a = carry[0]
    c_p = carry[1]
    nj = accel.shape[0] // q
    for j0 in range(0, nj, chunk):
        nc = min(chunk, nj - j0)
        m = nc * q
        wa = np.empty(m if sd_a > 0.0 else 0)
        wx = np.empty(m if sd_p > 0.0 else 0)
        wy = np.empty(wx.shape[0])
        _fill_standard_normal(rng_a, wa)
        _fill_standard_normal(rng_x, wx)
        _fill_standard_normal(rng_y, wy)
        xin = np.empty((3, q, nc))
        flag = np.empty((2, q, nc), dtype=np.bool_)
        # per sample: the accelerometer and the mirror's kinematics (sines and cosines of the
        # angles); the lever's spots then a row at a time (sample i of every interval), which
        # vectorises (_lever_row)
        mxk = np.empty((q, nc))
        mzk = np.empty((q, nc))
        mrk = np.empty((q, nc))
        nxr = np.empty((q, nc if wx.shape[0] else 0))
        nyr = np.empty(nxr.shape)
        for j in range(nc):
            for i in range(q):
                k = (j0 + j) * q + i
                h = z_out[k, hp_col] if hp_col >= 0 else 0.0
                va = gain_a * (accel[k] - wc * h)
                if wa.shape[0]:
                    va = va + sd_a * wa[j * q + i]
                flag[0, i, j] = abs(va) > lim_a
                xin[0, i, j] = min(max(va, -lim_a), lim_a)
                mxk[i, j], mzk[i, j], mrk[i, j] = mirror_point(z_out, k, th0, lengths, body, s_m)
                if wx.shape[0]:
                    nxr[i, j] = sd_p * wx[j * q + i]
                    nyr[i, j] = sd_p * wy[j * q + i]
        for i in range(q):
            _lever_row(mxk[i], mzk[i], mrk[i], nxr[i], nyr[i], cphi, sphi, dist, half, gain_x,
                       gain_y, xin[1, i], xin[2, i], flag[1, i])
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
        _lifted_sections_pass(xin, aa, am_t, ac, ad, s_aa, volts, j0)
    carry[0] = c_a
    carry[1] = c_p
    carry[2] = c_p
