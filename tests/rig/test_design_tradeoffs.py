"""rig.design.tradeoffs: each sweep moves one group with the others held, and its metrics agree
with the one-at-a-time chain model and the paper's exact limit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rig.design.tradeoffs import policy_pair, sweep
from rig.ishizaki import FITTED_DESIGN, design_parameters, rotation_isolation


@pytest.mark.parametrize("group", ["alpha", "nu", "sigma2"])
def test_a_sweep_moves_only_its_group_and_matches_the_chain(group):
    s = sweep(FITTED_DESIGN, group, points=9)
    base = design_parameters(FITTED_DESIGN.chain())
    for k in (0, 4, 7):
        v = s.values[k]
        kw = dict(alpha=base.alpha, nu=base.nu, sigma2=base.sigma2)
        kw[group] = v
        r1 = kw["sigma2"] * base.g_mps2 / base.omega1**2
        inputs = dataclasses.replace(FITTED_DESIGN, r1_m=r1, r2_m=kw["alpha"] * r1,
                                     f2_hz=kw["nu"] * FITTED_DESIGN.f1_hz)
        ch = inputs.chain()
        p = design_parameters(ch)
        for name in ("alpha", "nu", "sigma2", "eps", "f1_hz"):
            want = kw.get(name, getattr(base, name))
            assert getattr(p, name) == pytest.approx(want, rel=1e-12), name
        grid = np.geomspace(*s.band_hz, 200)
        th = ch.frf_angles(grid)
        sup = -20 * np.log10(np.max(np.abs(th[:, 1] / th[:, 0])))
        assert s.suppression_db[k] == pytest.approx(sup, abs=1e-9)
        lim = rotation_isolation(p)
        if np.isfinite(lim.ratio_db):
            assert s.limit_db[k] == pytest.approx(-lim.ratio_db, abs=1e-9)
        np.testing.assert_allclose(s.modes_hz[k], ch.modes()[0], rtol=1e-9)


def test_suppression_hardly_depends_on_alpha_but_on_nu():
    """Claim (29) says |theta2/theta1| = alpha above f1; the exact limit nu^2 (1-sigma^2)/(1 -
    beta^2/sigma^2) depends on alpha only through beta^2: 0.1 dB over alpha 1e-3 .. 0.3."""
    a = sweep(FITTED_DESIGN, "alpha", points=20)
    assert np.ptp(a.suppression_db) < 0.2 and np.ptp(a.alpha_db) > 40
    n = sweep(FITTED_DESIGN, "nu", points=20)
    slope = np.polyfit(np.log10(n.values[:10]), n.limit_db[:10], 1)[0]
    assert slope == pytest.approx(-40, abs=0.5)  # nu^2: 40 dB per decade


def test_policy_pair_moves_the_notch_to_infinity():
    i, ii = policy_pair(FITTED_DESIGN)
    p = design_parameters(ii.chain())
    assert p.sigma2 == pytest.approx(1, abs=1e-12) and ii.chain().inertia_kgm2[0] == 0
    assert p.alpha == pytest.approx(design_parameters(i.chain()).alpha, rel=1e-12)
    s = sweep(FITTED_DESIGN, "sigma2", values=[0.5, 1.0])
    assert np.isinf(s.notch_hz[1]) and np.isnan(s.notch_depth_db[1])
