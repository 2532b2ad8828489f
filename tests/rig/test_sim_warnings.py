"""A simulation says when its own error estimate is large against the motion (WARNING, recorded
in the trajectory file), and fixed-step runs put a sample on every whole second by default."""

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from daq.cli import main
from rig.scene import load_scene
from rig.sim_checks import WARN_FRACTION
from rig.simulate import simulate


def test_chaotic_double_rod_past_its_horizon_warns():
    sc = load_scene("double-rod")
    tr = simulate(sc.chain, 20, theta0=sc.theta0_rad)
    motion = np.max(np.ptp(tr.theta_rad, axis=0))
    assert tr.max_error_rad > WARN_FRACTION * motion  # the premise: 17 rad of ~50
    assert len(tr.warnings) == 1 and "not resolved" in tr.warnings[0]


def test_a_resolved_run_does_not_warn():
    sc = load_scene("double-rod")
    tr = simulate(sc.chain, 2, theta0=sc.theta0_rad)
    assert tr.max_error_rad < WARN_FRACTION * np.max(np.ptp(tr.theta_rad, axis=0))
    assert tr.warnings == ()
    small = simulate(sc.chain, 20, theta0=[0.01, 0.01], method="linear")
    assert small.warnings == ()


def test_linear_model_far_off_its_energy_warns():
    sc = load_scene("double-rod")
    tr = simulate(sc.chain, 20, theta0=sc.theta0_rad, method="linear")
    assert tr.max_error_rad < 1e-12  # its own estimate is round-off only ...
    assert len(tr.warnings) == 1 and "too large for the linearised model" in tr.warnings[0]


@pytest.mark.parametrize("method", ["rk4", "gauss4", "midpoint", "linear"])
def test_fixed_step_output_lands_on_every_whole_second(method):
    sc = load_scene("double-rod")
    tr = simulate(sc.chain, 7, theta0=[0.1, 0.1], method=method, estimate_error=False)
    np.testing.assert_allclose(tr.t_s, np.arange(8.0), rtol=0, atol=1e-12)
    tr = simulate(sc.chain, 6, theta0=[0.1, 0.1], method=method, output_dt_s=1.5,
                  estimate_error=False)
    np.testing.assert_allclose(tr.t_s, np.arange(5) * 1.5, rtol=0, atol=1e-12)


def test_simulate_cli_prints_and_records_the_warning(tmp_path):
    out = tmp_path / "t.h5"
    res = CliRunner().invoke(main, ["simulate", "double-rod", "--duration", "20", "--out",
                                    str(out)])
    assert res.exit_code == 0, res.output
    assert "WARNING: the estimated angle error" in res.stderr
    with h5py.File(out) as f:
        warnings = json.loads(f["trajectory"].attrs["warnings"])
    assert len(warnings) == 1 and warnings[0] in res.stderr
