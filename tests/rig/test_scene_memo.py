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
