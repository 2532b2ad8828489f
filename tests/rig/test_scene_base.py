"""Scenes that start from another (base = "PRESET" or a file), and the complete TOML a scene
writes back (``daq scene show --toml``), which loads to the same scene."""

import numpy as np
import pytest

from rig.errors import ConfigError
from rig.scene import SECTIONS, load_scene, preset_names
from rig.scene_toml import scene_toml


def same_scene(a, b):
    assert a.settings == b.settings
    assert a.chain == b.chain
    assert (a.mirror, a.theta0_rad, a.omega0_rad_s) == (b.mirror, b.theta0_rad, b.omega0_rad_s)


def test_base_preset_inherits_every_key_not_given_and_the_file_names_the_scene(tmp_path):
    p = tmp_path / "soft.toml"
    p.write_text('base = "ishizaki2009"\n[pendulum]\nq1 = 300.0\n[source]\nlevel_vrms = 0.5\n')
    sc, ref = load_scene(p), load_scene("ishizaki2009")
    assert sc.settings["pendulum"]["q1"] == 300.0
    assert sc.settings["source"]["level_vrms"] == 0.5
    for section, values in ref.settings.items():
        for key, value in values.items():
            if (section, key) not in {("pendulum", "q1"), ("source", "level_vrms"),
                                      ("scene", "name")}:
                assert sc.settings[section][key] == value, (section, key)
    assert sc.settings["scene"]["name"] == "soft"  # a file is named after itself
    assert sc.origin == f"{p} (base preset:ishizaki2009)"


def test_base_file_is_relative_to_the_file_naming_it_and_bases_chain(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "mid.toml").write_text('base = "ishizaki2009"\n[pendulum]\nq2 = 50.0\n')
    top = tmp_path / "sub" / "top.toml"
    top.write_text('base = "../mid.toml"\n[scene]\nname = "top"\n')
    sc = load_scene(top)
    assert (sc.name, sc.settings["pendulum"]["q2"], sc.settings["pendulum"]["q1"]) == \
        ("top", 50.0, 530.0)


def test_overrides_apply_after_the_base(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('base = "rod-chain"\n[pendulum]\nn = 3\n')
    assert load_scene(p, ["pendulum.n=4"]).chain.n == 4
    assert load_scene(p).chain.n == 3


def test_other_pendulum_kind_than_the_base_inherits_no_pendulum_key(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('base = "ishizaki2009"\n[pendulum]\nkind = "rod-chain"\nn = 2\n'
                 'total_length_m = 1.0\n')
    sc = load_scene(p)
    assert sc.chain.n == 2 and "q1" not in sc.settings["pendulum"]
    assert sc.settings["stage"] == load_scene("ishizaki2009").settings["stage"]


def test_a_base_cycle_and_a_bad_base_are_one_line_errors(tmp_path):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('base = "b.toml"\n')
    b.write_text('base = "a.toml"\n')
    with pytest.raises(ConfigError, match="comes back to itself"):
        load_scene(a)
    a.write_text("base = 3\n")
    with pytest.raises(ConfigError, match=r"base = 3 is invalid: expected a preset name"):
        load_scene(a)
    a.write_text('base = "no-such-preset"\n')
    with pytest.raises(ConfigError, match="'no-such-preset' is not a preset"):
        load_scene(a)


@pytest.mark.parametrize("name", preset_names())
def test_toml_of_every_preset_loads_back_to_the_same_scene(name, tmp_path):
    sc = load_scene(name)
    p = tmp_path / "dump.toml"
    p.write_text(scene_toml(sc, header="from a preset"))
    same_scene(load_scene(p), sc)


@pytest.mark.parametrize("overrides", [
    ["pendulum.l_m=0.03", "scene.description=\"caf\u00e9 \\\"quoted\\\" \\\\ tab\\t\""],
    ["pendulum.rod_lengths_m=[0.1, 0.25, 0.4]", "initial.theta0_rad=[0.1, 0.2, 0.3]",
     "acquisition.antialias_attenuation_db=90.0", "stage.reaction=false"],
])
def test_toml_round_trip_keeps_unset_keys_strings_lists_and_booleans(overrides, tmp_path):
    base = "rod-chain" if "rod_lengths" in overrides[0] else "ishizaki2009"
    sc = load_scene(base, overrides)
    text = scene_toml(sc)
    p = tmp_path / "dump.toml"
    p.write_text(text)
    same_scene(load_scene(p), sc)


def test_toml_gives_every_key_with_its_documentation():
    text = scene_toml(load_scene("ishizaki2009"))
    assert "# l_m =  # not set: O1 to O2 [m]; default r1_m (O2 at G1)" in text
    assert "q1 = 530.0  # quality factor of stage 1" in text
    assert "reaction = true  #" in text
    assert "None" not in text and "True" not in text
    assert text.count("\n[") == len(SECTIONS) - 1  # every section; the first on line 1
