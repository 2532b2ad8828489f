"""What the live view draws of the bench: positions in millimetres from the run's data.

Everything here is plain numpy (the viewer module turns it into rerun archetypes). Coordinates
are a side view in millimetres in *image* coordinates, as rerun's 2D views use them: +x along the
stage's motion (toward the laser), **+y down** (a hanging pendulum points to +y); the origin is
the top pivot at rest.

Scale: the bench's sizes (link lengths, the PSD) are drawn to scale; its motions are tiny (the
paper's drive tilts the bodies by a few mrad and moves the stage by ~2 mm rms), so the angles are
multiplied by ``magnification`` and the stage's displacement by ``magnification /
STAGE_RATIO`` (both said on screen). The PSD view is to scale (x1): the spot moves by a fraction
of a millimetre on a 12 mm detector.

Sources (nothing here is stored in the run file beyond what it already holds, so a live run and a
replay of its file draw the same):

- the bodies from the recorded true angles ``theta_rad`` (the bench's state at the sample
  instants);
- the stage from the recorded true stage acceleration, integrated twice by a critically damped
  second-order filter ``1 / (s + w0)^2`` (bilinear transform, ``w0 = 2 pi 5 mHz``): the double
  integral above ~0.05 Hz, without the drift an open integral has. It starts at rest at the
  first record, so the first ~30 s (1 / w0) settle in; it is a drawing, not a measurement;
- the laser spot on the PSD from the x and y channels' volts: ``u = V_x / (sign_x G)``,
  ``v = V_y / (sign_y G)`` (``rig.devices.optical_lever``: the detector outputs ``sign G`` times
  the spot position).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.sosfilt import sosfilt_inplace

#: Angles in the bench drawing are multiplied by this by default ...
MAGNIFICATION = 30.0
#: ... and the stage's displacement by MAGNIFICATION / STAGE_RATIO.
STAGE_RATIO = 6.0
#: Drawing frames per simulated second (the geometry is decimated to about this).
FRAMES_PER_S = 33.0
#: Corner of the stage position's double integrator [Hz].
STAGE_CORNER_HZ = 0.005
MM = 1e3


@dataclass(frozen=True)
class BenchDrawing:
    """The static geometry of a scene's bench [mm] and how motions are scaled.

    Attributes
    ----------
    lengths_mm, com_mm : per body, joint-to-joint length and centre of mass from the upper joint.
    mirror_body : 0-based body that carries the mirror; mirror_mm : its position along the body.
    psd_half_mm : half the PSD's side [mm]; psd_gain_vpm : G [V/m]; psd_signs : (sign_x, sign_y).
    magnification : factor on the angles (1 for free motion at large angles);
        :attr:`stage_magnification` the stage's displacement's.
    """

    lengths_mm: tuple
    com_mm: tuple
    mirror_body: int
    mirror_mm: float
    psd_half_mm: float | None
    psd_gain_vpm: float | None
    psd_signs: tuple
    magnification: float

    @classmethod
    def from_scene(cls, scene, magnification: float = MAGNIFICATION) -> "BenchDrawing":
        """From a resolved :class:`rig.scene.Scene` (its chain, mirror and optical lever)."""
        if not (isinstance(magnification, (int, float)) and math.isfinite(magnification)
                and magnification > 0):
            raise ValueError(f"magnification = {magnification!r} is invalid: expected a "
                             "finite number > 0")
        chain, lever = scene.chain, scene.lever
        return cls(lengths_mm=tuple(MM * float(v) for v in chain.length_m),
                   com_mm=tuple(MM * float(v) for v in chain.com_m),
                   mirror_body=int(scene.mirror.body),
                   mirror_mm=MM * float(scene.mirror.position_m),
                   psd_half_mm=MM * lever.size_m / 2, psd_gain_vpm=lever.gain_vpm,
                   psd_signs=(lever.sign_x, lever.sign_y),
                   magnification=float(magnification))

    @property
    def stage_magnification(self) -> float:
        return self.magnification / STAGE_RATIO

    @property
    def reach_mm(self) -> float:
        """Total length of the chain [mm]."""
        return float(sum(self.lengths_mm))

    def joints(self, theta_rad: np.ndarray) -> np.ndarray:
        """Pivots and lower ends of the bodies relative to the top pivot, (frames, n + 1, 2) [mm],
        angles magnified: ``P_j = P_{j-1} + l_j (sin M th_j, cos M th_j)``."""
        th = self.magnification * np.atleast_2d(np.asarray(theta_rad, float))
        steps = np.stack([np.sin(th), np.cos(th)], axis=-1) * np.asarray(self.lengths_mm)[:, None]
        out = np.zeros((th.shape[0], th.shape[1] + 1, 2))
        np.cumsum(steps, axis=1, out=out[:, 1:])
        return out

    def centres_of_mass(self, theta_rad: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Centres of mass of the bodies, (frames, n, 2) [mm]."""
        th = self.magnification * np.atleast_2d(np.asarray(theta_rad, float))
        d = np.stack([np.sin(th), np.cos(th)], axis=-1)
        return joints[:, :-1] + d * np.asarray(self.com_mm)[:, None]

    def mirror(self, theta_rad: np.ndarray, joints: np.ndarray, half_mm: float = 6.0
               ) -> tuple[np.ndarray, np.ndarray]:
        """The mirror's centre (frames, 2) and its face as a segment along its body
        (frames, 2, 2) [mm]: it turns with the body (magnified)."""
        th = self.magnification * np.atleast_2d(np.asarray(theta_rad, float))[:, self.mirror_body]
        d = np.stack([np.sin(th), np.cos(th)], axis=-1)
        centre = joints[:, self.mirror_body] + self.mirror_mm * d
        return centre, np.stack([centre - half_mm * d, centre + half_mm * d], axis=1)

    def spot_mm(self, volts_x: np.ndarray, volts_y: np.ndarray) -> np.ndarray:
        """The laser spot on the PSD (u right, v up) -> image coordinates (u, -v), (n, 2) [mm]."""
        g = float(self.psd_gain_vpm)
        u = MM * np.asarray(volts_x, float) / (self.psd_signs[0] * g)
        v = MM * np.asarray(volts_y, float) / (self.psd_signs[1] * g)
        return np.stack([u, -v], axis=-1)


def frame_step(rate_hz: float, frames_per_s: float = FRAMES_PER_S) -> int:
    """Samples between drawn frames: about ``frames_per_s`` frames per simulated second."""
    return max(1, int(round(rate_hz / frames_per_s)))


def frame_indices(first_sample: int, samples: int, step: int) -> np.ndarray:
    """Indices within a block (starting at global sample ``first_sample``) of the samples whose
    global index is a multiple of ``step``: the same frames whatever the block boundaries."""
    start = (-first_sample) % step
    return np.arange(start, samples, step)


def stage_integrator_sos(rate_hz: float, corner_hz: float = STAGE_CORNER_HZ) -> np.ndarray:
    """``1 / (s + w0)^2`` by the bilinear transform, one section ``[b0, b1, b2, 1, a1, a2]``:
    stage acceleration [m/s^2] -> position [m] above the corner."""
    k, w = 2.0 * rate_hz, 2.0 * math.pi * corner_hz
    a0 = (k + w) ** 2
    return np.array([[1.0 / a0, 2.0 / a0, 1.0 / a0, 1.0,
                      (2.0 * w * w - 2.0 * k * k) / a0, (k - w) ** 2 / a0]])


class StagePosition:
    """The stage position for the drawing, block by block (module docstring): the state carries
    over, so any split of the same samples gives the same positions."""

    def __init__(self, rate_hz: float, corner_hz: float = STAGE_CORNER_HZ):
        self.sos = stage_integrator_sos(rate_hz, corner_hz)
        self.zi = np.zeros((1, 1, 2))

    def __call__(self, accel_mps2: np.ndarray) -> np.ndarray:
        """Positions [m] at the samples of ``accel_mps2`` (the next samples of the run)."""
        x = np.array(accel_mps2, dtype=float).reshape(1, -1)
        sosfilt_inplace(self.sos, x, self.zi)
        return x[0]
