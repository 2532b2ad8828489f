"""The paper's relations as functions of the five independent design variables, and the bounds.

With l = r1 (O2 at G1) every design variable of :data:`rig.design.targets.VARIABLES` is a
monomial in ``u = ln(r1, r2, f1, f2, eps)`` (g fixed; :func:`monomial`)::

    alpha = r2/r1   nu = f2/f1   sigma^2 = r1 w1^2/g   beta^2 = alpha sigma^4 nu^2/eps
    mu = alpha/(eps nu^2)   delta = alpha sigma^2/eps          (w1 = 2 pi f1)

:func:`constraints` are the conditions a buildable design meets, each ``f(u) >= 0`` with a label
naming it: stated bounds, the default range the optimiser stays in (:data:`DEFAULT_BOX`; eps >
1 + 1e-6 is m1 > 0), and the rigid bodies' J1 >= j1_min (sigma^2 <= 1 for 0), J2 >= j2_min, in
logarithms. :func:`performance` evaluates the performance targets on the exact batched model.
"""

from __future__ import annotations

import math

import numpy as np

from rig.design.model import Pendulums
from rig.design.targets import VARIABLES, SuppressionTarget, Targets

__all__ = ["INDEPENDENT", "DEFAULT_BOX", "LN_BOX", "GRID", "monomial", "in_box", "physical_of",
           "performance_bands", "performance", "constraints", "constraint_values"]

INDEPENDENT = ("r1_m", "r2_m", "f1_hz", "f2_hz", "eps")
#: name -> exponents of (r1, r2, f1, f2, eps); the constant is (power of sigma^2) ln(4 pi^2/g)
EXPONENTS = {
    "r1_m": ((1, 0, 0, 0, 0), 0), "r2_m": ((0, 1, 0, 0, 0), 0), "f1_hz": ((0, 0, 1, 0, 0), 0),
    "f2_hz": ((0, 0, 0, 1, 0), 0), "eps": ((0, 0, 0, 0, 1), 0), "alpha": ((-1, 1, 0, 0, 0), 0),
    "nu": ((0, 0, -1, 1, 0), 0), "sigma2": ((1, 0, 2, 0, 0), 1), "beta2": ((1, 1, 2, 2, -1), 2),
    "mu": ((-1, 1, 2, -2, -1), 0), "delta": ((0, 1, 2, 0, -1), 1),
}
#: Bounds the optimiser never leaves (ln space), reported when they bind.
DEFAULT_BOX = {"r1_m": (1e-4, 10.0), "r2_m": (1e-7, 10.0), "f1_hz": (1e-3, 1e3),
                "f2_hz": (1e-3, 1e3), "eps": (1.0 + 1e-6, 100.0)}
GRID = 96  # log-spaced points per suppression band


def monomial(name: str, g_mps2: float) -> tuple[np.ndarray, float]:
    """(a, c) with ``ln(variable) = a . ln(r1, r2, f1, f2, eps) + c`` (l = r1)."""
    a, k = EXPONENTS[name]
    return np.asarray(a, float), k * math.log(4 * math.pi**2 / g_mps2)


#: (5, 2): ln of DEFAULT_BOX's low and high
LN_BOX = np.log(np.array(list(DEFAULT_BOX.values())))


def in_box(u):
    """``u`` clipped into the default range: where the model is evaluated while an optimiser
    explores outside it (the constraints still see the true ``u``)."""
    return np.clip(u, LN_BOX[:, 0], LN_BOX[:, 1])


def physical_of(u, targets: Targets) -> dict:
    """The :class:`Pendulums` parameters (SI, l = r1) of ``u`` and the targets' M, Q1, Q2, g."""
    r1, r2, f1, f2, eps = np.exp(u)
    g, m = targets.g_mps2, targets.total_mass_kg
    w1, w2 = 2 * math.pi * f1, 2 * math.pi * f2
    m2 = m / eps
    m1 = m - m2
    j1 = m * r1 * (g / w1**2 - r1)
    j2 = m2 * r2 * (g / w2**2 - r2)
    s1 = m * r1
    gam1 = 0.0 if math.isinf(targets.q1) else g * s1 / (w1 * targets.q1)
    gam2 = 0.0 if math.isinf(targets.q2) else g * m2 * r2 / (w2 * targets.q2)
    return dict(m1_kg=m1, m2_kg=m2, r1_m=r1, l_m=r1, r2_m=r2, j1_kgm2=max(j1, 0.0),
                j2_kgm2=max(j2, 0.0), gamma1_nms=gam1, gamma2_nms=gam2)


def performance_bands(targets: Targets, f1: float) -> list[tuple[SuppressionTarget, float, float]]:
    """(target, lo, hi) of every suppression band; without any performance target the default
    one, as much suppression as possible over 1.5 f1 .. 10 f1."""
    sup = list(targets.suppression)
    if not sup and not targets.translation:
        sup = [SuppressionTarget((1.5 * f1, 10.0 * f1), None)]
    return [(s, *s.band_hz) for s in sup]


def performance(p: Pendulums, targets: Targets, f1: float, *, per_point: bool = False):
    """The performance targets of ``targets`` on pendulum 0 of ``p``.

    Returns a list of (description, value [dB], limit [dB] or None, margins [dB]) with ``margins``
    the array over the band's grid (``per_point``) or its minimum.
    """
    out = []
    for s, lo, hi in performance_bands(targets, f1):
        grid = np.geomspace(lo, hi, GRID)
        fz = float(p.theta1_zero_hz()[0])
        if lo < fz < hi:  # Theta_1's zero (the ratio's peak) replaces its nearest point
            grid[np.argmin(np.abs(np.log(grid / fz)))] = fz
        with np.errstate(divide="ignore"):
            sup = -20 * np.log10(np.abs(p.rotation_ratio(grid)[0]))
        limit = s.min_db
        margins = sup - (limit if limit is not None else 0.0)
        what = f"rotation suppression -20 log10|theta2/theta1| over {lo:.4g}-{hi:.4g} Hz"
        if not targets.suppression:
            what += " (default band, no target)"
        out.append((what, float(sup.min()), limit, margins if per_point else float(margins.min())))
    for t in targets.translation:
        h = p.translation([t.freq_hz])[0, 0]
        if t.response == "isolation":
            h = 1 - (2 * math.pi * t.freq_hz) ** 2 * h
            what = f"translation isolation |x_abs/x0| at {t.freq_hz:g} Hz"
        else:
            what = f"translation |x/x0''| at {t.freq_hz:g} Hz [dB re 1 m/(m/s^2)]"
        db = float(20 * np.log10(abs(h)))
        ms = []
        if t.max_db is not None:
            ms.append(t.max_db - db)
        if t.min_db is not None:
            ms.append(db - t.min_db)
        limit = t.max_db if t.max_db is not None else t.min_db
        out.append((what, db, limit, np.asarray(ms) if per_point else float(min(ms))))
    return out


# -- constraints ------------------------------------------------------------------------------

def constraints(targets: Targets) -> list[tuple[str, callable]]:
    """(label, f(u) -> float >= 0) for every bound and rigid-body condition."""
    g, m = targets.g_mps2, targets.total_mass_kg
    out = []
    for name, v in targets.variables.items():
        a, c = monomial(name, g)
        unit = VARIABLES[name][0]
        u_s = "" if unit == "-" else f" {unit}"
        if v.lo is not None:
            out.append((f"{name} >= {v.lo:g}{u_s} (stated bound)",
                        lambda u, a=a, c=c, lo=math.log(v.lo): a @ u + c - lo))
        if v.hi is not None:
            out.append((f"{name} <= {v.hi:g}{u_s} (stated bound)",
                        lambda u, a=a, c=c, hi=math.log(v.hi): hi - a @ u - c))
    for i, name in enumerate(INDEPENDENT):
        lo, hi = DEFAULT_BOX[name]
        unit = VARIABLES[name][0]
        u_s = "" if unit == "-" else f" {unit}"
        what = "m1 > 0" if name == "eps" else "default range"
        shown_lo = "1 + 1e-6" if name == "eps" else f"{lo:g}"
        out.append((f"{name} >= {shown_lo}{u_s} ({what})",
                    lambda u, i=i, lo=math.log(lo): u[i] - lo))
        out.append((f"{name} <= {hi:g}{u_s} (default range)",
                    lambda u, i=i, hi=math.log(hi): hi - u[i]))
    a_s, c_s = monomial("sigma2", g)
    j1min, j2min = targets.j1_min_kgm2, targets.j2_min_kgm2

    def log1p_exp(x):  # ln(1 + e^x) without overflow
        return float(np.logaddexp(0.0, x))

    ln_j1, ln_j2 = (math.log(j / m) if j > 0 else None for j in (j1min, j2min))

    def j1(u):  # J1 = M r1^2 (1/sigma^2 - 1) >= j1min, as -ln sigma^2 - ln(1 + j1min/(M r1^2))
        extra = 0.0 if ln_j1 is None else log1p_exp(ln_j1 - 2 * u[0])
        return -(a_s @ u + c_s) - extra

    def j2(u):  # J2 = m2 r2^2 (g/(r2 w2^2) - 1) >= j2min, the same in logarithms
        extra = 0.0 if ln_j2 is None else log1p_exp(ln_j2 + u[4] - 2 * u[1])
        return -(u[1] + 2 * u[3] + c_s) - extra

    out.append((f"J1 >= {j1min:g} kg m^2 (sigma^2 <= {'1' if j1min == 0 else '1/(1 + J1min/(M r1^2))'}"
                ": a rigid stage 1)", j1))
    out.append((f"J2 >= {j2min:g} kg m^2 (r2 w2^2/g <= 1: a rigid stage 2)", j2))
    return out


def constraint_values(cons, u) -> np.ndarray:
    """Every constraint's value at ``u`` (>= 0: met)."""
    return np.array([f(u) for _, f in cons])


# -- the solve ----------------------------------------------------------------------------------
