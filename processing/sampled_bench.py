"""The bench's exact sampled responses per source volt at many frequencies, built once per scene.

The fields are those of :func:`rig.bench.expected_response` ``sampled=True`` (``a, x, y`` in
channel volts, ``stage_accel``, ``mirror_x``, ``mirror_rot``, ``theta``, and the ratios ``h_t``,
``theta_2``, ``h_t_pendulum``, ``theta_2_pendulum``), combined the same way, but evaluated through
the modal form of the bench's exact ZOH step (:meth:`rig.linear.SampledSystem.modal`): O(nz) per
frequency and output instead of one ``(nz, nz)`` solve. Its round-off differs from the solve's
only where the modal terms cancel (near 0 Hz and at the anti-resonances; bounded against
``expected_response`` in tests/processing/test_analyzer.py). Used for the dense grids (``E[H1]``'s
correlation functions, the fits' input spectrum, the fine grids of the peaks and plots); the model
at the analyzer's lines stays ``expected_response``'s (or the run file's).
"""

from __future__ import annotations


import numpy as np

from rig.errors import ConfigError
from rig.linear import SampledSystem

__all__ = ["SampledBench", "linear_scene", "resolved_fields"]


def linear_scene(scene):
    """``scene`` with the linear acquisition model (the bench's exact linear step)."""
    return scene.with_acquisition(model="linear")


class SampledBench:
    """``SampledBench(scene)(f)``: the exact sampled fields at ``f`` [Hz] (dict of (nf,) arrays,
    ``theta`` (nf, n)); ``tau_s`` the bench's slowest decay time [s]; ``fs`` its simulation rate
    [Hz]. Cost: one model build and one eigendecomposition, then O(nz) per frequency."""

    def __init__(self, scene):
        from rig.bench import build_model, calibrations

        self.scene = scene
        model = build_model(linear_scene(scene))
        acc = model.accelerometer
        nz = model.n_states
        rows = [np.asarray(model.accel_row, float)]
        sensed = rows[0].copy()
        if acc.n_states:
            q = np.zeros(nz)
            q[model.slices["accel_highpass_q_mps"]] = 1.0
            sensed = sensed - acc.corner_rad_s * q
        rows.append(sensed)
        rows.extend(np.eye(nz)[model.slices["theta_rad"]])
        decay = -np.linalg.eigvals(model.a).real
        decay = decay[decay > 0]
        #: slowest decay time of the bench [s]
        self.tau_s = float(1.0 / decay.min()) if decay.size else 0.0
        system = SampledSystem(model.phi, np.reshape(model.gamma, (nz, 1)), np.vstack(rows),
                               model.fs_hz)
        self.modal = system.modal()
        self.fs = model.fs_hz
        cal = calibrations(scene)
        self.vpm = acc.volts_per_mps2
        self.cal = {k: cal[k].volts_per_unit for k in ("a", "x", "y")}
        self.weights = scene.mirror_weights()
        self.body = scene.mirror.body

    def __call__(self, f) -> dict:
        """The fields (and ``theta``, (nf, n)) at ``f`` [Hz], ``0 <= f < fs_sim / 2``."""
        f = np.atleast_1d(np.asarray(f, dtype=float))
        if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f >= self.fs / 2):
            raise ConfigError(f"freqs_hz must lie in [0, {self.fs / 2:g}) Hz (half the "
                              "simulation rate)")
        y = self.modal.frequency_response(f)
        stage_accel, sensed, theta = y[:, 0], y[:, 1], y[:, 2:]
        a = self.vpm * sensed
        mirror_x = theta @ self.weights
        mirror_rot = theta[:, self.body]
        a_eng = a / self.cal["a"]
        with np.errstate(invalid="ignore", divide="ignore"):
            return {"a": a, "x": self.cal["x"] * mirror_x, "y": self.cal["y"] * mirror_rot,
                    "stage_accel": stage_accel, "theta": theta, "mirror_x": mirror_x,
                    "mirror_rot": mirror_rot, "h_t": mirror_x / a_eng,
                    "theta_2": mirror_rot / a_eng, "h_t_pendulum": mirror_x / stage_accel,
                    "theta_2_pendulum": mirror_rot / stage_accel}


def resolved_fields(scene, fmin_hz: float, fmax_hz: float, points: int = 1500, *,
                    bench: SampledBench | None = None) -> tuple[np.ndarray, dict]:
    """``(f, fields)``: :class:`SampledBench`'s fields of ``scene`` on a grid over
    [fmin_hz, fmax_hz] [Hz] (``points`` log-spaced ones as its base) that draws every mode and
    anti-resonance of ``h_t``, ``theta_2`` and the stage-1 curves within 0.1 dB
    (:func:`rig.response_grid.resolving_grid`), with ``theta1`` [rad] and ``g1`` [m] (body 1's
    angle and centre of mass per unit sensed stage acceleration [per m/s^2]) added. What a
    person sees of the exact whole-chain model (the figures, the live view)."""
    from rig.response_grid import resolving_grid, scene_features

    bench = SampledBench(scene) if bench is None else bench
    chain = scene.chain
    w_g1 = chain.point_weights(0, chain.com_m[0])

    def fields(f):
        r = dict(bench(f))
        with np.errstate(divide="ignore", invalid="ignore"):
            a_eng = r["mirror_x"] / r["h_t"]  # sensed stage acceleration per source volt
            r["theta1"] = r["theta"][:, 0] / a_eng
        r["g1"] = r["theta1"] * w_g1[0]
        return r

    def curves(f):
        r = fields(f)
        return np.stack([r["h_t"], r["theta_2"], r["theta1"], r["g1"]], axis=-1)

    weights = (scene.mirror_weights(), np.eye(chain.n)[scene.mirror.body], w_g1,
               np.eye(chain.n)[0])
    modes, notches = scene_features(scene, weights)
    f = resolving_grid(curves, max(fmin_hz, 1e-3), fmax_hz, points, modes=modes,
                       notches=notches)
    return f, fields(f)
