"""The typed scene round-trips: ``load_scene(scene.to_dict()) == scene`` and the settings a run file
stores (JSON) rebuild the same scene, for valid values drawn from every device and acquisition
key's own declared range and choices (hypothesis, bounded example count); the key tables are
the dataclasses' fields."""

import dataclasses
import json

from hypothesis import given, settings
from hypothesis import strategies as st

from rig.acquisition_settings import AcquisitionSettings
from rig.devices import Accelerometer, OpticalLever, Source, Stage
from rig.params import keys_of
from rig.scene import SECTIONS, load_scene, preset_names, scene_from_settings

ROUND = settings(max_examples=40, deadline=None, derandomize=True, database=None)
#: the sections whose keys are dataclass fields, and their classes
TYPED = {"source": Source, "stage": Stage, "accelerometer": Accelerometer, "psd": OpticalLever,
         "acquisition": AcquisitionSettings}


def _value(key):
    """Valid values of one key: its choices, a bool, or a number inside its static range."""
    if key.choices:
        return st.sampled_from(key.choices)
    if key.type == "bool":
        return st.booleans()
    if key.lo is not None:
        return st.floats(min_value=key.lo, max_value=key.lo + 1e3, exclude_min=key.strict)
    return None


OVERRIDES = st.lists(st.sampled_from([
    (section, name, strategy) for section, cls in TYPED.items()
    for name, key in keys_of(cls).items() if (strategy := _value(key)) is not None]),
    max_size=6, unique_by=lambda t: t[:2])


def test_the_typed_sections_key_tables_are_their_dataclass_fields():
    for section, cls in TYPED.items():
        fields = [f.name for f in dataclasses.fields(cls) if "key" in f.metadata]
        assert list(SECTIONS[section]) == fields
        assert all(SECTIONS[section][f.name].default == f.default
                   for f in dataclasses.fields(cls) if "key" in f.metadata)
    assert "fs_hz" not in SECTIONS["source"]  # the DAC rate is acquisition.simulation_rate_hz


@ROUND
@given(preset=st.sampled_from(preset_names()), picks=OVERRIDES, data=st.data())
def test_to_dict_and_the_stored_settings_reload_to_the_same_scene(preset, picks, data):
    overrides = [f"{s}.{k}={data.draw(strategy)!r}".replace("True", "true").replace("False",
                                                                                  "false")
                 for s, k, strategy in picks]
    scene = load_scene(preset, overrides)
    again = load_scene(scene.to_dict())
    assert again == scene
    assert again.origin == scene.origin == f"preset:{preset}"
    stored = json.loads(json.dumps(scene.settings, sort_keys=True))  # what a run file holds
    assert scene_from_settings(stored, origin=scene.origin) == scene
    assert list(again.settings) == list(SECTIONS)
    assert [list(again.settings[s]) for s in TYPED] == [list(SECTIONS[s]) for s in TYPED]


def test_with_acquisition_equals_loading_the_changed_scene():
    scene = load_scene("ishizaki2009")
    forced = scene.with_acquisition(model="linear", simulation_rate_hz=2000.0)
    assert forced == load_scene("ishizaki2009", ["acquisition.model=linear",
                                                 "acquisition.simulation_rate_hz=2000.0"])
    assert forced.source.fs_hz == 2000.0 and scene.acquisition.model == "auto"
