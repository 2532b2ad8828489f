"""Plain data passed from the emulated bench (``rig``) to the acquisition (``daq``).

The bench runs continuously at the simulation rate and hands out :class:`AnalogBlock` s: the sensor
output voltages (before any anti-alias filter) and the ground truth at the same instants. Each
sensor channel describes its own calibration with a :class:`Calibration`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Calibration:
    """How a channel's volts relate to its physical quantity, at the calibration frequency.

    ``volts = volts_per_unit * quantity`` in the sensor's pass band; ``volts_per_unit`` carries the
    sign of the mounting/orientation (SPEC section 5: processing must undo it).

    Attributes
    ----------
    quantity : what is measured, e.g. "stage acceleration x0''".
    unit : its SI unit, e.g. "m/s^2", "m", "rad".
    volts_per_unit : signed sensitivity [V per unit].
    """

    quantity: str
    unit: str
    volts_per_unit: float


@dataclass(frozen=True)
class AnalogBlock:
    """A block of the continuous analog run, sampled at the simulation rate.

    Attributes
    ----------
    t0_s : time of the first sample [s] (from the start of the run, settling included).
    fs_hz : simulation rate [Hz]; sample k is at ``t0_s + k / fs_hz``.
    volts : sensor outputs before the anti-alias filter [V], each shape (samples,), keyed by
        channel name ("a", "x", "y").
    truth : ground truth at the same instants, keyed by name with the unit as suffix, e.g.
        "stage_accel_mps2" (samples,), "theta_rad" (samples, n), "mirror_x_m", "mirror_rot_rad",
        "source_v".
    """

    t0_s: float
    fs_hz: float
    volts: dict
    truth: dict

    @property
    def samples(self) -> int:
        """Number of samples in the block."""
        return len(next(iter(self.volts.values())))

    def times_s(self) -> np.ndarray:
        """Sample instants [s], shape (samples,)."""
        return self.t0_s + np.arange(self.samples) / self.fs_hz


@dataclass(frozen=True)
class DecimatedBlock:
    """A block of the run already through the anti-alias filter and the decimation: only the
    kept instants (every ``decimation``-th simulation sample from ``t0_s``).

    Attributes
    ----------
    t0_s : time of the block's first simulation sample (its first kept instant) [s].
    fs_hz : simulation rate [Hz]; ``decimation`` simulation samples per kept instant;
        ``samples`` simulation samples in the block (a multiple of ``decimation``).
    volts : filtered channel volts at the kept instants [V], each (kept,).
    truth : the ground truth at the kept instants (names as :class:`AnalogBlock`).
    saturated : channel -> (kept,) bool: its sensor saturated within the kept instant's
        decimation interval (since the previous kept instant, up to and including it).
    """

    t0_s: float
    fs_hz: float
    decimation: int
    samples: int
    volts: dict
    truth: dict
    saturated: dict
