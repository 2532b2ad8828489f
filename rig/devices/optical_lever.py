"""Laser, optical lever and position sensitive detector (PSD), all riding on the stage.

Why laser and PSD move with the stage
-------------------------------------
SPEC section 5 defines the translation channel as the mirror's displacement *relative to the
stage*, and the paper compares the measured x with relative-displacement models (H_t -> -l/g at
low frequency, phase 180 deg; an inertial measurement would tend to 0 instead). A laser and PSD
fixed to the ground would add the stage's own displacement, ~2.5 mm rms here, a thousand times
the mirror's relative motion at low frequency. So both are mounted on the stage (their mass is in
``stage.moving_mass_kg``) and the spot sees only the pendulum's motion relative to its pivot.

Geometry
--------
Stage frame: x along the stage motion (the mirror's rest normal, toward the laser), y lateral, z
up. The mirror centre moves by ``(dx, 0, dz)`` and its body turns by ``theta`` about y; the beam
arrives in the horizontal plane at incidence ``phi``, and the detector is a plane at distance
``D`` normal to the rest reflected beam. :meth:`OpticalLever.spot_m` traces the ray exactly
(the derivation: docs/devices.md); linearised, the spot moves by ``u = 2 sin(phi) dx``
horizontally and ``v = 2 cos(phi) D theta`` vertically, which the calibrations use.

Detector, output and edges
--------------------------
``volts_x = sign_x G u``, ``volts_y = sign_y G v`` (G = ``gain_vpm``; the PSD and its amplifiers are
flat far above the simulation band). Position noise, white with one-sided density
``noise_m_rthz`` on each axis, is added to the spot position. The detector is a square of side
``size_m`` centred on the rest spot: each coordinate is clipped at its edge (the output saturates
at +-G size/2) and a spot beyond it flags the sample (``off_detector``, both channels): flagged
samples must not be trusted.

Defaults: the fields of :class:`OpticalLever`; the spot excursions and signal-to-noise ratios
they give are in ``docs/devices.md``.

Public API: :class:`OpticalLever`, :class:`PsdReading`, :class:`LeverRow`, :func:`lever_row`.
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


class LeverRow(NamedTuple):
    """The lever's numbers for the compiled row kernels (:meth:`OpticalLever.row_params`):
    ``cphi``, ``sphi`` = cos, sin of the incidence, ``distance_m`` = D, ``half_m`` (the
    detector's edge), ``gain_x``, ``gain_y`` = the signed gains [V/m], ``noise_sd_m`` the spot
    noise rms per sample and axis (0: none drawn)."""

    cphi: float
    sphi: float
    distance_m: float
    half_m: float
    gain_x: float
    gain_y: float
    noise_sd_m: float


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
    """Laser + mirror + PSD (frozen, validated; see the module docstring). The fields are the keys
    of the scene's ``[psd]`` section (unit, default and range in each field's doc,
    :func:`rig.params.param`): the angle of incidence phi (at 0 a translation does not move the
    spot; at 90 the beam grazes the mirror), D, the detector's side, G (the orientation is in the
    signs), the spot noise and the orientation of the detector axes."""

    incidence_deg: float = param(30.0, "angle of incidence on the mirror in the horizontal "
                                 "plane [deg], 0 < phi < 90")
    distance_m: float = param(0.2, "mirror to PSD along the reflected beam [m], > 0", unit="m",
                              lo=0.0, strict=True)
    size_m: float = param(0.012, "side of the square detector [m], > 0; the output clips at "
                          "its edge (flagged)", unit="m", lo=0.0, strict=True)
    gain_vpm: float = param(1000.0, "PSD output per spot displacement [V/m], > 0",
                            unit="V/m (the orientation is sign_x, sign_y)", lo=0.0, strict=True)
    noise_m_rthz: float = param(3e-8, "spot-position noise density per axis "
                                "[m/sqrt(Hz)], >= 0", unit="m/rtHz", lo=0.0)
    sign_x: int = param(1, "orientation of the PSD x axis, +1 or -1", choices=(1, -1))
    sign_y: int = param(1, "orientation of the PSD y axis, +1 or -1", choices=(1, -1))

    def __post_init__(self):
        phi = self.incidence_deg
        ok = not isinstance(phi, bool) and isinstance(phi, (int, float)) and math.isfinite(phi)
        if not ok or not 0 < phi < 90:
            raise ConfigError(f"psd.incidence_deg = {phi!r} is invalid: expected 0 < incidence_deg"
                              " < 90 deg (0: the mirror translation would not move the spot; "
                              ">= 90: the beam misses the mirror)")
        object.__setattr__(self, "incidence_deg", float(phi))
        check_fields(self, "psd")

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

    def row_params(self, fs_hz: float) -> LeverRow:
        """The numbers :func:`lever_row` takes at the rate ``fs_hz`` (the noise rms 0 without
        noise)."""
        return LeverRow(math.cos(self.phi_rad), math.sin(self.phi_rad), float(self.distance_m),
                        float(self.half_size_m), float(self.sign_x * self.gain_vpm),
                        float(self.sign_y * self.gain_vpm),
                        float(self.noise_rms_m(fs_hz)) if self.noise_m_rthz > 0 else 0.0)

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
        _measure_kernel(dx, dz, th, self.row_params(fs_hz), wx, wy, sd, u0, v0, x_v, y_v, off)
        return PsdReading(x_v=x_v, y_v=y_v, spot_u_m=u0, spot_v_m=v0, off_detector=off)


#: below this |theta| [rad] :func:`_cos_sin` sums the Taylor series instead of calling libm
SMALL_ANGLE_RAD = 2.0 ** -6

# The spot's kernels divide under numpy's error model: a zero divisor (a lever at 90 degrees or
# a mirror edge-on, neither a measurement) gives inf or nan, which the bench's finite checks
# report, instead of Python's ZeroDivisionError, whose test in every division keeps a loop of
# spots from vectorising (lever_row).


@njit(cache=True, nogil=True)
def _cos_sin(th):
    """(cos th, sin th). For ``|th| <= SMALL_ANGLE_RAD`` (a mirror's tilt is microradians) the
    Taylor polynomials through th^8 and th^9, Horner's rule, the leading term added last: the
    first omitted terms are below 2.4e-25 and 2.2e-26 of the value there. The polynomial part's
    own rounding (below ~2^-53 th^2 of the value's ulp) adds to the final one, so where the
    exact value lies that close to a tie between two doubles the result is libm's neighbour, 1
    ulp away, both then within 0.5001 ulp: at most one value in 1 / th^2 (none at a mirror's
    tilts; tests/rig/devices/test_sensors.py compares them with math.cos and math.sin below
    1e-4 rad and near the threshold); beyond, libm."""
    if abs(th) <= SMALL_ANGLE_RAD:
        return _cos_sin_small(th)
    return math.cos(th), math.sin(th)


@njit(cache=True, nogil=True, error_model="numpy")
def _cos_sin_small(th):
    """:func:`_cos_sin` for ``|th| <= SMALL_ANGLE_RAD``: the Taylor polynomials alone (no branch,
    no call: a loop of them vectorises)."""
    t2 = th * th
    c = 1.0 + t2 * (-0.5 + t2 * (1.0 / 24.0 + t2 * (-1.0 / 720.0 + t2 * (1.0 / 40320.0))))
    s = th + th * (t2 * (-1.0 / 6.0 + t2 * (1.0 / 120.0 + t2 * (-1.0 / 5040.0
                                                                + t2 * (1.0 / 362880.0)))))
    return c, s


@njit(cache=True, nogil=True, error_model="numpy")
def _spot(dx, dz, th, cphi, sphi, dist):
    """Exact spot (u, v) of one sample (module docstring)."""
    c, s = _cos_sin(th)
    return _spot_cs(dx, dz, c, s, cphi, sphi, dist)


@njit(cache=True, nogil=True, error_model="numpy")
def _spot_small(dx, dz, th, cphi, sphi, dist):
    """:func:`_spot` for ``|th| <= SMALL_ANGLE_RAD`` (the same arithmetic, without a branch or a
    call: a loop of it vectorises)."""
    c, s = _cos_sin_small(th)
    return _spot_cs(dx, dz, c, s, cphi, sphi, dist)


@njit(cache=True, nogil=True, error_model="numpy")
def _spot_cs(dx, dz, c, s, cphi, sphi, dist):
    """:func:`_spot` from the mirror's ``cos th``, ``sin th``."""
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
def _measure_kernel(dx, dz, th, p, wx, wy, sd, u, v, x_v, y_v, off):
    """Per sample: the exact spot (``u``, ``v``), plus noise ``sd wx``, ``sd wy`` (``wx`` empty:
    none), clipped at the edge and flagged there (``off``), times the signed gains (``x_v``,
    ``y_v``; ``p``: :class:`LeverRow`); one pass."""
    cphi, sphi, dist, h, gx, gy = p.cphi, p.sphi, p.distance_m, p.half_m, p.gain_x, p.gain_y
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


@njit(cache=True, nogil=True, error_model="numpy")
def lever_row(dx, dz, th, wx, wy, p, out_x, out_y, flag):
    """One sample of every interval of a chunk: the exact spot (:func:`_spot`) of the mirror's
    translations ``dx``, heights ``dz`` and rotations ``th``, plus the noise ``wx``, ``wy`` [m]
    (empty: none), clipped at the detector's edge ``+-p.half_m`` times the signed gains into
    ``out_x``, ``out_y`` and flagged beyond it (``p``: :class:`LeverRow`;
    :meth:`OpticalLever.measure`'s arithmetic). Where every tilt is within the small-angle
    polynomial's range (a mirror's tilts are microradians) and there is noise, the spot is
    :func:`_spot_small`, the same arithmetic without a branch or a call, so the loop
    vectorises. The bench's fused chain (:mod:`rig.bench.fused`) runs the lever so; equal to
    :meth:`OpticalLever.measure` bit for bit (tests/rig/devices/test_fused_sensors.py)."""
    cphi, sphi, dist, half, gain_x, gain_y = p.cphi, p.sphi, p.distance_m, p.half_m, p.gain_x, \
        p.gain_y
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
