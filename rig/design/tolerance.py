"""Tolerances: a Monte Carlo over the exact linear model, vectorised over the samples.

A tolerance file gives each physical parameter a distribution around the design's value::

    [tolerances]
    r2_m = { dist = "normal", abs = 20e-6 }      # machining: 1 sigma [m]
    l_m = { dist = "uniform", abs = 50e-6 }      # O2 off G1: half-width [m]
    m1_kg = { dist = "normal", rel = 0.005 }     # relative 1 sigma
    j1_kgm2 = { dist = "normal", rel = 0.02 }
    q1 = { dist = "lognormal", rel = 0.3 }       # sigma of ln Q (damping scatter)
    [accept]                                     # windows the coupled modes must fall in [Hz]
    f1_hz = [2.45, 2.51]                         # (the upper mode)
    f2_hz = [0.80, 0.86]                         # (the lower mode)

Parameters: :data:`TOLERANCED` (``l_m`` defaults to r1: O2 at G1; damping enters as Q, i.e.
``Gamma = Gamma_design Q_design / Q``). ``normal``: abs or rel is the standard deviation;
``uniform``: the half-width; ``lognormal``: ``rel`` is the standard deviation of the logarithm.

:func:`monte_carlo` draws N pendulums (``numpy.random.default_rng(seed)``, one parameter after
another in :data:`TOLERANCED` order) and evaluates them all at once (:class:`Pendulums`): the two
coupled modes, the suppression in each target band, the translation targets, the notch; the
yield is the fraction meeting every performance target and acceptance window (a sample that is
not a rigid body, e.g. J < 0, fails), with its Wilson 95 % interval. :func:`sensitivities`
ranks the parameters by ``|d output / d parameter| * spread`` (central differences on the same
batched model). :func:`evaluate_loop` is the plain one-at-a-time reference (``Chain`` per sample).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field

import numpy as np

from rig.validation import integer, number, positive, shown
from rig.design.model import Pendulums
from rig.design.relations import performance_bands
from rig.design.solve import Design
from rig.errors import ConfigError

__all__ = ["TOLERANCED", "Tolerance", "Tolerances", "parse_tolerances", "MonteCarlo",
           "monte_carlo", "evaluate", "evaluate_loop", "Sensitivity", "sensitivities",
           "samples_of"]

#: parameter -> (unit, what)
TOLERANCED = {"r1_m": ("m", "O1 to G1"), "l_m": ("m", "O1 to O2"), "r2_m": ("m", "O2 to G2"),
              "m1_kg": ("kg", "stage-1 mass"), "m2_kg": ("kg", "stage-2 mass"),
              "j1_kgm2": ("kg m^2", "stage-1 inertia about G1"),
              "j2_kgm2": ("kg m^2", "stage-2 inertia about G2"),
              "q1": ("-", "stage-1 quality factor"), "q2": ("-", "stage-2 quality factor")}
DISTRIBUTIONS = ("normal", "uniform", "lognormal")
_Z95 = 1.959963984540054


@dataclass(frozen=True)
class Tolerance:
    """One parameter's distribution: ``dist`` with spread ``abs`` (SI) or ``rel`` (fraction)."""

    name: str
    dist: str
    abs: float | None = None
    rel: float | None = None

    def spread(self, nominal: float) -> float:
        """The standard deviation [SI] of the parameter (uniform: half-width / sqrt 3)."""
        s = self.abs if self.abs is not None else self.rel * abs(nominal)
        if self.dist == "uniform":
            return s / math.sqrt(3)
        if self.dist == "lognormal":
            return abs(nominal) * math.sqrt(math.expm1(self.rel**2)) * math.exp(self.rel**2 / 2)
        return s

    def draw(self, rng, nominal: float, n: int) -> np.ndarray:
        if self.dist == "lognormal":
            return nominal * np.exp(self.rel * rng.standard_normal(n))
        s = self.abs if self.abs is not None else self.rel * abs(nominal)
        if self.dist == "uniform":
            return nominal + s * rng.uniform(-1.0, 1.0, n)
        return nominal + s * rng.standard_normal(n)


@dataclass(frozen=True)
class Tolerances:
    """A parsed tolerance file: ``items`` (name -> :class:`Tolerance`, in :data:`TOLERANCED`
    order) and ``accept`` (``"f1_hz"``/``"f2_hz"`` -> (lo, hi) [Hz])."""

    items: dict = field(default_factory=dict)
    accept: dict = field(default_factory=dict)


def parse_tolerances(text: str, *, source: str = "tolerances") -> Tolerances:
    """Parse a tolerance file's TOML text (module docstring); ConfigError names the bad key."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: invalid TOML: {exc}") from None
    extra = set(data) - {"tolerances", "accept"}
    if extra:
        raise ConfigError(f"{source}: unknown table [{sorted(extra)[0]}]: expected [tolerances] "
                          "and optionally [accept]")
    tol = data.get("tolerances")
    if not isinstance(tol, dict) or not tol:
        raise ConfigError(f"{source}: no [tolerances] table: expected one parameter or more of "
                          f"{', '.join(TOLERANCED)}")
    items = {}
    for name, spec in tol.items():
        if name not in TOLERANCED:
            raise ConfigError(f"unknown key tolerances.{name}; valid keys: "
                              f"{', '.join(TOLERANCED)}")
        items[name] = _tolerance(name, spec)
    accept = {}
    for key, win in data.get("accept", {}).items():
        if key not in ("f1_hz", "f2_hz"):
            raise ConfigError(f"unknown key accept.{key}; valid keys: f1_hz, f2_hz")
        if not (isinstance(win, list) and len(win) == 2):
            raise ConfigError(f"accept.{key} = {win!r} is invalid: expected [low, high] in Hz")
        lo, hi = (positive(f"accept.{key}", w, unit="Hz") for w in win)
        if hi <= lo:
            raise ConfigError(f"accept.{key} = {win!r} is invalid: expected low < high [Hz]")
        accept[key] = (lo, hi)
    order = [n for n in TOLERANCED if n in items]
    return Tolerances(items={n: items[n] for n in order}, accept=accept)


def _tolerance(name: str, spec) -> Tolerance:
    where = f"tolerances.{name}"
    if not isinstance(spec, dict):
        raise ConfigError(f"{where} = {spec!r} is invalid: expected a table like "
                          '{ dist = "normal", abs = 1e-5 } or { dist = "normal", rel = 0.01 }')
    for key in spec:
        if key not in ("dist", "abs", "rel"):
            raise ConfigError(f"unknown key {where}.{key}; valid keys: dist, abs, rel")
    dist = spec.get("dist", "normal")
    if dist not in DISTRIBUTIONS:
        raise ConfigError(f"{where}.dist = {shown(dist)} is invalid: expected one of "
                          f"{', '.join(DISTRIBUTIONS)}")
    if ("abs" in spec) == ("rel" in spec):
        raise ConfigError(f"{where} needs exactly one of abs (SI) and rel (a fraction)")
    if dist == "lognormal" and "rel" not in spec:
        raise ConfigError(f"{where}: a lognormal spread is rel (the standard deviation of ln)")
    if "abs" in spec:
        return Tolerance(name, dist, abs=positive(f"{where}.abs", spec["abs"],
                                                  unit=TOLERANCED[name][0]))
    return Tolerance(name, dist, rel=number(f"{where}.rel", spec["rel"], lo=0.0, lo_open=True,
                                            hi=1.0))


# -- sampling and evaluation --------------------------------------------------------------------

def _nominal(d: Design) -> dict:
    c = d.chain
    return {"r1_m": c.com_m[0], "l_m": c.length_m[0], "r2_m": c.com_m[1], "m1_kg": c.mass_kg[0],
            "m2_kg": c.mass_kg[1], "j1_kgm2": c.inertia_kgm2[0], "j2_kgm2": c.inertia_kgm2[1],
            "q1": d.inputs.q1, "q2": d.inputs.q2}


def _pendulums(d: Design, values: dict) -> Pendulums:
    """Pendulums of parameter values (arrays) with damping Gamma_design Q_design / Q."""
    c = d.chain
    g1 = c.damping_nms[0] * d.inputs.q1 / values["q1"] if math.isfinite(d.inputs.q1) else 0.0
    g2 = c.damping_nms[1] * d.inputs.q2 / values["q2"] if math.isfinite(d.inputs.q2) else 0.0
    return Pendulums(values["m1_kg"], values["m2_kg"], values["r1_m"], values["l_m"],
                     values["r2_m"], values["j1_kgm2"], values["j2_kgm2"], g1, g2,
                     g_mps2=c.g_mps2)


def samples_of(d: Design, tol: Tolerances, n: int, seed: int) -> dict:
    """N draws of every parameter (name -> (N,) array; untoleranced ones at the design's value)."""
    n = integer("samples", n, minimum=1)
    rng = np.random.default_rng(integer("seed", seed, minimum=0))
    nominal = _nominal(d)
    out = {k: np.full(n, float(v)) for k, v in nominal.items()}
    for name, t in tol.items.items():
        out[name] = t.draw(rng, float(nominal[name]), n)
    return out


def _outputs(d: Design):
    """(name, unit, band or target) of every evaluated output, in order."""
    outs = [("f_mode1_hz", "Hz", None), ("f_mode2_hz", "Hz", None), ("notch_hz", "Hz", None),
            ("notch_depth_db", "dB", None)]
    for i, (s, lo, hi) in enumerate(performance_bands(d.targets, d.inputs.f1_hz)):
        outs.append((f"suppression{i + 1}_db", "dB", (s, lo, hi)))
    for i, t in enumerate(d.targets.translation):
        outs.append((f"translation{i + 1}_db", "dB", t))
    return outs


def evaluate(d: Design, p: Pendulums, *, grid_points: int = 96) -> dict:
    """Every output (:func:`_outputs`) of N pendulums at once: name -> (N,) array."""
    fm, _ = p.modes()
    res = {"f_mode1_hz": fm[:, 0], "f_mode2_hz": fm[:, 1], "notch_hz": p.notch_hz(),
           "notch_depth_db": p.notch_depth_db()}
    for name, _, what in _outputs(d)[4:]:
        if name.startswith("suppression"):
            _, lo, hi = what
            ratio = np.abs(p.rotation_ratio(np.geomspace(lo, hi, grid_points)))
            with np.errstate(divide="ignore"):
                res[name] = -20 * np.log10(np.max(ratio, axis=1))
        else:
            h = p.translation([what.freq_hz])[:, 0]
            if what.response == "isolation":
                h = 1 - (2 * np.pi * what.freq_hz) ** 2 * h
            res[name] = 20 * np.log10(np.abs(h))
    return res


def evaluate_loop(d: Design, values: dict, *, grid_points: int = 96) -> dict:
    """:func:`evaluate`, one pendulum at a time through :class:`rig.chain.Chain` (its direct
    complex solve, its pencil eigenvalues, its bordered anti-resonance problem): the plain
    reference for tests and the benchmark."""
    p = _pendulums(d, values)
    outs = _outputs(d)
    res = {name: np.empty(len(p)) for name, *_ in outs}
    for i in range(len(p)):
        ch = p.chain(i)
        f, _ = ch.modes()
        res["f_mode1_hz"][i], res["f_mode2_hz"][i] = f[0], f[1]
        z = ch.antiresonances_hz([0.0, 1.0])
        res["notch_hz"][i] = z[0] if z.size else math.inf
        res["notch_depth_db"][i] = p.notch_depth_db()[i]  # a closed form (module model)
        for name, _, what in outs[4:]:
            if name.startswith("suppression"):
                _, lo, hi = what
                th = ch.frf_angles(np.geomspace(lo, hi, grid_points))
                res[name][i] = -20 * np.log10(np.max(np.abs(th[:, 1] / th[:, 0])))
            else:
                h = ch.frf_point([what.freq_hz], 0, ch.length_m[0])[0]
                if what.response == "isolation":
                    h = 1 - (2 * np.pi * what.freq_hz) ** 2 * h
                res[name][i] = 20 * np.log10(abs(h))
    return res


def _passes(d: Design, tol: Tolerances, res: dict, physical: np.ndarray) -> np.ndarray:
    ok = physical.copy()
    for name, _, what in _outputs(d)[4:]:
        v = res[name]
        if name.startswith("suppression") and what[0].min_db is not None:
            ok &= v >= what[0].min_db
        elif name.startswith("translation"):
            if what.max_db is not None:
                ok &= v <= what.max_db
            if what.min_db is not None:
                ok &= v >= what.min_db
    for key, col in (("f1_hz", "f_mode2_hz"), ("f2_hz", "f_mode1_hz")):
        if key in tol.accept:
            lo, hi = tol.accept[key]
            ok &= (res[col] >= lo) & (res[col] <= hi)
    return ok


@dataclass(frozen=True, eq=False)
class MonteCarlo:
    """A Monte Carlo's draws and results.

    Attributes
    ----------
    samples : parameter -> (N,) draws. outputs : output -> (N,) values (units in ``units``).
    physical : (N,) rigid-body samples. passed : (N,) every target and window met.
    yield_ : passed fraction; yield_ci : its Wilson 95 % interval. seed : the generator's seed.
    """

    samples: dict
    outputs: dict
    units: dict
    physical: np.ndarray
    passed: np.ndarray
    yield_: float
    yield_ci: tuple
    seed: int

    def summary(self) -> dict:
        """output -> {mean, std, p5, p50, p95} over the physical samples."""
        out = {}
        ok = self.physical
        for k, v in self.outputs.items():
            x = v[ok & np.isfinite(v)]
            if x.size:
                p5, p50, p95 = np.percentile(x, [5, 50, 95])
                out[k] = {"mean": float(x.mean()), "std": float(x.std()), "p5": float(p5),
                          "p50": float(p50), "p95": float(p95), "finite": int(x.size)}
            else:
                out[k] = {"finite": 0}
        return out


def _wilson(k: int, n: int) -> tuple[float, float]:
    p = k / n
    den = 1 + _Z95**2 / n
    mid = (p + _Z95**2 / (2 * n)) / den
    half = _Z95 * math.sqrt(p * (1 - p) / n + _Z95**2 / (4 * n * n)) / den
    return max(0.0, mid - half), min(1.0, mid + half)


def monte_carlo(d: Design, tol: Tolerances, *, samples: int, seed: int = 0) -> MonteCarlo:
    """N draws of the tolerances around design ``d``, evaluated at once (module docstring)."""
    values = samples_of(d, tol, samples, seed)
    nominal = _nominal(d)
    q_ok = (values["q1"] > 0) & (values["q2"] > 0)  # a drawn Q <= 0 is no pendulum
    p = _pendulums(d, {k: np.where(q_ok, v, nominal[k]) for k, v in values.items()})
    physical = p.physical & q_ok
    safe = _pendulums(d, {k: np.where(physical, v, nominal[k]) for k, v in values.items()})
    res = evaluate(d, safe)
    for k in res:  # a non-rigid sample has no outputs
        res[k] = np.where(physical, res[k], np.nan)
    passed = _passes(d, tol, res, physical)
    k = int(passed.sum())
    return MonteCarlo(samples=values, outputs=res, units={n: u for n, u, _ in _outputs(d)},
                      physical=physical, passed=passed, yield_=k / samples,
                      yield_ci=_wilson(k, samples), seed=seed)


@dataclass(frozen=True)
class Sensitivity:
    """d output / d parameter at the design [output unit per SI unit], the parameter's spread
    (its standard deviation) and their product, the output's linearised spread from it."""

    output: str
    parameter: str
    derivative: float
    spread: float
    contribution: float


def sensitivities(d: Design, tol: Tolerances, *, step: float = 1e-5) -> dict[str, list]:
    """output -> [:class:`Sensitivity`], largest ``|contribution|`` first: central differences
    (relative ``step`` of each parameter's value, or of r1 for ``l_m``) in one batch."""
    nominal = _nominal(d)
    names = list(tol.items)
    cols = {k: [float(v)] for k, v in nominal.items()}
    hs = []
    for name in names:
        h = step * (abs(nominal[name]) if nominal[name] else nominal["r1_m"])
        hs.append(h)
        for sign in (1, -1):
            for k in cols:
                cols[k].append(float(nominal[k]) + (sign * h if k == name else 0.0))
    res = evaluate(d, _pendulums(d, {k: np.asarray(v) for k, v in cols.items()}))
    out = {}
    for o, vals in res.items():
        rows = []
        for i, name in enumerate(names):
            dv = (vals[1 + 2 * i] - vals[2 + 2 * i]) / (2 * hs[i])
            if not math.isfinite(dv):
                continue
            sp = tol.items[name].spread(float(nominal[name]))
            rows.append(Sensitivity(o, name, float(dv), sp, float(abs(dv) * sp)))
        out[o] = sorted(rows, key=lambda r: -r.contribution)
    return out
