"""The bench's exact sampled response in modal form: built once per scene, cheap per frequency.

:func:`sampled_response` builds a :class:`SampledResponse` of a scene: the linear bench model
(:func:`rig.bench.build_model` of :func:`rig.bench.linear_scene`) and one eigendecomposition of
its exact step. Called at ``freqs_hz`` [Hz] (``0 <= f < fs_hz / 2``) it gives a
:class:`rig.bench.BenchResponse` (``sampled=True``) with the fields of
:func:`rig.bench.expected_response` ``sampled=True`` (per source volt; the ratios in
engineering units; ``theta_1``, ``h_g1`` the stage-1 curves), combined the same way but
evaluated through the modal form of the exact ZOH step (:meth:`rig.linear.SampledSystem.modal`):
O(nz) per frequency and output instead of one ``(nz, nz)`` solve. Its round-off differs from the
solve's only where the modal terms cancel (near 0 Hz and at the anti-resonances; bounded in
tests/rig/test_bench_sampled.py); at 0 Hz it takes no limits (``expected_response`` does), so
the ratios there are whatever the modal sums give.

:meth:`SampledResponse.resolved`: the same on a grid that draws every mode and anti-resonance of
``h_t``, ``theta_2`` and the stage-1 curves within 0.1 dB
(:func:`rig.response_grid.resolving_grid`): what a person sees of the exact whole-chain model
(the analyzer's figures, the live view).

Used for the dense grids of the analysis (``E[H1]``'s correlation functions, the fits' input
spectrum, the coherence budget, the figures); the model at the analyzer's lines stays
``expected_response``'s (or the run file's). An analysis builds one and passes it on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from rig.bench.model import build_model, linear_scene
from rig.bench.response import BenchResponse, calibrations, g1_weight_m
from rig.errors import ConfigError
from rig.linear import ModalForm, SampledSystem
from rig.scene import Scene

__all__ = ["SampledResponse", "sampled_response"]


@dataclass(frozen=True, eq=False)
class SampledResponse:
    """The exact sampled response of one scene's bench (build with :func:`sampled_response`).

    Attributes
    ----------
    scene : the scene (any acquisition model: the response is the linear bench's).
    modal : :class:`rig.linear.ModalForm` with outputs stage acceleration [(m/s^2)/V], sensed
        stage acceleration [(m/s^2)/V], the angles [rad/V] and stage displacement [m/V].
    fs_hz : the simulation rate [Hz]; responses are defined for ``0 <= f < fs_hz / 2``.
    tau_s : the bench's slowest decay time [s] (0 without a decaying mode).
    volts_per_unit : the channels' calibrations ``{"a", "x", "y": V per unit}``
        (:func:`rig.bench.calibrations`).
    """

    scene: Scene
    modal: ModalForm
    fs_hz: float
    tau_s: float
    volts_per_unit: Mapping

    def __call__(self, freqs_hz) -> BenchResponse:
        """The responses at ``freqs_hz`` [Hz] (module docstring); a ConfigError outside
        ``[0, fs_hz / 2)``."""
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f >= self.fs_hz / 2):
            raise ConfigError(f"freqs_hz must lie in [0, {self.fs_hz / 2:g}) Hz (half the "
                              "simulation rate)")
        scene = self.scene
        y = self.modal.frequency_response(f)
        stage_accel, sensed, theta, stage_disp = y[:, 0], y[:, 1], y[:, 2:-1], y[:, -1]
        cal = self.volts_per_unit
        a = scene.accelerometer.volts_per_mps2 * sensed
        mirror_x = theta @ scene.mirror_weights()
        mirror_rot = theta[:, scene.mirror.body]
        a_eng = a / cal["a"]
        with np.errstate(invalid="ignore", divide="ignore"):
            theta_1 = theta[:, 0] / a_eng
            return BenchResponse(
                freqs_hz=f, a=a, x=cal["x"] * mirror_x, y=cal["y"] * mirror_rot,
                stage_accel=stage_accel, stage_disp=stage_disp, theta=theta, mirror_x=mirror_x,
                mirror_rot=mirror_rot, h_t=mirror_x / a_eng, theta_2=mirror_rot / a_eng,
                h_t_pendulum=mirror_x / stage_accel, theta_2_pendulum=mirror_rot / stage_accel,
                theta_1=theta_1, h_g1=theta_1 * g1_weight_m(scene.chain), sampled=True)

    def resolved(self, fmin_hz: float, fmax_hz: float, points: int = 1500) -> BenchResponse:
        """The responses on a grid over ``[fmin_hz, fmax_hz]`` [Hz] (``points`` log-spaced ones
        as its base, refined until every mode and anti-resonance of ``h_t``, ``theta_2``,
        ``theta_1`` and ``h_g1`` is drawn within 0.1 dB: :func:`rig.response_grid.
        resolving_grid`)."""
        from rig.response_grid import resolving_grid, scene_features

        scene = self.scene
        chain = scene.chain

        def curves(f):
            r = self(f)
            return np.stack([r.h_t, r.theta_2, r.theta_1, r.h_g1], axis=-1)

        weights = (scene.mirror_weights(), np.eye(chain.n)[scene.mirror.body],
                   chain.point_weights(0, chain.com_m[0]), np.eye(chain.n)[0])
        modes, notches = scene_features(scene, weights)
        f = resolving_grid(curves, max(fmin_hz, 1e-3), fmax_hz, points, modes=modes,
                           notches=notches)
        return self(f)


def sampled_response(scene: Scene) -> SampledResponse:
    """The :class:`SampledResponse` of ``scene``'s bench. Cost: one model build and one
    eigendecomposition of its exact step; ConfigError for a bad bench section."""
    model = build_model(linear_scene(scene))
    nz = model.n_states
    eye = np.eye(nz)
    rows = [np.asarray(model.accel_row, float)]
    sensed = rows[0].copy()
    acc = model.accelerometer
    if acc.n_states:
        sensed = sensed - acc.corner_rad_s * eye[model.slices["accel_highpass_q_mps"]][0]
    rows.append(sensed)
    rows.extend(eye[model.slices["theta_rad"]])
    rows.append(eye[1])  # the stage's displacement (expected_response's stage_disp)
    decay = -np.linalg.eigvals(model.a).real
    decay = decay[decay > 0]
    system = SampledSystem(model.phi, np.reshape(model.gamma, (nz, 1)), np.vstack(rows),
                           model.fs_hz)
    return SampledResponse(scene=scene, modal=system.modal(), fs_hz=float(model.fs_hz),
                           tau_s=float(1.0 / decay.min()) if decay.size else 0.0,
                           volts_per_unit=MappingProxyType(
                               {k: c.volts_per_unit for k, c in calibrations(scene).items()}))
