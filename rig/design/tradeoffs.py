"""The trade-offs a designer looks at, on the exact linear model, batched over each sweep.

A design is moved along one of the paper's groups at a time, alpha, nu = f2/f1 or sigma^2, with
the others of the independent set (alpha, nu, sigma^2, eps, f1) held, so each sweep changes one
physical length or frequency (alpha: r2; nu: f2; sigma^2: r1 and r2 together). For every point:

- ``suppression_db``: ``-20 log10 max |theta2/theta1|`` over the band (the targets' first band,
  else 1.5 f1 .. 10 f1), and ``limit_db``, the exact high-frequency limit
  ``-20 log10 |nu^2 (1 - sigma^2)/(1 - beta^2/sigma^2)|`` beside claim (29)'s ``-20 log10 alpha``;
- ``translation_dev_db``: the largest ``|20 log10 |x / x_single||`` over 0.1 f2 .. 10 f1, where
  ``x_single`` is stage 1 with stage 2 locked at G1 (one pendulum of f1, Q1): how much stage 2
  disturbs the translation the mirror reports;
- ``notch_hz``, ``notch_depth_db``: the Theta_2 notch (:meth:`Pendulums.notch_hz`).

:func:`policy_pair` gives a design's policy (i) and (ii) versions side by side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.design.model import Pendulums
from rig.errors import ConfigError
from rig.ishizaki import DesignInputs

__all__ = ["Sweep", "sweep", "SWEEPS", "policy_pair", "pendulums_of_groups"]

#: group -> default sweep range (log-spaced) and label
SWEEPS = {"alpha": ((1e-3, 0.3), "alpha = r2/r1"),
          "nu": ((0.05, 0.95), "nu = f2/f1"),
          "sigma2": ((0.05, 1.0), "sigma^2 = r1 omega1^2/g")}


@dataclass(frozen=True, eq=False)
class Sweep:
    """One sweep: ``values`` of ``group`` and the metrics (module docstring), each (n,)."""

    group: str
    values: np.ndarray
    design_value: float
    band_hz: tuple
    suppression_db: np.ndarray
    limit_db: np.ndarray
    alpha_db: np.ndarray
    translation_dev_db: np.ndarray
    notch_hz: np.ndarray
    notch_depth_db: np.ndarray
    modes_hz: np.ndarray

    def columns(self) -> dict:
        """CSV columns: name [unit] -> (n,) array."""
        return {self.group: self.values, "suppression_db": self.suppression_db,
                "limit_db": self.limit_db, "claim29_alpha_db": self.alpha_db,
                "translation_dev_db": self.translation_dev_db, "notch_hz": self.notch_hz,
                "notch_depth_db": self.notch_depth_db, "mode1_hz": self.modes_hz[:, 0],
                "mode2_hz": self.modes_hz[:, 1]}


def pendulums_of_groups(alpha, nu, sigma2, eps, f1_hz, *, total_mass_kg, q1, q2,
                        g_mps2) -> Pendulums:
    """Pendulums (l = r1) of the groups, each an array or scalar (the inverse of the paper's
    definitions, as :func:`rig.ishizaki.chain_from_design`)."""
    alpha, nu, s2, eps, f1 = np.broadcast_arrays(*(np.asarray(x, float) for x in
                                                   (alpha, nu, sigma2, eps, f1_hz)))
    w1 = 2 * np.pi * f1
    w2 = nu * w1
    r1 = s2 * g_mps2 / w1**2
    r2 = alpha * r1
    m = total_mass_kg
    m2 = m / eps
    m1 = m - m2
    j1 = np.maximum(m * r1 * (g_mps2 / w1**2 - r1), 0.0)
    j2 = m2 * r2 * (g_mps2 / w2**2 - r2)
    if np.any(j2 < 0):
        raise ConfigError("alpha sigma^2 nu^2 > 1 in the sweep: stage 2 would need J2 < 0")
    gam1 = 0.0 if math.isinf(q1) else g_mps2 * m * r1 / (w1 * q1)
    gam2 = 0.0 if math.isinf(q2) else g_mps2 * m2 * r2 / (w2 * q2)
    return Pendulums(m1, m2, r1, r1, r2, j1, j2, gam1 * np.ones_like(r1),
                     gam2 * np.ones_like(r1), g_mps2=g_mps2)


def _metrics(p: Pendulums, f1, f2, q1, band, alpha):
    n = len(p)
    grid = np.geomspace(*band, 200)
    with np.errstate(divide="ignore"):
        sup = -20 * np.log10(np.max(np.abs(p.rotation_ratio(grid)), axis=1))
    wide = np.geomspace(0.1 * np.min(f2), 10 * np.max(f1), 1500)
    x = p.translation(wide)
    w = 2 * np.pi * wide[None, :]
    d1, s1, g = p.d1[:, None], p.s1[:, None], p.g_mps2
    single = -p.l_m[:, None] * s1 / (g * s1 - w**2 * d1 + 1j * w * p.gamma1_nms[:, None])
    dev = np.max(np.abs(20 * np.log10(np.abs(x / single))), axis=1)
    nu2 = (f2 / f1) ** 2
    s2 = p.r1_m * (2 * np.pi * f1) ** 2 / g
    b2 = (p.l_m * p.s2) ** 2 / (p.d1 * p.d2)
    with np.errstate(divide="ignore"):
        lim = -20 * np.log10(np.abs(nu2 * (1 - s2) / (1 - b2 / s2)))
    fm, _ = p.modes()
    return dict(suppression_db=sup, limit_db=lim, alpha_db=-20 * np.log10(alpha) * np.ones(n),
                translation_dev_db=dev, notch_hz=p.notch_hz(), notch_depth_db=p.notch_depth_db(),
                modes_hz=fm)


def sweep(inputs: DesignInputs, group: str, *, values=None, points: int = 60,
          band_hz: tuple | None = None) -> Sweep:
    """Sweep ``group`` ("alpha", "nu" or "sigma2") around the design ``inputs`` (l = r1) with the
    other groups held (module docstring); ``values`` default to :data:`SWEEPS`' range."""
    if group not in SWEEPS:
        raise ConfigError(f"group = {group!r} is invalid: expected one of {', '.join(SWEEPS)}")
    if inputs.l_m is not None and inputs.l_m != inputs.r1_m:
        raise ConfigError("the sweeps assume l = r1 (O2 at G1)")
    g = inputs.g_mps2
    base = dict(alpha=inputs.r2_m / inputs.r1_m, nu=inputs.f2_hz / inputs.f1_hz,
                sigma2=inputs.r1_m * (2 * math.pi * inputs.f1_hz) ** 2 / g)
    lo, hi = SWEEPS[group][0]
    v = np.geomspace(lo, hi, points) if values is None else np.asarray(values, float)
    if group == "alpha":  # stage 2 needs alpha sigma^2 nu^2 <= 1
        v = v[v * base["sigma2"] * base["nu"] ** 2 <= 1]
    groups = {**base, group: v}
    p = pendulums_of_groups(groups["alpha"], groups["nu"], groups["sigma2"], inputs.eps,
                            inputs.f1_hz, total_mass_kg=inputs.total_mass_kg, q1=inputs.q1,
                            q2=inputs.q2, g_mps2=g)
    band = band_hz or (1.5 * inputs.f1_hz, 10 * inputs.f1_hz)
    f1 = np.full(len(p), inputs.f1_hz)
    f2 = groups["nu"] * f1
    m = _metrics(p, f1, f2, inputs.q1, band, np.broadcast_to(groups["alpha"], f1.shape))
    return Sweep(group=group, values=v, design_value=base[group], band_hz=tuple(band), **m)


def policy_pair(inputs: DesignInputs) -> tuple[DesignInputs, DesignInputs]:
    """The design as given (policy (i)) and its policy (ii) version: sigma^2 = 1 (r1 = g /
    omega1^2, J1 = 0) with alpha, nu, eps, f1 held (r2 scales with r1)."""
    import dataclasses

    r1 = inputs.g_mps2 / (2 * math.pi * inputs.f1_hz) ** 2
    ii = dataclasses.replace(inputs, r1_m=r1, r2_m=inputs.r2_m / inputs.r1_m * r1)
    return inputs, ii
