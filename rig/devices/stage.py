"""The X stage: voltage amplifier, voice-coil motor and the moving stage on its guide.

Model (SI; the source voltage ``V`` is the DAC value held between samples,
:mod:`rig.devices.source`)::

    coil:   L di/dt + R i = G V - Kf v0                    (Kf v0: back EMF, Kf [N/A] = [V s/m])
    stage:  M x0'' = Kf i - k x0 - c v0 - F_p              (v0 = x0', a = x0'')
    F_p  =  d/dt (horizontal momentum of the pendulum) = m x0'' + S^T theta''   (linearised)

``G`` is the amplifier's voltage gain (flat: its bandwidth is far above the simulation band),
``M`` the moving mass without the pendulum (carriage, coil, the laser and PSD riding on it),
``k`` the centring springs of the guide and ``c`` its viscous loss. ``F_p`` is the force the
pendulum pulls on its pivot (the pendulum's reaction on the stage).

The reaction (``stage.reaction``, on by default): stage and pendulum share the symmetric,
positive definite mass matrix ``[[M + m, S^T], [S, H]]``, so in the frequency domain the
pendulum acts as a frequency-dependent mass ``M_eff(s) = M + m + s^2 S^T T(s)`` (``T`` the
angles per unit stage acceleration, :meth:`rig.chain.Chain.frf_angles`) and::

    X(s) / V(s) = G Kf / ((L s + R)(M_eff(s) s^2 + c s + k) + Kf^2 s),   A = s^2 X

The stage acceleration then has a deep, narrow notch at each fixed-base pendulum mode, followed
by a coupled resonance; the angles per unit *stage acceleration* are unchanged, so H_t = x/a is
not (which is why the analyzer divides by the measured a). With ``reaction = false`` the stage
ignores the pendulum. Nonlinear, :mod:`rig.solvers.coupled` integrates stage and pendulum together
with ``F_p = m x0'' + sum_j S_j (cos th_j th_j'' - sin th_j th_j'^2)``. The derivation:
docs/devices.md.

Defaults: ``G = 1 V/V, Kf = 1 N/A, R = 8 ohm, L = 4 mH, M = 2 kg, k = 0.8 N/m, c = 1 N
s/m`` (the fields of :class:`Stage`); their justification and the levels they give are in
``docs/devices.md``.

Public API: :class:`Stage`, :class:`StageStateSpace`, :class:`StageResponse`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.chain import Chain
from rig.params import check_fields, param


@dataclass(frozen=True)
class Stage:
    """Amplifier, voice coil and stage (frozen, validated; see the module docstring). The fields
    are the keys of the scene's ``[stage]`` section: symbol, unit, default and range in each
    field's doc (:func:`rig.params.param`): G, Kf (= back-EMF constant [V s/m]), R, L, M (without
    the pendulum), k, c, and whether the pendulum's reaction loads the stage."""

    amplifier_gain_vpv: float = param(1.0, "voltage gain of the power amplifier [V/V], > 0",
                                      unit="V/V", lo=0.0, strict=True)
    force_constant_npa: float = param(1.0, "voice-coil force constant = back-EMF constant "
                                      "[N/A], > 0", unit="N/A", lo=0.0, strict=True)
    coil_resistance_ohm: float = param(8.0, "coil resistance [ohm], > 0", unit="ohm", lo=0.0,
                                       strict=True)
    coil_inductance_h: float = param(4e-3, "coil inductance [H], > 0 (L/R = 0.5 ms)", unit="H",
                                     lo=0.0, strict=True)
    moving_mass_kg: float = param(2.0, "stage moving mass incl. coil, laser and PSD, without "
                                  "the pendulum [kg], > 0", unit="kg", lo=0.0, strict=True)
    stiffness_npm: float = param(0.8, "centring stiffness of the guide [N/m], >= 0 "
                                 "(suspension ~0.1 Hz)", unit="N/m", lo=0.0)
    damping_nspm: float = param(1.0, "viscous damping of the guide [N s/m], >= 0", unit="N s/m",
                                lo=0.0)
    reaction: bool = param(True, "the pendulum's reaction force loads the stage (linear "
                           "and nonlinear models, rig/solvers/coupled.py)")

    def __post_init__(self):
        check_fields(self, "stage")

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
