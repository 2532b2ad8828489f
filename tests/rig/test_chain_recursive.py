"""The O(n) articulated-body recursion solves the same equations as the dense mass-matrix solve."""

import numpy as np
import pytest

from rig.chain import Chain
from rig.errors import ConfigError

from chains import random_sturdy_chain


@pytest.mark.parametrize("mode", ["absolute", "relative"])
@pytest.mark.parametrize("n", [1, 2, 3, 8, 40])
def test_recursive_accelerations_equal_the_dense_solve(n, mode):
    rng = np.random.default_rng(n)
    for _ in range(5):
        ch = random_sturdy_chain(rng, n, mode)
        th = rng.uniform(-3, 3, n)
        om = rng.uniform(-3, 3, n)
        ax, ay = rng.normal(size=2)
        dense = ch.accelerations(th, om, ax, ay)
        rec = ch.accelerations(th, om, ax, ay, algorithm="recursive")
        # both are backward stable: the difference is round-off times the condition of M(theta)
        cond = np.linalg.cond(ch.mass_matrix(th))
        bound = 50 * np.finfo(float).eps * cond * n * np.max(np.abs(dense))
        np.testing.assert_allclose(rec, dense, rtol=0, atol=bound)


def test_base_force_equals_the_rate_of_horizontal_momentum():
    # In the lab frame the base pushes the chain with F = sum m_j (xG_j'' + ax); the chain pushes
    # the base with -F. xG_j'' (relative to the base) follows from the accelerations.
    rng = np.random.default_rng(7)
    ch = random_sturdy_chain(rng, 4, "relative")
    th = rng.uniform(-2, 2, 4)
    om = rng.uniform(-2, 2, 4)
    ax, ay = 0.3, -0.2
    alpha = ch.accelerations(th, om, ax, ay)
    l, c, m = (np.asarray(v) for v in (ch.length_m, ch.com_m, ch.mass_kg))
    # x of a point at s on body j: sum_{k<j} l_k sin th_k + s sin th_j
    xdd = np.cos(th) * alpha - np.sin(th) * om**2  # d2/dt2 sin(th)
    above = np.concatenate([[0.0], np.cumsum(l * xdd)[:-1]])
    xg = above + c * xdd
    expected = -np.sum(m * (xg + ax))
    assert ch.base_force(th, om, ax, ay) == pytest.approx(expected, rel=1e-12, abs=1e-14)


def test_hanging_chain_at_rest_pushes_back_with_its_weight_times_base_acceleration():
    ch = Chain([1.0, 2.0], [1.0, 1.0], [0.5, 0.5], [0.1, 0.1], [0.0, 0.0])
    # at the instant the base starts accelerating, nothing has moved yet but the chain reacts
    # through its joint forces: the force is less than m_tot * ax because the chain swings back
    f = ch.base_force([0.0, 0.0], [0.0, 0.0], ax=1.0)
    assert -3.0 < f < 0.0


def test_unknown_algorithm_is_refused():
    ch = Chain([1.0], [1.0], [0.5], [0.1], [0.0])
    with pytest.raises(ConfigError, match="algorithm = 'fast' is invalid"):
        ch.accelerations([0.0], [0.0], algorithm="fast")
