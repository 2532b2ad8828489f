"""Integrators: right-hand sides, convergence orders, exactness of the linear discretisation,
the Gauss stage solver, and how honest the error estimates are."""

import math

import numpy as np
import pytest
import scipy.linalg

from rig.chain import G_STANDARD, Chain
from rig.solvers import COUPLED_BENCH, PENDULUM, SOLVERS, integrate, names_for, solver_named
from rig.linear import discretise
from rig.solvers.rhs import rhs
from rig.simulate import BaseInput, simulate

from chains import paper_pendulum, random_chain, rod_chain

EPS = np.finfo(float).eps


# -- right-hand sides ---------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 3, 6])
@pytest.mark.parametrize("mode", ["absolute", "relative"])
def test_kernel_rhs_equals_chain_accelerations(n, mode):
    """The integrators' own right-hand sides (scalar n = 2 path and the any-n path with
    angle-difference identities) agree with rig.chain's accelerations to round-off,
    |error| <= 100 cond(M) eps |th''|."""
    rng = np.random.default_rng(10 * n + len(mode))
    for _ in range(20):
        chain = random_chain(rng, n, mode)
        theta = rng.uniform(-3, 3, n)
        omega = rng.uniform(-5, 5, n)
        ax, ay = rng.normal(0, 3, 2)
        ref = chain.accelerations(theta, omega, ax, ay)
        tol = 100 * np.linalg.cond(chain.mass_matrix(theta)) * EPS * np.max(np.abs(ref))
        y = np.concatenate([theta, omega])
        for generic in (False, True):
            f = rhs(chain, y, ax, ay, generic=generic)
            np.testing.assert_array_equal(f[:n], omega)
            np.testing.assert_allclose(f[n:], ref, rtol=0, atol=tol)


@pytest.mark.parametrize("n", [2, 4])
def test_canonical_rhs_is_theta_dot_and_the_time_derivative_of_momentum(n):
    """For y = (theta, p = M omega): theta' = omega and p' = M th'' + dM/dt omega with
    dM_jk/dt = -H_jk sin(th_j - th_k)(w_j - w_k) (th'' from rig.chain)."""
    rng = np.random.default_rng(n)
    for _ in range(20):
        chain = random_chain(rng, n, "relative")
        theta = rng.uniform(-3, 3, n)
        omega = rng.uniform(-5, 5, n)
        ax, ay = rng.normal(0, 3, 2)
        m = chain.mass_matrix(theta)
        mdot = -chain.H * np.sin(theta[:, None] - theta[None, :]) * (omega[:, None] - omega[None])
        pdot = m @ chain.accelerations(theta, omega, ax, ay) + mdot @ omega
        y = solver_named("gauss4").init(chain, np.concatenate([theta, omega]))
        p = m @ omega
        np.testing.assert_allclose(y[n:], p, rtol=1e-14, atol=1e-14 * np.abs(p).max())
        tol = 100 * np.linalg.cond(m) * EPS * max(np.abs(pdot).max(), np.abs(omega).max())
        for generic in (False, True):
            f = rhs(chain, y, ax, ay, canonical=True, generic=generic)
            np.testing.assert_allclose(f[:n], omega, rtol=0, atol=tol)
            np.testing.assert_allclose(f[n:], pdot, rtol=0, atol=tol)


def test_registry_states_order_kind_and_description_of_every_method():
    assert set(SOLVERS) == {"rk4", "dop853", "gauss4", "midpoint", "linear", "etd3", "etd3m",
                            "etd4m", "lawson4", "etdab"}
    assert {k: (v.order, v.kind) for k, v in SOLVERS.items()} == {
        "rk4": (4, "fixed"), "dop853": (8, "adaptive"), "gauss4": (4, "implicit"),
        "midpoint": (2, "implicit"), "linear": (None, "exact"), "etd3": (3, "exponential"),
        "etd3m": (3, "exponential"), "etd4m": (4, "exponential"), "lawson4": (4, "exponential"),
        "etdab": (4, "exponential")}
    assert names_for(COUPLED_BENCH) == ["lawson4", "etdab"]
    assert names_for(PENDULUM) == [k for k in SOLVERS if k not in ("lawson4", "etdab")]
    assert [k for k, v in SOLVERS.items() if v.multisample] == ["etd3m", "etd4m"]
    assert all(v.description and v.name == k for k, v in SOLVERS.items())
    assert [k for k, v in SOLVERS.items() if v.symplectic] == ["gauss4", "midpoint"]


# -- convergence orders -------------------------------------------------------------------------

def _forced_rod_problem():
    """Damped double rod from (0.5, -0.3) rad on a zoh random base (20 samples of 0.1 s)."""
    chain = rod_chain(2, damping=0.05)
    base = BaseInput(0.2 * np.random.default_rng(3).standard_normal(20), 0.1)
    return chain, base, np.array([0.5, -0.3, 0.0, 0.0])


def _dop_fixed(chain, base, y0, substeps):
    return integrate(chain, y0, base.ax_mps2, None, hold="zoh", h_in=base.dt_s,
                     n_intervals=base.n_intervals, out_every=1,
                     solver=solver_named("dop853", substeps=substeps, adaptive_steps=False)).y_out


def _fitted_order(errors, steps):
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    pairwise = np.diff(np.log(errors)) / np.diff(np.log(steps))
    return slope, pairwise


@pytest.mark.parametrize("method, substeps, tol", [
    ("rk4", [8, 16, 32, 64], 0.25),
    ("gauss4", [4, 8, 16, 32], 0.25),
    ("midpoint", [8, 16, 32, 64], 0.25),
])
def test_fixed_step_methods_converge_at_their_order_through_a_held_input(method, substeps, tol):
    """Max error over the trajectory against a fixed-step DOP853 reference (error < 1e-13) falls
    as h^p; the zoh input does not spoil the order because steps land on its sample instants.
    The slope of log(error) vs log(h) is within 1/4 of p (pre-asymptotic O(h) correction)."""
    chain, base, y0 = _forced_rod_problem()
    ref = _dop_fixed(chain, base, y0, 96)
    assert np.abs(ref - _dop_fixed(chain, base, y0, 48)).max() < 1e-13
    errors = []
    for k in substeps:
        tr = simulate(chain, base.duration_s, theta0=y0[:2], base=base, method=method,
                      dt_s=base.dt_s / k, output_dt_s=base.dt_s, estimate_error=False)
        errors.append(np.abs(np.hstack([tr.theta_rad, tr.omega_rad_s]) - ref).max())
    slope, pairwise = _fitted_order(errors, base.dt_s / np.array(substeps))
    p = SOLVERS[method].order
    assert abs(slope - p) < tol, (errors, slope)
    assert abs(pairwise[-1] - p) < tol  # and the finest pair is asymptotic
    assert min(errors) > 1e3 * 1e-13  # all well above the reference's own error


def test_dop853_tableau_is_eighth_order():
    """Driven with fixed steps (no error control), the copied DOP853 tableau converges as h^8.
    The pairwise slopes decrease toward 8 as h shrinks (pre-asymptotic h^9 term), and the slope
    fitted over the three finest steps, whose errors are still 10x above the round-off floor, is
    within 1/2 of 8."""
    chain, base, y0 = _forced_rod_problem()
    ref = _dop_fixed(chain, base, y0, 96)
    floor = np.abs(ref - _dop_fixed(chain, base, y0, 48)).max()
    substeps = [3, 4, 5, 6, 8]
    errors = [np.abs(_dop_fixed(chain, base, y0, k) - ref).max() for k in substeps]
    steps = base.dt_s / np.array(substeps)
    _, pairwise = _fitted_order(errors, steps)
    slope, _ = _fitted_order(errors[-3:], steps[-3:])
    assert abs(slope - 8) < 0.5, (errors, slope)
    assert np.all(np.diff(pairwise) < 0.05) and np.all(pairwise > 8 - 0.5)
    assert min(errors) > 10 * floor


def test_dop853_error_follows_rtol_and_its_estimate_is_honest():
    """Undamped double rod from (1.0, -0.6) rad for 10 s: the rtol/100 estimate is within a
    factor 2 of the true error (against rtol = 1e-14) at every tolerance (it leaves out only the
    reference's own error, ~100 times smaller); and the true error falls with rtol. Per-step
    control gives global error ~ rtol^(7/8) (local error ~ tol, steps ~ tol^(-1/8)), which holds
    only roughly (Hairer II.4, tolerance proportionality): slope in 7/8 +- 0.3 over 4 decades."""
    chain = rod_chain(2)
    kw = dict(theta0=(1.0, -0.6), method="dop853", output_dt_s=0.1)
    ref = simulate(chain, 10.0, rtol=1e-14, atol=1e-16, estimate_error=False, **kw)
    rtols = np.array([1e-6, 1e-7, 1e-8, 1e-9, 1e-10])
    errors = []
    for rtol in rtols:
        tr = simulate(chain, 10.0, rtol=rtol, atol=rtol * 1e-2, **kw)
        err = np.abs(tr.theta_rad - ref.theta_rad).max()
        assert 0.5 < err / tr.max_error_rad < 2.0
        assert tr.error_method.startswith("|y - y_ref| against the same run with rtol")
        errors.append(err)
    slope = np.polyfit(np.log(rtols), np.log(errors), 1)[0]
    assert abs(slope - 7 / 8) < 0.3, (errors, slope)


@pytest.mark.parametrize("dt_s", [0.01, 0.05])
def test_dop853_estimate_is_honest_when_the_sample_grid_sets_the_step(dt_s):
    """On a 100 Hz (20 Hz) zoh input the paper's pendulum needs ~1 (2) DOP853 steps per sample at
    rtol = 1e-8, so the steps are set by the sample grid, not by the tolerance; the estimate (which
    also takes >= 2 steps per interval) still matches the true error (against fixed steps of
    dt/8) within a factor 2, instead of reporting zero."""
    chain = paper_pendulum()
    n = round(20.0 / dt_s)
    base = BaseInput(0.05 * np.random.default_rng(1).standard_normal(n), dt_s)
    tr = simulate(chain, 20.0, theta0=0.0, base=base, method="dop853", rtol=1e-8,
                  output_dt_s=10 * dt_s)
    ref = integrate(chain, np.zeros(4), base.ax_mps2, None, hold="zoh", h_in=dt_s, n_intervals=n,
                    out_every=10,
                    solver=solver_named("dop853", substeps=8, adaptive_steps=False)).y_out
    true = np.abs(tr.theta_rad - ref[:, :2]).max()
    assert tr.n_steps < 2.1 * n
    assert 0.5 < true / tr.max_error_rad < 2.0, (true, tr.max_error_rad)


@pytest.mark.parametrize("method", ["rk4", "gauss4", "midpoint"])
def test_richardson_estimate_of_fixed_step_methods_is_honest(method):
    """Richardson (|y_h - y_h/2| 2^p / (2^p - 1)) estimates the true angle error at every output
    instant to within 20 % once the error is asymptotic (dt = 5 ms, 10 s double rod)."""
    chain = rod_chain(2)
    ref = simulate(chain, 10.0, theta0=(1.0, -0.6), rtol=1e-14, atol=1e-16, output_dt_s=0.1,
                   estimate_error=False)
    tr = simulate(chain, 10.0, theta0=(1.0, -0.6), method=method, dt_s=5e-3, output_dt_s=0.1)
    true = np.abs(tr.theta_rad - ref.theta_rad)
    big = true > 1e-3 * true.max()  # where the error is not at a zero crossing
    ratio = true[big] / tr.error_estimate_rad[big]
    assert np.all((ratio > 0.8) & (ratio < 1.2)), (ratio.min(), ratio.max())
    assert tr.error_method.startswith("Richardson")


# -- exact discretisation of the linear model ----------------------------------------------------

def _sdof(zeta=0.05):
    """One uniform rod (D = 1/3 kg m^2, S = 0.5 kg m) with damping ratio zeta."""
    d, s = 1 / 12 + 0.25, 0.5
    k = G_STANDARD * s
    gamma = 2 * zeta * math.sqrt(k * d)
    chain = Chain((1.0,), (1.0,), (0.5,), (1 / 12,), (gamma,))
    w0 = math.sqrt(k / d)
    return chain, w0, zeta, s, k, gamma


def test_linear_method_is_exact_for_a_held_step():
    """Damped single rod from rest under a constant (zoh) base acceleration U: the linear method
    equals theta(t) = -U/g [1 - e^{-zeta w0 t}(cos wd t + zeta/sqrt(1-zeta^2) sin wd t)] at every
    sample, to round-off (1000 steps x a few eps: 1e-12 of the static deflection)."""
    chain, w0, zeta, _, _, _ = _sdof()
    u, dt = 0.3, 0.01
    tr = simulate(chain, 10.0, theta0=0.0, base=BaseInput(np.full(1000, u), dt),
                  method="linear", output_dt_s=dt)
    t = tr.t_s
    wd = w0 * math.sqrt(1 - zeta**2)
    th_ss = -u / G_STANDARD
    theta = th_ss * (1 - np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2)
                                                   * np.sin(wd * t)))
    omega = th_ss * w0 / math.sqrt(1 - zeta**2) * np.exp(-zeta * w0 * t) * np.sin(wd * t)
    np.testing.assert_allclose(tr.theta_rad[:, 0], theta, rtol=0, atol=1e-12 * abs(th_ss))
    np.testing.assert_allclose(tr.omega_rad_s[:, 0], omega, rtol=0, atol=1e-12 * abs(th_ss) * w0)
    assert tr.max_error_rad < 1e-12 * abs(th_ss)  # the estimate sees round-off only
    assert "round-off only" in tr.error_method and "model error" in tr.error_method


def test_linear_method_is_exact_for_a_linearly_held_ramp():
    """Linear hold of samples u_k = r t_k is the ramp u = r t; the response from rest is
    theta = a t + b + e^{-sigma t}(A cos wd t + B sin wd t) with a = -S r/K, b = -Gamma a/K,
    A = -b, B = (sigma A - a)/wd. The linear method (with the Van Loan Gamma1 term) equals it to
    round-off."""
    chain, w0, zeta, s, k, gamma = _sdof()
    r, dt, n = 0.05, 0.02, 500
    tr = simulate(chain, n * dt, theta0=0.0, base=BaseInput(r * dt * np.arange(n + 1), dt,
                                                            hold="linear"),
                  method="linear", output_dt_s=dt)
    t = tr.t_s
    sigma, wd = zeta * w0, w0 * math.sqrt(1 - zeta**2)
    a = -s * r / k
    b = -gamma * a / k
    big_a = -b
    big_b = (sigma * big_a - a) / wd
    theta = a * t + b + np.exp(-sigma * t) * (big_a * np.cos(wd * t) + big_b * np.sin(wd * t))
    omega = a + np.exp(-sigma * t) * ((-sigma * big_a + wd * big_b) * np.cos(wd * t)
                                      + (-sigma * big_b - wd * big_a) * np.sin(wd * t))
    scale = np.abs(theta).max()
    np.testing.assert_allclose(tr.theta_rad[:, 0], theta, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(tr.omega_rad_s[:, 0], omega, rtol=0, atol=1e-12 * scale * w0)


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_linear_method_gives_the_same_answer_at_half_the_step(hold):
    """The held input resampled at dt/2 (zoh: each sample twice; linear: midpoints added) is the
    same continuous signal, so the exact method must give the same trajectory at the common
    instants, to round-off (2000 steps: 1e-12 of the largest angle)."""
    chain = paper_pendulum()
    ax = 0.05 * np.random.default_rng(7).standard_normal(1001)
    dt = 0.01
    if hold == "zoh":
        fine = np.repeat(ax, 2)
    else:
        fine = np.empty(2 * ax.size - 1)
        fine[0::2] = ax
        fine[1::2] = 0.5 * (ax[:-1] + ax[1:])
    a = simulate(chain, 10.0, theta0=0.0, base=BaseInput(ax, dt, hold), method="linear",
                 output_dt_s=dt, estimate_error=False)
    b = simulate(chain, 10.0, theta0=0.0, base=BaseInput(fine, dt / 2, hold), method="linear",
                 output_dt_s=dt, estimate_error=False)
    scale = np.abs(a.theta_rad).max()
    np.testing.assert_allclose(b.theta_rad, a.theta_rad, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(b.t_s, a.t_s, rtol=1e-15)


def test_van_loan_discretisation_matches_its_integral_definition():
    """Phi = e^{Ah}, Gamma0 = int_0^h e^{Ar} dr B, Gamma1 = int_0^h e^{A(h-r)} B r/h dr, checked by
    Gauss-Legendre quadrature (40 nodes: exact to round-off for these smooth integrands)."""
    a, b = paper_pendulum().state_space()
    h = 0.05
    phi, g0, g1 = discretise(a, b, h, "linear")
    x, w = np.polynomial.legendre.leggauss(40)
    r = 0.5 * h * (x + 1)
    w = 0.5 * h * w
    q0 = sum(wi * scipy.linalg.expm(a * ri) @ b for ri, wi in zip(r, w))
    q1 = sum(wi * scipy.linalg.expm(a * (h - ri)) @ b * ri / h for ri, wi in zip(r, w))
    np.testing.assert_allclose(phi, scipy.linalg.expm(a * h), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(g0, q0, rtol=1e-11, atol=1e-17)
    np.testing.assert_allclose(g1, q1, rtol=1e-11, atol=1e-17)
    assert not np.any(discretise(a, b, h, "zoh")[2])


# -- Gauss stage equations ----------------------------------------------------------------------

@pytest.mark.parametrize("method", ["gauss4", "midpoint"])
def test_gauss_stage_equations_fall_back_to_newton_and_give_the_exact_rational_map(method):
    """Single undamped rod at 1e-8 rad (linear to 1e-17) with w0 h = 3, where fixed-point
    iteration cannot converge: every step uses Newton, and the result equals the method's exact
    step map for y' = L y, R(hL) = (I - hL/2 + (hL)^2/12)^-1 (I + hL/2 + (hL)^2/12) (gauss4) or
    (I - hL/2)^-1 (I + hL/2) (midpoint), to round-off; |R| = 1, so the amplitude is kept."""
    chain, w0, _, s, k, _ = _sdof(zeta=0.0)
    d = chain.D[0]
    h = 3.0 / w0
    steps = 40
    tr = simulate(chain, steps * h, theta0=1e-8, method=method, dt_s=h, output_dt_s=h,
                  estimate_error=False)
    assert tr.n_newton == tr.n_steps == steps
    lam = np.array([[0.0, 1.0 / d], [-k, 0.0]]) * h  # (theta, p)
    eye = np.eye(2)
    if method == "gauss4":
        step = np.linalg.solve(eye - lam / 2 + lam @ lam / 12, eye + lam / 2 + lam @ lam / 12)
    else:
        step = np.linalg.solve(eye - lam / 2, eye + lam / 2)
    y = np.array([1e-8, 0.0])
    expect = [y]
    for _ in range(steps):
        y = step @ y
        expect.append(y)
    expect = np.array(expect)
    np.testing.assert_allclose(tr.theta_rad[:, 0], expect[:, 0], rtol=0, atol=1e-12 * 1e-8)
    np.testing.assert_allclose(tr.omega_rad_s[:, 0] * d, expect[:, 1], rtol=0,
                               atol=1e-12 * 1e-8 * math.sqrt(k * d))


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_scalar_n2_rk4_kernel_equals_the_generic_one(hold):
    """rk4 for n = 2 runs a scalar kernel (polynomial sines, fused multiply-adds); against the
    generic kernel with the dense solve it differs by round-off only (1e-12 rad over 5 s of the
    damped double rod from (1.0, -0.5) rad on a random base, horizontal and vertical)."""
    chain = rod_chain(2, damping=0.05)
    rng = np.random.default_rng(2)
    extra = 1 if hold == "linear" else 0
    base = BaseInput(0.5 * rng.standard_normal(500 + extra), 0.01, hold,
                     0.3 * rng.standard_normal(500 + extra))
    kw = dict(theta0=(1.0, -0.5), base=base, method="rk4", dt_s=0.005, output_dt_s=0.01,
              estimate_error=False)
    fast = simulate(chain, 5.0, **kw)
    dense = simulate(chain, 5.0, algorithm="dense", **kw)
    assert (fast.settings["rhs"], dense.settings["rhs"]) == ("n=2 scalar", "dense")
    np.testing.assert_allclose(fast.theta_rad, dense.theta_rad, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.omega_rad_s, dense.omega_rad_s, rtol=0, atol=1e-11)
