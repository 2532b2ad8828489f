"""rig.scene_memo: a pure function of a scene is computed once per scene and arguments, and
every caller gets its own copy."""

import numpy as np

from rig.scene import load_scene
from rig.scene_memo import per_scene, scene_key


def test_a_memoised_function_runs_once_per_scene_and_arguments_and_hands_out_copies():
    calls = []

    @per_scene(maxsize=2)
    def f(scene, grid, *, flag=False):
        calls.append(1)
        return {"level": scene.source.level_vrms, "grid": np.array(grid) * 2}

    a = load_scene("ishizaki2009")
    b = load_scene("ishizaki2009", ["source.level_vrms=0.2"])
    g = np.linspace(0, 1, 5)
    first = f(a, g)
    first["grid"][0] = 99.0  # the caller's copy, not the memo's
    again = f(load_scene("ishizaki2009"), g.copy())  # an equal scene, an equal grid
    assert len(calls) == 1 and again["grid"][0] == 0.0
    assert f(b, g)["level"] == 0.2 and len(calls) == 2
    f(a, g, flag=True)
    f(a, g[:3])
    assert len(calls) == 4
    assert scene_key(a) == scene_key(load_scene("ishizaki2009")) != scene_key(b)


def test_the_model_choice_is_memoised_per_scene():
    from rig.bench import select_model

    sc = load_scene("ishizaki2009", ["acquisition.records=1", "acquisition.record_s=2",
                                     "acquisition.settle_s=1"])
    one = select_model(sc)
    two = select_model(sc)
    assert one == two and one is not two


def test_settings_a_function_ignores_are_left_out_of_its_key():
    calls = []

    @per_scene(ignore=("source.level_vrms",))
    def f(scene):
        calls.append(1)
        return len(calls)

    f(load_scene("ishizaki2009"))
    f(load_scene("ishizaki2009", ["source.level_vrms=0.37"]))  # ignored: one entry
    assert len(calls) == 1
    f(load_scene("ishizaki2009", ["source.fmax_hz=10"]))  # not ignored
    assert len(calls) == 2
    a, b = load_scene("ishizaki2009"), load_scene("ishizaki2009", ["source.level_vrms=0.37"])
    assert scene_key(a, ("source.level_vrms",)) == scene_key(b, ("source.level_vrms",))
    assert scene_key(a) != scene_key(b) and "level_vrms" in scene_key(a)


def test_the_expected_responses_do_not_depend_on_the_drive_level_which_their_memo_ignores():
    # what lets a sweep of the drive's level compute the responses once: computed afresh (the
    # memo emptied) at two levels and two source types, they are equal bit for bit
    from rig.bench import expected_response

    f = np.linspace(0.0, 49.9, 101)
    for base in ([], ["source.type=burst-random"]):
        got = []
        for level in ("0.1", "2.5"):
            expected_response.cache_clear()
            sc = load_scene("ishizaki2009", [*base, f"source.level_vrms={level}"])
            got.append([expected_response(sc, f, sampled=s) for s in (True, False)])
        for one, two in zip(*got):
            for name in ("a", "x", "y", "h_t", "theta_2", "stage_accel", "theta"):
                assert np.asarray(getattr(one, name)).tobytes() == \
                    np.asarray(getattr(two, name)).tobytes(), name
    expected_response.cache_clear()
