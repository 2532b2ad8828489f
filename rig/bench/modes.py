"""The bench's own modes, exactly: what an operational modal analysis of its responses should find.

In an output-only (OMA) test the stage is shaken by broadband noise that is not measured, and
the modes are identified from the responses alone. The modes it can find are those of the whole
linear bench driven by the source (coil, stage and pendulum coupled through the pendulum's
reaction), not those of the pendulum on a fixed base: with ``stage.reaction`` the upper mode of
``ishizaki2009`` sits at the coupled bench's 2.52 Hz, not the 2.48 Hz the stage acceleration
shows as a notch. :func:`bench_modes` gives each oscillatory pole of the linear bench below a
frequency limit: natural frequency ``|p| / 2 pi`` [Hz], damping ratio ``-Re p / |p|`` and its
shape at the optical lever's two outputs, the mirror's translation relative to the stage [m] and
its rotation [rad] (the linearised mirror point, :meth:`rig.scene.Scene.mirror_weights`),
normalised so that the larger of the two (in those units) is 1 with zero phase.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BenchModes", "bench_modes", "OUTPUTS"]

#: The outputs a mode shape is given at, with their units.
OUTPUTS = (("x", "m"), ("y", "rad"))


@dataclass(frozen=True)
class BenchModes:
    """Oscillatory modes of the linear bench, ascending in frequency.

    f_hz (modes,) natural frequency |p|/2pi [Hz]; damped_hz (modes,) Im p / 2pi [Hz];
    zeta (modes,) damping ratio; shapes (modes, 2) complex, at :data:`OUTPUTS` (x [m], y [rad]),
    the larger component 1; poles (modes,) [rad/s].
    """

    f_hz: np.ndarray
    damped_hz: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    poles: np.ndarray

    def to_dict(self) -> dict:
        return {"f_hz": self.f_hz.tolist(), "damped_hz": self.damped_hz.tolist(),
                "zeta": self.zeta.tolist(), "outputs": [f"{n} [{u}]" for n, u in OUTPUTS],
                "shapes_real": self.shapes.real.tolist(), "shapes_imag": self.shapes.imag.tolist()}


def bench_modes(scene, *, fmax_hz: float | None = None) -> BenchModes:
    """The oscillatory modes of ``scene``'s linear bench below ``fmax_hz`` (default: the
    acquisition's Nyquist frequency, ``rate_hz / 2``), module docstring."""
    from rig.bench.model import build_model, linear_scene

    model = build_model(linear_scene(scene))
    if fmax_hz is None:
        fmax_hz = scene.acquisition.rate_hz / 2
    lam, vec = np.linalg.eig(model.a)
    keep = (lam.imag > 0) & (np.abs(lam) / (2 * np.pi) < fmax_hz)
    lam, vec = lam[keep], vec[:, keep]
    order = np.argsort(np.abs(lam))
    lam, vec = lam[order], vec[:, order]
    theta = vec[model.slices["theta_rad"], :]
    rows = np.vstack([scene.mirror_weights(), np.eye(scene.chain.n)[scene.mirror.body]])
    shapes = (rows @ theta).T  # (modes, 2): x [m], y [rad]
    big = np.take_along_axis(shapes, np.argmax(np.abs(shapes), axis=1)[:, None], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        shapes = np.where(np.abs(big) > 0, shapes / big, 0.0)
    w = np.abs(lam)
    return BenchModes(f_hz=w / (2 * np.pi), damped_hz=lam.imag / (2 * np.pi), zeta=-lam.real / w,
                      shapes=shapes, poles=lam)
