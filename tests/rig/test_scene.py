"""Scenes: presets, TOML files, --set overrides and the errors bad values give."""

import math

import numpy as np
import pytest

from rig.errors import ConfigError
from rig.scene import apply_override, load_scene, preset_names, scene_from_settings

CHAIN_TOML = """
[scene]
name = "two-bodies"

[pendulum]
kind = "chain"
mass_kg = [0.2, 0.1]
length_m = [0.3, 0.2]
com_m = [0.15, 0.1]
inertia_kgm2 = [1.5e-3, 3e-4]
damping_nms = [1e-4, 1e-4]

[initial]
theta0_rad = [0.1, -0.2]
"""


@pytest.fixture
def chain_file(tmp_path):
    p = tmp_path / "two.toml"
    p.write_text(CHAIN_TOML)
    return p


def test_presets_listed_include_the_three_required():
    assert {"ishizaki2009", "double-rod", "rod-chain"} <= set(preset_names())


def test_double_rod_is_takenos_two_uniform_one_metre_rods():
    c = load_scene("double-rod").chain
    assert c.n == 2
    np.testing.assert_allclose(c.mass_kg, [1.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(c.length_m, [1.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(c.com_m, [0.5, 0.5], rtol=1e-15)
    np.testing.assert_allclose(c.inertia_kgm2, [1 / 12, 1 / 12], rtol=1e-15)
    assert load_scene("double-rod").theta0_rad == (2.0, 2.5)


@pytest.mark.parametrize("n", [1, 2, 7, 50])
def test_rod_chain_has_n_rods_of_total_length_one_metre(n):
    sc = load_scene("rod-chain", [f"pendulum.n={n}"])
    c = sc.chain
    assert c.n == n
    assert math.isclose(sum(c.length_m), 1.0, rel_tol=1e-12)
    assert math.isclose(sum(c.mass_kg), 1.0, rel_tol=1e-12)
    np.testing.assert_allclose(c.inertia_kgm2, np.array(c.mass_kg) * np.array(c.length_m) ** 2 / 12)
    assert len(sc.theta0_rad) == n
    assert sc.mirror.body == n - 1 and sc.mirror.position_m == c.com_m[-1]


def test_ishizaki_preset_mirror_sits_at_the_stage2_pivot():
    sc = load_scene("ishizaki2009")
    # x = l1 * theta1: the mirror centre at O2 on body 2
    np.testing.assert_array_equal(sc.mirror_weights(), [sc.chain.length_m[0], 0.0])
    assert sc.mirror.body == 1


def test_scene_file_loads_with_per_body_lists(chain_file):
    sc = load_scene(chain_file)
    assert sc.name == "two-bodies"
    assert sc.chain.mass_kg == (0.2, 0.1)
    assert sc.theta0_rad == (0.1, -0.2)
    assert sc.omega0_rad_s == (0.0, 0.0)


def test_overrides_set_values_list_elements_and_bare_strings(chain_file):
    sc = load_scene(chain_file, ["pendulum.mass_kg[2]=0.3", "pendulum.damping_mode=relative",
                                 "initial.omega0_rad_s=[1, 2]", "pendulum.g_mps2=9.81"])
    assert sc.chain.mass_kg == (0.2, 0.3)
    assert sc.chain.damping_mode == "relative"
    assert sc.omega0_rad_s == (1.0, 2.0)
    assert sc.chain.g_mps2 == 9.81


def test_resolved_settings_rebuild_the_same_scene():
    for name in preset_names():
        sc = load_scene(name)
        again = scene_from_settings(sc.settings)
        assert again.chain == sc.chain
        assert again.mirror == sc.mirror
        assert again.theta0_rad == sc.theta0_rad


@pytest.mark.parametrize("override, match", [
    ("pendulum.mass_kg[1]=0", r"pendulum\.mass_kg of body 1 = 0\.0 is invalid: expected > 0"),
    ("pendulum.mass_kg[1]=-0.1", r"mass_kg of body 1 = -0\.1 is invalid: expected > 0"),
    ("pendulum.mass_kg[1]=nan", r"pendulum\.mass_kg = nan is invalid: expected a finite number"),
    ("pendulum.length_m[2]=0", r"pendulum\.length_m of body 2 = 0\.0 is invalid: expected > 0"),
    ("pendulum.inertia_kgm2[1]=-1e-6", r"inertia_kgm2 of body 1 = -1e-06 is invalid: expected >= 0"),
    ("pendulum.damping_nms[1]=-1", r"damping_nms of body 1 = -1\.0 is invalid: expected >= 0"),
    ("pendulum.mass_kg=[0.1]", r"length_m has 2 entries; expected 1"),
    ("pendulum.mass_kg[1]='heavy'", r"pendulum\.mass_kg of body 1 = 'heavy' is invalid: expected a number"),
    ("pendulum.g_mps2=true", r"pendulum\.g_mps2 = True is invalid: expected a number"),
    ("pendulum.damping_mode=sticky", r"pendulum\.damping_mode = 'sticky' is invalid: expected one of absolute, relative"),
    ("pendulum.spring=1", r"unknown key pendulum\.spring = 1; valid keys: .*mass_kg"),
    ("bench.gain=1", r"unknown section \[bench\]"),
    ("mirror.body=3", r"mirror\.body = 3 is invalid: expected 1\.\.2"),
    ("mirror.position_m=0.5", r"mirror\.position_m = 0\.5 is invalid: expected 0 \.\. 0\.2 m"),
    ("initial.theta0_rad=[0.1, 0.2, 0.3]", r"initial\.theta0_rad has 3 entries; expected 1 or 2"),
    ("pendulum.com_m[1]=-0.2", r"com_m of body 1 = -0\.2 gives S_1 .* needs S_j > 0"),
])
def test_invalid_values_name_the_key_the_value_and_what_is_valid(chain_file, override, match):
    with pytest.raises(ConfigError, match=match):
        load_scene(chain_file, [override])


@pytest.mark.parametrize("override, match", [
    ("pendulum.n=0", r"pendulum\.n = 0 is invalid: expected 1 <= n <= 200"),
    ("pendulum.n=1000", r"pendulum\.n = 1000 is invalid: expected 1 <= n <= 200 \(the chain's "
                        r"modes are an O\(n\^3\) eigenproblem"),
    ("pendulum.n=2.5", r"pendulum\.n = 2\.5 is invalid: expected an integer"),
    ("pendulum.total_length_m=-1", r"total_length_m = -1\.0 is invalid: expected > 0"),
    ("pendulum.linear_density_kgpm=0", r"linear_density_kgpm = 0\.0 is invalid: expected > 0"),
])
def test_invalid_rod_chain_values_are_named(override, match):
    with pytest.raises(ConfigError, match=match):
        load_scene("rod-chain", [override])


@pytest.mark.parametrize("override, match", [
    ("pendulum.q1=0", r"pendulum\.q1 = 0\.0 is invalid: expected > 0"),
    ("pendulum.eps=1", r"pendulum\.eps = 1\.0 is invalid: expected > 1"),
    ("pendulum.r2_m=-1e-3", r"pendulum\.r2_m = -0\.001 is invalid: expected > 0"),
])
def test_invalid_ishizaki_design_values_are_named(override, match):
    with pytest.raises(ConfigError, match=match):
        load_scene("ishizaki2009", [override])


def test_unknown_scene_and_malformed_override_are_explained(tmp_path):
    with pytest.raises(ConfigError, match=r"scene 'nope' is not a preset \(.*ishizaki2009.*\)"):
        load_scene("nope")
    with pytest.raises(ConfigError, match=r"scene file .*missing\.toml.* does not exist"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match=r"override 'q1' is invalid: expected section\.key=value"):
        apply_override({}, "q1")
    bad = tmp_path / "bad.toml"
    bad.write_text("[pendulum\nkind=1")
    with pytest.raises(ConfigError, match=r"invalid TOML"):
        load_scene(bad)


def test_a_resolution_memo_gives_the_scenes_and_errors_of_loads_without_it():
    """Overrides that compare equal but are not the same value (2, 2.0, true; 0.0, -0.0), in
    both orders through one memo, and a failing step met twice: each result is that of a load
    without the memo."""
    from rig.errors import ConfigError
    from rig.scene import ResolutionMemo

    sets = [["acquisition.records=2"], ["acquisition.records=2.0"], ["acquisition.records=true"],
            ["stage.reaction=true"], ["stage.reaction=1"], ["initial.theta0_rad=-0.0"],
            ["initial.theta0_rad=0.0"], ["pendulum.f2_hz=20.0"], ["pendulum.q2=1e400"],
            ["initial.theta0_rad[2]=0.1"], ["initial.theta0_rad=[0.0, 0.1]"],
            ["source.level_vrms=-0.1"], ["source.level_vrms=0.2", "pendulum.q1=300"]]

    def outcome(overrides, memo):
        try:
            sc = load_scene("ishizaki2009", overrides, memo=memo)
        except ConfigError as exc:
            return str(exc)
        return repr(sc.settings), sc.chain, sc.source, sc.stage, sc.acquisition, sc.theta0_rad

    memo = ResolutionMemo()
    for order in (sets, sets[::-1], sets):
        for o in order:
            assert outcome(o, memo) == outcome(o, None), o
    base = load_scene("ishizaki2009", memo=memo)
    assert base == load_scene("ishizaki2009")
