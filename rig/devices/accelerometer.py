"""The stage accelerometer (the paper's TEAC 710) with its conditioning amplifier.

Type chosen: piezoelectric, read by a charge amplifier
------------------------------------------------------
The paper names the sensor only as a TEAC 710; we take it to be what TEAC's 700-series vibration
transducers are, a piezoelectric (charge-output) accelerometer read through a charge amplifier (an
assumption: the papers give no data sheet). A piezoelectric element cannot pass DC, and the charge
amplifier's feedback time constant (far shorter than the element's own leakage time constant) sets
the low-frequency corner. The model is therefore a first-order high-pass in front of a flat
sensitivity::

    volts = sign * S * s / (s + w_c) * x0''        (w_c = 2 pi highpass_hz)
    state form:  q' = -w_c q + x0'',   volts = sign * S * (x0'' - w_c q)

``highpass_hz = 0.05`` (time constant 3.2 s, the charge amplifier's "long" setting): at 0.1 Hz the
accelerometer reads -0.97 dB and leads by +26.6 deg, at 1 Hz -0.011 dB, +2.9 deg. The corner is
inside the analysis band on purpose: a real bench shows it in H_t = x/a at the low end, and
:func:`rig.bench.expected_response` includes it. ``highpass_hz = 0`` models a servo
(force-balance) accelerometer, flat to DC (no state). The piezo's own mounted resonance (tens of
kHz) is far above the simulation band and is not modelled.

Output stage: the measured volts are ``front end + noise``, then clipped to ``+-|S| range``.

Defaults: the fields of :class:`Accelerometer` (1 V per m/s^2, 0.05 Hz corner, 1e-5 m/s^2/rtHz
white noise, +-10 m/s^2 range, polarity +1); samples beyond the range are clipped (flat-topped, as
a saturated amplifier does) and flagged (``overrange``); the polarity is part of the
:class:`~rig.blocks.Calibration`, and processing must undo it (SPEC section 5). The levels and
signal-to-noise ratios they give are in ``docs/devices.md``.

The noise is white over the simulation band: each sample gets ``|S| noise sqrt(fs / 2)`` rms (a
one-sided density ``noise`` up to the Nyquist frequency).

Public API: :class:`Accelerometer`, :class:`AccelerometerState`, :class:`AccelerometerRow`,
:func:`accelerometer_row`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rig.blocks import Calibration
from rig.errors import ConfigError
from rig.jit import njit
from rig.params import check_fields, param
from rig.linear import discretise


class AccelerometerRow(NamedTuple):
    """The output stage's numbers for the compiled row kernels (:meth:`Accelerometer.row_params`):
    ``gain`` = sign S [V/(m/s^2)], ``limit_v`` = |S| range (the clip), ``noise_sd_v`` the noise
    rms per sample (0: none drawn), ``corner_rad_s`` = w_c (the sensed acceleration is
    x0'' - w_c q)."""

    gain: float
    limit_v: float
    noise_sd_v: float
    corner_rad_s: float


@dataclass(frozen=True, eq=False)
class AccelerometerState:
    """Carried between blocks by :meth:`Accelerometer.measure`: the high-pass state ``q``
    [m/s] and the last input sample [m/s^2] (the input is linear between samples)."""

    q: float = 0.0
    last_accel_mps2: float | None = None


@dataclass(frozen=True)
class Accelerometer:
    """Piezoelectric accelerometer + charge amplifier (frozen, validated; module docstring). The
    fields are the keys of the scene's ``[accelerometer]`` section (unit, default and range in
    each field's doc, :func:`rig.params.param`); the output clips at +-S range."""

    sensitivity_vpmps2: float = param(1.0, "sensitivity [V per m/s^2] incl. the charge "
                                      "amplifier, > 0", unit="V per m/s^2 (the polarity is sign)",
                                      lo=0.0, strict=True)
    highpass_hz: float = param(0.05, "first-order low-frequency corner of the charge "
                               "amplifier [Hz], >= 0 (0: flat to DC, servo type)",
                               unit="Hz (0: flat to DC)", lo=0.0)
    noise_mps2_rthz: float = param(1e-5, "input-referred white noise density "
                                   "[m/s^2/sqrt(Hz)], >= 0", unit="m/s^2/rtHz", lo=0.0)
    range_mps2: float = param(10.0, "measuring range [m/s^2], > 0; the output clips beyond "
                              "(flagged)", unit="m/s^2", lo=0.0, strict=True)
    sign: int = param(1, "polarity of the mounted sensor, +1 or -1", choices=(1, -1))

    def __post_init__(self):
        check_fields(self, "accelerometer")

    # -- description ------------------------------------------------------------------------
    @property
    def volts_per_mps2(self) -> float:
        """Signed pass-band sensitivity sign * S [V per m/s^2]."""
        return self.sign * self.sensitivity_vpmps2

    @property
    def corner_rad_s(self) -> float:
        """w_c = 2 pi highpass_hz [rad/s]."""
        return 2 * math.pi * self.highpass_hz

    @property
    def n_states(self) -> int:
        """States of the front end (1 with a high-pass, 0 flat to DC)."""
        return 1 if self.highpass_hz > 0 else 0

    def calibration(self) -> Calibration:
        """Pass-band calibration: volts = sign S x0''."""
        return Calibration(quantity="stage acceleration x0''", unit="m/s^2",
                           volts_per_unit=self.volts_per_mps2)

    def frequency_response(self, freqs_hz) -> np.ndarray:
        """Volts per m/s^2 of stage acceleration, complex (nf,): sign S s / (s + w_c)."""
        s = 2j * np.pi * np.atleast_1d(np.asarray(freqs_hz, float))
        if self.highpass_hz == 0:
            return np.full(s.shape, self.volts_per_mps2, dtype=complex)
        return self.volts_per_mps2 * s / (s + self.corner_rad_s)

    def sensed(self, accel_mps2, q) -> np.ndarray:
        """The front end's output in m/s^2 (high-passed acceleration, x0'' - w_c q), given the
        acceleration and the high-pass state at the same instants."""
        return np.asarray(accel_mps2, float) - self.corner_rad_s * np.asarray(q, float)

    def noise_rms_v(self, fs_hz: float) -> float:
        """Rms of the white noise per sample at the rate ``fs_hz`` [V]."""
        return self.sensitivity_vpmps2 * self.noise_mps2_rthz * math.sqrt(fs_hz / 2)

    def row_params(self, fs_hz: float) -> AccelerometerRow:
        """The numbers :func:`accelerometer_row` takes at the rate ``fs_hz`` (the noise rms 0
        without noise)."""
        return AccelerometerRow(
            float(self.volts_per_mps2), float(self.sensitivity_vpmps2 * self.range_mps2),
            float(self.noise_rms_v(fs_hz)) if self.noise_mps2_rthz > 0 else 0.0,
            float(self.corner_rad_s))

    # -- measurement ------------------------------------------------------------------------
    def output(self, sensed_mps2, fs_hz: float, rng: np.random.Generator | None, *,
               noise: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Output stage: volts = clip(sign S sensed + noise, +-S range), and the overrange flags.

        ``sensed_mps2`` is the front end's output (:meth:`sensed`) at the sample instants;
        ``rng`` draws the noise (one standard normal per sample) unless ``noise`` is False.
        Returns (volts (N,), overrange (N,) bool).
        """
        s = np.ascontiguousarray(sensed_mps2, dtype=float).reshape(-1)
        if noise and self.noise_mps2_rthz > 0:
            sd, w = self.noise_rms_v(fs_hz), rng.standard_normal(s.shape[0])
        else:
            sd, w = 0.0, np.zeros(0)
        volts, over = np.empty(s.shape[0]), np.empty(s.shape[0], dtype=np.bool_)
        _output_kernel(s, self.volts_per_mps2, w, sd, self.sensitivity_vpmps2 * self.range_mps2,
                       volts, over)
        return volts, over

    def sense_and_output(self, accel_mps2, q, fs_hz: float, rng: np.random.Generator | None, *,
                         noise: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`sensed` then :meth:`output` in one pass (the same values): the acceleration
        [m/s^2] and the high-pass state q [m/s] at the sample instants (1-D, any strides; q is
        ignored flat to DC). Returns (sensed [m/s^2], volts [V], overrange (N,) bool)."""
        a = np.asarray(accel_mps2, dtype=float).reshape(-1)
        q = np.asarray(q, dtype=float).reshape(-1) if self.n_states else np.zeros(a.shape[0])
        if q.shape != a.shape:
            raise ConfigError(f"q has shape {q.shape}: expected that of the acceleration, "
                              f"{a.shape}")
        if noise and self.noise_mps2_rthz > 0:
            sd, w = self.noise_rms_v(fs_hz), rng.standard_normal(a.shape[0])
        else:
            sd, w = 0.0, np.zeros(0)
        sensed, volts = np.empty(a.shape[0]), np.empty(a.shape[0])
        over = np.empty(a.shape[0], dtype=np.bool_)
        _sense_output_kernel(a, q, self.corner_rad_s, self.volts_per_mps2, w, sd,
                             self.sensitivity_vpmps2 * self.range_mps2, sensed, volts, over)
        return sensed, volts, over

    def measure(self, accel_mps2, fs_hz: float, state: AccelerometerState | None,
                rng: np.random.Generator | None, *, noise: bool = True
                ) -> tuple[np.ndarray, AccelerometerState, np.ndarray]:
        """Measure an acceleration record given at the sample instants (standalone use).

        The front end is integrated exactly for an acceleration that is linear between the
        samples (first-order hold, exact discretisation of ``q' = -w_c q + x0''``); :mod:`rig.bench`
        instead carries ``q`` inside its exact discretisation of the whole bench, where x0'' is
        known between the samples. ``state`` (None: at rest, q = 0) is handed back for the next
        block; the first block's first sample starts the hold.

        Returns (volts (N,), state after the block, overrange (N,) bool).
        """
        a = np.asarray(accel_mps2, float)
        if a.ndim != 1:
            raise ConfigError(f"accel_mps2 has shape {a.shape}: expected a 1-D record")
        state = AccelerometerState() if state is None else state
        if a.size == 0:
            return np.empty(0), state, np.zeros(0, bool)
        if self.highpass_hz == 0:
            q = np.zeros_like(a)
        else:
            phi, g0, g1 = self._foh_coefficients(fs_hz)
            # q_k = phi q_{k-1} + g0 a_{k-1} + g1 (a_k - a_{k-1})   (a linear between samples)
            if state.last_accel_mps2 is None:  # the record starts the hold: q_0 = state.q
                prev = np.concatenate([[a[0]], a[:-1]])
                drive = g0 * prev + g1 * (a - prev)
                drive[0] = state.q
                q0 = 0.0
            else:
                prev = np.concatenate([[state.last_accel_mps2], a[:-1]])
                drive = g0 * prev + g1 * (a - prev)
                q0 = state.q
            q = _first_order_recursion(phi, drive, q0)
        new = AccelerometerState(q=float(q[-1]), last_accel_mps2=float(a[-1]))
        volts, over = self.output(self.sensed(a, q), fs_hz, rng, noise=noise)
        return volts, new, over

    def _foh_coefficients(self, fs_hz: float) -> tuple[float, float, float]:
        """phi, Gamma0, Gamma1 of the exact first-order-hold step of q' = -w_c q + u."""
        phi, g0, g1 = discretise(np.array([[-self.corner_rad_s]]), np.array([[1.0]]),
                                 1.0 / fs_hz, "linear")
        return float(phi[0, 0]), float(g0[0, 0]), float(g1[0, 0])


@njit(cache=True, nogil=True)
def _first_order_recursion(phi, drive, q_before):
    """``q[k] = drive[k] + phi q[k-1]`` with ``q[-1] = q_before`` (what
    ``scipy.signal.lfilter([1], [1, -phi], drive, zi=[phi q_before])`` computes, without
    importing scipy.signal)."""
    q = np.empty(drive.shape[0])
    acc = q_before
    for k in range(drive.shape[0]):
        acc = drive[k] + phi * acc
        q[k] = acc
    return q


@njit(cache=True, nogil=True)
def _output_kernel(sensed, volts_per_mps2, w, sd, lim, volts, over):
    """``volts = clip(volts_per_mps2 sensed + sd w, +-lim)``, ``over = |.| > lim`` in one pass
    (``w`` empty: no noise)."""
    noisy = w.shape[0] > 0
    for k in range(sensed.shape[0]):
        v = volts_per_mps2 * sensed[k]
        if noisy:
            v = v + sd * w[k]
        over[k] = abs(v) > lim
        volts[k] = min(max(v, -lim), lim)


@njit(cache=True, nogil=True)
def _sense_output_kernel(accel, q, wc, volts_per_mps2, w, sd, lim, sensed, volts, over):
    """``sensed = accel - wc q``, then :func:`_output_kernel`'s arithmetic, in one pass."""
    noisy = w.shape[0] > 0
    for k in range(accel.shape[0]):
        s = accel[k] - wc * q[k]
        sensed[k] = s
        v = volts_per_mps2 * s
        if noisy:
            v = v + sd * w[k]
        over[k] = abs(v) > lim
        volts[k] = min(max(v, -lim), lim)


@njit(cache=True, nogil=True)
def accelerometer_row(r, w, p, out, flag):
    """One sample of every interval of a chunk: the sensed accelerations ``r`` [m/s^2] times
    the gain, plus the noise ``w`` [V] (empty: none), clipped at ``+-p.limit_v`` into ``out``
    and flagged beyond it (``p``: :class:`AccelerometerRow`; :meth:`Accelerometer.output`'s
    arithmetic, a loop that vectorises). The bench's fused chain (:mod:`rig.bench.fused`) runs
    the accelerometer so; equal to it bit for bit (tests/rig/devices/test_fused_sensors.py)."""
    gain = p.gain
    lim = p.limit_v
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
