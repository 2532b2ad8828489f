"""rig.design.tolerance: the batched Monte Carlo equals a plain loop over Chain, is reproducible
by seed, counts its yield right, ranks sensitivities by derivatives that match the chain's."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rig.design import design, parse_targets
from rig.design.tolerance import (
    evaluate_loop, monte_carlo, parse_tolerances, samples_of, sensitivities)
from rig.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
TARGETS = ROOT / "examples" / "design" / "suppression_targets.toml"
TOLERANCES = ROOT / "examples" / "design" / "tolerances.toml"


@pytest.fixture(scope="module")
def case():
    return (design(parse_targets(TARGETS.read_text())),
            parse_tolerances(TOLERANCES.read_text()))


def test_batched_monte_carlo_equals_the_loop_over_chains(case):
    """Round-off only: the band's worst ratio in dB to 1e-12 dB, the modes and notch to 1e-12."""
    d, tol = case
    mc = monte_carlo(d, tol, samples=300, seed=3)
    ref = evaluate_loop(d, mc.samples)
    for k, v in ref.items():
        np.testing.assert_allclose(mc.outputs[k], v, rtol=1e-12, atol=1e-11, err_msg=k)


def test_same_seed_same_draws_bit_for_bit(case):
    d, tol = case
    a, b = samples_of(d, tol, 1000, 7), samples_of(d, tol, 1000, 7)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    c = samples_of(d, tol, 1000, 8)
    assert not np.array_equal(a["r2_m"], c["r2_m"])
    assert monte_carlo(d, tol, samples=500, seed=7).yield_ == \
        monte_carlo(d, tol, samples=500, seed=7).yield_


def test_yield_counts_the_targets_and_windows(case):
    d, tol = case
    mc = monte_carlo(d, tol, samples=4000, seed=1)
    o = mc.outputs
    want = ((o["suppression1_db"] >= 30) & (o["translation1_db"] <= -60)
            & (o["f_mode2_hz"] >= 2.40) & (o["f_mode2_hz"] <= 2.56)
            & (o["f_mode1_hz"] >= 0.78) & (o["f_mode1_hz"] <= 0.88))
    assert np.array_equal(mc.passed, want)
    assert mc.yield_ == want.mean()
    lo, hi = mc.yield_ci
    assert lo < mc.yield_ < hi and hi - lo < 0.04  # Wilson, n = 4000: about +-1.3 %
    # the spread the samples show is the one the tolerance file asks for
    r2 = mc.samples["r2_m"]
    assert np.std(r2) == pytest.approx(20e-6, rel=0.05)  # 4000 draws: 1.1 % standard error


def test_sensitivities_match_the_chain_derivatives(case):
    d, tol = case
    sens = sensitivities(d, tol)
    row = next(r for r in sens["f_mode2_hz"] if r.parameter == "j1_kgm2")
    ch = d.chain
    h = 1e-3 * ch.inertia_kgm2[0]
    up = dataclasses.replace(ch, inertia_kgm2=(ch.inertia_kgm2[0] + h, ch.inertia_kgm2[1]))
    dn = dataclasses.replace(ch, inertia_kgm2=(ch.inertia_kgm2[0] - h, ch.inertia_kgm2[1]))
    fd = (up.modes()[0][1] - dn.modes()[0][1]) / (2 * h)
    assert row.derivative == pytest.approx(fd, rel=1e-4)
    assert row.spread == pytest.approx(0.02 * ch.inertia_kgm2[0])
    # ranked, largest contribution first
    c = [r.contribution for r in sens["suppression1_db"]]
    assert c == sorted(c, reverse=True)


def test_unphysical_draws_fail_and_give_no_numbers(case):
    d, _ = case
    tol = parse_tolerances('[tolerances]\nj1_kgm2 = { dist = "normal", rel = 0.9 }\n')
    mc = monte_carlo(d, tol, samples=2000, seed=2)
    bad = ~mc.physical
    assert bad.sum() > 100  # J1 < 0 in ~13 % of the draws (0.9 sigma: P(z < -1.11))
    assert not mc.passed[bad].any() and np.isnan(mc.outputs["f_mode1_hz"][bad]).all()
    assert np.isfinite(mc.outputs["f_mode1_hz"][~bad]).all()


@pytest.mark.parametrize("text, pattern", [
    ("[tolerances]\nr3_m = { abs = 1e-5 }\n", r"unknown key tolerances\.r3_m; valid keys"),
    ('[tolerances]\nr2_m = { dist = "cauchy", abs = 1e-5 }\n', r"dist = 'cauchy' is invalid"),
    ("[tolerances]\nr2_m = { abs = 1e-5, rel = 0.1 }\n", r"exactly one of abs .* and rel"),
    ('[tolerances]\nq1 = { dist = "lognormal", abs = 10 }\n', r"lognormal spread is rel"),
    ("[tolerances]\nr2_m = { abs = -1e-5 }\n", r"tolerances\.r2_m\.abs = -1e-05 is invalid"),
    ("[tolerances]\nr2_m = { abs = 1e-5 }\n[accept]\nf1_hz = [3, 2]\n", r"expected low < high"),
    ("[tolerance]\n", r"unknown table \[tolerance\]"),
])
def test_bad_tolerance_files_name_the_key(text, pattern):
    with pytest.raises(ConfigError, match=pattern):
        parse_tolerances(text)


def test_a_normal_q_that_crosses_zero_fails_its_samples_only(case):
    d, _ = case
    tol = parse_tolerances('[tolerances]\nq2 = { dist = "normal", rel = 0.8 }\n')
    mc = monte_carlo(d, tol, samples=2000, seed=5)
    bad = mc.samples["q2"] <= 0
    assert bad.any() and np.array_equal(~mc.physical, bad)
    assert np.isfinite(mc.outputs["f_mode1_hz"][~bad]).all()
