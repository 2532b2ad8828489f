"""An output-only data set of the bench is what pyOMA2 takes, and its SSI finds the bench's exact
modes in it.

The exact modes are the coupled linear bench's poles (:func:`rig.bench.modes.bench_modes`): the
stage is shaken by the source's broadband noise, which the OMA does not see. The tolerance on
the frequencies, 0.5 %, is the issue's; SSI-cov on 1000 s of data resolves the two modes'
frequencies to about 0.1 % here (the lower mode's half-power bandwidth is 1 %), so the test can
fail if the truth or the data were wrong (the fixed-base 2.48 Hz mode, for one, is 1.7 % off).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from processing.oma import compare_modes, comparison_table, mac
from rig.bench.modes import bench_modes
from rig.scene import load_scene


@pytest.fixture(scope="module")
def oma_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("oma")
    run = d / "run.h5"
    cmd = [sys.executable, "-m", "daq.cli"]
    p = subprocess.run(cmd + ["acquire", "ishizaki2009", "--records", "10", "--seed", "2009",
                              "--out", str(run), "-q"], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    p = subprocess.run(cmd + ["export", str(run), "--oma", str(d / "oma.npz")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return d / "oma.npz"


def test_the_bench_modes_are_the_coupled_poles_not_the_fixed_base_ones():
    scene = load_scene("ishizaki2009")
    m = bench_modes(scene)
    fixed = scene.chain.natural_frequencies_hz()
    assert m.f_hz.size == 3  # the stage's own (0.098 Hz, heavily damped) and the pendulum's two
    assert abs(m.f_hz[2] / fixed[1] - 1) > 0.01  # the reaction moves the upper mode
    no_reaction = bench_modes(load_scene("ishizaki2009", ["stage.reaction=false"]))
    np.testing.assert_allclose(no_reaction.f_hz[-2:], fixed, rtol=1e-3)  # damping shifts |p|
    assert np.allclose(np.abs(m.shapes).max(axis=1), 1.0)


def test_pyoma2_ssi_finds_the_exact_modes_in_the_output_only_export(oma_file):
    pytest.importorskip("pyoma2")
    from pyoma2.algorithms import SSI
    from pyoma2.setup import SingleSetup

    z = np.load(oma_file)
    assert z["data"].shape == (10 * 10000, 2) and float(z["fs"]) == 100.0
    assert list(z["units"]) == ["m", "rad"]
    setup = SingleSetup(z["data"], float(z["fs"]))
    setup.decimate_data(q=4)  # 25 Hz: the modes are below 3 Hz
    ssi = SSI(name="SSIcov", method="cov", br=60, ordmax=20)
    setup.add_algorithms(ssi)
    setup.run_by_name("SSIcov")
    exact_f = z["exact_f_hz"]
    setup.mpe("SSIcov", sel_freq=list(exact_f[1:]), order_in="find_min")
    r = ssi.result
    matches = compare_modes(exact_f, z["exact_zeta"], z["exact_shapes"], r.Fn, r.Xi, r.Phi.T,
                            fmin_hz=0.5)
    print(comparison_table(matches, "pyOMA2 SSI-cov"))
    for m in matches:
        assert abs(m.f_relative_error) < 0.005, m
        assert m.mac > 0.99, m
        assert abs(m.zeta_error) < 0.5 * m.exact_zeta, m  # damping: the harder quantity


def test_mac_is_one_for_the_same_shape_up_to_a_complex_factor_and_zero_for_orthogonal():
    a = np.array([0.3 + 0.1j, 1.0])
    assert mac(a, (2 - 1j) * a) == pytest.approx(1.0)
    assert mac([1, 0], [0, 1]) == 0.0
