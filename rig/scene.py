"""Scenes: a TOML file (or built-in preset) describing the pendulum, its damping, its initial state,
and the mirror the optical lever looks at; ``--set key=value`` overrides any value.

A scene file has the sections below (every key optional unless marked required; SI units, the unit
is the key's suffix). ``daq scene show NAME`` prints a scene fully resolved.

``[scene]``      name, description
``[pendulum]``   kind = "ishizaki" | "chain" | "rod-chain", damping_mode = "absolute" | "relative",
                 g_mps2, and per kind:
                 - ishizaki: r1_m, r2_m, f1_hz, f2_hz, eps, total_mass_kg, q1, q2 (required), l_m
                   (O1 to O2; default r1_m), length2_m (places the lower end of body 2 only);
                 - chain: mass_kg, length_m, com_m, inertia_kgm2, damping_nms (one per body);
                 - rod-chain: n, total_length_m, linear_density_kgpm (uniform rods, c = l/2,
                   J = m l^2/12), or rod_lengths_m for unequal rods; damping_nms (per joint).
``[mirror]``     body (1-based; default the last body), position_m (distance of the mirror centre
                 from the body's upper joint along the body; default its centre of mass). The translation channel x is the
                 horizontal displacement of that point relative to the base, the rotation channel y
                 is the angle of that body (SPEC section 5).
``[initial]``    theta0_rad, omega0_rad_s: one number for every body or a list of n.

A top-level ``base = "PRESET"`` (or a TOML file path, relative to the file) inherits every key not
given (:func:`load_scene`); :func:`rig.scene_toml.scene_toml` writes a resolved scene back as a
complete file.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rig.chain import DAMPING_MODES, G_STANDARD, Chain
from rig.errors import ConfigError

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One scene key: its type (``float``, ``int``, ``str``, ``floats`` = a number or a list of
    numbers), its default (``REQUIRED`` if none), allowed choices and a one-line description."""

    type: str
    default: Any = REQUIRED
    doc: str = ""
    choices: tuple = ()


_COMMON_PENDULUM = {
    "kind": Key("str", REQUIRED, "how the pendulum is given", ("ishizaki", "chain", "rod-chain")),
    "damping_mode": Key("str", "absolute", "viscous torque on each body, or in each joint",
                        DAMPING_MODES),
    "g_mps2": Key("float", G_STANDARD, "gravitational acceleration [m/s^2]"),
}
PENDULUM_KINDS: dict[str, dict[str, Key]] = {
    "ishizaki": {
        "r1_m": Key("float", doc="O1 to G1, stage-1 centre of mass [m]"),
        "r2_m": Key("float", doc="O2 to G2, stage-2 centre of mass [m]"),
        "f1_hz": Key("float", doc="stage-1 natural frequency omega1/2pi [Hz]"),
        "f2_hz": Key("float", doc="stage-2 natural frequency omega2/2pi [Hz]"),
        "eps": Key("float", doc="(m1 r1 + m2 l)/(m2 l) [-]"),
        "total_mass_kg": Key("float", doc="m1 + m2 [kg]"),
        "q1": Key("float", doc="quality factor of stage 1, 1/(2 zeta1) [-]"),
        "q2": Key("float", doc="quality factor of stage 2, 1/(2 zeta2) [-]"),
        "l_m": Key("float", None, "O1 to O2 [m]; default r1_m (O2 at G1)"),
        "length2_m": Key("float", 0.0375, "length of body 2 below O2 [m] (no dynamical effect; "
                         "the mirror at O2 is the centre of the 75 mm pendulum)"),
    },
    "chain": {
        "mass_kg": Key("floats", doc="m_j [kg]"),
        "length_m": Key("floats", doc="joint-to-joint length l_j [m]"),
        "com_m": Key("floats", doc="upper joint to centre of mass c_j [m]"),
        "inertia_kgm2": Key("floats", doc="J_j about the centre of mass [kg m^2]"),
        "damping_nms": Key("floats", 0.0, "Gamma_j [N m s/rad]"),
    },
    "rod-chain": {
        "n": Key("int", None, "number of equal rods (ignored if rod_lengths_m is given)"),
        "total_length_m": Key("float", None, "total length of the n equal rods [m]"),
        "rod_lengths_m": Key("floats", None, "lengths of unequal rods [m]"),
        "linear_density_kgpm": Key("float", 1.0, "mass per length rho [kg/m]"),
        "damping_nms": Key("floats", 0.0, "Gamma_j [N m s/rad]"),
    },
}
SECTIONS: dict[str, dict[str, Key]] = {
    "scene": {"name": Key("str", "custom", "scene name"), "description": Key("str", "", "what it is")},
    "pendulum": _COMMON_PENDULUM,  # plus the keys of its kind
    "mirror": {"body": Key("int", None, "body carrying the mirror, 1-based; default the last"),
               "position_m": Key("float", None, "mirror centre from the body's upper joint [m]; "
                                 "default the body's centre of mass")},
    "initial": {"theta0_rad": Key("floats", 0.0, "initial angles [rad]"),
                "omega0_rad_s": Key("floats", 0.0, "initial angular velocities [rad/s]")},
    # -- the bench (issue 3): defaults are owned and documented by the module that uses them --
    "source": {  # the analyzer's source: a DAC held between samples (rig/source.py)
        "type": Key("str", "random", "source signal (random: band-limited Gaussian noise)",
                    ("random", "burst-random", "periodic-chirp", "pink", "sine")),
        "level_vrms": Key("float", 0.1, "rms source voltage [V] (burst random: while on)"),
        "fmin_hz": Key("float", 0.0, "lower band edge of random/pink/chirp [Hz], 0 <= fmin < fmax"),
        "fmax_hz": Key("float", 12.5, "upper band edge (the analysis span) [Hz], <= fs/2"),
        "frequency_hz": Key("float", 2.0, "frequency of the fixed sine [Hz], 0 < f < fs/2"),
        "period_s": Key("float", 100.0, "period of chirp and burst random [s], whole samples"),
        "burst_fraction": Key("float", 0.5, "on-fraction of each burst-random period, (0, 1]"),
        "reconstruction_hz": Key("float", 100.0, "corner of the source output's smoothing filter "
                                 "(Butterworth) [Hz]; 0: off, the raw DAC staircase"),
        "reconstruction_order": Key("int", 4, "order of that filter, 1..8"),
    },
    "stage": {  # amplifier, voice-coil motor and X stage (rig/stage.py; defaults justified there)
        "amplifier_gain_vpv": Key("float", 1.0, "voltage gain of the power amplifier [V/V], > 0"),
        "force_constant_npa": Key("float", 1.0, "voice-coil force constant = back-EMF constant "
                                  "[N/A], > 0"),
        "coil_resistance_ohm": Key("float", 8.0, "coil resistance [ohm], > 0"),
        "coil_inductance_h": Key("float", 4e-3, "coil inductance [H], > 0 (L/R = 0.5 ms)"),
        "moving_mass_kg": Key("float", 2.0, "stage moving mass incl. coil, laser and PSD, without "
                              "the pendulum [kg], > 0"),
        "stiffness_npm": Key("float", 0.8, "centring stiffness of the guide [N/m], >= 0 "
                             "(suspension ~0.1 Hz)"),
        "damping_nspm": Key("float", 1.0, "viscous damping of the guide [N s/m], >= 0"),
        "reaction": Key("bool", True, "the pendulum's reaction force loads the stage (linear "
                        "and nonlinear models, rig/coupled.py)"),
    },
    "accelerometer": {  # piezoelectric + charge amplifier (rig/accelerometer.py)
        "sensitivity_vpmps2": Key("float", 1.0, "sensitivity [V per m/s^2] incl. the charge "
                                  "amplifier, > 0"),
        "highpass_hz": Key("float", 0.05, "first-order low-frequency corner of the charge "
                           "amplifier [Hz], >= 0 (0: flat to DC, servo type)"),
        "noise_mps2_rthz": Key("float", 1e-5, "input-referred white noise density "
                               "[m/s^2/sqrt(Hz)], >= 0"),
        "range_mps2": Key("float", 10.0, "measuring range [m/s^2], > 0; the output clips beyond "
                          "(flagged)"),
        "sign": Key("int", 1, "polarity of the mounted sensor, +1 or -1", (1, -1)),
    },
    "psd": {  # laser, optical lever and position sensitive detector on the stage (rig/psd.py)
        "incidence_deg": Key("float", 30.0, "angle of incidence on the mirror in the horizontal "
                             "plane [deg], 0 < phi < 90"),
        "distance_m": Key("float", 0.2, "mirror to PSD along the reflected beam [m], > 0"),
        "size_m": Key("float", 0.012, "side of the square detector [m], > 0; the output clips at "
                      "its edge (flagged)"),
        "gain_vpm": Key("float", 1000.0, "PSD output per spot displacement [V/m], > 0"),
        "noise_m_rthz": Key("float", 3e-8, "spot-position noise density per axis "
                            "[m/sqrt(Hz)], >= 0"),
        "sign_x": Key("int", 1, "orientation of the PSD x axis, +1 or -1", (1, -1)),
        "sign_y": Key("int", 1, "orientation of the PSD y axis, +1 or -1", (1, -1)),
    },
    "acquisition": {  # synchronous sampling, anti-alias filter, ADC, records (daq/)
        "rate_hz": Key("float", 100.0, "sample rate of every channel [Hz]"),
        "simulation_rate_hz": Key("float", 1000.0, "rate of the analog simulation and source DAC "
                                  "[Hz]; an integer multiple q >= 2 of rate_hz"),
        "records": Key("int", 30, "number of records (>= 1), taken back to back"),
        "record_s": Key("float", 100.0, "duration of one record [s]; a whole number of samples"),
        "settle_s": Key("float", 300.0, "settling time before the first record [s]; a whole "
                        "number of samples"),
        "adc_bits": Key("int", 16, "ADC resolution [bits], 2..32"),
        "antialias": Key("str", "elliptic", "anti-alias low-pass before decimation ('none' "
                         "decimates unfiltered, to show aliasing)", ("elliptic", "none")),
        "antialias_passband": Key("float", 0.4, "anti-alias passband edge as a fraction of "
                                  "rate_hz (< 0.5); the stopband starts at rate_hz / 2"),
        "antialias_ripple_db": Key("float", 0.01, "anti-alias passband ripple [dB]"),
        "antialias_attenuation_db": Key("float", None, "anti-alias attenuation at and above "
                                        "rate_hz / 2 [dB]; default 20 log10(2^(adc_bits+1))"),
        "range_a_v": Key("float", 1.0, "ADC full scale of channel a, +-[V]"),
        "range_x_v": Key("float", 10.0, "ADC full scale of channel x, +-[V]"),
        "range_y_v": Key("float", 10.0, "ADC full scale of channel y, +-[V]"),
        "model": Key("str", "auto", "pendulum model simulated: 'auto' picks the cheapest that "
                     "meets error_budget (exact linear where the predicted linearisation error "
                     "is inside it, else nonlinear); 'linear' or 'nonlinear' force one "
                     "(rig/bench.py)", ("auto", "linear", "nonlinear")),
        "error_budget": Key("float", 1e-2, "allowed relative RMS error of the simulated angles "
                            "over the records (max over the bodies), > 0; decides model = "
                            "'auto' and is checked for a forced model (the paper's default "
                            "drive: the linear model is predicted 0.5 % off, rig/bench.py)"),
        "truth": Key("bool", True, "store the ground truth beside the channels"),
    },
}


@dataclass(frozen=True)
class Mirror:
    """Where the optical lever looks: ``body`` (0-based) and ``position_m`` from its upper joint."""

    body: int
    position_m: float


@dataclass(frozen=True)
class Scene:
    """A fully resolved scene. ``settings`` is the resolved input (every key, defaults filled) and
    reloads to the same scene; ``chain`` the resulting physical parameters."""

    name: str
    description: str
    source: str
    settings: dict
    chain: Chain
    mirror: Mirror
    theta0_rad: tuple
    omega0_rad_s: tuple

    def mirror_weights(self) -> np.ndarray:
        """Weights w with x_mirror = w . theta (linearised, relative to the base) [m/rad]."""
        return self.chain.point_weights(self.mirror.body, self.mirror.position_m)

    def to_dict(self) -> dict:
        """The scene as plain data: resolved settings, physical chain parameters (SI), mirror."""
        c = self.chain
        return {
            "source": self.source,
            "settings": copy.deepcopy(self.settings),
            "chain": {
                "n": c.n,
                "mass_kg": list(c.mass_kg), "length_m": list(c.length_m), "com_m": list(c.com_m),
                "inertia_kgm2": list(c.inertia_kgm2), "damping_nms": list(c.damping_nms),
                "damping_mode": c.damping_mode, "g_mps2": c.g_mps2,
            },
            "mirror": {"body": self.mirror.body + 1, "position_m": self.mirror.position_m},
            "initial": {"theta0_rad": list(self.theta0_rad),
                        "omega0_rad_s": list(self.omega0_rad_s)},
        }


# -- loading ---------------------------------------------------------------------------------

def preset_names() -> list[str]:
    """Names of the built-in presets."""
    files = resources.files("rig").joinpath("presets").iterdir()
    return sorted(p.name[:-5] for p in files if p.name.endswith(".toml"))


def preset_text(name: str) -> str:
    """The TOML text of a built-in preset."""
    if name not in preset_names():
        raise ConfigError(f"scene {name!r} is not a preset ({', '.join(preset_names())}) "
                          "nor an existing .toml file")
    return resources.files("rig").joinpath("presets", f"{name}.toml").read_text()


def load_scene(scene: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    """Load a scene from a preset name or a TOML file path and apply ``key=value`` overrides.

    A scene may start from another: a top-level ``base = "PRESET"`` (or a path to a TOML file,
    relative to the file that names it) inherits every key the scene does not give, section by
    section; bases may chain (a cycle is an error). A scene that gives a different
    ``pendulum.kind`` than its base inherits none of the base's pendulum keys.

    Overrides use dotted keys (``pendulum.q1=300``), an index for one list element
    (``initial.theta0_rad[2]=0.1``, 1-based like the bodies) and TOML values (a bare word is
    taken as a string: ``pendulum.damping_mode=relative``). They apply after the inheritance.
    """
    data, source = read_scene_data(scene)
    for item in overrides:
        apply_override(data, item)
    return resolve_scene(data, source=source)


def read_scene_data(scene: str | Path, *, relative_to: Path | None = None,
                    _chain: tuple[str, ...] = ()) -> tuple[dict, str]:
    """The raw data of a scene (a preset name or a TOML file) with its ``base`` chain merged in,
    and a description of where it came from (``"file.toml (base preset:ishizaki2009)"``)."""
    path = Path(scene)
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ConfigError(f"scene file {str(path)!r} does not exist")
        try:
            text, source = path.read_text(encoding="utf-8"), str(path)
        except UnicodeDecodeError as exc:
            raise ConfigError(f"scene file {str(path)!r} is not a TOML text file (byte "
                              f"{exc.start} is not UTF-8)") from None
        except OSError as exc:
            raise ConfigError(f"scene file {str(path)!r} cannot be read: {exc.strerror}") from None
        key = str(path.resolve())
    else:
        text, source = preset_text(str(scene)), f"preset:{scene}"
        key = source
    if key in _chain:
        raise ConfigError(f"scene {source}: its base chain comes back to itself "
                          f"({' -> '.join((*_chain, key))})")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"scene {source}: invalid TOML: {exc}") from None
    base = data.pop("base", None)
    if base is None:
        return data, source
    if not isinstance(base, str) or not base:
        raise ConfigError(f"scene {source}: base = {base!r} is invalid: expected a preset name "
                          f"({', '.join(preset_names())}) or a .toml file path in quotes")
    folder = path.parent if source != f"preset:{scene}" else None
    base_data, base_source = read_scene_data(base, relative_to=folder, _chain=(*_chain, key))
    return merge_scene_data(base_data, data), f"{source} (base {base_source})"


def merge_scene_data(base: dict, child: dict) -> dict:
    """``child`` over ``base``: each section's keys of the child replace the base's, the rest
    are inherited; a child naming another ``pendulum.kind`` replaces the whole pendulum section."""
    out = copy.deepcopy(base)
    for section, table in child.items():
        inherited = out.get(section)
        if not isinstance(table, dict) or not isinstance(inherited, dict):
            out[section] = copy.deepcopy(table)
            continue
        if section == "pendulum" and "kind" in table and table["kind"] != inherited.get("kind"):
            out[section] = copy.deepcopy(table)
            continue
        inherited.update(copy.deepcopy(table))
    return out


def scene_from_settings(settings: dict, source: str = "settings") -> Scene:
    """Rebuild a scene from ``Scene.settings`` (e.g. read back from a file)."""
    return resolve_scene(copy.deepcopy(settings), source=source)


_OVERRIDE = re.compile(r"^(?P<key>[A-Za-z_][\w-]*(?:\.[A-Za-z_][\w-]*)+)(?:\[(?P<idx>\d+)\])?=(?P<val>.*)$")


def parse_value(text: str) -> Any:
    """A TOML value (number, bool, string in quotes, list); a bare word becomes a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()


def apply_override(data: dict, item: str) -> None:
    """Apply one ``section.key=value`` or ``section.key[i]=value`` override to raw scene data."""
    m = _OVERRIDE.match(item.strip())
    if not m:
        raise ConfigError(f"--set {item!r} is invalid: expected section.key=value, e.g. "
                          "pendulum.q1=300 or initial.theta0_rad[1]=0.2")
    *sections, key = m["key"].split(".")
    node = data
    for s in sections:
        node = node.setdefault(s, {})
        if not isinstance(node, dict):
            raise ConfigError(f"--set {item!r}: {s!r} is not a section")
    value = parse_value(m["val"])
    if m["idx"] is None:
        node[key] = value
        return
    i = int(m["idx"])
    current = node.get(key)
    if not isinstance(current, list):
        raise ConfigError(f"--set {item!r}: {m['key']} is not a list in this scene "
                          "(set the whole list instead, e.g. key=[0.1, 0.2])")
    if not 1 <= i <= len(current):
        raise ConfigError(f"--set {item!r}: index {i} is out of range 1..{len(current)}")
    current[i - 1] = value


# -- validation ------------------------------------------------------------------------------

def _check_type(where: str, key: Key, value: Any) -> Any:
    if value is None and key.default is None:
        return None
    def number(v, what):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{where} = {v!r} is invalid: expected {what}")
        if not math.isfinite(float(v)):
            raise ConfigError(f"{where} = {v!r} is invalid: expected a finite number")
        return float(v)

    if key.type == "float":
        return number(value, "a number")
    if key.type == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{where} = {value!r} is invalid: expected true or false")
        return value
    if key.type == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where} = {value!r} is invalid: expected an integer")
        if key.choices and value not in key.choices:
            raise ConfigError(f"{where} = {value!r} is invalid: expected one of "
                              f"{', '.join(map(str, key.choices))}")
        return value
    if key.type == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{where} = {value!r} is invalid: expected a string")
        if key.choices and value not in key.choices:
            raise ConfigError(f"{where} = {value!r} is invalid: expected one of "
                              f"{', '.join(key.choices)}")
        return value
    if key.type == "floats":
        if isinstance(value, list):
            if not value:
                raise ConfigError(f"{where} = [] is invalid: expected a number or a non-empty list")
            for i, v in enumerate(value):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ConfigError(f"{where} of body {i + 1} = {v!r} is invalid: expected a number")
            return [number(v, "a finite number") for v in value]
        return number(value, "a number or a list of numbers")
    raise AssertionError(key.type)


def _validate_section(name: str, raw: dict, keys: dict[str, Key]) -> dict:
    if not isinstance(raw, dict):
        raise ConfigError(f"[{name}] is invalid: expected a table of keys")
    for k in raw:
        if k not in keys:
            raise ConfigError(f"unknown key {name}.{k} = {raw[k]!r}; valid keys: "
                              f"{', '.join(sorted(keys))}")
    out = {}
    for k, spec in keys.items():
        if k in raw:
            out[k] = _check_type(f"{name}.{k}", spec, raw[k])
        elif spec.default is REQUIRED:
            raise ConfigError(f"missing required key {name}.{k} ({spec.doc})")
        else:
            out[k] = spec.default
    return out


def _per_body(where: str, value, n: int) -> list[float]:
    if isinstance(value, list):
        if len(value) != n:
            raise ConfigError(f"{where} has {len(value)} entries; expected 1 or {n} (one per body)")
        return list(value)
    return [value] * n


def _prefixed(exc: ConfigError, prefix: str) -> ConfigError:
    return ConfigError(f"{prefix}{exc}")


def _finite_chain(p: dict, raw: dict) -> Chain:
    """:func:`_build_chain`, and its linearised model evaluated: values that are each valid but
    together overflow or divide by zero (e.g. f1_hz = 1e300) are a ConfigError naming them."""
    given = ", ".join(f"pendulum.{k} = {v!r}" for k, v in raw.items()
                      if isinstance(v, (int, float, list)) and not isinstance(v, bool))
    try:
        with np.errstate(over="raise", invalid="raise"):
            chain = _build_chain(p)
            chain.modes()
    except ConfigError as exc:
        if p.get("kind") != "ishizaki" or any(f"pendulum.{k} " in str(exc) for k in raw):
            raise
        # a body value derived from the design numbers: name the numbers given
        raise ConfigError(f"{given}: {str(exc).removeprefix('pendulum.')}") from None
    except (ZeroDivisionError, OverflowError, FloatingPointError, np.linalg.LinAlgError,
            ValueError) as exc:
        raise ConfigError(f"{given or 'the [pendulum] values'}: no finite pendulum follows "
                          f"(numerical {type(exc).__name__}: {exc}); expected values of "
                          "ordinary size (lengths in m, frequencies in Hz)") from None
    return chain


def _build_chain(p: dict) -> Chain:
    kind = p["kind"]
    try:
        if kind == "ishizaki":
            for k in ("r1_m", "r2_m", "f1_hz", "f2_hz", "total_mass_kg", "q1", "q2", "length2_m"):
                if not p[k] > 0:
                    raise ConfigError(f"{k} = {p[k]} is invalid: expected > 0")
            if not p["eps"] > 1:
                raise ConfigError(f"eps = {p['eps']} is invalid: expected > 1 (eps = 1 + m1/m2 "
                                  "for l = r1)")
            if p["l_m"] is not None and not p["l_m"] > 0:
                raise ConfigError(f"l_m = {p['l_m']} is invalid: expected > 0")
            from rig.ishizaki import chain_from_design

            chain = chain_from_design(
                r1_m=p["r1_m"], r2_m=p["r2_m"], f1_hz=p["f1_hz"], f2_hz=p["f2_hz"], eps=p["eps"],
                total_mass_kg=p["total_mass_kg"], q1=p["q1"], q2=p["q2"], l_m=p["l_m"],
                length2_m=p["length2_m"], g_mps2=p["g_mps2"])
            return dataclasses.replace(chain, damping_mode=p["damping_mode"])
        if kind == "chain":
            n = len(p["mass_kg"]) if isinstance(p["mass_kg"], list) else 1
            return Chain(
                mass_kg=_per_body("mass_kg", p["mass_kg"], n),
                length_m=_per_body("length_m", p["length_m"], n),
                com_m=_per_body("com_m", p["com_m"], n),
                inertia_kgm2=_per_body("inertia_kgm2", p["inertia_kgm2"], n),
                damping_nms=_per_body("damping_nms", p["damping_nms"], n),
                damping_mode=p["damping_mode"], g_mps2=p["g_mps2"])
        # rod-chain
        if p["rod_lengths_m"] is not None:
            lengths = p["rod_lengths_m"] if isinstance(p["rod_lengths_m"], list) else [p["rod_lengths_m"]]
        else:
            if p["n"] is None or p["total_length_m"] is None:
                raise ConfigError("a rod-chain needs n and total_length_m, or rod_lengths_m")
            if not 1 <= p["n"] <= 10_000:
                raise ConfigError(f"n = {p['n']} is invalid: expected 1 <= n <= 10000")
            if not p["total_length_m"] > 0:
                raise ConfigError(f"total_length_m = {p['total_length_m']} is invalid: expected > 0")
            lengths = [p["total_length_m"] / p["n"]] * p["n"]
        rho = p["linear_density_kgpm"]
        if not rho > 0:
            raise ConfigError(f"linear_density_kgpm = {rho} is invalid: expected > 0")
        for i, l in enumerate(lengths):
            if not l > 0:
                raise ConfigError(f"rod_lengths_m[{i}] = {l} is invalid: expected > 0")
        m = [rho * l for l in lengths]
        return Chain(mass_kg=m, length_m=lengths, com_m=[l / 2 for l in lengths],
                     inertia_kgm2=[mi * l * l / 12 for mi, l in zip(m, lengths)],
                     damping_nms=_per_body("damping_nms", p["damping_nms"], len(lengths)),
                     damping_mode=p["damping_mode"], g_mps2=p["g_mps2"])
    except ConfigError as exc:
        msg = str(exc)
        raise ConfigError(msg if msg.startswith(("pendulum.", "a rod-chain")) else f"pendulum.{msg}") from None


def resolve_scene(data: dict, *, source: str) -> Scene:
    """Validate raw scene data (as parsed from TOML) and build the :class:`Scene`."""
    if not isinstance(data, dict):
        raise ConfigError(f"scene {source}: expected a table")
    for section in data:
        if section not in SECTIONS:
            raise ConfigError(f"unknown section [{section}] in scene {source}; valid sections: "
                              f"{', '.join(SECTIONS)}")
    raw_p = data.get("pendulum")
    if raw_p is None:
        raise ConfigError(f"scene {source} has no [pendulum] section")
    kind = raw_p.get("kind") if isinstance(raw_p, dict) else None
    if not isinstance(kind, str) or kind not in PENDULUM_KINDS:
        raise ConfigError(f"pendulum.kind = {kind!r} is invalid: expected one of "
                          f"{', '.join(PENDULUM_KINDS)}")
    settings = {}
    for section, keys in SECTIONS.items():
        if section == "pendulum":
            keys = {**keys, **PENDULUM_KINDS[kind]}
        settings[section] = _validate_section(section, data.get(section, {}), keys)
    chain = _finite_chain(settings["pendulum"], raw_p)
    n = chain.n

    mirror_body = settings["mirror"]["body"]
    if mirror_body is None:
        mirror_body = n
    if not 1 <= mirror_body <= n:
        raise ConfigError(f"mirror.body = {mirror_body} is invalid: expected 1..{n} (1-based)")
    settings["mirror"]["body"] = mirror_body
    pos = settings["mirror"]["position_m"]
    if pos is None:
        pos = chain.com_m[mirror_body - 1]
    if not 0 <= pos <= chain.length_m[mirror_body - 1]:
        raise ConfigError(f"mirror.position_m = {pos} is invalid: expected 0 .. "
                          f"{chain.length_m[mirror_body - 1]:.6g} m (along body {mirror_body})")
    settings["mirror"]["position_m"] = pos
    mirror = Mirror(body=mirror_body - 1, position_m=pos)

    theta0 = _per_body("initial.theta0_rad", settings["initial"]["theta0_rad"], n)
    omega0 = _per_body("initial.omega0_rad_s", settings["initial"]["omega0_rad_s"], n)
    return Scene(name=settings["scene"]["name"], description=settings["scene"]["description"],
                 source=source, settings=settings, chain=chain, mirror=mirror,
                 theta0_rad=tuple(theta0), omega0_rad_s=tuple(omega0))


def describe_keys() -> dict[str, dict[str, str]]:
    """Documentation of every scene key: ``{section: {key: "type, default: doc"}}``."""
    out: dict[str, dict[str, str]] = {}
    for section, keys in SECTIONS.items():
        all_keys = dict(keys)
        if section == "pendulum":
            for kind, extra in PENDULUM_KINDS.items():
                all_keys.update({f"{k} ({kind})": v for k, v in extra.items()})
        out[section] = {k: f"{v.type}; " + ("required" if v.default is REQUIRED
                                            else f"default {v.default!r}") + f"; {v.doc}"
                        for k, v in all_keys.items()}
    return out
