"""``daq scene show`` as TOML and as text without Python reprs, and ``daq acquire SCENE``."""

import pytest
from click.testing import CliRunner

from daq.cli import main
from daq.hdf5 import read_run
from rig.scene import load_scene


@pytest.fixture
def runner():
    return CliRunner()


def test_scene_show_toml_is_a_scene_file_that_loads_back(runner, tmp_path):
    res = runner.invoke(main, ["scene", "show", "rod-chain", "--set", "pendulum.n=3", "--toml"])
    assert res.exit_code == 0, res.output
    assert res.output.startswith("# scene rod-chain resolved from preset:rod-chain "
                                 "--set pendulum.n=3 by pendulum-daq ")
    p = tmp_path / "mine.toml"
    p.write_text(res.output)
    assert load_scene(p).settings == load_scene("rod-chain", ["pendulum.n=3"]).settings


def test_scene_show_text_has_json_values_not_python_reprs(runner):
    res = runner.invoke(main, ["scene", "show", "ishizaki2009"])
    assert res.exit_code == 0, res.output
    assert "l_m: null" in res.output and "reaction: true" in res.output
    for word in ("None", "True", "False"):
        assert word not in res.output


def test_scene_show_refuses_json_and_toml_together(runner):
    res = runner.invoke(main, ["scene", "show", "ishizaki2009", "--json", "--toml"])
    assert res.exit_code == 2 and "give --json or --toml, not both" in res.output


SHORT = ["--records", "1", "--duration", "2", "--rate", "50", "--set", "acquisition.settle_s=1",
         "--seed", "3", "--quiet"]


def test_acquire_takes_the_scene_as_argument_or_as_the_scene_option(runner, tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    res = runner.invoke(main, ["acquire", "ishizaki2009", *SHORT, "--out", str(a)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["acquire", "--scene", "ishizaki2009", *SHORT, "--out", str(b)])
    assert res.exit_code == 0, res.output
    assert (read_run(a).codes["a"] == read_run(b).codes["a"]).all()


@pytest.mark.parametrize("args, message", [
    (["double-rod", "--scene", "ishizaki2009"], "two scenes given: 'double-rod' and --scene"),
    ([], "missing the scene: daq acquire SCENE"),
])
def test_acquire_needs_exactly_one_scene(runner, tmp_path, args, message):
    out = tmp_path / "r.h5"
    res = runner.invoke(main, ["acquire", *args, *SHORT, "--out", str(out)])
    assert res.exit_code == 2 and message in res.output
    assert not out.exists()


def test_acquire_progress_shows_average_n_of_N_and_time_left():
    from daq.cli.acquire import _ProgressBar

    bar = _ProgressBar("acquiring", records=30, record_s=100.0, settle_s=300.0)
    assert bar.status(0.0) == "settling, average 0 of 30"
    assert bar.status(299.9) == "settling, average 0 of 30"
    assert bar.status(300.0) == "average 0 of 30"
    assert bar.status(499.99) == "average 1 of 30"
    assert bar.status(500.0) == "average 2 of 30"
    assert bar.status(3300.0) == "average 30 of 30"
    bar(0.0, 3300.0)
    try:
        assert bar.bar.show_eta and bar.bar.item_show_func(None) == "settling, average 0 of 30"
        bar(1400.0, 3300.0)
        assert bar.bar.item_show_func(None) == "average 11 of 30"
    finally:
        bar.close()
