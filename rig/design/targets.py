"""A designer's targets: what is fixed, what is free, what is bounded and what must be achieved.

A targets file is TOML with a ``[targets]`` table (:func:`parse_targets` takes its text)::

    [targets]
    policy = "i"              # "i": omega2 << omega1, alpha << 1; "ii": also sigma^2 = 1 (J1 = 0)
    f1_hz = 2.48              # a number fixes a design variable ...
    f2_hz = "free"            # ... "free" leaves it to the optimiser (so does leaving it out)
    alpha = { max = 0.05 }    # ... a table bounds it ({min, max}) or states its tolerance
    eps = { value = 2.13, tol = 0.01 }   # ({value, tol}: tol absolute)
    r1_m = 0.029
    r2_min_m = 0.0005         # geometric bounds: r1_min_m, r1_max_m, r2_min_m, r2_max_m
    total_mass_kg = 0.100     # only scales masses, inertias, damping
    q1 = 530                  # quality factors (the paper's fitted 530 and 100 by default)
    margin_db = 3             # performance margin asked for once every target can be met

    [[targets.suppression]]   # |theta2/theta1| at most -min_db dB over the band
    band_hz = [3.0, 10.0]
    min_db = 30
    [[targets.translation]]   # the mirror's translation x per stage acceleration at freq_hz
    freq_hz = 5.0             # [dB re 1 m/(m/s^2)], or response = "isolation": |x_abs / x0|
    max_db = -40

The design variables are the paper's (l = r1, O2 at G1): ``r1_m, r2_m, f1_hz, f2_hz, eps`` and
the groups they determine, ``alpha, beta2, nu, sigma2, mu, delta`` (:data:`VARIABLES`). A fixed
number's tolerance, used only to judge an over-determined set, is half a unit of its last digit
as written in the file (``0.029`` -> 0.0005). Optional ``[design]`` table: ``name``,
``description``, ``base`` (the scene the designed one inherits its bench from; default
"ishizaki2009").
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field

from rig.validation import number, positive, shown
from rig.chain import G_STANDARD
from rig.errors import ConfigError

__all__ = ["VARIABLES", "VariableTarget", "SuppressionTarget", "TranslationTarget", "Targets",
           "parse_targets", "targets_from_data", "POLICIES", "RESPONSES"]

#: Design variable -> (unit, what it is). The first five are the independent ones (l = r1).
VARIABLES = {
    "r1_m": ("m", "O1 to G1 (= l, O1 to O2)"),
    "r2_m": ("m", "O2 to G2"),
    "f1_hz": ("Hz", "stage-1 frequency omega1/2pi"),
    "f2_hz": ("Hz", "stage-2 frequency omega2/2pi"),
    "eps": ("-", "1 + m1/m2"),
    "alpha": ("-", "r2/r1"),
    "nu": ("-", "omega2/omega1"),
    "sigma2": ("-", "r1 omega1^2/g"),
    "beta2": ("-", "(m2 l r2)^2/((I1 + m2 l^2) I2)"),
    "mu": ("-", "I2/(I1 + m2 l^2)"),
    "delta": ("-", "m2 l r2/(I1 + m2 l^2)"),
}
POLICIES = ("i", "ii")
RESPONSES = ("x", "isolation")
_BOUND_KEYS = {"r1_min_m": ("r1_m", "min"), "r1_max_m": ("r1_m", "max"),
               "r2_min_m": ("r2_m", "min"), "r2_max_m": ("r2_m", "max")}
_SCALARS = {"policy", "total_mass_kg", "q1", "q2", "g_mps2", "margin_db", "j1_min_kgm2",
            "j2_min_kgm2", "suppression", "translation"}
_VALUE_FORMS = ('a number (fixed), "free", {min = .., max = ..} (bounds) or '
                '{value = .., tol = ..}')


@dataclass(frozen=True)
class VariableTarget:
    """What the targets say of one design variable (SI, the unit of :data:`VARIABLES`).

    ``value`` fixes it (with absolute tolerance ``tol``); ``None`` leaves it free, within
    ``lo`` .. ``hi`` (``None``: unbounded).
    """

    name: str
    value: float | None = None
    tol: float | None = None
    lo: float | None = None
    hi: float | None = None

    @property
    def fixed(self) -> bool:
        return self.value is not None


@dataclass(frozen=True)
class SuppressionTarget:
    """Rotation suppression: ``-20 log10 max |theta2/theta1|`` over ``band_hz`` >= ``min_db``
    [dB] (``None``: as much as possible)."""

    band_hz: tuple[float, float]
    min_db: float | None = None


@dataclass(frozen=True)
class TranslationTarget:
    """The mirror's translation at ``freq_hz`` [Hz]: ``response`` "x" is ``|x / x0''|`` [dB re
    1 m/(m/s^2)] (the measured channel), "isolation" ``|x_abs / x0|`` [dB]; within
    ``min_db`` .. ``max_db`` (either may be ``None``)."""

    freq_hz: float
    min_db: float | None = None
    max_db: float | None = None
    response: str = "x"


@dataclass(frozen=True)
class Targets:
    """A parsed targets file (see the module docstring); every value checked."""

    variables: dict = field(default_factory=dict)  # name -> VariableTarget, every VARIABLES key
    policy: str = "i"
    total_mass_kg: float = 0.1
    total_mass_free: bool = False
    q1: float = 530.0
    q2: float = 100.0
    g_mps2: float = G_STANDARD
    margin_db: float = 3.0
    j1_min_kgm2: float = 0.0
    j2_min_kgm2: float = 0.0
    suppression: tuple = ()
    translation: tuple = ()
    name: str = "designed"
    description: str = ""
    base: str = "ishizaki2009"
    source: str = "targets"

    def fixed(self) -> dict:
        """The fixed variables, name -> VariableTarget."""
        return {k: v for k, v in self.variables.items() if v.fixed}


# -- parsing -----------------------------------------------------------------------------------

_NUMBER = re.compile(r"^\s*([A-Za-z0-9_]+)\s*=\s*([-+]?[0-9_]*\.?[0-9_]*(?:[eE][-+]?[0-9_]+)?)"
                     r"\s*(?:#.*)?$")


def _half_units(text: str) -> dict[str, float]:
    """key -> half a unit of the last digit of its number as written (``2.48`` -> 0.005)."""
    out = {}
    for line in text.splitlines():
        m = _NUMBER.match(line)
        if m and m.group(2) and any(c.isdigit() for c in m.group(2)):
            out[m.group(1)] = _half_unit_of(m.group(2))
    return out


def _half_unit_of(token: str) -> float:
    t = token.replace("_", "").lstrip("+-")
    mant, _, exp = t.lower().partition("e")
    decimals = len(mant.partition(".")[2])
    return 0.5 * 10.0 ** ((int(exp) if exp else 0) - decimals)


def parse_targets(text: str, *, source: str = "targets") -> Targets:
    """Parse a targets file's TOML text (module docstring); ConfigError names a bad key or value
    and what is valid."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: invalid TOML: {exc}") from None
    return targets_from_data(data, half_units=_half_units(text), source=source)


def targets_from_data(data: dict, *, half_units: dict | None = None,
                      source: str = "targets") -> Targets:
    """:func:`parse_targets` of already-parsed TOML data; a fixed number's tolerance is
    ``half_units[key]`` if given, else half a unit of the last digit of its shortest repr."""
    half_units = half_units or {}
    unknown = set(data) - {"targets", "design"}
    if unknown:
        raise ConfigError(f"{source}: unknown table [{sorted(unknown)[0]}]: expected [targets] "
                          "and optionally [design]")
    t = data.get("targets")
    if not isinstance(t, dict):
        raise ConfigError(f"{source}: no [targets] table: expected one naming what is fixed and "
                          f"what is free ({', '.join(VARIABLES)})")
    valid = sorted(set(VARIABLES) | set(_BOUND_KEYS) | _SCALARS)
    for key in t:
        if key not in valid:
            raise ConfigError(f"{source}: unknown key targets.{key}; valid keys: "
                              f"{', '.join(valid)}")
    variables = {k: _variable(k, t.get(k, "free"), half_units.get(k)) for k in VARIABLES}
    for key, (var, side) in _BOUND_KEYS.items():
        if key in t:
            bound = positive(f"targets.{key}", t[key], unit="m")
            v = variables[var]
            lo, hi = (bound, v.hi) if side == "min" else (v.lo, bound)
            variables[var] = VariableTarget(var, v.value, v.tol,
                                            _tighter(lo, v.lo, max), _tighter(hi, v.hi, min))
    for v in variables.values():
        if v.lo is not None and v.hi is not None and v.lo > v.hi:
            raise ConfigError(f"targets.{v.name}: min = {v.lo:g} > max = {v.hi:g}: expected "
                              "min <= max")
    policy = t.get("policy", "i")
    if policy not in POLICIES:
        raise ConfigError(f"targets.policy = {shown(policy)} is invalid: expected \"i\" "
                          "(omega2 << omega1, alpha << 1) or \"ii\" (also sigma^2 = 1)")
    design = data.get("design", {})
    if not isinstance(design, dict):
        raise ConfigError(f"{source}: [design] must be a table (name, description, base)")
    for key in design:
        if key not in ("name", "description", "base"):
            raise ConfigError(f"{source}: unknown key design.{key}; valid keys: base, "
                              "description, name")
        if not isinstance(design[key], str) or not design[key]:
            raise ConfigError(f"design.{key} = {shown(design[key])} is invalid: expected a "
                              "non-empty string")
    mass = t.get("total_mass_kg", 0.1)
    mass_free = mass == "free"
    return Targets(
        variables=variables, policy=policy, total_mass_free=mass_free,
        total_mass_kg=0.1 if mass_free else positive(
            "targets.total_mass_kg", mass, unit="kg",
            valid='a finite number > 0 kg, or "free" (it only scales the pendulum)'),
        q1=positive("targets.q1", t.get("q1", 530.0), allow_inf=True),
        q2=positive("targets.q2", t.get("q2", 100.0), allow_inf=True),
        g_mps2=positive("targets.g_mps2", t.get("g_mps2", G_STANDARD), unit="m/s^2"),
        margin_db=number("targets.margin_db", t.get("margin_db", 3.0), lo=0.0, hi=60.0,
                         unit="dB"),
        j1_min_kgm2=number("targets.j1_min_kgm2", t.get("j1_min_kgm2", 0.0), lo=0.0,
                           unit="kg m^2"),
        j2_min_kgm2=number("targets.j2_min_kgm2", t.get("j2_min_kgm2", 0.0), lo=0.0,
                           unit="kg m^2"),
        suppression=tuple(_suppression(i, s) for i, s in
                          enumerate(_tables("suppression", t.get("suppression", [])))),
        translation=tuple(_translation(i, s) for i, s in
                          enumerate(_tables("translation", t.get("translation", [])))),
        name=design.get("name", "designed"), description=design.get("description", ""),
        base=design.get("base", "ishizaki2009"), source=source)


def _tighter(a, b, pick):
    return a if b is None else b if a is None else pick(a, b)


def _variable(name: str, raw, half_unit: float | None) -> VariableTarget:
    where = f"targets.{name}"
    unit = VARIABLES[name][0]
    kw = {"valid": f"a finite number > 0{'' if unit == '-' else ' ' + unit}, or "
               + _VALUE_FORMS[len("a number (fixed), "):]}
    if raw == "free":
        return VariableTarget(name)
    if isinstance(raw, dict):
        keys = set(raw)
        if keys <= {"min", "max"} and keys:
            lo = positive(f"{where}.min", raw["min"], unit=unit) if "min" in raw else None
            hi = positive(f"{where}.max", raw["max"], unit=unit) if "max" in raw else None
            return VariableTarget(name, lo=lo, hi=hi)
        if keys == {"value", "tol"} or keys == {"value"}:
            v = positive(f"{where}.value", raw["value"], unit=unit)
            tol = (positive(f"{where}.tol", raw["tol"], unit=unit) if "tol" in raw
                   else _half_unit_of(repr(v)))
            return VariableTarget(name, value=v, tol=tol)
        raise ConfigError(f"{where} = {raw!r} is invalid: expected {_VALUE_FORMS}")
    if isinstance(raw, str):
        raise ConfigError(f"{where} = {raw!r} is invalid: expected {_VALUE_FORMS}")
    v = positive(where, raw, **kw)
    if name == "eps" and v <= 1:
        raise ConfigError(f"{where} = {shown(raw)} is invalid: expected eps = 1 + m1/m2 > 1")
    return VariableTarget(name, value=v, tol=half_unit or _half_unit_of(repr(v)))


def _tables(name: str, raw) -> list:
    if isinstance(raw, dict):
        return [raw]
    if isinstance(raw, list) and all(isinstance(x, dict) for x in raw):
        return raw
    raise ConfigError(f"targets.{name} = {raw!r} is invalid: expected a table [targets.{name}] "
                      f"or tables [[targets.{name}]]")


def _check_keys(where: str, table: dict, allowed: tuple) -> None:
    for key in table:
        if key not in allowed:
            raise ConfigError(f"unknown key {where}.{key}; valid keys: {', '.join(allowed)}")


def _suppression(i: int, s: dict) -> SuppressionTarget:
    where = f"targets.suppression[{i + 1}]"
    _check_keys(where, s, ("band_hz", "min_db"))
    band = s.get("band_hz")
    if (not isinstance(band, list) or len(band) != 2):
        raise ConfigError(f"{where}.band_hz = {band!r} is invalid: expected [low, high] in Hz")
    lo = positive(f"{where}.band_hz[1]", band[0], unit="Hz")
    hi = positive(f"{where}.band_hz[2]", band[1], unit="Hz")
    if hi <= lo:
        raise ConfigError(f"{where}.band_hz = {band!r} is invalid: expected low < high [Hz]")
    min_db = s.get("min_db")
    if min_db is not None:
        min_db = number(f"{where}.min_db", min_db, lo=-200.0, hi=300.0, unit="dB")
    return SuppressionTarget((lo, hi), min_db)


def _translation(i: int, s: dict) -> TranslationTarget:
    where = f"targets.translation[{i + 1}]"
    _check_keys(where, s, ("freq_hz", "min_db", "max_db", "response"))
    if "freq_hz" not in s:
        raise ConfigError(f"{where} has no freq_hz: expected the frequency [Hz] of the target")
    f = positive(f"{where}.freq_hz", s["freq_hz"], unit="Hz")
    lim = {k: number(f"{where}.{k}", s[k], lo=-400.0, hi=400.0, unit="dB")
           for k in ("min_db", "max_db") if k in s}
    if not lim:
        raise ConfigError(f"{where} has neither min_db nor max_db: expected at least one [dB]")
    if "min_db" in lim and "max_db" in lim and lim["min_db"] > lim["max_db"]:
        raise ConfigError(f"{where}: min_db = {lim['min_db']:g} > max_db = {lim['max_db']:g}")
    response = s.get("response", "x")
    if response not in RESPONSES:
        raise ConfigError(f"{where}.response = {shown(response)} is invalid: expected \"x\" "
                          "(m per m/s^2) or \"isolation\" (|x_abs/x0|)")
    return TranslationTarget(f, lim.get("min_db"), lim.get("max_db"), response)

