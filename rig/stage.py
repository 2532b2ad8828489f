"""The X stage: voltage amplifier, voice-coil motor and the moving stage on its guide.

Model (SI; the source voltage ``V`` is the DAC value held between samples, :mod:`rig.source`)::

    coil:   L di/dt + R i = G V - Kf v0                    (Kf v0: back EMF, Kf [N/A] = [V s/m])
    stage:  M x0'' = Kf i - k x0 - c v0 - F_p              (v0 = x0', a = x0'')
    F_p  =  d/dt (horizontal momentum of the pendulum) = m x0'' + S^T theta''   (linearised)

``G`` is the amplifier's voltage gain (flat: its bandwidth is far above the simulation band),
``M`` the moving mass without the pendulum (carriage, coil, the laser and PSD riding on it),
``k`` the centring springs of the guide and ``c`` its viscous loss. ``F_p`` is the force the
pendulum pulls on its pivot (the pendulum's reaction on the stage).

The reaction (``stage.reaction``)
---------------------------------
The pendulum's horizontal momentum is ``P = m x0' + sum_j S_j cos(th_j) th_j'`` (``m`` its total
mass, ``S_j`` the first moments of :mod:`rig.chain`), and the only horizontal external force on it
is the pivot force, so ``F_p = dP/dt`` (its damping torques, absolute or in the joints, are pure
torques: the guide takes them without translating the stage). Linearised about the hanging rest,
``F_p = m x0'' + S^T theta''``. With the pendulum's linear equation ``H theta'' + C theta' +
g diag(S) theta = -S x0''`` the stage and pendulum share the symmetric mass matrix::

    [[M + m, S^T], [S, H]] (x0'', theta'')^T = (Kf i - k x0 - c v0,  -C theta' - g diag(S) theta)^T

which is the Hessian of the kinetic energy ``1/2 (M + m) x0'^2 + x0' S^T theta' + 1/2 theta'^T H
theta'`` (Lagrange with x0 as a coordinate); it is positive definite because ``m - S^T H^-1 S >=
0`` (the pendulum's kinetic energy is) and ``M > 0``. In the frequency domain, with ``Theta(s) =
T(s) A(s)`` and ``T(s) = (H s^2 + C s + g diag(S))^-1 (-S)`` (:meth:`rig.chain.Chain.frf_angles`),
the pendulum acts as a frequency-dependent mass::

    M_eff(s) = M + m + s^2 S^T T(s)      (-> M + m at DC, -> M + m - S^T H^-1 S at high f)
    X(s) / V(s) = G Kf / ((L s + R)(M_eff(s) s^2 + c s + k) + Kf^2 s),   A = s^2 X

Near a pendulum mode ``|s^2 S^T T|`` grows to about Q times the mode's effective mass, so the stage
acceleration has a deep, narrow notch at each fixed-base pendulum mode (for the defaults -25 dB at
2.479 Hz), followed by a coupled resonance (+21 dB at 2.523 Hz); the angles per unit *stage
acceleration* are unchanged, so H_t = x/a is not (that is why the analyzer divides by the
measured a). With ``reaction = false`` the stage ignores the
pendulum altogether (neither its mass nor its swinging loads the stage). Nonlinear, the reaction
is ``F_p = m x0'' + sum_j S_j (cos th_j th_j'' - sin th_j th_j'^2)``, the rate of the momentum
above; :mod:`rig.coupled` integrates stage and nonlinear pendulum together with it (the chain's
force is affine in ``x0''``, so the stage equation is solved for ``x0''`` at every evaluation).

Defaults and their justification (``ishizaki2009`` pendulum, default source 0.1 V rms, 0-12.5 Hz)
-----------------------------------------------------------------------------------------------
``G = 1 V/V, Kf = 1 N/A, R = 8 ohm, L = 4 mH, M = 2 kg, k = 0.8 N/m, c = 1 N s/m``: a small voice
coil (1 N/A, 8 ohm, L/R = 0.5 ms, corner 318 Hz) on a 2 kg aluminium carriage that also carries
the laser and the PSD, held by soft centring springs (suspension 0.098 Hz with the pendulum on,
damping ratio 0.43 including the back-EMF damping Kf^2/R = 0.125 N s/m).

* Acceleration: above the suspension the stage is mass controlled, a/V = G Kf / (R (M + m)) =
  0.0595 (m/s^2)/V (0.0625 without the reaction), flat within +2/-3 dB from 0.076 Hz to 12.5 Hz;
  with the reaction the pendulum adds a -25 dB notch at 2.479 Hz (its fixed-base mode) and a
  +21 dB coupled resonance at 2.523 Hz (the same mode on a free stage, 2.479 sqrt(1 + 0.036)).
  The default source gives a ~ 6.5e-3 m/s^2 rms (6.3e-3 without the reaction), an acceleration
  density ~ 1.8e-3 m/s^2/rtHz.
* Linear range: with Q1 = 530, 0.05 m/s^2 rms flat over 0-12.5 Hz would swing theta1 to 0.065
  rad rms (0.1 rad and more at its peaks) and theta2 to 0.019 rad: a pendulum's frequency falls by
  ~A^2/16 at amplitude A, at 3 rms 2.4e-3, two and a half times the 2.48 Hz mode's half-power
  half-bandwidth 1/(2 Q1) = 9.4e-4: visibly nonlinear. The default drive gives theta1 = 6.1e-3
  rad and theta2 = 2.2e-3 rad rms (stationary, reaction on; 8.2e-3 and 2.4e-3 without it): a
  shift of 2.1e-5 at 3 rms, 2 % of the half-bandwidth (tests/test_stage.py).
* Stroke: the spring takes the near-DC part of the source (DC per volt G Kf / (R k) = 0.16 m/V):
  x0 = 1.9 mm rms.
* Sensors: the signal-to-noise ratios this gives on every channel are listed in
  :mod:`rig.accelerometer` and :mod:`rig.psd` (:func:`rig.bench.signal_to_noise`).

Public API: :class:`Stage`, :class:`StageStateSpace`, :class:`StageResponse`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.chain import Chain
from rig.errors import ConfigError


def _param(where: str, value, *, strict: bool, unit: str) -> float:
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if not ok or value < 0 or (strict and value == 0):
        rel = ">" if strict else ">="
        raise ConfigError(f"{where} = {value!r} is invalid: expected a finite number {rel} 0 "
                          f"{unit}")
    return float(value)


@dataclass(frozen=True)
class Stage:
    """Amplifier, voice coil and stage (frozen, validated; see the module docstring).

    Parameters
    ----------
    amplifier_gain_vpv : G [V/V], > 0.
    force_constant_npa : Kf [N/A] (= back-EMF constant [V s/m]), > 0.
    coil_resistance_ohm : R [ohm], > 0.
    coil_inductance_h : L [H], > 0.
    moving_mass_kg : M [kg] without the pendulum, > 0.
    stiffness_npm : k [N/m], >= 0.
    damping_nspm : c [N s/m], >= 0.
    reaction : whether the pendulum's reaction loads the stage.
    """

    amplifier_gain_vpv: float = 1.0
    force_constant_npa: float = 1.0
    coil_resistance_ohm: float = 8.0
    coil_inductance_h: float = 4e-3
    moving_mass_kg: float = 2.0
    stiffness_npm: float = 0.8
    damping_nspm: float = 1.0
    reaction: bool = True

    def __post_init__(self):
        set_ = object.__setattr__
        for name, strict, unit in (("amplifier_gain_vpv", True, "V/V"),
                                   ("force_constant_npa", True, "N/A"),
                                   ("coil_resistance_ohm", True, "ohm"),
                                   ("coil_inductance_h", True, "H"),
                                   ("moving_mass_kg", True, "kg"),
                                   ("stiffness_npm", False, "N/m"),
                                   ("damping_nspm", False, "N s/m")):
            set_(self, name, _param(f"stage.{name}", getattr(self, name), strict=strict, unit=unit))
        if not isinstance(self.reaction, bool):
            raise ConfigError(f"stage.reaction = {self.reaction!r} is invalid: expected true or "
                              "false")

    @classmethod
    def from_settings(cls, stage: dict) -> "Stage":
        """Build from a scene's ``settings["stage"]``."""
        return cls(**{k: stage[k] for k in (
            "amplifier_gain_vpv", "force_constant_npa", "coil_resistance_ohm", "coil_inductance_h",
            "moving_mass_kg", "stiffness_npm", "damping_nspm", "reaction")})

    # -- derived constants ------------------------------------------------------------------
    @property
    def back_emf_damping_nspm(self) -> float:
        """Kf^2 / R [N s/m]: the damping the voltage drive adds through the back EMF."""
        return self.force_constant_npa**2 / self.coil_resistance_ohm

    @property
    def electrical_corner_hz(self) -> float:
        """R / (2 pi L) [Hz]: above it the coil current lags the voltage."""
        return self.coil_resistance_ohm / (2 * math.pi * self.coil_inductance_h)

    def loaded_mass_kg(self, chain: Chain | None) -> float:
        """Mass the coil accelerates at low frequency [kg]: M (+ m with the reaction)."""
        if chain is None or not self.reaction:
            return self.moving_mass_kg
        return self.moving_mass_kg + float(sum(chain.mass_kg))

    def suspension_hz(self, chain: Chain | None = None) -> float:
        """Undamped suspension frequency sqrt(k / M_loaded) / 2 pi [Hz]."""
        return math.sqrt(self.stiffness_npm / self.loaded_mass_kg(chain)) / (2 * math.pi)

    def suspension_damping_ratio(self, chain: Chain | None = None) -> float:
        """(c + Kf^2/R) / (2 sqrt(k M_loaded)) [-] (inf without springs)."""
        k = self.stiffness_npm
        if k == 0:
            return math.inf
        return (self.damping_nspm + self.back_emf_damping_nspm) / (
            2 * math.sqrt(k * self.loaded_mass_kg(chain)))

    def midband_accel_per_volt(self, chain: Chain | None = None) -> float:
        """G Kf / (R M_loaded) [(m/s^2)/V]: the mass-controlled acceleration per source volt."""
        return (self.amplifier_gain_vpv * self.force_constant_npa
                / (self.coil_resistance_ohm * self.loaded_mass_kg(chain)))

    # -- linear dynamics --------------------------------------------------------------------
    def state_space(self, chain: Chain | None = None) -> "StageStateSpace":
        """The stage (and, with ``chain``, the linearised pendulum on it) as z' = A z + B V.

        State ``z = (i [A], x0 [m], v0 [m/s], theta (n) [rad], omega (n) [rad/s])`` (the last two
        only with a chain), input the held source voltage V [V]. With ``reaction`` the pendulum
        loads the stage through the coupled mass matrix (module docstring); without it the stage
        drives the pendulum one way.
        """
        G, kf, R, L = (self.amplifier_gain_vpv, self.force_constant_npa,
                       self.coil_resistance_ohm, self.coil_inductance_h)
        M, k, c = self.moving_mass_kg, self.stiffness_npm, self.damping_nspm
        n = 0 if chain is None else chain.n
        nz = 3 + 2 * n
        a = np.zeros((nz, nz))
        b = np.zeros((nz, 1))
        # coil
        a[0, 0] = -R / L
        a[0, 2] = -kf / L
        b[0, 0] = G / L
        a[1, 2] = 1.0
        # generalised forces f = F z for the velocity coordinates q' = (v0, omega)
        f = np.zeros((1 + n, nz))
        f[0, 0] = kf
        f[0, 1] = -k
        f[0, 2] = -c
        e = np.zeros((1 + n, 1 + n))
        e[0, 0] = M
        if chain is not None:
            a[3:3 + n, 3 + n:] = np.eye(n)
            f[1:, 3:3 + n] = -chain.K
            f[1:, 3 + n:] = -chain.C
            e[1:, 1:] = chain.H
            e[1:, 0] = chain.S
            if self.reaction:
                e[0, 0] += float(sum(chain.mass_kg))
                e[0, 1:] = chain.S
        acc = np.linalg.solve(e, f)  # rows: v0', omega' as functions of z
        a[2, :] = acc[0]
        if chain is not None:
            a[3 + n:, :] = acc[1:]
        return StageStateSpace(a=a, b=b, accel_row=acc[0].copy(), n_bodies=n)

    def frequency_response(self, freqs_hz, chain: Chain | None = None) -> "StageResponse":
        """Analytic response per source volt at ``freqs_hz`` [Hz] (continuous time, no DAC hold).

        Closed form of the module docstring: ``X/V = G Kf / ((L s + R)(M_eff s^2 + c s + k) +
        Kf^2 s)`` with ``M_eff = M + m + s^2 S^T T(s)`` (reaction) or ``M`` (none); the angles are
        ``T(s) A(s)``. At 0 Hz the acceleration, velocity and angles are 0.
        """
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        s = 2j * np.pi * f
        G, kf, R, L = (self.amplifier_gain_vpv, self.force_constant_npa,
                       self.coil_resistance_ohm, self.coil_inductance_h)
        m_eff = np.full(f.shape, self.moving_mass_kg, dtype=complex)
        theta_per_a = None
        if chain is not None:
            theta_per_a = chain.frf_angles(f)
            if self.reaction:
                m_eff = m_eff + float(sum(chain.mass_kg)) + s**2 * (theta_per_a @ chain.S)
        x = G * kf / ((L * s + R) * (m_eff * s**2 + self.damping_nspm * s + self.stiffness_npm)
                      + kf**2 * s)
        acc = s**2 * x
        current = (G - kf * s * x) / (L * s + R)
        theta = None if chain is None else theta_per_a * acc[:, None]
        return StageResponse(freqs_hz=f, accel=acc, disp=x, current=current, theta=theta)


@dataclass(frozen=True, eq=False)
class StageStateSpace:
    """z' = a z + b V for z = (i, x0, v0[, theta, omega]); ``accel_row`` gives x0'' = accel_row . z
    (no direct feedthrough of V: the coil current is continuous)."""

    a: np.ndarray
    b: np.ndarray
    accel_row: np.ndarray
    n_bodies: int

    @property
    def names(self) -> list[str]:
        """State names with units."""
        n = self.n_bodies
        return (["coil_current_a", "stage_disp_m", "stage_vel_mps"]
                + [f"theta{j + 1}_rad" for j in range(n)]
                + [f"omega{j + 1}_rad_s" for j in range(n)])


@dataclass(frozen=True, eq=False)
class StageResponse:
    """Per source volt (continuous time): ``accel`` [(m/s^2)/V], ``disp`` [m/V], ``current``
    [A/V], ``theta`` (nf, n) [rad/V] or None; all complex, shape (nf,)."""

    freqs_hz: np.ndarray
    accel: np.ndarray
    disp: np.ndarray
    current: np.ndarray
    theta: np.ndarray | None
