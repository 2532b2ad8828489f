"""Bad input, fuzzed (hypothesis, bounded: fixed example counts, no deadline): scene values,
``--set`` strings, TOML files (binary junk and mutated presets) and analyzer settings. An invalid
input is a ConfigError (the analyzer's: a SettingsError) whose message names the key; never
another exception type. A valid but extreme scene either resolves, with a finite model, or stops
with a clear error of the rig (a RigError)."""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from faults import record_inputs
from rig.errors import ConfigError, RigError
from rig.scene import PENDULUM_KINDS, SECTIONS, load_scene, preset_text

FUZZ = settings(max_examples=200, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])
KEYS = sorted({(s, k) for s, keys in SECTIONS.items() for k in keys}
              | {("pendulum", k) for k in PENDULUM_KINDS["ishizaki"]})
_counts: dict[str, int] = {}


def _count(kind):
    _counts[kind] = _counts.get(kind, 0) + 1
    record_inputs(kind, 1)


def _toml(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return {math.inf: "inf", -math.inf: "-inf"}.get(v, "nan" if v != v else repr(v))
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(v)


VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-1e3, max_value=1e3),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, 5e-324, 2.0 ** 63, -1.0]),
    st.integers(min_value=-2 ** 70, max_value=2 ** 70),
    st.booleans(),
    st.text(max_size=12),
    st.lists(st.floats(allow_nan=True), max_size=4),
)


def _model_is_finite_or_clear(scene):
    """A resolved scene's exact model: finite, or a clear rig error."""
    from rig.describe import log_grid, mirror_response

    try:
        r = mirror_response(scene, log_grid(0.1, 10.0, 20))
    except RigError:
        return
    assert np.all(np.isfinite(r.x)) and np.all(np.isfinite(r.y)), scene.settings["pendulum"]


@FUZZ
@given(key=st.sampled_from(KEYS), value=VALUES)
def test_any_scene_value_resolves_or_is_a_config_error_naming_its_key(key, value):
    section, name = key
    item = f"{section}.{name}={_toml(value)}"
    _count("scene values (one --set each, every key)")
    try:
        scene = load_scene("ishizaki2009", [item])
    except ConfigError as exc:
        assert name in str(exc) or section in str(exc), (item, str(exc))
        assert "\n" not in str(exc).strip()
        return
    except RigError:
        return  # a clear numerical error of the rig
    _model_is_finite_or_clear(scene)


@FUZZ
@given(item=st.one_of(st.text(max_size=40),
                      st.builds(lambda k, v: f"{k}={v}", st.text(max_size=20),
                                st.text(max_size=20))))
def test_any_set_string_is_applied_or_a_config_error(item):
    _count("--set strings (arbitrary text)")
    try:
        load_scene("ishizaki2009", [item])
    except ConfigError as exc:
        assert str(exc).strip()
    except RigError:
        pass


@FUZZ
@given(data=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode)))
def test_any_file_given_as_a_scene_is_a_config_error_naming_the_file(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("toml") / "scene.toml"
    p.write_bytes(data)
    _count("scene files (binary and text junk)")
    try:
        load_scene(p)
    except ConfigError as exc:
        assert str(p) in str(exc) or "pendulum" in str(exc) or "section" in str(exc), str(exc)
    except RigError:
        pass


@FUZZ
@given(flips=st.lists(st.tuples(st.integers(min_value=0), st.integers(0, 255)), min_size=1,
                      max_size=4))
def test_a_mutated_preset_resolves_or_is_a_config_error(tmp_path_factory, flips):
    text = bytearray(preset_text("ishizaki2009").encode())
    for at, byte in flips:
        text[at % len(text)] = byte
    p = tmp_path_factory.mktemp("toml") / "mutated.toml"
    p.write_bytes(bytes(text))
    _count("mutated preset files (1-4 bytes changed)")
    try:
        scene = load_scene(p)
    except RigError:
        return
    _model_is_finite_or_clear(scene)


ANALYZER = {
    "window": st.one_of(st.sampled_from(["hann", "uniform", "flattop", "force", "exponential"]),
                        st.text(max_size=8)),
    "averaging": st.one_of(st.sampled_from(["rms", "vector", "exponential", "peak"]),
                           st.text(max_size=8)),
    "nperseg": st.one_of(st.none(), st.integers(-10, 10 ** 7), st.floats(allow_nan=True)),
    "lines": st.one_of(st.none(), st.integers(-10, 10 ** 6)),
    "span_hz": st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True)),
    "overlap": st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.5)),
    "fmin_hz": st.floats(allow_nan=True, allow_infinity=True),
    "fmax_hz": st.floats(allow_nan=True, allow_infinity=True),
}


@FUZZ
@given(kw=st.fixed_dictionaries({}, optional=ANALYZER))
def test_any_analyzer_settings_are_valid_or_a_settings_error_naming_the_key(kw):
    from processing.analyzer import AnalyzerSettings
    from processing.spectra import SettingsError

    _count("analyzer settings")
    try:
        s = AnalyzerSettings(**kw)
        s.spectral(100.0, 10000)  # the paper's record: 100 s at 100 Hz
    except SettingsError as exc:
        assert any(k in str(exc) for k in kw) or "record" in str(exc), (kw, str(exc))


EXTREMES = ["1e300", "-1e300", "1e-300", "5e-324", "9.3e18", "1e15", "1e9", "1e5", "1e-5",
            "1e-9", "1e-15", "0", "-1"]


def test_extreme_values_of_every_key_resolve_with_a_finite_model_or_name_the_key():
    """Every scene key at 13 extreme magnitudes (each alone, on the paper's scene)."""
    import warnings

    for section, name in KEYS:
        for v in EXTREMES:
            item = f"{section}.{name}={v}"
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # an overflow warning is a failure too
                try:
                    scene = load_scene("ishizaki2009", [item])
                except RigError as exc:
                    assert name in str(exc), (item, str(exc))
                    continue
                _model_is_finite_or_clear(scene)
    record_inputs("scene values at extreme magnitudes (every key)", len(KEYS) * len(EXTREMES))
