"""The exact linear model of many two-body pendulums at once (absolute damping, SPEC section 2).

:class:`Pendulums` holds N pendulums as arrays of their physical parameters (m1, m2, r1 = c_1,
l = l_1, r2 = c_2, J1, J2, Gamma1, Gamma2; one g) and evaluates, vectorised over the N and over
frequency, the same linear model as :meth:`rig.chain.Chain.frf_angles` and ``modes``: the 2 x 2
system ``Z Theta = -S`` with ``Z = K - w^2 H + i w C`` solved by Cramer's rule (exact; only the
round-off differs from a library solve), the four poles of ``det(K + s C + s^2 H)`` from batched
companion matrices, and the undamped zeros of Theta_1 and Theta_2 in closed form::

    Theta_1 = (S2 Z12 - S1 Z22) / det Z,     Theta_2 = (S1 Z21 - S2 Z11) / det Z
    theta2 / theta1 = (S2 Z11 - S1 Z21) / (S1 Z22 - S2 Z12)          (no resonant denominator)
    Theta_2 zero (the notch):  w^2 = K1 / (D1 - l S1) = g S1 / (J1 + m1 r1 (r1 - l))
    Theta_1 zero:              w^2 = K2 S1 / (S1 D2 - l S2^2)

With l = r1 the notch is at ``w^2 = g (m1 + m2) r1 / J1``: at infinity for J1 = 0 (sigma^2 = 1,
the paper's goal (ii)). Its depth is the damped numerator against its undamped terms,
``|N(i w_z)| / (|S2 K1| + w_z^2 |S2 (D1 - l S1)|) = w_z Gamma1 / (2 K1) = (w_z / omega1) / (2 Q1)``.

The mirror is at O2 (SPEC section 5): translation ``x = l theta1`` [m per m/s^2], rotation
``y = theta2`` [rad per m/s^2]. Units SI, frequencies in Hz at the interface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from rig.chain import G_STANDARD, Chain
from rig.errors import ConfigError

__all__ = ["Pendulums", "PARAMETERS"]

#: The physical parameters of :class:`Pendulums`, with their units.
PARAMETERS = {"m1_kg": "kg", "m2_kg": "kg", "r1_m": "m", "l_m": "m", "r2_m": "m",
              "j1_kgm2": "kg m^2", "j2_kgm2": "kg m^2", "gamma1_nms": "N m s/rad",
              "gamma2_nms": "N m s/rad"}


@dataclass(frozen=True, eq=False)
class Pendulums:
    """N two-body pendulums with absolute damping, each parameter an (N,) array (SI).

    Attributes
    ----------
    m1_kg, m2_kg : masses [kg]. r1_m : O1 to G1 [m]. l_m : O1 to O2 [m]. r2_m : O2 to G2 [m].
    j1_kgm2, j2_kgm2 : inertias about the centres of mass [kg m^2].
    gamma1_nms, gamma2_nms : absolute damping Gamma1, Gamma2 [N m s/rad].
    g_mps2 : gravitational acceleration [m/s^2] (one for all).

    Construction broadcasts the arrays to one shape (N,) and checks them only for finiteness;
    a sample with a non-positive mass, S_j or inertia is flagged by :attr:`physical` rather than
    rejected, so a Monte Carlo keeps its shape.
    """

    m1_kg: np.ndarray
    m2_kg: np.ndarray
    r1_m: np.ndarray
    l_m: np.ndarray
    r2_m: np.ndarray
    j1_kgm2: np.ndarray
    j2_kgm2: np.ndarray
    gamma1_nms: np.ndarray
    gamma2_nms: np.ndarray
    g_mps2: float = G_STANDARD

    def __post_init__(self):
        names = [f.name for f in fields(self) if f.name != "g_mps2"]
        arrays = np.broadcast_arrays(*(np.atleast_1d(np.asarray(getattr(self, n), float))
                                       for n in names))
        for name, a in zip(names, arrays):
            if a.ndim != 1 or not np.all(np.isfinite(a)):
                raise ConfigError(f"Pendulums.{name} has shape {a.shape} or non-finite values: "
                                  "expected finite numbers, one per pendulum")
            object.__setattr__(self, name, np.array(a))
        if not (math.isfinite(self.g_mps2) and self.g_mps2 > 0):
            raise ConfigError(f"g_mps2 = {self.g_mps2!r} is invalid: expected a finite number > 0")

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def from_chain(cls, chain: Chain) -> Pendulums:
        """The one pendulum of a 2-body chain with absolute damping."""
        if chain.n != 2 or chain.damping_mode != "absolute":
            raise ConfigError(f"chain has n = {chain.n}, damping_mode = {chain.damping_mode!r}: "
                              "expected a 2-body chain with absolute damping")
        (m1, m2), (r1, r2), (j1, j2) = chain.mass_kg, chain.com_m, chain.inertia_kgm2
        return cls(m1, m2, r1, chain.length_m[0], r2, j1, j2, *chain.damping_nms,
                   g_mps2=chain.g_mps2)

    def params(self) -> dict[str, np.ndarray]:
        """The parameters by name (:data:`PARAMETERS`), each (N,)."""
        return {n: getattr(self, n) for n in PARAMETERS}

    def replace(self, **arrays) -> Pendulums:
        """The same pendulums with some parameters replaced (broadcast to N)."""
        return Pendulums(**{**self.params(), **arrays}, g_mps2=self.g_mps2)

    def chain(self, i: int = 0, length2_m: float = 0.0375) -> Chain:
        """Pendulum ``i`` as a :class:`Chain` (the slow, one-at-a-time reference)."""
        return Chain(mass_kg=(self.m1_kg[i], self.m2_kg[i]), length_m=(self.l_m[i], length2_m),
                     com_m=(self.r1_m[i], self.r2_m[i]),
                     inertia_kgm2=(self.j1_kgm2[i], self.j2_kgm2[i]),
                     damping_nms=(self.gamma1_nms[i], self.gamma2_nms[i]),
                     damping_mode="absolute", g_mps2=self.g_mps2)

    def __len__(self) -> int:
        return self.m1_kg.shape[0]

    # -- the matrices ---------------------------------------------------------------------------
    @property
    def s1(self) -> np.ndarray:
        """S1 = m1 r1 + m2 l [kg m]."""
        return self.m1_kg * self.r1_m + self.m2_kg * self.l_m

    @property
    def s2(self) -> np.ndarray:
        """S2 = m2 r2 [kg m]."""
        return self.m2_kg * self.r2_m

    @property
    def d1(self) -> np.ndarray:
        """D1 = J1 + m1 r1^2 + m2 l^2 [kg m^2]."""
        return self.j1_kgm2 + self.m1_kg * self.r1_m**2 + self.m2_kg * self.l_m**2

    @property
    def d2(self) -> np.ndarray:
        """D2 = I2 = J2 + m2 r2^2 [kg m^2]."""
        return self.j2_kgm2 + self.m2_kg * self.r2_m**2

    @property
    def physical(self) -> np.ndarray:
        """(N,) bool: positive masses, S1, S2, D1 D2 - h^2 and non-negative inertias, damping."""
        det = self.d1 * self.d2 - (self.l_m * self.s2) ** 2
        return ((self.m1_kg > 0) & (self.m2_kg > 0) & (self.s1 > 0) & (self.s2 > 0)
                & (self.j1_kgm2 >= 0) & (self.j2_kgm2 >= 0) & (det > 0)
                & (self.gamma1_nms >= 0) & (self.gamma2_nms >= 0))

    def _z(self, freqs_hz):
        w = 2 * np.pi * np.asarray(freqs_hz, float)
        w = w[None, :] if w.ndim == 1 else w
        g = self.g_mps2
        s1, s2 = self.s1[:, None], self.s2[:, None]
        w2 = w * w
        z11 = g * s1 - w2 * self.d1[:, None] + 1j * w * self.gamma1_nms[:, None]
        z22 = g * s2 - w2 * self.d2[:, None] + 1j * w * self.gamma2_nms[:, None]
        z12 = -w2 * (self.l_m * self.s2)[:, None]
        return z11, z12, z22, s1, s2

    # -- responses ------------------------------------------------------------------------------
    def angles(self, freqs_hz) -> tuple[np.ndarray, np.ndarray]:
        """(Theta_1, Theta_2) [rad per m/s^2], each (N, nf); ``freqs_hz`` (nf,) or (N, nf)."""
        z11, z12, z22, s1, s2 = self._z(freqs_hz)
        det = z11 * z22 - z12 * z12
        return (s2 * z12 - s1 * z22) / det, (s1 * z12 - s2 * z11) / det

    def rotation_ratio(self, freqs_hz) -> np.ndarray:
        """theta2 / theta1 [-], (N, nf): the mirror's rotation per rotation of stage 1."""
        z11, z12, z22, s1, s2 = self._z(freqs_hz)
        return (s2 * z11 - s1 * z12) / (s1 * z22 - s2 * z12)

    def translation(self, freqs_hz) -> np.ndarray:
        """x = l Theta_1: the mirror centre O2 relative to the stage [m per m/s^2], (N, nf)."""
        return self.l_m[:, None] * self.angles(freqs_hz)[0]

    # -- modes and zeros ------------------------------------------------------------------------
    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Damped modes: natural frequencies [Hz] and Q, each (N, 2), ascending in frequency.

        The roots of ``det(K + s C + s^2 H)`` (a quartic in s, scaled by omega_ref = sqrt(K1/D1)),
        from the eigenvalues of N companion matrices at once. A pendulum whose roots are not two
        oscillatory pairs (an overdamped mode) is computed by :meth:`Chain.modes` instead.
        """
        g = self.g_mps2
        k1, k2 = g * self.s1, g * self.s2
        d1, d2, h = self.d1, self.d2, self.l_m * self.s2
        g1, g2 = self.gamma1_nms, self.gamma2_nms
        wr = np.sqrt(k1 / d1)
        coef = np.stack([(d1 * d2 - h * h) * wr**4, (g1 * d2 + g2 * d1) * wr**3,
                         (k1 * d2 + k2 * d1 + g1 * g2) * wr**2, (k1 * g2 + k2 * g1) * wr,
                         k1 * k2], axis=1)
        coef = coef / coef[:, :1]
        n = coef.shape[0]
        comp = np.zeros((n, 4, 4))
        comp[:, 0, :] = -coef[:, 1:]
        comp[:, 1, 0] = comp[:, 2, 1] = comp[:, 3, 2] = 1.0
        roots = np.linalg.eigvals(comp) * wr[:, None]
        osc = roots.imag > 0
        good = osc.sum(axis=1) == 2
        sel = roots[good][osc[good]].reshape(-1, 2)
        sel = np.take_along_axis(sel, np.argsort(np.abs(sel), axis=1), axis=1)
        f = np.full((n, 2), np.nan)
        q = np.full((n, 2), np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            f[good] = np.abs(sel) / (2 * np.pi)
            q[good] = np.where(sel.real < 0, np.abs(sel) / (-2 * sel.real), np.inf)
        for i in np.flatnonzero(~good):
            fi, qi = self.chain(i).modes()
            f[i, :fi.size], q[i, :qi.size] = fi[:2], qi[:2]
        return f, q

    def notch_hz(self) -> np.ndarray:
        """The undamped zero of Theta_2 [Hz], (N,): ``sqrt(K1 / (D1 - l S1)) / 2 pi``; ``inf``
        where ``D1 - l S1 <= 0`` (no zero at a finite frequency)."""
        den = self.d1 - self.l_m * self.s1
        with np.errstate(divide="ignore", invalid="ignore"):
            w2 = np.where(den > 0, self.g_mps2 * self.s1 / den, np.inf)
        return np.sqrt(w2) / (2 * np.pi)

    def notch_depth_db(self) -> np.ndarray:
        """Depth of the Theta_2 notch [dB], (N,): ``20 log10(w_z Gamma1 / (2 K1))``, the damped
        numerator against its undamped terms at the zero (module docstring); ``-inf`` without
        damping on stage 1, ``nan`` where there is no finite notch."""
        wz = 2 * np.pi * self.notch_hz()
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = wz * self.gamma1_nms / (2 * self.g_mps2 * self.s1)
            return np.where(np.isfinite(wz), 20 * np.log10(ratio), np.nan)

    def theta1_zero_hz(self) -> np.ndarray:
        """The undamped zero of Theta_1 [Hz], (N,) (``inf`` where there is none)."""
        den = self.s1 * self.d2 - self.l_m * self.s2**2
        with np.errstate(divide="ignore", invalid="ignore"):
            w2 = np.where(den > 0, self.g_mps2 * self.s2 * self.s1 / den, np.inf)
        return np.sqrt(w2) / (2 * np.pi)

    def uncoupled_hz(self) -> tuple[np.ndarray, np.ndarray]:
        """The paper's f1 = sqrt(K1/D1)/2pi and f2 = sqrt(K2/I2)/2pi [Hz], each (N,)."""
        g = self.g_mps2
        return (np.sqrt(g * self.s1 / self.d1) / (2 * np.pi),
                np.sqrt(g * self.s2 / self.d2) / (2 * np.pi))
