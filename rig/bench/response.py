"""The bench's calibrations, exact linear responses and analytic levels.

:func:`expected_response`: the exact linear response of the whole chain source -> channels
(linear pendulum, linearised optical lever), either the continuous chain times the DAC's hold
(``sampled=False``: what a real bench with an ideally anti-aliased analyzer reads) or the exact
discrete-time transfer function of the simulated samples ``C (e^{i w h} I - Phi)^-1 Gamma``
(``sampled=True``), which also holds the hold's images ``m fs +- f`` folded back by sampling at
the DAC instants; the source's reconstruction filter (:mod:`rig.devices.source`) removes most of
them, and without it the two differ most in ``a`` (hence in H_t and Theta_2), falling as
``1 / fs^2`` (docs/bench_model.md has the figures). Valid for ``0 <= f < fs / 2``.
:func:`stationary_levels` and :func:`signal_to_noise` integrate it under the source's PSD.
Cost: one ``(n_states, n_states)`` complex solve per frequency (sampled) or the parts' closed
forms.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rig.blocks import Calibration
from rig.errors import ConfigError
from rig.linear import FrequencyResponse
from rig.scene import Scene
from rig.scene_memo import per_scene
from rig.devices.source import NOISE_TYPES, Source
from rig.bench.model import build_model, linear_scene


def calibrations(scene: Scene) -> dict[str, Calibration]:
    """Channel calibrations: ``a`` [V per m/s^2] (pass band, polarity included), ``x`` [V per m of
    mirror translation relative to the stage], ``y`` [V per rad of mirror rotation]."""
    return {"a": scene.accelerometer.calibration(), **scene.lever.calibrations()}


#: Units of the responses of :func:`rig.bench.expected_response` that a run file stores (per
#: source volt unless stated; ``*_continuous``: a field of its ``sampled=False`` response, as an
#: acquisition records it).
RESPONSE_UNITS = {
    "a": "V/V", "x": "V/V", "y": "V/V", "stage_accel": "(m/s^2)/V", "stage_disp": "m/V",
    "mirror_x": "m/V", "mirror_rot": "rad/V", "h_t": "m/(m/s^2)", "theta_2": "rad/(m/s^2)",
    "h_t_pendulum": "m/(m/s^2)", "theta_2_pendulum": "rad/(m/s^2)",
    "h_t_pendulum_continuous": "m/(m/s^2)", "theta_2_pendulum_continuous": "rad/(m/s^2)",
}
#: What each response of :func:`rig.bench.expected_response` is.
RESPONSE_LONG_NAMES = {
    "a": "channel a per source volt: DAC hold, amplifier, coil, stage, accelerometer",
    "x": "channel x per source volt: ... stage, pendulum, optical lever (linearised)",
    "y": "channel y per source volt: ... stage, pendulum, optical lever (linearised)",
    "stage_accel": "stage acceleration per source volt",
    "stage_disp": "stage displacement per source volt",
    "mirror_x": "mirror translation relative to the stage per source volt",
    "mirror_rot": "mirror rotation per source volt",
    "h_t": "H_t = (x / cal_x) / (a / cal_a): what the analyzer measures (accelerometer high-pass "
           "in the denominator)",
    "theta_2": "Theta_2 = (y / cal_y) / (a / cal_a): what the analyzer measures",
    "h_t_pendulum": "mirror translation / stage acceleration of the sampled bench",
    "theta_2_pendulum": "mirror rotation / stage acceleration of the sampled bench",
    "h_t_pendulum_continuous": "mirror translation / stage acceleration, continuous linear "
                               "pendulum (rig.describe.mirror_response)",
    "theta_2_pendulum_continuous": "mirror rotation / stage acceleration, continuous linear "
                                   "pendulum",
}


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
    theta_1, h_g1 : stage 1 as the analyzer reads it: body 1's angle [rad per m/s^2] and the
        translation of its centre of mass G1 relative to the stage [m per m/s^2], per unit of
        sensed stage acceleration (a / cal_a, as h_t and theta_2). Not stored in run files.
    sampled : False: continuous-time chain times the DAC's hold ``(1 - e^{-i w h}) / (i w h)``
        (what an ideally anti-aliased measurement sees); True: the exact transfer function from
        the DAC samples to the simulated samples, ``C (e^{i w h} I - Phi)^-1 Gamma``, which also
        contains the hold's images folded back by sampling at the DAC rate.

    ``UNITS``, ``LONG_NAMES`` (class constants): unit and description of each response a run
    file stores.
    """

    UNITS: ClassVar[dict] = RESPONSE_UNITS
    LONG_NAMES: ClassVar[dict] = RESPONSE_LONG_NAMES

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
    theta_1: np.ndarray
    h_g1: np.ndarray
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
                    "theta_2", "h_t_pendulum", "theta_2_pendulum", "theta_1", "h_g1")


@per_scene(ignore=("source.level_vrms",))
def expected_response(scene: Scene, freqs_hz, *, sampled: bool = False) -> BenchResponse:
    """The exact linear response of the whole chain source -> channels at ``freqs_hz`` [Hz].

    ``sampled=False`` (default) uses the closed forms of the parts (:meth:`Stage.
    frequency_response`, :meth:`Accelerometer.frequency_response`, :meth:`OpticalLever.
    frequency_response`) times the DAC hold; ``sampled=True`` the exact discrete-time transfer
    function of the simulated samples (:class:`BenchResponse`). Both use the linear pendulum and
    the linearised optical lever; both need ``0 <= f < fs / 2``. At 0 Hz, where the stage's
    acceleration and the mirror's motion vanish, the ratios (``h_t``, ``theta_2`` and the
    pendulum's) are their limits: finite for the pendulum, NaN through an accelerometer with a
    high-pass (:func:`_dc_ratios`). Memoised per scene and grid (:mod:`rig.scene_memo`), the
    source's level left out of the key: the responses are per source volt, so a sweep of the
    drive's level computes them once (tests/rig/test_scene_memo.py).
    """
    model = build_model(linear_scene(scene))
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
    dc = f == 0.0
    if sampled and dc.any():
        # at 0 Hz the stage rests displaced, the pendulum hangs: the closed form's exact zeros,
        # where the solve at z = 1 leaves round-off (~1e-16 of the values nearby)
        for arr in (stage_accel, theta, a):
            arr[dc] = 0.0
    mirror_x = theta @ scene.mirror_weights()
    mirror_rot = theta[:, scene.mirror.body]
    cal = calibrations(scene)
    x = cal["x"].volts_per_unit * mirror_x
    y = cal["y"].volts_per_unit * mirror_rot
    a_eng = a / cal["a"].volts_per_unit
    with np.errstate(invalid="ignore", divide="ignore"):
        h_t = (x / cal["x"].volts_per_unit) / a_eng
        theta_2 = (y / cal["y"].volts_per_unit) / a_eng
        h_t_p = mirror_x / stage_accel
        th2_p = mirror_rot / stage_accel
        theta_1 = theta[:, 0] / a_eng
    g1 = g1_weight_m(chain)
    if dc.any():
        h_t_p[dc], th2_p[dc], h_t[dc], theta_2[dc], theta_1[dc] = _dc_ratios(scene, acc, cal)
    return BenchResponse(freqs_hz=f, a=a, x=x, y=y, stage_accel=stage_accel,
                         stage_disp=stage_disp, theta=theta, mirror_x=mirror_x,
                         mirror_rot=mirror_rot, h_t=h_t, theta_2=theta_2, h_t_pendulum=h_t_p,
                         theta_2_pendulum=th2_p, theta_1=theta_1, h_g1=theta_1 * g1,
                         sampled=bool(sampled))


def g1_weight_m(chain) -> float:
    """Translation of body 1's centre of mass G1 relative to the stage per radian of body 1's
    angle [m/rad] (linearised: :meth:`rig.chain.Chain.point_weights`)."""
    return float(chain.point_weights(0, chain.com_m[0])[0])


def _dc_ratios(scene: Scene, acc, cal) -> tuple[complex, ...]:
    """The ratios' values at 0 Hz, where numerator and denominator both vanish (the stage's
    acceleration, the mirror's motion): their limits. The pendulum alone: its static deflection
    per unit base acceleration (:meth:`rig.chain.Chain.frf_angles` at 0 Hz, ``-1/g`` per body;
    a sampled model has the same, as a zero-order hold keeps the DC gain). Through the
    accelerometer: that over its DC gain in engineering units, which is 0 with its high-pass
    (the ratio grows without bound: NaN) and 1 without. Returns ``h_t_pendulum,
    theta_2_pendulum, h_t, theta_2, theta_1`` there."""
    theta = scene.chain.frf_angles(0.0)[0]
    h_t_p = complex(theta @ scene.mirror_weights())
    th2_p = complex(theta[scene.mirror.body])
    gain = complex(acc.frequency_response(np.zeros(1))[0]) / cal["a"].volts_per_unit
    if gain == 0:
        nan = complex(np.nan, np.nan)
        return h_t_p, th2_p, nan, nan, nan
    return h_t_p, th2_p, h_t_p / gain, th2_p / gain, complex(theta[0]) / gain


def _source_psd(source: Source, f: np.ndarray) -> np.ndarray:
    """One-sided PSD of the source [V^2/Hz] used for level estimates: the design PSD of the
    noise types (burst random scaled by its on-fraction), a flat band of the same power for the
    chirp; None for a sine (a line)."""
    if source.type in NOISE_TYPES:
        p = source.design_psd(f)
        if source.type == "burst-random":
            p = p * source.burst_samples / source.period_samples
        return p
    if source.type in ("periodic-chirp", "multisine"):
        inband = (f >= source.fmin_hz) & (f <= source.fmax_hz)
        return np.where(inband, source.level_vrms**2 / (source.fmax_hz - source.fmin_hz), 0.0)
    return None


def stationary_levels(scene: Scene, *, points: int = 100_001) -> dict:
    """Analytic stationary rms levels of the default drive (linear model, reaction as set):
    stage acceleration, stroke, angles, mirror translation and spot positions, from the
    source PSD and :func:`expected_response` (``sampled=False``) integrated over 0..fmax.
    For a sine source the rms of the steady-state line."""
    model = build_model(linear_scene(scene))
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
    model = build_model(linear_scene(scene))
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
