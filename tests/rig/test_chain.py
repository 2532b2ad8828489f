"""The general n-body chain (rig.chain) against the two source papers and against mechanics.

- Ishizaki et al. (2009) eqs. (5), (6) for n = 2, with the damping torques of (5)', (6)';
- Takeno (2018) eq. (19) and the matrix form (20)-(22) for uniform rods (m = rho l, c = l/2,
  J = m l^2 / 12; his row j is ours divided by rho l_j; his (12) should read l_i, not l_m);
- the mass matrix is the kinetic energy of the bodies computed from their kinematics, symmetric
  positive definite; with a fixed base dE/dt = -w^T C w; the linearisation is the Jacobian of the
  nonlinear right-hand side; the frequency response tends to -1/g; invalid inputs are named.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.chain import G_STANDARD, Chain
from rig.errors import ConfigError

G = G_STANDARD
ROUNDOFF = 1e-12  # relative bound for identities evaluated two ways in double precision


def random_chain(rng, n, damping_mode="absolute", zero_inertia=False) -> Chain:
    """A random but physical chain: masses 0.1-2 kg, lengths 0.2-1.5 m, centres of mass anywhere
    between 0.05 l and l (body 1 sometimes above its pivot, which S_1 > 0 still allows)."""
    m = rng.uniform(0.1, 2.0, n)
    l = rng.uniform(0.2, 1.5, n)
    c = rng.uniform(0.05, 1.0, n) * l
    if n > 1:  # G1 above its pivot, held up by the bodies below: m1 c1 >= -0.5 l1 mu1, S1 > 0
        c[0] = -0.5 * l[0] * rng.uniform() * m[1:].sum() / m[0]
    j = np.zeros(n) if zero_inertia else rng.uniform(0.0, 0.1, n) * m * l**2
    gam = rng.uniform(0.0, 0.5, n)
    return Chain(mass_kg=m, length_m=l, com_m=c, inertia_kgm2=j, damping_nms=gam,
                 damping_mode=damping_mode, g_mps2=G)


def random_states(rng, n, count):
    """Large angles (anywhere on the circle, several turns), fast rotations, violent base motion."""
    th = rng.uniform(-2 * np.pi, 2 * np.pi, (count, n))
    om = rng.uniform(-10.0, 10.0, (count, n))
    ax = rng.uniform(-30.0, 30.0, count)
    ay = rng.uniform(-5.0, 5.0, count)
    return th, om, ax, ay


# -- Ishizaki (5), (6) ---------------------------------------------------------------------

def ishizaki_accelerations(m1, m2, r1, r2, l, j1, j2, gam1, gam2, g, th, om, ax):
    """Ishizaki (5), (6), damping torques -Gamma_i th_i' on the right as in (5)', (6)', solved for
    (th1'', th2'') by Cramer's rule. Written from the paper, independent of rig.chain."""
    th1, th2 = th
    w1, w2 = om
    i1, i2 = j1 + m1 * r1**2, j2 + m2 * r2**2
    a11 = i1 + m2 * l**2
    a12 = m2 * l * r2 * math.cos(th1 - th2)
    a22 = i2
    b1 = (-(m1 * g * r1 + m2 * g * l) * math.sin(th1) - m2 * l * r2 * math.sin(th1 - th2) * w2**2
          - (m1 * r1 + m2 * l) * ax * math.cos(th1) - gam1 * w1)
    b2 = (-m2 * g * r2 * math.sin(th2) + m2 * l * r2 * math.sin(th1 - th2) * w1**2
          - m2 * r2 * ax * math.cos(th2) - gam2 * w2)
    det = a11 * a22 - a12 * a12
    return np.array([(b1 * a22 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det])


def test_accelerations_equal_ishizaki_5_6_at_large_angles():
    rng = np.random.default_rng(20090130)
    for _ in range(5):
        ch = random_chain(rng, 2)
        (m1, m2), (l, _), (r1, r2), (j1, j2), (g1, g2) = (
            ch.mass_kg, ch.length_m, ch.com_m, ch.inertia_kgm2, ch.damping_nms)
        th, om, ax, _ = random_states(rng, 2, 40)
        for k in range(40):
            want = ishizaki_accelerations(m1, m2, r1, r2, l, j1, j2, g1, g2, G, th[k], om[k], ax[k])
            got = ch.accelerations(th[k], om[k], ax[k], 0.0)
            np.testing.assert_allclose(got, want, rtol=0, atol=ROUNDOFF * np.abs(want).max())


def test_vertical_base_acceleration_acts_as_gravity():
    """Equivalence principle: a base accelerating upward by ay is gravity g + ay."""
    rng = np.random.default_rng(7)
    ch = random_chain(rng, 3)
    th, om, ax, ay = random_states(rng, 3, 20)
    for k in range(20):
        heavier = Chain(ch.mass_kg, ch.length_m, ch.com_m, ch.inertia_kgm2, ch.damping_nms,
                        g_mps2=G + ay[k])
        want = heavier.accelerations(th[k], om[k], ax[k], 0.0)
        np.testing.assert_allclose(ch.accelerations(th[k], om[k], ax[k], ay[k]), want,
                                   rtol=0, atol=ROUNDOFF * np.abs(want).max())


# -- Takeno (19), (20)-(22) ----------------------------------------------------------------

def rod_chain(lengths, rho=1.0) -> Chain:
    """Uniform rods, Takeno's setting: m = rho l, c = l/2, J = m l^2 / 12, no friction."""
    l = np.asarray(lengths, float)
    m = rho * l
    return Chain(mass_kg=m, length_m=l, com_m=l / 2, inertia_kgm2=m * l**2 / 12,
                 damping_nms=np.zeros(l.size), g_mps2=G)


def takeno_matrices(lengths, th):
    """Takeno (20)-(22): A(th), B(th) and the gravity vector L with (12) read as
    L_j = l_j/2 + sum_{i>j} l_i (the printed l_m is a typo for l_i)."""
    l = np.asarray(lengths, float)
    n = l.size
    big_l = l / 2 + np.concatenate([np.cumsum(l[::-1])[::-1][1:], [0.0]])
    j, k = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    alpha = big_l[np.maximum(j, k)] - l[j] / 6 * (j == k)  # (20)
    d = th[:, None] - th[None, :]
    return l[k] * alpha * np.cos(d), l[k] * alpha * np.sin(d), big_l  # (21)


def takeno_accelerations(lengths, th, om, g=G):
    a, b, big_l = takeno_matrices(lengths, th)
    return np.linalg.solve(a, -b @ om**2 - g * big_l * np.sin(th))  # (22)


def takeno_19(l, th, om, g=G):
    """Takeno (19): two equal rods of length l, written out as printed."""
    d = th[0] - th[1]
    a = np.array([[4 / 3, 0.5 * math.cos(d)], [0.5 * math.cos(d), 1 / 3]])
    rhs = np.array([-0.5 * om[1] ** 2 * math.sin(d) - 1.5 * g / l * math.sin(th[0]),
                    0.5 * om[0] ** 2 * math.sin(d) - 0.5 * g / l * math.sin(th[1])])
    return np.linalg.solve(a, rhs)


def test_accelerations_equal_takeno_19_for_two_equal_rods():
    rng = np.random.default_rng(2018)
    for l, rho in ((1.0, 1.0), (0.37, 7.9)):
        ch = rod_chain([l, l], rho)
        th, om, _, _ = random_states(rng, 2, 50)
        for k in range(50):
            want = takeno_19(l, th[k], om[k])
            np.testing.assert_allclose(ch.accelerations(th[k], om[k]), want,
                                       rtol=0, atol=ROUNDOFF * np.abs(want).max())


@pytest.mark.parametrize("lengths", [[1.0, 1.0], [0.3, 1.1], [0.5, 0.2, 1.3, 0.7, 0.9]])
def test_accelerations_equal_takeno_matrix_form(lengths):
    rng = np.random.default_rng(len(lengths))
    rho = 2.7
    ch = rod_chain(lengths, rho)
    th, om, _, _ = random_states(rng, len(lengths), 50)
    rows = rho * np.asarray(lengths)[:, None]  # his row j is ours divided by rho l_j
    for k in range(50):
        want = takeno_accelerations(lengths, th[k], om[k])
        np.testing.assert_allclose(ch.accelerations(th[k], om[k]), want,
                                   rtol=0, atol=ROUNDOFF * np.abs(want).max())
        a, b, big_l = takeno_matrices(lengths, th[k])
        m = ch.mass_matrix(th[k])
        np.testing.assert_allclose(m / rows, a, rtol=ROUNDOFF, atol=0)
        d = th[k][:, None] - th[k][None, :]
        np.testing.assert_allclose(ch.H * np.sin(d) / rows, b, rtol=0,
                                   atol=ROUNDOFF * np.abs(a).max())
        np.testing.assert_allclose(ch.S / rows[:, 0], big_l, rtol=ROUNDOFF)


def test_takeno_12_typo_matters_for_unequal_rods():
    """Reading (12) literally with l_j in place of l_i (sum_{i>j} l_j) gives another gravity
    vector as soon as the rods differ: the chain's S_j / (rho l_j) is the corrected L_j only."""
    lengths = np.array([0.5, 0.2, 1.3])
    ch = rod_chain(lengths)
    n = lengths.size
    misread = lengths / 2 + (n - 1 - np.arange(n)) * lengths
    corrected = takeno_matrices(lengths, np.zeros(n))[2]
    np.testing.assert_allclose(ch.S / lengths, corrected, rtol=ROUNDOFF)
    assert np.abs(ch.S / lengths - misread).max() > 0.1


# -- structure: mass matrix, energy ----------------------------------------------------------

def kinematic_energy(ch: Chain, th, om):
    """T and U summed body by body from the positions and velocities of the centres of mass
    (fixed base at the origin, y up)."""
    n = ch.n
    x = y = vx = vy = 0.0  # upper joint of the current body
    t = u = 0.0
    for j in range(n):
        s, c = math.sin(th[j]), math.cos(th[j])
        cj, lj = ch.com_m[j], ch.length_m[j]
        gx, gy = x + cj * s, y - cj * c
        gvx, gvy = vx + cj * c * om[j], vy + cj * s * om[j]
        t += 0.5 * ch.mass_kg[j] * (gvx**2 + gvy**2) + 0.5 * ch.inertia_kgm2[j] * om[j] ** 2
        u += ch.mass_kg[j] * G * gy
        x, y, vx, vy = x + lj * s, y - lj * c, vx + lj * c * om[j], vy + lj * s * om[j]
    return t, u


@pytest.mark.parametrize("n", [1, 2, 3, 8])
def test_mass_matrix_is_the_kinetic_energy_and_spd(n):
    rng = np.random.default_rng(100 + n)
    ch = random_chain(rng, n, zero_inertia=(n == 3))  # point masses too
    th, om, _, _ = random_states(rng, n, 30)
    for k in range(30):
        m = ch.mass_matrix(th[k])
        assert np.array_equal(m, m.T)
        np.linalg.cholesky(m)  # positive definite, or LinAlgError
        assert np.linalg.eigvalsh(m).min() > 0
        t, u = kinematic_energy(ch, th[k], om[k])
        np.testing.assert_allclose(0.5 * om[k] @ m @ om[k], t, rtol=ROUNDOFF)
        np.testing.assert_allclose(ch.energy(th[k], om[k]), t + u, rtol=0,
                                   atol=ROUNDOFF * (abs(t) + abs(u)))
    traj = ch.energy(th, om)  # a trajectory (T, n) gives (T,)
    assert traj.shape == (30,)
    np.testing.assert_array_equal(traj[3], ch.energy(th[3], om[3]))


@pytest.mark.parametrize("mode", ["absolute", "relative"])
@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_fixed_base_energy_rate_is_minus_dissipation(mode, n):
    """dE/dt = w^T M th'' + 1/2 w^T (dM/dt) w + g sum S_j sin th_j w_j, with th'' from
    ``accelerations`` and dM/dt_jk = -H_jk sin(th_j - th_k)(w_j - w_k), equals -w^T C w to
    round-off (the gyroscopic terms cancel exactly because N is antisymmetric)."""
    rng = np.random.default_rng(10 * n + len(mode))
    ch = random_chain(rng, n, damping_mode=mode)
    th, om, _, _ = random_states(rng, n, 40)
    for k in range(40):
        acc = ch.accelerations(th[k], om[k])
        m = ch.mass_matrix(th[k])
        d = th[k][:, None] - th[k][None, :]
        mdot = -ch.H * np.sin(d) * (om[k][:, None] - om[k][None, :])
        terms = np.array([om[k] @ m @ acc, 0.5 * om[k] @ mdot @ om[k],
                          G * np.sum(ch.S * np.sin(th[k]) * om[k])])
        want = -om[k] @ ch.C @ om[k]
        assert abs(terms.sum() - want) <= ROUNDOFF * np.abs(terms).sum()
    if mode == "relative":  # a rigid rotation of the whole chain only rubs in the top joint
        w = np.full(n, 1.7)
        assert math.isclose(w @ ch.C @ w, ch.damping_nms[0] * 1.7**2, rel_tol=1e-12)


# -- linear model ------------------------------------------------------------------------------

@pytest.mark.parametrize("mode", ["absolute", "relative"])
def test_state_space_is_the_jacobian_of_accelerations_at_rest(mode):
    """Central differences with step h = 1e-6 (truncation ~ h^2 |f'''| ~ 1e-12, round-off
    ~ eps |f| / h ~ 1e-10 relative): agreement to 1e-7 relative."""
    rng = np.random.default_rng(3)
    n = 4
    ch = random_chain(rng, n, damping_mode=mode)
    a, b = ch.state_space()
    h = 1e-6
    zero = np.zeros(n)
    jac = np.zeros((n, 2 * n + 2))
    for i in range(2 * n):
        dz = np.zeros(2 * n)
        dz[i] = h
        jac[:, i] = (ch.accelerations(zero + dz[:n], zero + dz[n:])
                     - ch.accelerations(zero - dz[:n], zero - dz[n:])) / (2 * h)
    jac[:, 2 * n] = (ch.accelerations(zero, zero, h) - ch.accelerations(zero, zero, -h)) / (2 * h)
    jac[:, 2 * n + 1] = (ch.accelerations(zero, zero, 0, h)
                         - ch.accelerations(zero, zero, 0, -h)) / (2 * h)
    scale = np.abs(a).max()
    np.testing.assert_array_equal(a[:n], np.hstack([np.zeros((n, n)), np.eye(n)]))
    np.testing.assert_array_equal(b[:n], 0)
    np.testing.assert_allclose(a[n:], jac[:, :2 * n], rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(b[n:, 0], jac[:, 2 * n], rtol=0, atol=1e-7 * np.abs(b).max())
    assert np.abs(jac[:, 2 * n + 1]).max() <= 1e-7 * np.abs(b).max()  # vertical input: 2nd order


@pytest.mark.parametrize("mode", ["absolute", "relative"])
@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_frf_tends_to_minus_one_over_g(mode, n):
    """At 0 Hz, K Theta = -S gives Theta_j = -1/g exactly (to round-off). At low frequency
    Theta = -(I + i w K^-1 C - w^2 K^-1 H)^-1 K^-1 S, so the relative deviation from -1/g is at
    most ~ w ||K^-1 C|| + w^2 ||K^-1 H|| (first order; the test allows twice that)."""
    rng = np.random.default_rng(n)
    ch = random_chain(rng, n, damping_mode=mode)
    f = 1e-4
    w = 2 * np.pi * f
    kinv = np.linalg.inv(ch.K)
    bound = w * np.linalg.norm(kinv @ ch.C, 2) + w**2 * np.linalg.norm(kinv @ ch.H, 2)
    assert bound < 1e-2
    th = ch.frf_angles([0.0, f])
    np.testing.assert_allclose(th[0], -1 / G, rtol=ROUNDOFF)
    np.testing.assert_allclose(th[1], -1 / G, rtol=2 * bound)
    assert np.all(np.abs(np.degrees(np.angle(th[1])) % 360 - 180) < 1.0)  # phase 180 deg


def test_frf_equals_state_space_transfer_function():
    rng = np.random.default_rng(11)
    ch = random_chain(rng, 3, damping_mode="relative")
    a, b = ch.state_space()
    f = np.array([0.05, 0.3, 1.1, 7.0])
    for fk, th in zip(f, ch.frf_angles(f)):
        z = np.linalg.solve(2j * np.pi * fk * np.eye(6) - a, b)[:3, 0]
        np.testing.assert_allclose(th, z, rtol=1e-10)


def test_frf_point_of_the_mirror_is_l1_theta1():
    """The mirror centre at O2: body 0 at s = l1 is body 1 at s = 0, and both are l1 Theta_1."""
    rng = np.random.default_rng(5)
    ch = random_chain(rng, 2)
    f = np.geomspace(0.01, 20, 50)
    th = ch.frf_angles(f)
    l1 = ch.length_m[0]
    np.testing.assert_allclose(ch.frf_point(f, 0, l1), l1 * th[:, 0], rtol=ROUNDOFF)
    np.testing.assert_allclose(ch.frf_point(f, 1, 0.0), l1 * th[:, 0], rtol=ROUNDOFF)
    s = 0.3
    np.testing.assert_allclose(ch.frf_point(f, 1, s), l1 * th[:, 0] + s * th[:, 1], rtol=ROUNDOFF)
    np.testing.assert_allclose(ch.frf_point([0.0], 1, s), -(l1 + s) / G, rtol=ROUNDOFF)
    with pytest.raises(ConfigError, match=r"body = 2 is invalid"):
        ch.point_weights(2, 0.0)


# -- invalid chains ----------------------------------------------------------------------------

GOOD = dict(mass_kg=(0.05, 0.05), length_m=(0.03, 0.04), com_m=(0.03, 0.001),
            inertia_kgm2=(3e-5, 1.4e-5), damping_nms=(1e-6, 1e-6))


@pytest.mark.parametrize("change, pattern", [
    (dict(mass_kg=(0.05, 0.0)), r"mass_kg of body 2 = 0\.0 is invalid: expected > 0"),
    (dict(mass_kg=(-0.05, 0.05)), r"mass_kg of body 1 = -0\.05 is invalid: expected > 0"),
    (dict(mass_kg=(float("nan"), 0.05)), r"mass_kg of body 1 = nan is invalid: expected a finite"),
    (dict(mass_kg=()), r"mass_kg is empty"),
    (dict(length_m=(0.03, 0.0)), r"length_m of body 2 = 0\.0 is invalid: expected > 0"),
    (dict(length_m=(-0.03, 0.04)), r"length_m of body 1 = -0\.03 is invalid: expected > 0"),
    (dict(length_m=(0.03, float("nan"))), r"length_m of body 2 = nan is invalid"),
    (dict(length_m=(0.03,)), r"length_m has 1 entries; expected 2"),
    (dict(com_m=(0.03, 0.001, 0.0)), r"com_m has 3 entries; expected 2"),
    (dict(com_m=(0.03, float("inf"))), r"com_m of body 2 = inf is invalid"),
    (dict(inertia_kgm2=(3e-5, -1e-6)),
     r"inertia_kgm2 of body 2 = -1e-06 is invalid: expected >= 0"),
    (dict(damping_nms=(-1e-6, 0.0)), r"damping_nms of body 1 = -1e-06 is invalid: expected >= 0"),
    (dict(damping_mode="viscous"), r"damping_mode = 'viscous' is invalid: expected one of "
                                   r"absolute, relative"),
    (dict(com_m=(0.03, 0.0)), r"com_m of body 2 = 0\.0 gives S_2 = m c \+ l mu = 0 kg m"),
    (dict(com_m=(-0.04, 0.001)), r"com_m of body 1 = -0\.04 gives S_1 = .* -0\.0005 kg m"),
    (dict(g_mps2=0.0), r"g_mps2 = 0\.0 is invalid: expected a finite number > 0"),
    (dict(g_mps2=float("nan")), r"g_mps2 = nan is invalid"),
    (dict(mass_kg="heavy"), r"mass_kg = 'heavy' is invalid: expected a sequence of numbers"),
])
def test_invalid_chains_name_field_index_and_value(change, pattern):
    with pytest.raises(ConfigError, match=pattern):
        Chain(**{**GOOD, **change})
    assert issubclass(ConfigError, ValueError)


def test_valid_edge_cases_are_accepted():
    """Point masses (J = 0), no damping and a centre of mass above the pivot held by the bodies
    below (S_1 > 0) are physical."""
    ch = Chain(**{**GOOD, "inertia_kgm2": (0.0, 0.0), "damping_nms": (0.0, 0.0),
                  "com_m": (-0.01, 0.001)})
    assert ch.S[0] > 0 and np.all(np.isfinite(ch.natural_frequencies_hz()))


def test_undamped_modes_have_infinite_q():
    ch = rod_chain([1.0, 1.0])
    f, q = ch.modes()
    np.testing.assert_allclose(f, ch.natural_frequencies_hz(), rtol=1e-12)
    assert np.all(q == np.inf)
