"""The sweep file: a TOML description of many runs, validated completely before any work starts.

A sweep file names a base scene, the settings every run shares and the parameters that vary::

    seed = 2026                          # the sweep seed (0 <= seed < 2**63)
    scene = "ishizaki2009"               # base scene: a preset or a TOML file (relative to this)
    set = ["acquisition.records=30"]     # --set-style overrides applied to every run

    [grid]                               # parameters on a grid
    combine = "cross"                    # "cross": every combination; "zip": element by element
    "source.level_vrms" = { logspace = [0.02, 0.5], num = 6 }   # log-spaced values, ends included
    "pendulum.q1" = { linspace = [300.0, 800.0], num = 4 }      # evenly spaced, ends included
    "stage.reaction" = [true, false]                            # a list of values

    [random]                             # parameters drawn at random, ``count`` draws per grid point
    count = 5                            # kinds: uniform, loguniform, normal (+ bounds)
    "pendulum.q2" = { loguniform = [50.0, 200.0] }

    [analysis]                           # processing.analyzer.AnalyzerSettings fields
    window = "hann"

    [keep]                               # what each run file keeps besides the run itself
    truth = true                         # the ground truth (acquisition.truth)
    spectra = true                       # auto and cross spectra at the analyzer's lines
    frf = true                           # H_t, Theta_2 with coherence and relative error
    modal = true                         # the modal fits' f, Q and their standard deviations
    expected = true                      # the exact model and E[H1] at the analyzer's lines
    analysis = true                      # false: no analysis (signals, truth and model only)

Parameters are scene keys (``section.key``, see :mod:`rig.scene`), written as quoted dotted keys
or as nested tables (``[grid.pendulum] q1 = [...]``). Without ``[grid]`` and ``[random]`` the
sweep is one run (or ``count`` seeds). Run ``i`` (0-based, grid points in order, the last grid
parameter varying fastest, then the draws of each point) has the seed
``SeedSequence(seed, spawn_key=(i,))`` (:func:`run_seed`) and its random parameters are drawn from
``SeedSequence(seed, spawn_key=(i, 0))`` in the order they are written, so a run's scene and data
do not depend on the sweep's size, the order the runs finish in or the engine.

Validation (:func:`load_sweep`) raises :class:`rig.errors.ConfigError` naming the key, the value
and what is valid for anything wrong with the file itself; a parameter *set* the scene rejects
(a negative Q from a wide normal draw) fails only that run, with the scene's message.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rig.validation import integer, number
from rig.errors import ConfigError

__all__ = ["Sweep", "Parameter", "RunSpec", "load_sweep", "parse_sweep", "run_seed",
           "KEEP_DEFAULTS", "GRID_KINDS", "RANDOM_KINDS", "MAX_RUNS"]

GRID_KINDS = ("values", "linspace", "logspace")
RANDOM_KINDS = ("uniform", "loguniform", "normal")
#: What a run keeps besides the acquisition's run file (raw records and the exact model response
#: are the run format itself and are always kept).
KEEP_DEFAULTS = {"truth": True, "spectra": True, "frf": True, "modal": True, "expected": True}
_TOP = ("seed", "scene", "set", "name", "description", "grid", "random", "analysis", "keep")
#: The largest sweep accepted: planning checks every run's scene (what the runs share once; a
#: varied pendulum means its chain and modes per run) and keeps its settings, so 100,000 runs
#: take a while and memory to plan (BENCHMARKS.md "Analysis and datasets"); split a larger sweep into several.
MAX_RUNS = 100_000


@dataclass(frozen=True)
class Parameter:
    """One varied scene key: ``key`` ("section.name"), ``kind`` (grid: values, linspace, logspace;
    random: uniform, loguniform, normal), the grid ``values`` or the draw's ``args`` and ``bounds``."""

    key: str
    kind: str
    values: tuple = ()
    args: tuple = ()
    bounds: tuple | None = None

    def draw(self, rng: np.random.Generator) -> float:
        """One random value (one uniform number consumed from ``rng``, whatever the kind)."""
        u = float(rng.random())
        if self.kind == "uniform":
            lo, hi = self.args
            return lo + (hi - lo) * u
        if self.kind == "loguniform":
            lo, hi = self.args
            return math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * u)
        # normal truncated to the bounds by the inverse CDF (one draw, no rejection)
        from scipy.special import ndtr, ndtri

        mu, sigma = self.args
        lo, hi = self.bounds if self.bounds is not None else (-math.inf, math.inf)
        plo, phi = ndtr((lo - mu) / sigma), ndtr((hi - mu) / sigma)
        x = mu + sigma * float(ndtri(plo + (phi - plo) * u))
        return min(max(x, lo), hi)

    def describe(self) -> dict:
        out = {"key": self.key, "kind": self.kind}
        if self.values:
            out["values"] = list(self.values)
        if self.args:
            out["args"] = list(self.args)
        if self.bounds is not None:
            out["bounds"] = list(self.bounds)
        return out


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: its ``index``, ``seed``, varied ``params`` ({key: value}), the scene
    overrides that make it (base ``set`` then the params) and ``spec_hash`` (sha256 of all that
    and of the shared settings: a run file whose hash differs belongs to another plan)."""

    index: int
    seed: int
    params: dict
    overrides: tuple
    spec_hash: str

    @property
    def name(self) -> str:
        """The run file's name, ``run_000042.h5``."""
        return f"run_{self.index:06d}.h5"


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file (:func:`load_sweep`)."""

    seed: int
    scene: str
    overrides: tuple
    grid: tuple
    combine: str
    random: tuple
    count: int
    analysis: dict
    keep: dict
    name: str = "sweep"
    description: str = ""
    source: str = "sweep"
    text: str = field(default="", repr=False, compare=False)

    @property
    def n_grid(self) -> int:
        if not self.grid:
            return 1
        sizes = [len(p.values) for p in self.grid]
        return math.prod(sizes) if self.combine == "cross" else sizes[0]

    @property
    def n_runs(self) -> int:
        return self.n_grid * self.count

    @property
    def parameter_keys(self) -> tuple:
        return tuple(p.key for p in self.grid) + tuple(p.key for p in self.random)

    def describe(self) -> dict:
        """Everything that decides the runs, as plain data (what a resumed sweep compares)."""
        return {"seed": self.seed, "scene": self.scene, "set": list(self.overrides),
                "grid": [p.describe() for p in self.grid], "combine": self.combine,
                "random": [p.describe() for p in self.random], "count": self.count,
                "analysis": dict(self.analysis), "keep": dict(self.keep)}

    def analyzer_settings(self):
        """The :class:`processing.analyzer.AnalyzerSettings` of every run."""
        from processing.analyzer import AnalyzerSettings

        return AnalyzerSettings(**_analysis_kwargs(self.analysis))

    def runs(self) -> list[RunSpec]:
        """Every run, in index order (parameters drawn, seeds derived; scenes not yet resolved)."""
        import itertools

        if self.grid:
            values = [p.values for p in self.grid]
            points = (list(itertools.product(*values)) if self.combine == "cross"
                      else list(zip(*values)))
        else:
            points = [()]
        # what decides a run besides its own overrides and seed (not the rest of the grid: a
        # run whose parameters stay keeps its file when the sweep is extended)
        shared = json.dumps({"seed": self.seed, "scene": self.scene, "set": list(self.overrides),
                             "analysis": self.analysis, "keep": self.keep,
                             "base_scene": _scene_digest(self)}, sort_keys=True)
        out = []
        for g, point in enumerate(points):
            for r in range(self.count):
                i = g * self.count + r
                params = {p.key: v for p, v in zip(self.grid, point)}
                if self.random:
                    rng = np.random.default_rng(np.random.SeedSequence(self.seed,
                                                                       spawn_key=(i, 0)))
                    for p in self.random:
                        params[p.key] = p.draw(rng)
                keep = () if self.keep["truth"] else ("acquisition.truth=false",)
                overrides = tuple(self.overrides) + keep + tuple(
                    f"{k}={_toml_value(v)}" for k, v in params.items())
                seed = run_seed(self.seed, i)
                h = hashlib.sha256(json.dumps([shared, i, seed, overrides]).encode()).hexdigest()
                out.append(RunSpec(index=i, seed=seed, params=params, overrides=overrides,
                                   spec_hash=h))
        return out


def run_seed(sweep_seed: int, index: int) -> int:
    """The seed of run ``index``: 63 bits of ``SeedSequence(sweep_seed, spawn_key=(index,))``
    (the same as ``SeedSequence(sweep_seed).spawn(n)[index]`` for any n)."""
    ss = np.random.SeedSequence(sweep_seed, spawn_key=(index,))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    return str(v)


def _scene_digest(sweep: Sweep) -> str:
    """sha256 of the base scene's text (a preset's or a file's): a changed file changes the plan."""
    from rig.scene import preset_names, preset_text

    p = Path(sweep.scene)
    if p.suffix == ".toml" or p.exists():
        text = p.read_text() if p.is_file() else ""
    else:
        text = preset_text(sweep.scene) if sweep.scene in preset_names() else ""
    return hashlib.sha256(text.encode()).hexdigest()


# -- parsing ---------------------------------------------------------------------------------

def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file (module docstring). Raises ConfigError."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep file {str(path)!r} does not exist")
    text = path.read_text()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"sweep file {str(path)!r}: invalid TOML: {exc}") from None
    return parse_sweep(data, base_dir=path.parent, source=str(path), text=text)


def parse_sweep(data: dict, *, base_dir: str | Path = ".", source: str = "sweep",
                text: str = "") -> Sweep:
    """Validate parsed sweep data (:func:`load_sweep` without the file)."""
    from rig.scene import load_scene

    data = copy.deepcopy(data)
    for k in data:
        if k not in _TOP:
            raise ConfigError(f"unknown key {k} = {_short(data[k])} in the sweep file; valid "
                              f"keys: {', '.join(_TOP)}")
    seed = data.get("seed")
    if seed is None:
        raise ConfigError("missing required key seed (the sweep seed, an integer "
                          "0 <= seed < 2**63)")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 63:
        raise ConfigError(f"seed = {seed!r} is invalid: expected an integer 0 <= seed < 2**63")
    scene = data.get("scene")
    if not isinstance(scene, str) or not scene:
        raise ConfigError(f"scene = {scene!r} is invalid: expected a preset name or a scene "
                          "TOML file (relative to the sweep file)")
    p = Path(scene)
    if p.suffix == ".toml" and not p.is_absolute():
        scene = str((Path(base_dir) / p).resolve())
    overrides = data.get("set", [])
    if not isinstance(overrides, list) or not all(isinstance(s, str) for s in overrides):
        raise ConfigError(f"set = {_short(overrides)} is invalid: expected a list of "
                          "\"section.key=value\" strings")
    try:
        base = load_scene(scene, overrides)
    except ConfigError as exc:
        raise ConfigError(f"scene = {data['scene']!r} with set = {overrides!r}: {exc}") from None
    for k in ("name", "description"):
        if k in data and not isinstance(data[k], str):
            raise ConfigError(f"{k} = {data[k]!r} is invalid: expected a string")

    grid_raw = data.get("grid", {})
    if not isinstance(grid_raw, dict):
        raise ConfigError(f"grid = {_short(grid_raw)} is invalid: expected a table")
    grid_raw = dict(grid_raw)
    combine = grid_raw.pop("combine", "cross")
    if combine not in ("cross", "zip"):
        raise ConfigError(f"grid.combine = {combine!r} is invalid: expected \"cross\" (every "
                          "combination) or \"zip\" (element by element)")
    grid = tuple(_grid_parameter(k, v, base) for k, v in _flatten("grid", grid_raw).items())
    if combine == "zip" and len({len(p.values) for p in grid}) > 1:
        sizes = ", ".join(f"{p.key}: {len(p.values)}" for p in grid)
        raise ConfigError(f"grid.combine = \"zip\" needs grids of one length; got {sizes}")

    rand_raw = data.get("random", {})
    if not isinstance(rand_raw, dict):
        raise ConfigError(f"random = {_short(rand_raw)} is invalid: expected a table")
    rand_raw = dict(rand_raw)
    count = rand_raw.pop("count", 1)
    count = integer("random.count", count, minimum=1,
                    valid="an integer >= 1 (runs per grid point)")
    if count > MAX_RUNS:
        raise ConfigError(f"random.count = {count} is invalid: a sweep has at most {MAX_RUNS} "
                          "runs (split it into several sweeps)")
    random = tuple(_random_parameter(k, v, base) for k, v in _flatten("random", rand_raw).items())
    keys = [p.key for p in grid] + [p.key for p in random]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise ConfigError(f"parameter {dup[0]} is varied twice (in grid and random); vary it once")

    analysis = data.get("analysis", {})
    if not isinstance(analysis, dict):
        raise ConfigError(f"analysis = {_short(analysis)} is invalid: expected a table of "
                          "AnalyzerSettings fields")
    _check_analysis(analysis)
    keep = data.get("keep", {})
    if not isinstance(keep, dict):
        raise ConfigError(f"keep = {_short(keep)} is invalid: expected a table of "
                          f"{', '.join(KEEP_DEFAULTS)} = true/false")
    for k, v in keep.items():
        if k in ("raw", "model"):
            if v is not True:
                raise ConfigError(f"keep.{k} = {v!r} is invalid: the raw records and the exact "
                                  "model response are the run file itself and are always kept "
                                  "(expected true)")
            continue
        if k not in KEEP_DEFAULTS and k != "analysis":
            raise ConfigError(f"unknown key keep.{k} = {_short(v)}; valid keys: raw, model, "
                              f"analysis, {', '.join(KEEP_DEFAULTS)}")
        if not isinstance(v, bool):
            raise ConfigError(f"keep.{k} = {v!r} is invalid: expected true or false")
    keep = _keep(keep)
    sweep = Sweep(seed=seed, scene=scene, overrides=tuple(overrides), grid=grid, combine=combine,
                  random=random, count=count, analysis=dict(analysis), keep=keep,
                  name=data.get("name", Path(source).stem if source != "sweep" else "sweep"),
                  description=data.get("description", ""), source=source, text=text)
    if sweep.n_runs > MAX_RUNS:
        raise ConfigError(f"the sweep has {sweep.n_runs} runs: expected at most {MAX_RUNS} "
                          "(split it into several sweeps)")
    return sweep


_SPEC_KEYS = set(GRID_KINDS) | set(RANDOM_KINDS) | {"num", "bounds"}


def _keep(keep: dict) -> dict:
    """The validated ``[keep]`` table with its defaults. ``analysis = false`` (raw-only runs)
    turns every analysis output off (naming one of them true with it is an error) and is then
    part of the table; when the analysis runs, ``analysis`` is left out of it, so that the plans
    (and spec hashes) of sweeps written before the key existed are unchanged."""
    out = {**KEEP_DEFAULTS, **{k: v for k, v in keep.items() if k in KEEP_DEFAULTS}}
    if keep.get("analysis", True):
        return out
    wanted = [k for k in KEEP_DEFAULTS if k != "truth" and keep.get(k) is True]
    if wanted:
        raise ConfigError(f"keep.{wanted[0]} = true needs the analysis, but keep.analysis = "
                          f"false: remove keep.{wanted[0]} or set keep.analysis = true")
    return {**out, **{k: False for k in KEEP_DEFAULTS if k != "truth"}, "analysis": False}


def _flatten(section: str, raw: dict, prefix: str = "") -> dict:
    """{"a.b": spec} from quoted dotted keys and nested tables; a table holding a spec keyword
    (linspace, uniform, ...), or under a key that is already ``section.name``, is a spec, not a
    section (so a misspelt keyword is reported as such, not as a scene key)."""
    out = {}
    for k, v in raw.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and "." not in key and not (set(v) & _SPEC_KEYS):
            out.update(_flatten(section, v, f"{key}."))
        else:
            out[key] = v
    return out


def _scene_key(where: str, key: str, base):
    """The :class:`rig.scene.Key` of ``section.name``; ConfigError naming the valid keys."""
    from rig.scene import SECTIONS, section_keys

    parts = key.split(".")
    if len(parts) != 2:
        raise ConfigError(f"{where}.{key} is invalid: expected a scene key section.name "
                          f"(sections: {', '.join(SECTIONS)})")
    section, name = parts
    if section not in SECTIONS:
        raise ConfigError(f"{where}.{key}: unknown scene section [{section}]; valid sections: "
                          f"{', '.join(SECTIONS)}")
    keys = section_keys(section, base.pendulum_kind)
    if name not in keys:
        raise ConfigError(f"{where}.{key}: unknown key {name!r} of [{section}]; valid keys: "
                          f"{', '.join(sorted(keys))}")
    return keys[name]


def _check_value(where: str, spec, v) -> Any:
    """One axis value checked like the scene checks its key (:func:`rig.params.check_value`);
    a per-body key (``floats``) takes one number per run."""
    from rig.params import check_value

    return number(where, v) if spec.type in ("float", "floats") else check_value(where, spec, v)


def _pair(where: str, v, *, positive: bool = False, ordered: bool = True) -> tuple:
    if not isinstance(v, list) or len(v) != 2:
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected [low, high]")
    lo, hi = (number(where, x) for x in v)
    if positive and not (lo > 0 and hi > 0):
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected two values > 0 (log "
                          "scale)")
    if ordered and not lo < hi:
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected low < high")
    return lo, hi


def _grid_parameter(key: str, v, base) -> Parameter:
    where = f"grid.{key}"
    spec = _scene_key("grid", key, base)
    if isinstance(v, list):
        if not v:
            raise ConfigError(f"{where} = [] is invalid: expected at least one value")
        values = tuple(_check_value(f"{where}[{i + 1}]", spec, x) for i, x in enumerate(v))
        return Parameter(key, "values", values=values)
    if not isinstance(v, dict):
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected a list of values or "
                          "{ linspace = [start, stop], num = N } or { logspace = [start, stop], "
                          "num = N }")
    kinds = [k for k in v if k in GRID_KINDS]
    extra = [k for k in v if k not in ("linspace", "logspace", "num")]
    if extra:
        raise ConfigError(f"{where}: unknown entry {extra[0]!r}; valid: linspace or logspace "
                          "with num (e.g. { linspace = [0.1, 0.5], num = 5 }), or a list of "
                          "values")
    if len(kinds) != 1 or kinds[0] == "values":
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected exactly one of linspace, "
                          "logspace with num (e.g. { linspace = [0.1, 0.5], num = 5 })")
    kind = kinds[0]
    if spec.type not in ("float", "floats"):
        raise ConfigError(f"{where} = {_short(v)} is invalid: {kind} makes numbers but {key} "
                          f"is a {spec.type}; give a list of values")
    num = v.get("num")
    num = integer(f"{where}.num", num, minimum=1)
    if num > MAX_RUNS:  # refused before the values are made
        raise ConfigError(f"{where}.num = {num} is invalid: a sweep has at most {MAX_RUNS} runs "
                          "(split it into several sweeps)")
    lo, hi = _pair(f"{where}.{kind}", v[kind], positive=kind == "logspace", ordered=False)
    vals = np.linspace(lo, hi, num) if kind == "linspace" else np.geomspace(lo, hi, num)
    return Parameter(key, kind, values=tuple(float(x) for x in vals), args=(lo, hi, num))


def _random_parameter(key: str, v, base) -> Parameter:
    where = f"random.{key}"
    spec = _scene_key("random", key, base)
    if spec.type not in ("float", "floats"):
        raise ConfigError(f"{where}: random draws make numbers but {key} is a {spec.type}; vary "
                          "it on the grid")
    if not isinstance(v, dict):
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected {{ uniform = [lo, hi] }}, "
                          "{ loguniform = [lo, hi] } or { normal = [mean, std], bounds = "
                          "[lo, hi] }")
    kinds = [k for k in v if k in RANDOM_KINDS]
    extra = [k for k in v if k not in RANDOM_KINDS and k != "bounds"]
    if extra:
        raise ConfigError(f"{where}: unknown distribution {extra[0]!r}; valid: "
                          f"{', '.join(RANDOM_KINDS)} (normal with optional bounds), e.g. "
                          "{ uniform = [0.5, 2.0] }")
    if len(kinds) != 1:
        raise ConfigError(f"{where} = {_short(v)} is invalid: expected exactly one of "
                          f"{', '.join(RANDOM_KINDS)} (and bounds for normal)")
    kind = kinds[0]
    if kind == "normal":
        if not isinstance(v["normal"], list) or len(v["normal"]) != 2:
            raise ConfigError(f"{where}.normal = {_short(v['normal'])} is invalid: expected "
                              "[mean, std]")
        mu, sigma = (number(f"{where}.normal", x) for x in v["normal"])
        if not sigma > 0:
            raise ConfigError(f"{where}.normal = {_short(v['normal'])} is invalid: expected a "
                              "std > 0")
        bounds = None
        if "bounds" in v:
            bounds = _pair(f"{where}.bounds", v["bounds"])
            from scipy.special import ndtr

            mass = ndtr((bounds[1] - mu) / sigma) - ndtr((bounds[0] - mu) / sigma)
            if not mass > 1e-12:
                raise ConfigError(f"{where}.bounds = {list(bounds)} is invalid: the normal "
                                  f"[{mu:g}, {sigma:g}] has no probability inside them")
        return Parameter(key, kind, args=(mu, sigma), bounds=bounds)
    if "bounds" in v:
        raise ConfigError(f"{where}.bounds is invalid for {kind}: its [lo, hi] are the bounds")
    lo, hi = _pair(f"{where}.{kind}", v[kind], positive=kind == "loguniform")
    return Parameter(key, kind, args=(lo, hi))


def _analysis_kwargs(analysis: dict) -> dict:
    kw = {}
    for k, v in analysis.items():
        kw[k] = tuple(v) if isinstance(v, list) else v
    return kw


def _check_analysis(analysis: dict) -> None:
    import dataclasses

    from processing.analyzer import AnalyzerSettings
    from processing.spectra import SettingsError

    names = [f.name for f in dataclasses.fields(AnalyzerSettings)]
    for k, v in analysis.items():
        if k not in names:
            raise ConfigError(f"unknown key analysis.{k} = {_short(v)}; valid keys: "
                              f"{', '.join(names)}")
    try:
        AnalyzerSettings(**_analysis_kwargs(analysis))
    except (SettingsError, TypeError, ValueError) as exc:
        raise ConfigError(f"analysis: {exc}") from None


def _short(v) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."
