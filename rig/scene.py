"""Scenes: a TOML file (or built-in preset) describing the pendulum, its damping, its initial state,
the mirror the optical lever looks at, the bench's devices and the acquisition; ``--set
key=value`` overrides any value. :func:`load_scene` validates every value and returns a frozen,
typed :class:`Scene` whose parts (chain, mirror, devices, acquisition) are built once, there.

A scene file has the sections below (every key optional unless marked required; SI units, the unit
is the key's suffix). ``daq scene show NAME`` prints a scene fully resolved, every key with its
doc.

``[scene]``      name, description
``[pendulum]``   kind = "ishizaki" | "chain" | "rod-chain", damping_mode = "absolute" | "relative",
                 g_mps2, and per kind:
                 - ishizaki: r1_m, r2_m, f1_hz, f2_hz, eps, total_mass_kg, q1, q2 (required), l_m
                   (O1 to O2; default r1_m), length2_m (places the lower end of body 2 only);
                 - chain: mass_kg, length_m, com_m, inertia_kgm2, damping_nms (one per body);
                 - rod-chain: n, total_length_m, linear_density_kgpm (uniform rods, c = l/2,
                   J = m l^2/12), or rod_lengths_m for unequal rods; damping_nms (per joint).
``[mirror]``     body (1-based; default the last body), position_m (distance of the mirror centre
                 from the body's upper joint along the body; default its centre of mass). The
                 translation channel x is the horizontal displacement of that point relative to
                 the base, the rotation channel y is the angle of that body (SPEC section 5).
``[initial]``    theta0_rad, omega0_rad_s: one number for every body or a list of n.
``[source]``     the analyzer's source (:class:`rig.devices.source.Source`);
``[stage]``      amplifier, voice coil and X stage (:class:`rig.devices.stage.Stage`);
``[accelerometer]`` (:class:`rig.devices.accelerometer.Accelerometer`);
``[psd]``        laser, optical lever and PSD (:class:`rig.devices.optical_lever.OpticalLever`,
                 ``Scene.lever``; the section keeps its historical name);
``[acquisition]`` rates, records, ADC, anti-alias filter, model choice
                 (:class:`rig.acquisition_settings.AcquisitionSettings`).

The keys of the last five sections are the fields of those frozen dataclasses (name, unit,
default, range and doc written once, :mod:`rig.params`); the pendulum's, mirror's and initial
state's keys are the tables below.

A top-level ``base = "PRESET"`` (or a TOML file path, relative to the file) inherits every key not
given (:func:`load_scene`); a scene file is named after itself (``scene.name`` defaults to its
file name without ``.toml``); :func:`rig.scene_toml.scene_toml` writes a resolved scene back as a
complete file.
"""

from __future__ import annotations

import copy
import dataclasses
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rig.acquisition_settings import AcquisitionSettings
from rig.chain import DAMPING_MODES, G_STANDARD, Chain
from rig.devices import Accelerometer, OpticalLever, Source, Stage
from rig.validation import shown
from rig.errors import ConfigError
from rig.params import REQUIRED, Key, check_value, keys_of

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
    # the bench: each device's keys are its dataclass fields (rig.params.param)
    "source": keys_of(Source),  # the analyzer's source: a DAC held between samples
    "stage": keys_of(Stage),  # amplifier, voice-coil motor and X stage
    "accelerometer": keys_of(Accelerometer),  # piezoelectric + charge amplifier
    "psd": keys_of(OpticalLever),  # laser, optical lever and position sensitive detector
    "acquisition": keys_of(AcquisitionSettings),  # sampling, anti-alias, ADC, records (daq/)
}

@dataclass(frozen=True)
class Mirror:
    """Where the optical lever looks: ``body`` (0-based) and ``position_m`` from its upper joint."""

    body: int
    position_m: float


@dataclass(frozen=True)
class Scene:
    """A fully resolved scene, validated when it is loaded (:func:`load_scene`).

    ``settings`` is the resolved input (every key of every section, defaults filled, in the order
    of :data:`SECTIONS`): it is what a run file stores and reloads to the same scene
    (``load_scene(scene.to_dict()) == scene``). The typed parts are built from it once: ``chain``
    the pendulum's physical parameters, ``mirror`` where the optical lever looks, the initial
    state, the bench's devices (``source`` at ``acquisition.simulation_rate_hz``, ``stage``,
    ``accelerometer``, ``lever`` of the ``[psd]`` section) and ``acquisition``. ``origin`` says
    where the scene came from (``"preset:ishizaki2009"``, a file, ``"settings"``).
    """

    name: str
    description: str
    origin: str
    settings: dict
    chain: Chain
    mirror: Mirror
    theta0_rad: tuple
    omega0_rad_s: tuple
    source: Source
    stage: Stage
    accelerometer: Accelerometer
    lever: OpticalLever
    acquisition: AcquisitionSettings

    @property
    def pendulum_kind(self) -> str:
        """How the pendulum was given: ``"ishizaki"`` (the paper's design numbers), ``"chain"``
        or ``"rod-chain"`` (``pendulum.kind``)."""
        return self.settings["pendulum"]["kind"]

    def mirror_weights(self) -> np.ndarray:
        """Weights w with x_mirror = w . theta (linearised, relative to the base) [m/rad]."""
        return self.chain.point_weights(self.mirror.body, self.mirror.position_m)

    def with_acquisition(self, **changes) -> "Scene":
        """The same scene with ``[acquisition]`` values changed (e.g. ``model="linear"``),
        validated like a loaded one; the settings keep their key order."""
        settings = copy.deepcopy(self.settings)
        unknown = set(changes) - set(settings["acquisition"])
        if unknown:
            raise ConfigError(f"unknown key acquisition.{sorted(unknown)[0]}; valid keys: "
                              f"{', '.join(sorted(settings['acquisition']))}")
        settings["acquisition"].update(changes)
        acquisition = dataclasses.replace(self.acquisition, **changes)
        return dataclasses.replace(self, settings=settings, acquisition=acquisition,
                                   source=dataclasses.replace(
                                       self.source, fs_hz=acquisition.simulation_rate_hz))

    def to_dict(self) -> dict:
        """The scene as plain data: its origin, the resolved settings, the physical chain
        parameters (SI), the mirror (1-based body) and the initial state. :func:`load_scene`
        of it (or of its ``settings``) gives the same scene."""
        c = self.chain
        return {
            "origin": self.origin,
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


def load_scene(scene: str | Path | dict, overrides: list[str] | tuple[str, ...] = (), *,
               memo: ResolutionMemo | None = None) -> Scene:
    """Load a scene from a preset name, a TOML file path or plain data, and apply ``key=value``
    overrides; every value is validated here (ConfigError naming the key, the value and what is
    valid).

    Plain data is either raw scene data (sections of keys, as parsed from TOML) or
    :meth:`Scene.to_dict` (its ``settings`` and ``origin`` are used).

    A scene may start from another: a top-level ``base = "PRESET"`` (or a path to a TOML file,
    relative to the file that names it) inherits every key the scene does not give, section by
    section; bases may chain, at most :data:`MAX_BASE_DEPTH` deep (a cycle is an error). A
    scene that gives a different ``pendulum.kind`` than its base inherits none of the base's
    pendulum keys.

    Overrides use dotted keys (``pendulum.q1=300``), an index for one list element
    (``initial.theta0_rad[2]=0.1``, 1-based like the bodies) and TOML values (a bare word is
    taken as a string: ``pendulum.damping_mode=relative``). They apply after the inheritance.

    ``memo`` (a :class:`ResolutionMemo`) serves many loads of scenes that differ in a few keys (a
    sweep's plan): the same scenes and errors, the unchanged parts checked once.
    """
    if isinstance(scene, dict):
        plain = scene["settings"] if isinstance(scene.get("settings"), dict) else scene
        origin = str(scene.get("origin", "settings")) if plain is not scene else "settings"
        if memo is None:
            data = copy.deepcopy(plain)
        else:  # only the sections the overrides change are copied (deeply if they reach in)
            touched = {}
            for item in overrides:
                head, _, rest = item.strip().partition(".")
                key = rest.partition("=")[0]
                touched[head] = touched.get(head, False) or "." in key or "[" in key
            data = {k: (copy.deepcopy(v) if touched[k] else copy.copy(v)) if k in touched
                    else v for k, v in plain.items()}
    else:
        data, origin = read_scene_data(scene)
    for item in overrides:
        apply_override(data, item)
    return resolve_scene(data, origin=origin, memo=memo)


class ResolutionMemo:
    """The steps of :func:`resolve_scene` (a section's checks, the pendulum's chain, each
    device) remembered by their inputs, so that resolving many scenes that differ in a few keys
    checks the rest once. Each step is a function of the inputs it is keyed on (their types
    and exact values), so a scene resolved with a memo equals one resolved without, and a step
    that fails fails again with the same message. Holds at most ``size`` steps (then starts
    afresh)."""

    def __init__(self, size: int = 4096):
        self.size = size
        self._steps: dict = {}

    def step(self, key, fn, errors: tuple = (ConfigError,)):
        """``fn()``, or what it returned (or raised, one of ``errors``) for ``key`` before."""
        try:
            ok, value = self._steps[key]
        except KeyError:
            try:
                ok, value = True, fn()
            except errors as exc:
                ok, value = False, exc.with_traceback(None)
            if len(self._steps) >= self.size:
                self._steps.clear()
            self._steps[key] = (ok, value)
        if ok:
            return value
        raise value


def _frozen(v) -> str:
    """A key of plain scene data (as parsed from TOML) that tells apart what ``==`` does not
    (1, 1.0 and True; 0.0 and -0.0): its repr (floats' repr round-trips)."""
    return repr(v)


def _step(memo: ResolutionMemo | None, key, fn):
    return fn() if memo is None else memo.step(key, fn)


#: the most scenes a chain of ``base`` files may hold (a deeper one is refused, not followed)
MAX_BASE_DEPTH = 32


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
    if len(_chain) >= MAX_BASE_DEPTH:
        raise ConfigError(f"scene {_chain[0]}: its chain of bases is deeper than "
                          f"{MAX_BASE_DEPTH} ({_chain[0]} -> {_chain[1]} -> ... -> {source}); "
                          f"expected at most {MAX_BASE_DEPTH} scenes, each naming the next as "
                          "its base")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"scene {source}: invalid TOML: {exc}") from None
    except ValueError:  # an integer beyond Python's 4300-digit limit for reading one
        raise ConfigError(f"scene {source}: a number in it has more than 4300 digits; expected "
                          "numbers in the keys' ranges") from None
    base = data.pop("base", None)
    if source != f"preset:{scene}":  # a file: named after itself unless it says otherwise
        data.setdefault("scene", {})
        if isinstance(data["scene"], dict):
            data["scene"].setdefault("name", path.stem)
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


def scene_from_settings(settings: dict, origin: str = "settings") -> Scene:
    """Rebuild a scene from ``Scene.settings`` (e.g. read back from a file)."""
    return resolve_scene(copy.deepcopy(settings), origin=origin)


_OVERRIDE = re.compile(r"^(?P<key>[A-Za-z_][\w-]*(?:\.[A-Za-z_][\w-]*)+)(?:\[(?P<idx>\d+)\])?=(?P<val>.*)$")


_TOML_INT = re.compile(r"[+-]?(?:0|[1-9][0-9]*)")
_TOML_FLOAT = re.compile(r"[+-]?(?:0|[1-9][0-9]*)(?:\.[0-9]+)?(?:[eE][+-]?[0-9]+)?")


def parse_value(text: str) -> Any:
    """A TOML value (number, bool, string in quotes, list); a bare word becomes a string."""
    t = text.strip()
    if len(t) <= 32:  # a plain decimal number (what a sweep writes): read as TOML reads it
        if _TOML_INT.fullmatch(t):
            return int(t)
        if _TOML_FLOAT.fullmatch(t):
            return float(t)
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()
    except ValueError:  # an integer beyond Python's 4300-digit limit for reading one
        raise ConfigError(f"the value {text[:12]}... ({len(text)} characters) is not a number "
                          "that can be read (integers have at most 4300 digits); expected a "
                          "number in its range") from None


def apply_override(data: dict, item: str) -> None:
    """Apply one ``section.key=value`` or ``section.key[i]=value`` override to raw scene data."""
    m = _OVERRIDE.match(item.strip())
    if not m:
        raise ConfigError(f"override {item!r} is invalid: expected section.key=value, e.g. "
                          "pendulum.q1=300 or initial.theta0_rad[1]=0.2")
    *sections, key = m["key"].split(".")
    node = data
    for s in sections:
        node = node.setdefault(s, {})
        if not isinstance(node, dict):
            raise ConfigError(f"override {item!r}: {s!r} is not a section")
    try:
        value = parse_value(m["val"])
    except ConfigError as exc:
        raise ConfigError(f"{m['key']}: {exc}") from None
    if m["idx"] is None:
        node[key] = value
        return
    i = int(m["idx"])
    current = node.get(key)
    if not isinstance(current, list):
        raise ConfigError(f"override {item!r}: {m['key']} is not a list in this scene "
                          "(set the whole list instead, e.g. key=[0.1, 0.2])")
    if not 1 <= i <= len(current):
        raise ConfigError(f"override {item!r}: index {i} is out of range 1..{len(current)}")
    current[i - 1] = value


# -- validation ------------------------------------------------------------------------------

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
            out[k] = check_value(f"{name}.{k}", spec, raw[k])
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


#: The most bodies a pendulum may have: its modes are a dense generalised eigenproblem, O(n^3)
#: (seconds at 200 bodies, minutes at 1000), solved when the scene loads.
MAX_BODIES = 200
_WHY_MAX_BODIES = ("the chain's modes are an O(n^3) eigenproblem solved when the scene loads: "
                   "seconds at 200 bodies, minutes at 1000")


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
                          f"(the numbers fail: {exc}); expected values of "
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
            if chain.damping_mode == p["damping_mode"]:
                return chain
            return dataclasses.replace(chain, damping_mode=p["damping_mode"])
        if kind == "chain":
            n = len(p["mass_kg"]) if isinstance(p["mass_kg"], list) else 1
            if n > MAX_BODIES:
                raise ConfigError(f"mass_kg has {n} bodies: expected at most {MAX_BODIES} "
                                  f"({_WHY_MAX_BODIES})")
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
            if not 1 <= p["n"] <= MAX_BODIES:
                raise ConfigError(f"n = {shown(p['n'])} is invalid: expected 1 <= n <= "
                                  f"{MAX_BODIES} ({_WHY_MAX_BODIES})")
            if not p["total_length_m"] > 0:
                raise ConfigError(f"total_length_m = {p['total_length_m']} is invalid: expected > 0")
            lengths = [p["total_length_m"] / p["n"]] * p["n"]
        if len(lengths) > MAX_BODIES:
            raise ConfigError(f"rod_lengths_m has {len(lengths)} rods: expected at most "
                              f"{MAX_BODIES} ({_WHY_MAX_BODIES})")
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


def resolve_scene(data: dict, *, origin: str, memo: ResolutionMemo | None = None) -> Scene:
    """Validate raw scene data (as parsed from TOML) and build the :class:`Scene` (``memo``:
    :meth:`load_scene`'s)."""
    if not isinstance(data, dict):
        raise ConfigError(f"scene {origin}: expected a table")
    for section in data:
        if section not in SECTIONS:
            raise ConfigError(f"unknown section [{section}] in scene {origin}; valid sections: "
                              f"{', '.join(SECTIONS)}")
    raw_p = data.get("pendulum")
    if raw_p is None:
        raise ConfigError(f"scene {origin} has no [pendulum] section")
    kind = raw_p.get("kind") if isinstance(raw_p, dict) else None
    if not isinstance(kind, str) or kind not in PENDULUM_KINDS:
        raise ConfigError(f"pendulum.kind = {kind!r} is invalid: expected one of "
                          f"{', '.join(PENDULUM_KINDS)}")
    settings = {}
    for section in SECTIONS:
        raw = data.get(section, {})
        settings[section] = dict(_step(
            memo, ("section", section, kind, _frozen(raw)),
            lambda: _validate_section(section, raw, section_keys(section, kind))))
    chain = _step(memo, ("chain", _frozen(settings["pendulum"]), _frozen(raw_p)),
                  lambda: _finite_chain(settings["pendulum"], raw_p))
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

    def device(cls, section, **more):
        return _step(memo, (section, _frozen(settings[section]), _frozen(more)),
                     lambda: cls(**settings[section], **more))

    acquisition = device(AcquisitionSettings, "acquisition")
    return Scene(name=settings["scene"]["name"], description=settings["scene"]["description"],
                 origin=origin, settings=settings, chain=chain, mirror=mirror,
                 theta0_rad=tuple(theta0), omega0_rad_s=tuple(omega0),
                 source=device(Source, "source", fs_hz=acquisition.simulation_rate_hz),
                 stage=device(Stage, "stage"), accelerometer=device(Accelerometer, "accelerometer"),
                 lever=device(OpticalLever, "psd"), acquisition=acquisition)


def section_keys(section: str, kind: str) -> dict[str, Key]:
    """The keys of ``[section]`` for a pendulum of ``kind`` (the pendulum's common keys and its
    kind's; every other section's keys do not depend on the kind)."""
    if section == "pendulum":
        return {**SECTIONS["pendulum"], **PENDULUM_KINDS[kind]}
    return SECTIONS[section]
