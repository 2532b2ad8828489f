"""The bench under a stepped sine: its run point by point, and the exact truth of every point.

:class:`SineBench` runs the scene's bench (the model chosen for the sine's worst point by the
error budget, :func:`sine_model`) from a :class:`rig.devices.stepped_sine.SinePoint` to the next
through the fused chain of every acquisition (:mod:`rig.bench.fused`: stage, pendulum, sensors with
their noise and clipping, the anti-alias filter, the decimation), carrying the bench, filter and
source states, so the points are one continuous run.

:class:`SineChain` is the exact linear chain from the DAC samples to the filtered channel volts
at the simulation rate, ``x_{k+1} = A x_k + B v_k``, ``y_k = C x_k`` (the bench's exact step
``Phi, Gamma``, the sensors' linear readings with their calibrations, and the anti-alias
sections of each channel; no feedthrough: the readings at sample k do not see ``v_k``). From it:

- the steady state at ``f``: ``X = (e^{i w h} I - A)^-1 B`` per unit complex input, ``Y = C X``
  per source volt (equal to :func:`rig.bench.expected_response` ``sampled=True`` times the
  filter's response, tests/rig/test_sine_bench.py);
- the transient of a step: at a point's first sample ``k0`` the state differs from the new
  steady state by ``e = x(k0) - Re(X u e^{i 2 pi phi_0})`` (``u = -i sqrt(2) L``: the sine's
  phasor), which then decays as ``A^k e``: the modes ``lambda_m`` of ``A`` (the poles) with
  residues ``(C v_m)(w_m . e)`` (``v_m, w_m`` right and left eigenvectors);
- the settle rule (:func:`settle_samples`): the fewest output samples ``S`` after which the
  modal bound of that transient, ``sum_m |C_c v_m| |w_m . e| |lambda_m|^(q S)``, is at most
  ``tolerance`` times the steady amplitude of every channel c (so the estimate's relative
  settling bias is below about ``2 tolerance``);
- the exact settling bias (:func:`settling_bias`): what the synchronous DFT over the window
  (``N`` output samples from ``k0 + q S``) makes of the transient, ``(2 / N) e^{-i 2 pi phi_w}
  C A^{q S} G e`` with ``G = sum_{j<N} (A^q e^{-i w q h})^j`` (a geometric series of matrices,
  summed by doubling, no inversion), added to the steady coefficients of every channel.

Public API: :class:`SineBench`, :class:`SineChain`, :func:`sine_chain`, :func:`sine_model`,
:func:`settle_samples`, :func:`settling_bias`, :func:`step_error`, :func:`filter_response`,
:class:`PointTruth`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError
from rig.scene import Scene
from rig.devices.stepped_sine import SinePoint, SineSourceState, sine_samples
from rig.bench.model import build_model
from rig.bench.run import start
from rig.bench.selection import select_model
from rig.bench.fused import (advance_decimated, advance_decimated_nonlinear, lift,
                             start_decimated)
from rig.sosfilt import lift_sections

CHANNELS = ("a", "x", "y")


def _sections_state_space(sos: np.ndarray):
    """(A, B, C, D) of the SOS cascade at its own rate (transposed direct form II per section,
    the sections in order), input and output scalars."""
    sos = np.asarray(sos, float).reshape(-1, 6)
    ns = 2 * sos.shape[0]
    a, b, c, d = np.zeros((ns, ns)), np.zeros(ns), np.zeros(ns), 1.0
    # running: the output of the cascade so far as (c_row, d) of the input and the states
    c_in, d_in = np.zeros(ns), 1.0
    for i, (b0, b1, b2, a0, a1, a2) in enumerate(sos):
        b0, b1, b2, a1, a2 = b0 / a0, b1 / a0, b2 / a0, a1 / a0, a2 / a0
        s = 2 * i
        # y = b0 u + s1;  s1' = b1 u - a1 y + s2;  s2' = b2 u - a2 y, with u = c_in x + d_in v
        c_out = b0 * c_in
        c_out[s] += 1.0
        d_out = b0 * d_in
        a[s] = b1 * c_in - a1 * c_out
        a[s, s + 1] += 1.0
        b[s] = b1 * d_in - a1 * d_out
        a[s + 1] = b2 * c_in - a2 * c_out
        b[s + 1] = b2 * d_in - a2 * d_out
        c_in, d_in = c_out, d_out
    c, d = c_in, d_in
    return a, b, c, d


@dataclass(frozen=True, eq=False)
class SineChain:
    """The exact linear chain DAC sample -> filtered channel volts (module docstring).

    Attributes
    ----------
    a, b, c : (nx, nx), (nx,), (3, nx): ``x_{k+1} = a x_k + b v_k``, volts ``c x_k`` of a, x, y.
    fs_hz, q : simulation rate [Hz] and decimation (output rate ``fs_hz / q``).
    volts_per_unit : (3,) the channels' signed calibrations (a: V per m/s^2, x: V/m, y: V/rad).
    poles : (nx,) eigenvalues of ``a`` (per DAC sample); modes, modes_inv: right eigenvectors
        and their inverse (rows: left eigenvectors).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    fs_hz: float
    q: int
    volts_per_unit: np.ndarray
    poles: np.ndarray
    modes: np.ndarray
    modes_inv: np.ndarray
    sos: np.ndarray

    @property
    def rate_hz(self) -> float:
        return self.fs_hz / self.q

    def steady_state(self, frequency_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """``(X, Y)``: the state (nx,) and channel volts (3,) per unit complex input at
        ``frequency_hz`` (``v_k = Re(e^{i w k h})``)."""
        z = np.exp(2j * np.pi * frequency_hz / self.fs_hz)
        x = np.linalg.solve(z * np.eye(self.a.shape[0]) - self.a, self.b.astype(complex))
        return x, self.c @ x

    def decay_time_s(self) -> np.ndarray:
        """Amplitude time constant of every mode [s]: ``-h / ln |lambda|``."""
        with np.errstate(divide="ignore"):
            return -1.0 / (self.fs_hz * np.log(np.abs(self.poles)))


def sine_chain(model, sos: np.ndarray) -> SineChain:
    """The :class:`SineChain` of a bench model (:func:`rig.bench.build_model`; its linear part
    is used whatever model runs) with the anti-alias sections ``sos`` (rows ``[b0 b1 b2 a0 a1
    a2]``; (0, 6) or one unit section: none).

    Raises ConfigError if the chain's modes cannot be separated (a defective or nearly
    defective eigenvector matrix) or a mode does not decay (|lambda| >= 1)."""
    phi, gamma = np.asarray(model.phi), np.asarray(model.gamma)
    nz = phi.shape[0]
    sl = model.slices
    th = sl["theta_rad"]
    scene = model.scene
    rows = np.zeros((3, nz))
    rows[0] = model.accel_row
    if model.accelerometer.n_states:
        rows[0, sl["accel_highpass_q_mps"].start] -= model.accelerometer.corner_rad_s
    rows[1, th] = np.asarray(scene.mirror_weights(), float)
    rows[2, th.start + scene.mirror.body] = 1.0
    cal = {"a": model.accelerometer.calibration(), **model.lever.calibrations()}
    vpu = np.array([cal[k].volts_per_unit for k in CHANNELS], float)
    readings = vpu[:, None] * rows  # channel volts before the filter, (3, nz)
    sa, sb, sc, sd = _sections_state_space(np.asarray(sos, float).reshape(-1, 6))
    ns = sa.shape[0]
    nx = nz + 3 * ns
    a = np.zeros((nx, nx))
    b = np.zeros(nx)
    c = np.zeros((3, nx))
    a[:nz, :nz] = phi
    b[:nz] = gamma
    for i in range(3):
        s = slice(nz + i * ns, nz + (i + 1) * ns)
        a[s, s] = sa
        a[s, :nz] = np.outer(sb, readings[i])
        c[i, :nz] = sd * readings[i]
        c[i, s] = sc
    poles, vecs = np.linalg.eig(a)
    if not np.all(np.isfinite(poles)) or np.max(np.abs(poles)) >= 1.0:
        raise ConfigError("the bench's chain has a mode that does not decay (a pole on or "
                          "outside the unit circle): a stepped sine cannot settle")
    cond = np.linalg.cond(vecs)
    if not np.isfinite(cond) or cond > 1e12:
        raise ConfigError(f"the bench's modes cannot be separated (eigenvector condition number "
                          f"{cond:.3g} > 1e12: nearly coincident modes); the settle rule and the "
                          "settling bias from poles and residues are not defined for this scene")
    return SineChain(a=a, b=b, c=c, fs_hz=float(model.fs_hz), q=int(model.decimation),
                     volts_per_unit=vpu, poles=poles, modes=vecs, modes_inv=np.linalg.inv(vecs),
                     sos=np.asarray(sos, float).reshape(-1, 6))


def filter_response(chain: SineChain, frequency_hz: float) -> complex:
    """The anti-alias sections' complex response at ``frequency_hz`` [Hz] (at the DAC rate)."""
    zinv = np.exp(-2j * np.pi * frequency_hz / chain.fs_hz)
    h = 1.0 + 0j
    for b0, b1, b2, a0, a1, a2 in chain.sos:
        h *= (b0 + zinv * (b1 + zinv * b2)) / (a0 + zinv * (a1 + zinv * a2))
    return complex(h)


def _phasor(level_vrms: float) -> complex:
    """Complex amplitude of ``sqrt(2) L sin(phase)``: ``-i sqrt(2) L``."""
    return -1j * math.sqrt(2.0) * level_vrms


def step_error(chain: SineChain, error_end: np.ndarray, prev: SinePoint | None,
               point: SinePoint, phase_cycles: float) -> np.ndarray:
    """The state's difference from ``point``'s steady state at its first sample (real, (nx,)):
    the previous point's remaining transient ``error_end`` (zeros, or the state itself from
    rest when ``prev`` is None) plus the jump between the two steady states at the common
    phase ``phase_cycles``."""
    rot = np.exp(2j * np.pi * phase_cycles)
    new = (chain.steady_state(point.frequency_hz)[0] * _phasor(point.level_vrms) * rot).real
    old = 0.0 if prev is None else \
        (chain.steady_state(prev.frequency_hz)[0] * _phasor(prev.level_vrms) * rot).real
    return np.asarray(error_end, float) + old - new


def transient_bound(chain: SineChain, error: np.ndarray, samples: int) -> np.ndarray:
    """The modal bound (3,) of each channel's transient [V] at ``samples`` DAC samples after
    the state error ``error``: ``sum_m |C v_m| |w_m . e| |lambda_m|^samples``."""
    coef = np.abs(chain.modes_inv @ error)
    res = np.abs(chain.c @ chain.modes) * coef[None, :]
    return res @ np.abs(chain.poles) ** samples


def settle_samples(chain: SineChain, error: np.ndarray, point: SinePoint, tolerance: float,
                   lo: int, hi: int) -> int:
    """The settle rule (module docstring): the fewest output samples S in [lo, hi] after which
    every channel's modal transient bound is at most ``tolerance`` times its steady amplitude
    (``hi`` if none is)."""
    amp = np.abs(chain.steady_state(point.frequency_hz)[1] * _phasor(point.level_vrms))
    amp = np.maximum(amp, 1e-300)

    def ok(s):
        return bool(np.all(transient_bound(chain, error, chain.q * s) <= tolerance * amp))

    if ok(lo):
        return lo
    if not ok(hi):
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def _geometric(m: np.ndarray, n: int) -> np.ndarray:
    """``sum_{j<n} m^j`` by doubling (the top right block of ``[[m, I], [0, I]]^n``)."""
    nx = m.shape[0]
    power, total = np.eye(nx, dtype=m.dtype), np.zeros_like(m)  # m^k, sum_{j<k} m^j for k = 0
    base_p, base_s = m, np.eye(nx, dtype=m.dtype)  # m^(2^i), sum_{j<2^i} m^j
    while n:
        if n & 1:
            total = total + power @ base_s
            power = power @ base_p
        n >>= 1
        if n:
            base_s = base_s + base_p @ base_s
            base_p = base_p @ base_p
    return total


@dataclass(frozen=True)
class PointTruth:
    """The exact linear truth of one point (per channel a, x, y, complex (3,)).

    Attributes
    ----------
    steady_v : the steady-state DFT coefficient of each channel [V] (filtered volts).
    transient_v : what the window's DFT makes of the step's remaining transient [V].
    error_end : (nx,) the transient state left at the point's end (the next step's start).
    settle_bound : (3,) the modal bound of the transient at the window's start relative to each
        channel's steady amplitude.
    """

    steady_v: np.ndarray
    transient_v: np.ndarray
    error_end: np.ndarray
    settle_bound: np.ndarray


def settling_bias(chain: SineChain, error: np.ndarray, point: SinePoint,
                  phase_cycles: float) -> PointTruth:
    """The exact truth of ``point`` started with the state error ``error`` (:func:`step_error`)
    at phase ``phase_cycles``: the steady and transient DFT coefficients over its window
    (module docstring) and the error left at its end. The transient is summed mode by mode:
    with ``c = W e`` (W the left eigenvectors) and ``r_m = lambda_m^q e^{-i w q h}``, the
    window's sum is ``C V diag(lambda_m^{q S} (1 - r_m^N) / (1 - r_m)) c`` (the matrix form,
    :func:`_geometric`, gives the same to round-off: tests/rig/test_sine_bench.py)."""
    q, f = chain.q, point.frequency_hz
    u = _phasor(point.level_vrms)
    steady = chain.steady_state(f)[1] * u
    k_w = q * point.settle_samples
    n = point.integrate_samples
    lam = chain.poles.astype(complex)
    coef = chain.modes_inv @ np.asarray(error, float).astype(complex)
    r = lam ** q * np.exp(-2j * np.pi * f * q / chain.fs_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        series = np.where(np.abs(1 - r) > 1e-14, (1 - r ** n) / (1 - r), n)
    phase_w = phase_cycles + f * k_w / chain.fs_hz
    modal = lam ** k_w * series * coef
    transient = (2.0 / n) * np.exp(-2j * np.pi * phase_w) * (chain.c @ (chain.modes @ modal))
    end = (chain.modes @ (lam ** (k_w + q * n) * coef)).real
    amp = np.maximum(np.abs(steady), 1e-300)
    bound = transient_bound(chain, error, k_w) / amp
    return PointTruth(steady_v=steady, transient_v=transient, error_end=end, settle_bound=bound)


def settling_bias_matrix(chain: SineChain, error: np.ndarray, point: SinePoint,
                         phase_cycles: float) -> np.ndarray:
    """The transient DFT coefficients (3,) of :func:`settling_bias` by matrix powers and the
    matrix geometric series (no eigenvectors): its check."""
    q, f = chain.q, point.frequency_hz
    k_w = q * point.settle_samples
    start = np.linalg.matrix_power(chain.a, k_w) @ np.asarray(error, float)
    m = np.linalg.matrix_power(chain.a, q) * np.exp(-2j * np.pi * f * q / chain.fs_hz)
    n = point.integrate_samples
    summed = _geometric(m, n) @ start.astype(complex)
    phase_w = phase_cycles + f * k_w / chain.fs_hz
    return (2.0 / n) * np.exp(-2j * np.pi * phase_w) * (chain.c @ summed)


# -- the run --------------------------------------------------------------------------------

def sine_model(scene: Scene, worst_hz: float, level_vrms: float, duration_s: float,
               fmax_hz: float):
    """The bench model for a stepped sine: with ``acquisition.model = "auto"`` chosen by the
    error budget (:func:`rig.bench.select_model`) for the sweep's worst point, a sine of
    ``level_vrms`` at ``worst_hz`` (where the pendulum's response per volt is largest) held for
    ``duration_s`` from rest; the model is built for a sine at ``fmax_hz`` (the highest drive
    frequency, which sets the nonlinear remainder's node spacing)."""
    acq = scene.acquisition
    record = max(1.0, math.ceil(duration_s)) if duration_s > 0 else 1.0

    def sine_scene(f):
        src = dataclasses.replace(scene.source, type="sine", frequency_hz=float(f),
                                  level_vrms=float(level_vrms))
        settings = dict(scene.settings)
        settings["source"] = dict(settings["source"], type="sine", frequency_hz=float(f),
                                  level_vrms=float(level_vrms))
        sc = dataclasses.replace(scene, source=src, settings=settings)
        return sc.with_acquisition(records=1, record_s=float(record), settle_s=0.0)

    selection = None
    if acq.model == "auto":
        selection = select_model(sine_scene(worst_hz))
    return build_model(sine_scene(min(fmax_hz, scene.source.fs_hz / 2 * 0.999)),
                       selection=selection), selection


class SineBench:
    """The bench run point by point through the fused acquisition chain (module docstring).

    Parameters
    ----------
    model : the bench model (:func:`sine_model`).
    seed : seeds the sensors' noise (the stepped sine draws nothing).
    sos : the acquisition's anti-alias sections (rows ``[b0 b1 b2 a0 a1 a2]``; (0, 6): none).
    """

    def __init__(self, model, seed, sos: np.ndarray):
        self.model = model
        self.state = start(model, seed)
        sos = np.asarray(sos, float).reshape(-1, 6)
        self._sections = lift_sections(sos, model.decimation)
        self._chain = start_decimated(sos)
        self._lifted = lift(model, model.decimation) if model.model == "linear" else None
        self.source = SineSourceState()

    def run(self, point: SinePoint):
        """Run ``point`` whole (settle and integrate): its :class:`rig.blocks.DecimatedBlock`
        (``point.samples`` output samples) and the source's phase at its first sample."""
        n = point.samples * self.model.decimation
        phase0 = self.source.phase_cycles
        v, self.source = sine_samples(point, self.source, n, self.model.fs_hz)
        return self.run_samples(v), phase0

    def run_samples(self, v: np.ndarray):
        """Run the DAC samples ``v`` [V] (a whole number of output intervals; any source, the
        swept one's too, :mod:`rig.devices.swept_sine`): their
        :class:`rig.blocks.DecimatedBlock`."""
        model = self.model
        n = int(v.shape[0])
        src = dataclasses.replace(self.state.source, index=self.state.source.index + n)
        if self._lifted is not None:
            block, self.state, self._chain = advance_decimated(
                model, self._lifted, self.state, self._chain, n, self._sections, (v, src))
        else:
            block, self.state, self._chain = advance_decimated_nonlinear(
                model, self.state, self._chain, n, self._sections, (v, src))
        return block
