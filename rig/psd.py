"""Laser, optical lever and position sensitive detector (PSD), all riding on the stage.

Why laser and PSD move with the stage
-------------------------------------
SPEC section 5 defines the translation channel as the mirror's displacement *relative to the
stage*, and the paper compares the measured x with relative-displacement models (H_t -> -l/g at
low frequency, phase 180 deg; an inertial measurement would tend to 0 instead). A laser and PSD
fixed to the ground would add the stage's own displacement, ~2.5 mm rms here, a thousand times
the mirror's relative motion at low frequency. So both are mounted on the stage (their mass is in
``stage.moving_mass_kg``) and the spot sees only the pendulum's motion relative to its pivot.

Geometry (exact, used by :meth:`OpticalLever.spot_m`)
-----------------------------------------------------
Stage frame: x along the stage motion (the mirror's rest normal, toward the laser), y lateral
(along the pivot axes), z up. The mirror centre is displaced by ``(dx, 0, dz)`` from its rest
position and its body is rotated by ``theta`` about y (positive as theta, x = +sin theta), so its
normal is ``n = (cos theta, 0, sin theta)``. The beam arrives in the horizontal plane at incidence
``phi`` along ``d = (-cos phi, -sin phi, 0)`` through the rest reflection point (the origin); at
rest it leaves along ``r0 = (cos phi, -sin phi, 0)`` and meets the detector, a plane normal to
``r0`` at distance ``D``, at its centre. In general the beam meets the mirror at ``q = t d``,
``t = n.p / n.d`` (p = mirror centre), leaves along ``r = d - 2 (d.n) n`` and hits the detector at
``P = q + s r``, ``s = (D - r0.q) / (r0.r)``. The detector axes are ``e_u = (sin phi, cos phi,
0)`` (horizontal, the sense in which +dx moves the spot) and ``e_v = (0, 0, 1)`` (up)::

    u = e_u.P = 2 sin(phi) (dx + dz tan theta) - s 2 sin(phi) cos(phi) sin^2 theta
    v = e_v.P = s cos(phi) sin(2 theta),   s = D + O(dx, theta)

Linearised (what the calibrations use): ``u = 2 sin(phi) dx`` and ``v = 2 cos(phi) D theta``.
The factor cos(phi) follows from ``r = d - 2 (d.n) n`` with ``d.n = -cos(phi) cos(theta)``: the
vertical component of the reflected ray is ``r_z = 2 cos(phi) cos(theta) sin(theta) = cos(phi)
sin(2 theta)``, i.e. only the part of the incoming beam along the normal (cos phi) is turned by the
tilt. We use it (not the normal-incidence ``2 D theta``). A translation within the mirror plane
(dz at theta = 0) moves nothing. :meth:`OpticalLever.measure` uses the exact form (numbers
below).

Detector, output and edges
--------------------------
``volts_x = sign_x G u``, ``volts_y = sign_y G v`` (G = ``gain_vpm``; the PSD and its amplifiers are
flat far above the simulation band). Position noise (laser pointing, air, electronics), white with
one-sided density ``noise_m_rthz`` on each axis, is added to the spot position. The detector is a
square of side ``size_m`` centred on the rest spot: when the spot leaves it (|u| or |v| >
size/2) a real PSD's normalised outputs lose their meaning (the centroid of the light still on
the detector sits at the edge, then the sum current vanishes). We clip each coordinate at the
edge (the output saturates at +-G size/2) and flag the sample (``off_detector``, both channels):
flagged samples must not be trusted.

Defaults (``ishizaki2009`` with the default drive; numbers from :mod:`rig.bench`)
---------------------------------------------------------------------------------
``incidence_deg = 30`` (2 sin phi = 1: the spot moves as much as the mirror), ``distance_m = 0.2``
(a lever that fits on the stage; 2 D cos phi = 0.346 m/rad), ``size_m = 0.012`` (a 12 mm x 12 mm
two-dimensional PSD), ``gain_vpm = 1000`` (+-6 V at the edges), ``noise_m_rthz = 3e-8`` (laser
pointing, air and electronics; a shot-noise-limited PSD would be far quieter). The stage-2 mode
(0.83 Hz, Q2 = 100) dominates v: theta2 = 2.2e-3 rad rms gives v = 0.76 mm rms (analytic,
stationary); over the paper's run (3000 s after 330 s of settling, seed 7) |v| peaked at 3.2 mm
(4.1 mm without the stage reaction), inside the 6 mm half-width; u = 0.18 mm rms, peak 0.7 mm.
Signal-to-noise ratio over 0.1-10 Hz (:func:`rig.bench.signal_to_noise`): x above 21 dB
everywhere (45 dB at low frequency, 21 dB at 10 Hz); y above 20 dB over 81 % and above 10 dB over
97 % of the log-frequency band: it drops at the anti-resonance of theta2 (4.68 Hz, where the
signal vanishes: -12 dB) and is 10.5 dB at 10 Hz. The second-order geometry (module docstring)
adds to u a term ``-D sin(2 phi) sin^2 theta2`` of 0.4 % of u's rms (rotation leaking into the
translation channel at twice the rotation's frequencies) and to v 0.07 % (the lever arm changes
with dx); being quadratic in Gaussian signals they do not bias x/a or y/a, they add a little
uncorrelated power.

Public API: :class:`OpticalLever`, :class:`PsdReading`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.blocks import Calibration
from rig.errors import ConfigError
from rig._jit import njit
from rig.validate import finite_at_least as _finite


@dataclass(frozen=True, eq=False)
class PsdReading:
    """One block of PSD output: ``x_v``, ``y_v`` [V] (N,); the noiseless spot ``spot_u_m``,
    ``spot_v_m`` [m] (exact geometry, before noise and clipping); ``off_detector`` (N,) bool: the
    noisy spot was outside the detector (both outputs clipped there and not to be trusted)."""

    x_v: np.ndarray
    y_v: np.ndarray
    spot_u_m: np.ndarray
    spot_v_m: np.ndarray
    off_detector: np.ndarray


@dataclass(frozen=True)
class OpticalLever:
    """Laser + mirror + PSD (frozen, validated; see the module docstring).

    Parameters
    ----------
    incidence_deg : angle of incidence phi on the mirror [deg], 0 < phi < 90 (at 0 a translation
        does not move the spot; at 90 the beam grazes the mirror).
    distance_m : D, mirror to detector along the reflected beam [m], > 0.
    size_m : side of the square detector [m], > 0.
    gain_vpm : G, output per spot displacement [V/m], > 0 (orientation: the signs).
    noise_m_rthz : spot-position noise density per axis [m/rtHz], >= 0.
    sign_x, sign_y : orientation of the detector axes, +1 or -1.
    """

    incidence_deg: float = 30.0
    distance_m: float = 0.2
    size_m: float = 0.012
    gain_vpm: float = 1000.0
    noise_m_rthz: float = 3e-8
    sign_x: int = 1
    sign_y: int = 1

    def __post_init__(self):
        set_ = object.__setattr__
        phi = self.incidence_deg
        ok = not isinstance(phi, bool) and isinstance(phi, (int, float)) and math.isfinite(phi)
        if not ok or not 0 < phi < 90:
            raise ConfigError(f"psd.incidence_deg = {phi!r} is invalid: expected 0 < incidence_deg"
                              " < 90 deg (0: the mirror translation would not move the spot; "
                              ">= 90: the beam misses the mirror)")
        set_(self, "incidence_deg", float(phi))
        set_(self, "distance_m", _finite("psd.distance_m", self.distance_m, lo=0.0, strict=True,
                                         unit="m"))
        set_(self, "size_m", _finite("psd.size_m", self.size_m, lo=0.0, strict=True, unit="m"))
        set_(self, "gain_vpm", _finite("psd.gain_vpm", self.gain_vpm, lo=0.0, strict=True,
                                       unit="V/m (the orientation is sign_x, sign_y)"))
        set_(self, "noise_m_rthz", _finite("psd.noise_m_rthz", self.noise_m_rthz, lo=0.0,
                                           strict=False, unit="m/rtHz"))
        for name in ("sign_x", "sign_y"):
            v = getattr(self, name)
            if isinstance(v, bool) or v not in (1, -1):
                raise ConfigError(f"psd.{name} = {v!r} is invalid: expected +1 or -1")

    @classmethod
    def from_settings(cls, psd: dict) -> "OpticalLever":
        """Build from a scene's ``settings["psd"]``."""
        return cls(**{k: psd[k] for k in (
            "incidence_deg", "distance_m", "size_m", "gain_vpm", "noise_m_rthz", "sign_x",
            "sign_y")})

    # -- linear description -----------------------------------------------------------------
    @property
    def phi_rad(self) -> float:
        """Incidence angle [rad]."""
        return math.radians(self.incidence_deg)

    @property
    def spot_per_translation(self) -> float:
        """du/d(dx) = 2 sin phi [m/m]."""
        return 2 * math.sin(self.phi_rad)

    @property
    def spot_per_rotation_m(self) -> float:
        """dv/d(theta) = 2 D cos phi [m/rad]."""
        return 2 * self.distance_m * math.cos(self.phi_rad)

    @property
    def half_size_m(self) -> float:
        """Half the detector side [m]: the spot leaves the detector beyond it."""
        return self.size_m / 2

    def calibrations(self) -> dict[str, Calibration]:
        """Linearised calibrations: x [V per m of mirror translation], y [V per rad]."""
        return {
            "x": Calibration(quantity="mirror translation relative to the stage", unit="m",
                             volts_per_unit=(self.sign_x * self.gain_vpm
                                             * self.spot_per_translation)),
            "y": Calibration(quantity="mirror rotation theta", unit="rad",
                             volts_per_unit=self.sign_y * self.gain_vpm * self.spot_per_rotation_m),
        }

    def frequency_response(self, freqs_hz) -> dict[str, np.ndarray]:
        """Volts per unit (x: per m, y: per rad), complex (nf,): frequency independent."""
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        cal = self.calibrations()
        return {k: np.full(f.shape, c.volts_per_unit, dtype=complex) for k, c in cal.items()}

    def noise_rms_m(self, fs_hz: float) -> float:
        """Rms spot-position noise per sample and axis at the rate ``fs_hz`` [m]."""
        return self.noise_m_rthz * math.sqrt(fs_hz / 2)

    # -- geometry ---------------------------------------------------------------------------
    def spot_m(self, mirror_x_m, mirror_rot_rad, mirror_z_m=0.0) -> tuple[np.ndarray, np.ndarray]:
        """Exact spot position (u, v) on the detector [m] (module docstring), broadcast over the
        inputs: mirror-centre displacement ``mirror_x_m`` (along the rest normal) and
        ``mirror_z_m`` (up) relative to the stage, rotation ``mirror_rot_rad``."""
        dx, dz, th = np.broadcast_arrays(np.asarray(mirror_x_m, float),
                                         np.asarray(mirror_z_m, float),
                                         np.asarray(mirror_rot_rad, float))
        shape = dx.shape
        u = np.empty(dx.size)
        v = np.empty(dx.size)
        spot_kernel(np.ascontiguousarray(dx).ravel(), np.ascontiguousarray(dz).ravel(),
                    np.ascontiguousarray(th).ravel(), math.cos(self.phi_rad),
                    math.sin(self.phi_rad), self.distance_m, u, v)
        return u.reshape(shape), v.reshape(shape)

    def spot_linear_m(self, mirror_x_m, mirror_rot_rad) -> tuple[np.ndarray, np.ndarray]:
        """Linearised spot position: (2 sin phi dx, 2 D cos phi theta) [m]."""
        return (self.spot_per_translation * np.asarray(mirror_x_m, float),
                self.spot_per_rotation_m * np.asarray(mirror_rot_rad, float))

    # -- measurement ------------------------------------------------------------------------
    def measure(self, mirror_x_m, mirror_rot_rad, fs_hz: float,
                rng_x: np.random.Generator | None, rng_y: np.random.Generator | None, *,
                mirror_z_m=0.0, noise: bool = True) -> PsdReading:
        """PSD output for the mirror's motion at the sample instants (no state: the PSD is flat).

        Spot from :meth:`spot_m`, plus white position noise (one standard normal per sample from
        ``rng_x`` and ``rng_y``, unless ``noise`` is False), clipped at the detector edge and
        flagged there; volts = sign G (clipped spot).
        """
        dx, dz, th = (np.asarray(a, float) for a in (mirror_x_m, mirror_z_m, mirror_rot_rad))
        shape = np.broadcast_shapes(dx.shape, dz.shape, th.shape)
        if len(shape) > 1:
            raise ConfigError(f"the mirror motion has shape {shape}: expected a 1-D record")
        n = shape[0] if shape else 1
        dx, dz, th = (np.ascontiguousarray(np.broadcast_to(a, (n,))) for a in (dx, dz, th))
        if noise and self.noise_m_rthz > 0:
            sd = self.noise_rms_m(fs_hz)
            wx, wy = rng_x.standard_normal(n), rng_y.standard_normal(n)
        else:
            sd, wx, wy = 0.0, np.zeros(0), np.zeros(0)
        u0, v0, x_v, y_v = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        off = np.empty(n, dtype=np.bool_)
        _measure_kernel(dx, dz, th, math.cos(self.phi_rad), math.sin(self.phi_rad),
                        self.distance_m, wx, wy, sd, self.half_size_m,
                        self.sign_x * self.gain_vpm, self.sign_y * self.gain_vpm, u0, v0, x_v,
                        y_v, off)
        return PsdReading(x_v=x_v, y_v=y_v, spot_u_m=u0, spot_v_m=v0, off_detector=off)


@njit(cache=True, nogil=True)
def _spot(dx, dz, th, cphi, sphi, dist):
    """Exact spot (u, v) of one sample (module docstring)."""
    c = math.cos(th)
    s = math.sin(th)
    t = (c * dx + s * dz) / (-cphi * c)  # q = t d, d = (-cphi, -sphi, 0)
    qx = -cphi * t
    qy = -sphi * t
    rx = -cphi + 2.0 * cphi * c * c  # r = d - 2 (d.n) n, n = (c, 0, s)
    ry = -sphi
    rz = 2.0 * cphi * c * s
    step = (dist - (cphi * qx - sphi * qy)) / (cphi * rx - sphi * ry)
    return sphi * (qx + step * rx) + cphi * (qy + step * ry), step * rz


@njit(cache=True, nogil=True)
def spot_kernel(dx, dz, th, cphi, sphi, dist, u, v):
    """Exact spot (u, v) for each sample (module docstring; compiled, one pass)."""
    for k in range(dx.shape[0]):
        u[k], v[k] = _spot(dx[k], dz[k], th[k], cphi, sphi, dist)


@njit(cache=True, nogil=True)
def _measure_kernel(dx, dz, th, cphi, sphi, dist, wx, wy, sd, h, gx, gy, u, v, x_v, y_v, off):
    """Per sample: the exact spot (``u``, ``v``), plus noise ``sd wx``, ``sd wy`` (``wx`` empty:
    none), clipped at the edge ``h`` and flagged there (``off``), times the signed gains
    (``x_v``, ``y_v``); one pass."""
    noisy = wx.shape[0] > 0
    for k in range(dx.shape[0]):
        uk, vk = _spot(dx[k], dz[k], th[k], cphi, sphi, dist)
        u[k] = uk
        v[k] = vk
        if noisy:
            uk = uk + sd * wx[k]
            vk = vk + sd * wy[k]
        off[k] = (abs(uk) > h) or (abs(vk) > h)
        x_v[k] = gx * min(max(uk, -h), h)
        y_v[k] = gy * min(max(vk, -h), h)
