"""rig.design: targets -> design. The paper's table gives back the preset; the batched exact model
equals the chain's; policy (ii), infeasible targets and bad targets files are stated clearly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rig.chain import Chain
from rig.design import Pendulums, design, design_dict, design_scene_toml, parse_targets
from rig.errors import ConfigError
from rig.ishizaki import FITTED_DESIGN
from rig.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "examples" / "design" / "ishizaki2009_targets.toml"


def design_of(text: str):
    return design(parse_targets(text))


# -- the paper's design ------------------------------------------------------------------------

def test_paper_targets_reproduce_the_preset_within_one_percent():
    """The design table as printed (mu included) -> r1, r2, m1, m2, J1, J2 of ishizaki2009."""
    d = design(parse_targets(PAPER.read_text()))
    preset = load_scene("ishizaki2009").chain
    got, want = d.chain, preset
    pairs = {"r1": (got.com_m[0], want.com_m[0]), "r2": (got.com_m[1], want.com_m[1]),
             "m1": (got.mass_kg[0], want.mass_kg[0]), "m2": (got.mass_kg[1], want.mass_kg[1]),
             "J1": (got.inertia_kgm2[0], want.inertia_kgm2[0]),
             "J2": (got.inertia_kgm2[1], want.inertia_kgm2[1])}
    for name, (a, b) in pairs.items():
        assert abs(a / b - 1) < 0.01, (name, a, b)
    # the preset is itself a least-squares fit to the same table: the two agree far closer
    assert max(abs(a / b - 1) for a, b in pairs.values()) < 1e-3
    assert d.status == "met"


def test_paper_table_mu_is_reported_inconsistent():
    d = design(parse_targets(PAPER.read_text()))
    (bad,) = d.inconsistent
    assert bad.name == "mu" and bad.wanted == 0.0918
    assert bad.implied == pytest.approx(d.params.alpha / (d.params.eps * d.params.nu**2))
    assert round(bad.implied, 3) == 0.123
    assert all(c.status == "met" and abs(c.residual) <= 1 for c in d.checks if c.name != "mu")
    assert "mu = 0.0918 is inconsistent" in d.notes[0]


def test_exactly_determined_targets_are_solved_exactly():
    d = design_of("[targets]\nr1_m = 0.029\nalpha = 0.0292\nf1_hz = 2.48\nnu = 0.334\n"
                  "eps = 2.13\n")
    p = d.params
    for got, want in ((p.r1, 0.029), (p.alpha, 0.0292), (p.f1_hz, 2.48), (p.nu, 0.334),
                      (p.eps, 2.13)):
        assert got == pytest.approx(want, rel=1e-13)
    assert d.optimised == () and d.status == "met"


# -- the batched exact model -------------------------------------------------------------------

def random_chains(n, seed=1):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        r1 = rng.uniform(0.01, 0.1)
        out.append(Chain(mass_kg=tuple(rng.uniform(0.01, 0.2, 2)),
                         length_m=(r1 * rng.uniform(0.7, 1.3), 0.04),
                         com_m=(r1, rng.uniform(1e-4, 0.01)),
                         inertia_kgm2=tuple(rng.uniform(1e-6, 1e-4, 2)),
                         damping_nms=tuple(rng.uniform(0, 1e-3, 2))))
    return out


def test_batched_model_equals_the_chain_solve():
    """Cramer's rule and the companion roots against Chain.frf_angles / modes /
    antiresonances_hz (direct solve, pencil eigenvalues): round-off only. The tolerance: the
    responses' relative difference is bounded by cond(Z) ulp ~ Q 1e-16 near a resonance."""
    chains = random_chains(12)
    f = np.geomspace(0.05, 50, 400)
    for ch in chains:
        p = Pendulums.from_chain(ch)
        t1, t2 = p.angles(f)
        ref = ch.frf_angles(f)
        np.testing.assert_allclose(t1[0], ref[:, 0], rtol=1e-10)
        np.testing.assert_allclose(t2[0], ref[:, 1], rtol=1e-10)
        fm, qm = p.modes()
        rf, rq = ch.modes()
        np.testing.assert_allclose(fm[0], rf, rtol=1e-10)
        np.testing.assert_allclose(qm[0], rq, rtol=1e-8)
        z2 = ch.antiresonances_hz([0.0, 1.0])
        if z2.size:
            assert p.notch_hz()[0] == pytest.approx(z2[0], rel=1e-9)
        else:
            assert math.isinf(p.notch_hz()[0])
    # all at once, the same numbers
    stacked = Pendulums(**{k: np.concatenate([Pendulums.from_chain(c).params()[k] for c in chains])
                           for k in Pendulums.from_chain(chains[0]).params()})
    np.testing.assert_allclose(stacked.angles(f)[0][5], chains[5].frf_angles(f)[:, 0], rtol=1e-10)


# -- policy (ii) -------------------------------------------------------------------------------

def test_policy_ii_puts_sigma2_at_one_and_the_notch_at_infinity():
    d = design_of('[targets]\npolicy = "ii"\nf1_hz = 2.48\nf2_hz = 0.83\nalpha = 0.0292\n'
                  "eps = 2.13\n")
    assert d.params.sigma2 == pytest.approx(1.0, abs=1e-12)
    assert d.chain.inertia_kgm2[0] == 0.0
    assert math.isinf(d.notch_hz) and d.status == "met"
    assert design_dict(d)["notch"]["frequency_hz"] is None  # never inf or NaN in the data
    assert any("J1 = 0" in n for n in d.notes)


def test_policy_ii_with_a_real_stage_1_is_the_nearest_and_names_j1():
    d = design_of('[targets]\npolicy = "ii"\nf1_hz = 2.48\nf2_hz = 0.83\nalpha = 0.0292\n'
                  "eps = 2.13\nj1_min_kgm2 = 5e-6\n")
    assert d.status == "nearest"
    assert d.chain.inertia_kgm2[0] == pytest.approx(5e-6, rel=1e-6)
    assert any(b.startswith("J1 >= 5e-06") for b in d.binding)
    assert d.params.sigma2 < 1 and math.isfinite(d.notch_hz)


def test_policy_ii_against_fixed_r1_and_f1_says_which_determine_sigma2():
    d = design_of('[targets]\npolicy = "ii"\nr1_m = 0.029\nf1_hz = 2.48\n')
    assert d.status == "nearest"
    assert any("determine sigma^2 = r1 (2 pi f1)^2/g = 0.718" in n for n in d.notes)


# -- performance targets and infeasible ones ------------------------------------------------------

def test_free_variables_are_optimised_to_meet_the_performance_targets():
    d = design_of("[targets]\nf1_hz = 2.48\nf2_hz = 0.83\neps = 2.13\nr2_min_m = 0.0005\n"
                  "[[targets.suppression]]\nband_hz = [4.0, 20.0]\nmin_db = 30\n"
                  "[[targets.translation]]\nfreq_hz = 5.0\nmax_db = -60\n")
    assert d.status == "met" and set(d.optimised) == {"r1_m", "r2_m"}
    assert all(c.met for c in d.performance)
    # checked independently on the chain's own solve
    f = np.geomspace(4, 20, 500)
    th = d.chain.frf_angles(f)
    assert np.min(-20 * np.log10(np.abs(th[:, 1] / th[:, 0]))) >= 30 - 0.01


def test_unreachable_suppression_gives_the_nearest_design_and_what_binds():
    d = design_of("[targets]\nf1_hz = 2.5\nf2_hz = 0.8\nr2_min_m = 0.0005\n"
                  "[[targets.suppression]]\nband_hz = [3.0, 30.0]\nmin_db = 30\n")
    assert d.status == "nearest"
    (perf,) = d.performance
    assert not perf.met and -3 < perf.margin_db < 0
    assert any("r2_m >= 0.0005 m" in b for b in d.binding)
    assert any("misses 30 dB" in n for n in d.notes)
    assert all(math.isfinite(x) for x in d.modes_hz)


def test_conflicting_bounds_are_refused_with_a_sentence():
    with pytest.raises(ConfigError, match=r"min = 0.01 > max = 0.001"):
        parse_targets("[targets]\nr2_m = {min = 0.01, max = 0.001}\n")


# -- the scene ---------------------------------------------------------------------------------

def test_designed_scene_loads_to_the_designed_pendulum(tmp_path):
    d = design(parse_targets(PAPER.read_text()))
    path = tmp_path / "designed.toml"
    path.write_text(design_scene_toml(d))
    sc = load_scene(path)
    assert sc.chain == d.chain
    assert sc.acquisition == load_scene("ishizaki2009").acquisition  # the base's bench


def test_the_fitted_preset_is_a_fixed_point():
    """Its own numbers as targets give it back (to round-off)."""
    f = FITTED_DESIGN
    d = design_of(f"[targets]\nr1_m = {f.r1_m}\nr2_m = {f.r2_m}\nf1_hz = {f.f1_hz}\n"
                  f"f2_hz = {f.f2_hz}\neps = {f.eps}\n")
    np.testing.assert_allclose(d.chain.inertia_kgm2, f.chain().inertia_kgm2, rtol=1e-12)


# -- bad targets files -------------------------------------------------------------------------

@pytest.mark.parametrize("text, pattern", [
    ("[targets]\nf3_hz = 1\n", r"unknown key targets\.f3_hz; valid keys: .*f1_hz"),
    ("[targets]\nf1_hz = -2.0\n", r"targets\.f1_hz = -2\.0 is invalid: expected a finite number "
                                  r"> 0 Hz, or \"free\""),
    ('[targets]\nalpha = "small"\n', r"targets\.alpha = 'small' is invalid: expected a number "
                                     r"\(fixed\), \"free\""),
    ("[targets]\neps = 0.5\n", r"targets\.eps = 0\.5 is invalid: expected eps = 1 \+ m1/m2 > 1"),
    ('[targets]\npolicy = "iii"\n', r"targets\.policy = 'iii' is invalid: expected \"i\""),
    ("[targets]\n[[targets.suppression]]\nband_hz = [10, 3]\n", r"band_hz = \[10, 3\] is "
                                                                r"invalid: expected low < high"),
    ("[targets]\n[[targets.translation]]\nfreq_hz = 5\n", r"neither min_db nor max_db"),
    ("[target]\nf1_hz = 2\n", r"unknown table \[target\]: expected \[targets\]"),
    ("[targets\n", r"invalid TOML"),
    ("[targets]\nq1 = 0\n", r"targets\.q1 = 0 is invalid"),
])
def test_bad_targets_get_one_sentence_naming_the_key(text, pattern):
    with pytest.raises(ConfigError, match=pattern):
        parse_targets(text)


def test_tolerance_of_a_number_is_half_its_last_written_digit():
    t = parse_targets("[targets]\nr1_m = 0.029\nbeta2 = 7.82e-4\nf1_hz = 2.50\n"
                      "eps = { value = 2.13, tol = 0.01 }\n")
    v = t.variables
    assert v["r1_m"].tol == pytest.approx(5e-4)
    assert v["beta2"].tol == pytest.approx(5e-7)
    assert v["f1_hz"].tol == pytest.approx(5e-3)  # as written: 2.50, not 2.5
    assert v["eps"].tol == 0.01
