"""The paper's run, shortened (tests/golden.py), gives the stored arrays (codes and flags exactly,
floats within round-off across CPUs: ROUNDOFF): any change of the acquisition's output beyond
round-off shows here. After an understood change, rewrite the golden files with
``python -m tests.golden`` in a commit of its own that states the bound of the change."""

import numpy as np
import pytest

from tests import golden


#: the golden files' floats were written on another CPU: numpy's OpenBLAS picks its kernels by
#: CPU (DYNAMIC_ARCH), so the matrix products and exponentials behind the truth and the model
#: response (rig.bench.fused's Phi^q, scipy's expm, the response's solves) may differ there in the last
#: bits. Measured between the host that wrote them and an AMD EPYC (2026-12-02): truth at most
#: 1.3e-14 of a series' largest value, model responses at most 1.8e-14; the bound is about a
#: hundred times that. Codes and flags must match exactly.
ROUNDOFF = 1e-12


@pytest.mark.parametrize("name", list(golden.RUNS))
def test_a_golden_run_gives_the_stored_arrays(name):
    stored = golden.load(name)
    fresh = golden.run_arrays(name)
    assert sorted(fresh) == sorted(stored)
    for k, v in stored.items():
        assert fresh[k].dtype == v.dtype and fresh[k].shape == v.shape, k
        if k.startswith(("codes/", "clipped/", "saturated/")):
            assert np.array_equal(fresh[k], v), k
        else:  # truth and model response: relative to the series' largest value; NaN (a
            # ratio's unbounded limit at 0 Hz) where the stored one has it
            nan = np.isnan(v)
            assert np.array_equal(np.isnan(fresh[k]), nan), k
            a, b = fresh[k][~nan], v[~nan]
            err = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)
            assert err <= ROUNDOFF, (k, err)


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


#: relative RMS of the truth, default path (etdab, its remainder every 5 steps on these weakly
#: nonlinear runs: rig.bench.model.remainder_every) against the earlier one (lawson4): 20 times
#: etdab's own error estimate on these runs (2.8e-9 at 0.1 V, 2.7e-7 at 1 V, 20 s probe;
#: lawson4's is thousands of times smaller)
TRUTH_BOUND = {"nonlinear": 6e-8, "nonlinear_1v": 6e-6}
#: the fraction of ADC codes that may differ by 1 LSB: a code changes only where its sample lies
#: within the truth's error of a rounding edge, ~2 err |x| / LSB with |x| <= 4,300 LSB here: 3e-5
#: at 0.1 V, 3e-3 at 1 V (measured 2.5e-3)
CODE_FRACTION = {"nonlinear": 1e-3, "nonlinear_1v": 1e-2}


@pytest.mark.parametrize("name", list(TRUTH_BOUND))
def test_the_default_nonlinear_path_equals_the_earlier_one_within_its_error(name):
    # the angles' error propagates to every truth series, and to the codes (CODE_FRACTION)
    new, old = golden.load(name), golden.load(name + "_lawson4")
    assert sorted(new) == sorted(old)
    for k, v in old.items():
        if k.startswith("truth/"):
            rel = np.sqrt(np.mean((new[k] - v) ** 2) / max(np.mean(v ** 2), 1e-300))
            assert rel <= TRUTH_BOUND[name], (k, rel)
        elif k.startswith("codes/"):
            d = np.abs(new[k].astype(np.int64) - v.astype(np.int64))
            assert d.max() <= 1 and np.mean(d > 0) <= CODE_FRACTION[name], k
        else:  # flags and the model response (NaN at 0 Hz in h_t, theta_2): unchanged
            assert np.array_equal(new[k], v, equal_nan=k.startswith("model/")), k
    assert not np.array_equal(new["truth/theta_rad"], old["truth/theta_rad"])  # another path
