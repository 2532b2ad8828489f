"""rig.design's hard cases (SPEC section 7): near-degenerate designs (nu -> 1, beta^2 -> 1,
sigma^2 -> 1) and infeasible targets give a finite design and a statement, never NaN; and a fuzz
over targets files (hypothesis, bounded): every file is either refused with one sentence naming
a key, or designed into a finite pendulum."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.design import design, design_dict, parse_targets
from rig.design.targets import VARIABLES
from rig.errors import ConfigError

FUZZ = settings(max_examples=150, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])


def finite_design(d) -> None:
    """Every physical number finite and every JSON value finite or None (never NaN/inf)."""
    c = d.chain
    for v in (*c.mass_kg, *c.com_m, *c.inertia_kgm2, *c.damping_nms, *d.modes_hz):
        assert math.isfinite(v)
    text = json.dumps(design_dict(d), allow_nan=False)  # raises on NaN / inf
    assert text


def designed(text):
    d = design(parse_targets("[targets]\n" + text))
    finite_design(d)
    return d


def test_coincident_frequencies_split_and_are_stated():
    d = designed("nu = 1.0\nf1_hz = 2.48\nalpha = 0.03\neps = 2.0\nsigma2 = 0.7\n")
    f = d.modes_hz
    assert f[0] < 2.48 < f[1] and f[1] / f[0] < 1.2
    assert any("nu = 1 ~ 1" in n and "policy (i)" in n for n in d.notes)


def test_beta2_near_one_locks_the_stages_and_is_stated():
    d = designed("beta2 = 0.999\nf1_hz = 2.48\n")
    assert d.params.beta2 == pytest.approx(0.999, abs=5e-4)
    assert any("nearly singular" in n for n in d.notes)
    assert d.modes_hz[1] > 10 * d.modes_hz[0]


def test_beta2_of_one_is_the_nearest_feasible_and_finite():
    d = designed("beta2 = { value = 1.0, tol = 1e-9 }\nf1_hz = 2.48\n")
    assert d.status == "nearest" and d.params.beta2 < 1
    assert any(b.startswith("eps >= 1 + 1e-6") for b in d.binding)


def test_sigma2_near_one_moves_the_notch_out_and_is_stated():
    d = designed("sigma2 = 0.9999999999\nf1_hz = 2.48\n")
    assert d.notch_hz > 100 * d.modes_hz[1] or math.isinf(d.notch_hz)
    assert any("sigma^2 = " in n and "notch moves to infinity" in n for n in d.notes)


def test_r1_longer_than_the_simple_pendulum_is_refused_by_name():
    """sigma^2 > 1 needs J1 < 0: the nearest buildable design and the binding J1 >= 0."""
    d = designed("r1_m = 0.05\nf1_hz = 2.48\n")
    assert d.status == "nearest"
    assert any(b.startswith("J1 >= 0") for b in d.binding)
    assert any(n.startswith("r1_m = 0.05 not met") for n in d.notes)


def test_contradictory_bounds_are_a_sentence():
    with pytest.raises(ConfigError, match=r"no buildable design satisfies the bounds"):
        design(parse_targets("[targets]\nr2_m = { min = 0.5 }\nf2_hz = 2.0\n"
                             "r1_m = { max = 0.01 }\nalpha = { max = 0.01 }\n"))


# -- fuzz --------------------------------------------------------------------------------------

NUMBERS = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=32),
                    st.sampled_from([0.0, -1.0, 1e-12, 1e12, 1.0, 0.5, 2.13, 0.029, 2.48]),
                    st.integers(-5, 1000))
VALUES = st.one_of(NUMBERS, st.just('"free"'), st.just('"fast"'),
                   st.builds(lambda a, b: f"{{ min = {a!r}, max = {b!r} }}", NUMBERS, NUMBERS),
                   st.builds(lambda a, b: f"{{ value = {a!r}, tol = {b!r} }}", NUMBERS, NUMBERS),
                   st.just("[1, 2]"), st.just("true"))
KEYS = st.sampled_from(sorted(VARIABLES) + ["r2_min_m", "r1_max_m", "total_mass_kg", "q1",
                                            "margin_db", "j1_min_kgm2", "g_mps2", "bogus"])


def _value(v) -> str:
    return repr(v) if isinstance(v, (int, float)) else v


@FUZZ
@given(st.dictionaries(KEYS, VALUES, max_size=6),
       st.sampled_from(['"i"', '"ii"', '"iii"', "2"]),
       st.one_of(st.none(), st.tuples(NUMBERS, NUMBERS, st.one_of(st.none(), NUMBERS))))
def test_fuzzed_targets_files_are_refused_clearly_or_designed_finitely(table, policy, band):
    lines = ["[targets]", f"policy = {policy}"] + [f"{k} = {_value(v)}" for k, v in table.items()]
    if band is not None:
        lines += ["[[targets.suppression]]", f"band_hz = [{band[0]!r}, {band[1]!r}]"]
        if band[2] is not None:
            lines.append(f"min_db = {band[2]!r}")
    text = "\n".join(lines) + "\n"
    try:
        t = parse_targets(text)
    except ConfigError as exc:
        msg = str(exc)
        assert "\n" not in msg and ("targets" in msg or "TOML" in msg), msg
        return
    try:
        d = design(t)
    except ConfigError as exc:
        assert "\n" not in str(exc)
        return
    finite_design(d)
    assert d.status in ("met", "nearest")
    assert np.all(np.isfinite([c.margin_db for c in d.performance]))


PLAUSIBLE = {"r1_m": (1e-3, 0.5), "r2_m": (1e-5, 0.05), "f1_hz": (0.1, 20.0),
             "f2_hz": (0.05, 20.0), "eps": (1.01, 20.0), "alpha": (1e-3, 0.9),
             "nu": (0.05, 2.0), "sigma2": (0.05, 1.0), "beta2": (1e-6, 0.99),
             "mu": (1e-3, 10.0), "delta": (1e-4, 0.5)}


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(sorted(PLAUSIBLE)), st.floats(0.0, 1.0), max_size=6),
       st.sampled_from(["i", "ii"]),
       st.one_of(st.none(), st.tuples(st.floats(0.2, 30.0), st.floats(1.2, 10.0),
                                      st.floats(0.0, 60.0))))
def test_fuzzed_valid_targets_give_a_finite_design(picks, policy, band):
    """Targets in plausible ranges (log-uniform), any subset, either policy, with or without a
    suppression target: a finite design and, if not every target is met, a note saying which."""
    lines = ["[targets]", f'policy = "{policy}"']
    for k, x in picks.items():
        lo, hi = PLAUSIBLE[k]
        lines.append(f"{k} = {lo * (hi / lo) ** x!r}")
    if band is not None:
        lines += ["[[targets.suppression]]", f"band_hz = [{band[0]!r}, {band[0] * band[1]!r}]",
                  f"min_db = {band[2]!r}"]
    try:
        d = design(parse_targets("\n".join(lines) + "\n"))
    except ConfigError as exc:
        assert "\n" not in str(exc) and "no buildable design" in str(exc)
        return
    finite_design(d)
    if d.status == "nearest":
        assert d.notes  # says what is not met and why
