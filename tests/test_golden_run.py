"""The paper's run, shortened (tests/golden.py), gives exactly the stored arrays: any change of
the acquisition's output shows here. After an understood change, rewrite the golden files with
``python -m tests.golden`` in a commit of its own that states the bound of the change."""

import numpy as np
import pytest

from tests import golden


@pytest.mark.parametrize("name", list(golden.RUNS))
def test_a_golden_run_gives_the_stored_arrays_bit_for_bit(name):
    stored = golden.load(name)
    fresh = golden.run_arrays(name)
    assert sorted(fresh) == sorted(stored)
    for k, v in stored.items():
        assert fresh[k].dtype == v.dtype and fresh[k].shape == v.shape, k
        assert np.array_equal(fresh[k], v), k


def test_golden_runs_are_distinct_runs_of_the_paper_scene():
    lin, nl, strong = (golden.load(n) for n in ("linear", "nonlinear_lawson4",
                                                  "nonlinear_1v_lawson4"))
    for arrays in (lin, nl, strong):
        assert arrays["codes/a"].shape == (3, 400)
        assert arrays["truth/theta_rad"].shape == (3, 400, 2)
    # the same drive: nonlinear and linear angles differ, but only by the small nonlinearity
    th_l, th_n = lin["truth/theta_rad"], nl["truth/theta_rad"]
    rel = np.sqrt(np.mean((th_n - th_l) ** 2)) / np.sqrt(np.mean(th_l ** 2))
    assert 0 < rel < 1e-2
    # ten times the drive: ten times the angles (within the nonlinearity)
    ratio = np.sqrt(np.mean(strong["truth/theta_rad"] ** 2) / np.mean(th_n ** 2))
    assert 9 < ratio < 11
