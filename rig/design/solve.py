"""From targets to a design: the paper's relations solved exactly, the rest optimised on the exact model.

With l = r1 every design variable is a monomial in ``u = ln(r1, r2, f1, f2, eps)``
(:mod:`rig.design.relations`), so the fixed targets are linear equations ``A u = b`` in
logarithms. :func:`design` solves them:

1. exactly (``lstsq``; the part of ``u`` they leave free is taken from the paper's design). An
   over-determined set is fitted by weighted least squares, each equation weighted by its
   tolerance; if it is then inconsistent, the one target whose removal leaves the others
   consistent to their tolerance is reported as inconsistent (with the value the rest imply)
   and left out (the paper's table: mu).
2. If that violates a bound or a rigid body's J1 >= j1_min (sigma^2 <= 1 for J1 = 0), J2 >= j2_min
   or m1 > 0: the nearest feasible design in the same weighted sense (SLSQP), naming the binding
   constraints and the targets it misses.
3. Policy (ii) adds sigma^2 = 1, i.e. J1 = 0 (stage 1's mass at G1), solved exactly along what
   the targets leave free; with ``j1_min_kgm2 > 0``, or targets that fix sigma^2, it cannot be
   met and the nearest design is returned with that statement.
4. Directions still free are optimised against the performance targets on the exact linear
   model (:class:`rig.design.model.Pendulums`): first the worst margin is maximised (its optimum
   says what limits the design); if every target can be met with ``margin_db``, the design
   closest to the paper's that keeps that margin is returned (for a target asking for as much
   as possible: the closest within 0.1 dB of the best). Without any performance target the free
   variables keep the paper's design's values, and the report says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import null_space
from scipy.optimize import minimize

from rig.chain import Chain
from rig.design.model import Pendulums
from rig.design.relations import (
    INDEPENDENT, LN_BOX, constraint_values, constraints, in_box, monomial,
    performance, performance_bands, physical_of)
from rig.design.targets import Targets
from rig.errors import ConfigError
from rig.ishizaki import FITTED_DESIGN, DesignInputs, DesignParameters, design_parameters

__all__ = ["Design", "TargetCheck", "PerformanceCheck", "design", "pendulums_of"]

_POLICY_II_TOL = 1e-6  # relative: sigma^2 = 1 to 1 ppm
_ACTIVE = 1e-6


@dataclass(frozen=True)
class TargetCheck:
    """One fixed target: ``wanted`` and ``tol`` as stated, ``got`` by the design, ``residual``
    (got - wanted)/tol; ``status`` "met", "missed" or "inconsistent" (then ``implied`` is the
    value the other targets imply)."""

    name: str
    wanted: float
    tol: float
    got: float
    residual: float
    status: str
    implied: float | None = None


@dataclass(frozen=True)
class PerformanceCheck:
    """One performance target: what, its value [dB], its limit [dB], margin [dB] (>= 0: met)."""

    what: str
    value_db: float
    limit_db: float | None
    margin_db: float

    @property
    def met(self) -> bool:
        """No limit (as much as possible) or a margin >= 0 (to 1e-6 dB)."""
        return self.limit_db is None or self.margin_db >= -1e-6


@dataclass(frozen=True, eq=False)
class Design:
    """A design and how it stands against its targets (SI; see :func:`design`).

    Attributes
    ----------
    targets : the targets it was made from.
    inputs : the paper's design numbers (r1, r2, f1, f2, eps, M, Q1, Q2) -> ``chain``.
    chain : the 2-body pendulum (l = r1, absolute damping).
    params : alpha, beta^2, delta, eps, mu, nu, sigma^2, zeta_i ... (:class:`DesignParameters`).
    modes_hz, modes_q : the coupled damped modes (exact), ascending.
    notch_hz, notch_depth_db : the Theta_2 notch (``inf`` / ``nan`` where none).
    checks : every fixed target. performance : every performance target.
    binding : the constraints that hold the design where it is (text).
    optimised : the independent variables the optimiser set (the targets left them free).
    status : "met" (every consistent target met) or "nearest" (the nearest feasible design).
    notes : statements for the designer (what cannot be met and why, policy (ii) ...).
    """

    targets: Targets
    inputs: DesignInputs
    chain: Chain
    params: DesignParameters
    modes_hz: tuple
    modes_q: tuple
    notch_hz: float
    notch_depth_db: float
    checks: tuple
    performance: tuple
    binding: tuple
    optimised: tuple
    status: str
    notes: tuple

    @property
    def inconsistent(self) -> tuple:
        """The checks reported as inconsistent with the other targets."""
        return tuple(c for c in self.checks if c.status == "inconsistent")


# -- the exact model of one u ------------------------------------------------------------------

def pendulums_of(inputs: DesignInputs) -> Pendulums:
    """The one pendulum of ``inputs`` (l = r1 or its l_m) for the batched model."""
    return Pendulums.from_chain(inputs.chain())


def _equations(targets: Targets, skip=()):
    rows = []
    g = targets.g_mps2
    for name, v in targets.fixed().items():
        if name in skip:
            continue
        a, c = monomial(name, g)
        rows.append((name, a, c, math.log(v.value), v.tol / v.value))
    return rows


def _lstsq(rows, u_ref):
    if not rows:
        return u_ref.copy()
    a = np.array([r[1] / r[4] for r in rows])
    b = np.array([(r[3] - r[2]) / r[4] for r in rows])
    return u_ref + np.linalg.lstsq(a, b - a @ u_ref, rcond=None)[0]


def _residuals(rows, u):
    return np.array([(r[1] @ u + r[2] - r[3]) / r[4] for r in rows])


def _rank(rows):
    return int(np.linalg.matrix_rank(np.array([r[1] for r in rows]))) if rows else 0


def _find_inconsistent(rows, u_ref):
    """The one row whose removal leaves the others consistent, or None."""
    u = _lstsq(rows, u_ref)
    res = _residuals(rows, u)
    if np.all(np.abs(res) <= 1 + 1e-9):
        return None, u
    rank = _rank(rows)
    for k in np.argsort(-np.abs(res)):
        rest = rows[:k] + rows[k + 1:]
        if _rank(rest) != rank:
            continue
        u2 = _lstsq(rest, u_ref)
        if np.all(np.abs(_residuals(rest, u2)) <= 1 + 1e-9):
            return int(k), u2
    return None, u


def _slsqp(fun, x0, cons_fun, **kw):
    return minimize(fun, x0, method="SLSQP", constraints=[{"type": "ineq", "fun": cons_fun}],
                    options={"maxiter": 300, "ftol": 1e-12}, **kw)


def design(targets: Targets) -> Design:
    """The design of ``targets`` (module docstring): exact where the targets determine it,
    optimised on the exact linear model where they do not, the nearest feasible design where
    they cannot all be met. Never returns a non-finite design; ConfigError if none exists."""
    u_ref = np.log([FITTED_DESIGN.r1_m, FITTED_DESIGN.r2_m, FITTED_DESIGN.f1_hz,
                    FITTED_DESIGN.f2_hz, FITTED_DESIGN.eps])
    notes = []
    rows = _equations(targets)
    bad, u = _find_inconsistent(rows, u_ref)
    excluded = {}
    if bad is not None:
        name = rows[bad][0]
        excluded[name] = math.exp(rows[bad][1] @ u + rows[bad][2])
        rows = rows[:bad] + rows[bad + 1:]
    cons = constraints(targets)
    if np.min(constraint_values(cons, u)) < 0:  # the exact solution is not buildable: nearest one
        def misfit(x):
            return float(np.sum(_residuals(rows, x) ** 2)) if rows else 0.0

        best = None
        for start in (np.clip(u, LN_BOX[:, 0], LN_BOX[:, 1]), u_ref,
                      np.clip(u, LN_BOX[:, 0] + 1e-3, LN_BOX[:, 1] - 1e-3)):
            scale = max(misfit(start), 1.0)
            r = _slsqp(lambda x, s=scale: misfit(x) / s, start, lambda x: constraint_values(cons, x),
                       bounds=list(map(tuple, LN_BOX)))
            if np.min(constraint_values(cons, r.x)) > -1e-9 and (best is None or
                                                        misfit(r.x) < misfit(best.x)):
                best = r
        if best is None:
            raise ConfigError(f"{targets.source}: no buildable design satisfies the bounds "
                              "together (J1 >= j1_min, J2 >= j2_min, stated min/max): loosen one")
        u = best.x
    if targets.policy == "ii":
        u, row, note = _policy_ii(u, rows, cons, targets)
        rows = rows + [row] if row is not None else rows
        notes.append(note)
    a_used = np.array([r[1] for r in rows]) if rows else np.zeros((0, 5))
    basis = null_space(a_used) if rows else np.eye(5)
    optimised = tuple(INDEPENDENT[i] for i in range(5) if np.any(np.abs(basis[i]) > 1e-9))
    if basis.shape[1] and not (targets.suppression or targets.translation):
        notes.append(f"{', '.join(optimised)} left free without a performance target: taken "
                     "from the paper's design (the nearest to it that meets the targets)")
        optimised = ()
    elif basis.shape[1]:
        u, opt_notes = _optimise(u, basis, targets, cons, u_ref)
        notes += opt_notes
    u = _snap(u, targets)
    return _assemble(u, targets, rows, excluded, cons, optimised, notes)


def _policy_ii(u, rows, cons, targets):
    """Bring sigma^2 to 1 (J1 = 0) along what the targets leave free, or as near as the bounds
    allow; returns (u, the row that now fixes sigma^2 or None, a note)."""
    a_s, c_s = monomial("sigma2", targets.g_mps2)
    a_used = np.array([r[1] for r in rows]) if rows else np.zeros((0, 5))
    if rows and _rank(rows) == np.linalg.matrix_rank(np.vstack([a_used, a_s])):
        s2 = math.exp(a_s @ u + c_s)
        return u, None, (f"policy (ii) needs sigma^2 = 1 but the fixed targets determine "
                         f"sigma^2 = r1 (2 pi f1)^2/g = {s2:.6g}: leave one of them free")
    exact = _lstsq(rows + [("policy (ii)", a_s, c_s, 0.0, _POLICY_II_TOL)], u)
    if np.min(constraint_values(cons, _snap(exact, targets))) > -1e-12:
        u = _snap(exact, targets)
    else:  # J1 >= j1_min > 0: sigma^2 as near 1 as the bound allows, the targets kept
        b_used = a_used @ u

        def eq(x):
            return a_used @ x - b_used

        r = minimize(lambda x: float((a_s @ x + c_s) ** 2) * 1e4, u, method="SLSQP",
                     constraints=[{"type": "ineq", "fun": lambda x: constraint_values(cons, x)}]
                     + ([{"type": "eq", "fun": eq}] if rows else []),
                     options={"maxiter": 300, "ftol": 1e-16})
        if np.min(constraint_values(cons, r.x)) > -1e-9 and (not rows or np.max(np.abs(eq(r.x))) < 1e-9):
            u = r.x
    s2 = math.exp(a_s @ u + c_s)
    row = ("policy (ii)", a_s, c_s, a_s @ u + c_s, _POLICY_II_TOL)
    if abs(s2 - 1) <= _POLICY_II_TOL:
        return u, row, ("policy (ii): sigma^2 = 1 means J1 = 0, stage 1 a point mass at G1 (set "
                        "j1_min_kgm2 for a real body); the Theta_2 notch is at infinity and "
                        "|theta2/theta1| falls as f^-2 above f1 (as f^-1 beyond ~Q1 f1)")
    return u, row, (f"policy (ii) needs sigma^2 = 1, i.e. J1 = 0 (all of stage 1's mass at G1); "
                    f"with J1 >= {targets.j1_min_kgm2:g} kg m^2 and the other targets, sigma^2 = "
                    f"{s2:.6g} is the nearest, so the Theta_2 notch stays at a finite frequency")


def _margins_of(u, targets, per_point):
    u = in_box(u)
    p = Pendulums(**physical_of(u, targets), g_mps2=targets.g_mps2)
    return performance(p, targets, math.exp(u[2]), per_point=per_point)


def _optimise(u0, basis, targets, cons, u_ref):
    """Maximise the worst performance margin over ``u0 + basis z``; then, if every target keeps
    ``margin_db``, the design closest to the paper's that keeps it."""
    k = basis.shape[1]

    def u_of(z):
        return u0 + basis @ z

    def margins(z):
        return np.concatenate([np.atleast_1d(m) for *_, m in
                               _margins_of(u_of(z), targets, per_point=True)])

    def feasible(z):
        return constraint_values(cons, u_of(z))

    t0 = float(np.min(margins(np.zeros(k))))
    x0 = np.append(np.zeros(k), t0)
    a = _slsqp(lambda x: -x[-1], x0,
               lambda x: np.concatenate([margins(x[:-1]) - x[-1], feasible(x[:-1])]),
               bounds=[(None, None)] * k + [(None, 300.0)])
    z = a.x[:-1] if np.min(feasible(a.x[:-1])) > -1e-9 else np.zeros(k)
    worst = float(np.min(margins(z)))
    notes = []
    if worst < float(np.min(margins(np.zeros(k)))) - 1e-9:  # the optimiser did not improve
        z = np.zeros(k)
        worst = float(np.min(margins(z)))
    maximise = any(s.min_db is None for s, *_ in performance_bands(targets, math.exp(u_of(z)[2])))
    cap = worst - 0.1 if maximise else targets.margin_db
    if maximise or worst >= cap:
        b = _slsqp(lambda zz: float(np.sum((u_of(zz) - u_ref) ** 2)), z,
                   lambda zz: np.concatenate([margins(zz) - cap, feasible(zz)]))
        if b.success and np.min(margins(b.x)) >= cap - 1e-6 and np.min(feasible(b.x)) > -1e-9:
            z = b.x
            if maximise:
                notes.append(f"the worst margin is at most {worst:.3g} dB; the design is the one "
                             "closest to the paper's within 0.1 dB of that")
            else:
                notes.append(f"every performance target can be met with {cap:g} dB margin; the "
                         "design is the one closest to the paper's (in ln r1, r2, f1, f2, eps) "
                         f"that keeps it (the most the free variables allow: {worst:.3g} dB)")
    elif not maximise and worst >= 0:
        notes.append(f"every performance target is met, with {worst:.3g} dB at most "
                     f"(less than margin_db = {cap:g} dB)")
    return u_of(z), notes


def _snap(u, targets):
    """Undo an optimiser's round-off across J1 >= 0 / J2 >= 0 (sigma^2 <= 1 by 1e-9)."""
    u = u.copy()
    a_s, c_s = monomial("sigma2", targets.g_mps2)
    over = a_s @ u + c_s
    if targets.j1_min_kgm2 == 0 and 0 < over < 1e-7:
        u[0] -= over  # r1 -> g / w1^2 exactly
    over2 = u[1] + 2 * u[3] + c_s
    if targets.j2_min_kgm2 == 0 and 0 < over2 < 1e-7:
        u[1] -= over2
    return u


def _degeneracies(p: DesignParameters, modes_hz, targets: Targets) -> list[str]:
    """Statements for a design near the paper's hard cases (SPEC section 7)."""
    out = []
    if 1 - p.beta2 < 1e-3:
        out.append(f"beta^2 = {p.beta2:.6g} -> 1: the mass matrix is nearly singular (det H / "
                   f"(D1 I2) = 1 - beta^2 = {1 - p.beta2:.3g}); the upper mode goes to "
                   f"{modes_hz[1]:.4g} Hz as the two stages lock together (beta^2 <= 1/eps "
                   "always, so this needs m1 << m2, sigma^2 -> 1 and r2 omega2^2/g -> 1)")
    if abs(p.nu - 1) < 0.05:
        out.append(f"nu = {p.nu:.6g} ~ 1: the stages' frequencies coincide, the modes split to "
                   f"{modes_hz[0]:.4g} and {modes_hz[1]:.4g} Hz through the coupling (beta) and "
                   "policy (i)'s omega2 << omega1 is not met")
    elif p.nu > 1:
        out.append(f"nu = {p.nu:.4g} > 1: stage 2 is stiffer than stage 1, against policy (i) "
                   "(omega2 << omega1)")
    if targets.policy == "i" and 1 - p.sigma2 < 1e-6:
        out.append(f"sigma^2 = {p.sigma2:.9g} ~ 1: J1 ~ 0, the Theta_2 notch moves to infinity "
                   "(the closed forms (20), (21) divide by ~0; the exact model does not)")
    return out


def _assemble(u, targets, rows, excluded, cons, optimised, notes) -> Design:
    r1, r2, f1, f2, eps = (float(x) for x in np.exp(u))
    leq1 = targets.g_mps2 / (2 * math.pi * f1) ** 2
    if abs(r1 / leq1 - 1) < 1e-12 and targets.j1_min_kgm2 == 0:
        r1 = leq1  # sigma^2 = 1 to round-off: J1 = 0 exactly (no notch at 1e8 Hz from 1 ulp)
    inputs = DesignInputs(r1_m=r1, r2_m=r2, f1_hz=f1, f2_hz=f2, eps=eps,
                          total_mass_kg=targets.total_mass_kg, q1=targets.q1, q2=targets.q2,
                          g_mps2=targets.g_mps2)
    chain = inputs.chain()
    params = design_parameters(chain)
    p = Pendulums.from_chain(chain)
    fm, qm = p.modes()
    checks = []
    for name, v in targets.fixed().items():
        got = float(getattr(params, {"r1_m": "r1", "r2_m": "r2"}.get(name, name)))
        res = (got - v.value) / v.tol
        if name in excluded:
            checks.append(TargetCheck(name, v.value, v.tol, got, res, "inconsistent",
                                      excluded[name]))
        else:
            checks.append(TargetCheck(name, v.value, v.tol, got, res,
                                      "met" if abs(res) <= 1 + 1e-6 else "missed"))
    if targets.policy == "ii":
        s2 = params.sigma2
        ok = abs(s2 - 1) <= _POLICY_II_TOL
        checks.append(TargetCheck("sigma2 (policy ii)", 1.0, _POLICY_II_TOL, s2,
                                  (s2 - 1) / _POLICY_II_TOL, "met" if ok else "missed"))
    perf = tuple(PerformanceCheck(w, v, lim, m) for w, v, lim, m in
                 performance(p, targets, f1, per_point=False))
    notes += _degeneracies(params, fm[0], targets)
    if targets.total_mass_free:
        notes.append("total_mass_kg free: no response depends on it (with l = r1 it scales the "
                     "masses, inertias and damping together); 0.1 kg taken")
    binding = [label for label, f in cons if f(u) <= _ACTIVE]
    if optimised and perf:
        worst = min(perf, key=lambda c: c.margin_db)
        binding.append(f"{worst.what}: margin {worst.margin_db:.3g} dB")
    met = all(c.status != "missed" for c in checks) and all(c.met for c in perf)
    for c in checks:
        if c.status == "inconsistent":
            notes.insert(0, f"{c.name} = {c.wanted:g} is inconsistent with the other targets, "
                         f"which imply {c.name} = {c.implied:.4g} ({(c.wanted - c.implied) / c.tol:+.0f}"
                         " of its half-units): left out of the fit")
        elif c.status == "missed":
            notes.append(f"{c.name} = {c.wanted:g} not met: the design has {c.got:.6g} "
                         f"({c.residual:+.3g} of its tolerance {c.tol:g})")
    for c in perf:
        if not c.met:
            notes.append(f"{c.what}: {c.value_db:.3g} dB misses {c.limit_db:g} dB by "
                         f"{-c.margin_db:.3g} dB")
    return Design(targets=targets, inputs=inputs, chain=chain, params=params,
                  modes_hz=tuple(float(x) for x in fm[0]), modes_q=tuple(float(x) for x in qm[0]),
                  notch_hz=float(p.notch_hz()[0]), notch_depth_db=float(p.notch_depth_db()[0]),
                  checks=tuple(checks), performance=perf, binding=tuple(binding),
                  optimised=optimised, status="met" if met else "nearest", notes=tuple(notes))
