"""etd3, the exponential integrator: its remainder split, its order, its error model, its accuracy
on the paper's run against a tight DOP853 reference, and the block-wise and kernel equivalences."""

import math

import numpy as np
import numba
import pytest

from rig.errors import DivergenceError
from rig.solvers import SOLVERS, integrate, solver_named
from rig.solvers.etd3 import etd3_kernel
from rig.solvers.primitives import SINCOS_POLY_MAX, chain_args, sincos_poly
from rig.solvers.etd3 import etd3_coefficients
from rig.solvers.rhs import nonlinear_remainder, rhs
from rig.scene import load_scene
from rig.simulate import BaseInput, simulate
from rig.devices.source import Source, generate, start_source

from chains import blockwise_and_one_shot, random_chain, rod_chain


def dop_fixed(chain, base, y0, substeps):
    """DOP853 driven with fixed steps (no error control): the reference."""
    return integrate(chain, y0, base.ax_mps2, base.ay_mps2, hold=base.hold, h_in=base.dt_s,
                     n_intervals=base.n_intervals, out_every=1,
                     solver=solver_named("dop853", substeps=substeps, adaptive_steps=False)).y_out


@pytest.fixture(scope="module")
def paper():
    return load_scene("ishizaki2009").chain


def paper_input(seconds, seed=5):
    """The paper's drive: band-limited (0-12.5 Hz) Gaussian noise, 0.05 m/s^2 rms, held at 1 kHz."""
    src = Source(type="random", level_vrms=0.05, fs_hz=1000.0)
    ax, _ = generate(src, start_source(src, seed), round(seconds * 1000))
    return BaseInput(ax, 1e-3)


# -- the split of the vector field ---------------------------------------------------------------

def test_sincos_polynomial_is_within_two_ulp_of_libm():
    @numba.njit
    def both(x):
        return sincos_poly(x)

    for x in np.linspace(-SINCOS_POLY_MAX, SINCOS_POLY_MAX, 40001):
        s, c = both(x)
        assert abs(s - math.sin(x)) <= 2 * np.spacing(abs(math.sin(x))) or s == math.sin(x)
        assert abs(c - math.cos(x)) <= 2 * np.spacing(math.cos(x))


@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("mode", ["absolute", "relative"])
def test_remainder_parts_add_up_to_the_full_vector_field(n, mode):
    """th'' = (A z + B ax)_omega + N0 + ax N1 + ay N2 for random chains, states and inputs, to
    round-off (100 cond(M) eps |th''|), through the n = 2 scalar code and the any-n code."""
    rng = np.random.default_rng(7 * n + len(mode))
    for _ in range(10):
        chain = random_chain(rng, n, mode)
        a, b = chain.state_space()
        y = np.concatenate([rng.uniform(-2, 2, n), rng.uniform(-3, 3, n)])
        ax, ay = rng.normal(0, 2, 2)
        full = rhs(chain, y, ax, ay)[n:]
        tol = 100 * np.linalg.cond(chain.mass_matrix(y[:n])) * np.finfo(float).eps * (
            np.abs(full).max() + np.abs(a @ y).max())
        for generic in (False, True):
            parts = nonlinear_remainder(chain, y, generic=generic)
            got = (a @ y + b[:, 0] * ax)[n:] + parts[0] + ax * parts[1] + ay * parts[2]
            np.testing.assert_allclose(got, full, rtol=0, atol=tol)


def test_remainder_vanishes_to_third_order_at_the_hanging_equilibrium(paper):
    """N ~ theta^3 (and theta^2 omega): halving the state divides N0 by 8, N1 (the input gain's
    change, ~ theta^2) by 4 and N2 (~ theta) by 2."""
    y = np.array([0.02, -0.01, 0.05, 0.03])
    big, small = nonlinear_remainder(paper, y), nonlinear_remainder(paper, y / 2)
    np.testing.assert_allclose(big[0] / small[0], 8.0, rtol=0.01)
    np.testing.assert_allclose(big[1] / small[1], 4.0, rtol=0.01)
    np.testing.assert_allclose(big[2] / small[2], 2.0, rtol=0.01)


# -- order and error model ----------------------------------------------------------------------

def _errors(chain, base, theta0, substeps):
    y0 = np.array([*theta0, 0.0, 0.0])
    ref = dop_fixed(chain, base, y0, 96)
    errors = []
    for k in substeps:
        tr = simulate(chain, base.duration_s, theta0=theta0, base=base, method="etd3",
                      dt_s=base.dt_s / k, output_dt_s=base.dt_s, estimate_error=False)
        errors.append(np.abs(np.hstack([tr.theta_rad, tr.omega_rad_s]) - ref).max())
    return np.array(errors)


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_etd3_converges_at_third_order_through_a_held_input(hold):
    """Damped double rod from (0.5, -0.3) rad on a random base held for 0.1 s (zoh or linear):
    max error over the run against fixed-step DOP853 (error < 1e-13) falls as h^3; the slope of
    log(error) vs log(h) over 8..64 steps per sample is within 0.15 of 3, and the finest pair
    within 0.05. The steps land on the sample instants, so the input's jumps do not lower the
    order."""
    x = 0.2 * np.random.default_rng(3).standard_normal(21)
    base = BaseInput(x if hold == "linear" else x[:20], 0.1, hold)
    chain = rod_chain(2, damping=0.05)
    substeps = [8, 16, 32, 64]
    errors = _errors(chain, base, (0.5, -0.3), substeps)
    slope = np.polyfit(np.log(1.0 / np.array(substeps)), np.log(errors), 1)[0]
    pair = np.log(errors[-2] / errors[-1]) / np.log(2.0)
    assert abs(slope - SOLVERS["etd3"].order) < 0.15, (errors, slope)
    assert abs(pair - 3) < 0.05
    assert errors.min() > 1e3 * 1e-13


def test_etd3_error_scales_with_the_nonlinearity():
    """The stated error model, O(h^3 |N| |dN/dz|) with |N| ~ theta^3 and |dN/dz| ~ theta^2:
    five times smaller angles (same input shape, scaled) give an error about 5^5 = 3125 times
    smaller at the same step (between 1500 and 6000), and the linear method's error (which is
    all model) only 5^3 = 125 times smaller."""
    chain = rod_chain(2, damping=0.05)
    x = np.random.default_rng(3).standard_normal(20)
    err = {}
    for scale in (1.0, 0.2):
        base = BaseInput(0.2 * scale * x, 0.1)
        err[scale] = _errors(chain, base, (0.5 * scale, -0.3 * scale), [16])[0]
    ratio = err[1.0] / err[0.2]
    assert 1500 < ratio < 6000, ratio


def test_etd3_is_the_exact_linear_method_when_the_motion_is_tiny(paper):
    """At 1e-7 rad the remainder is ~1e-21 of the motion: etd3 equals the exact discretisation of
    the linearised chain to round-off (1e-12 of the largest angle over 10 s at 1 kHz)."""
    base = BaseInput(1e-6 * paper_input(10.0).ax_mps2, 1e-3)
    kw = dict(theta0=0.0, base=base, output_dt_s=0.01, estimate_error=False)
    lin = simulate(paper, 10.0, method="linear", **kw)
    etd = simulate(paper, 10.0, method="etd3", **kw)
    scale = np.abs(lin.theta_rad).max()
    np.testing.assert_allclose(etd.theta_rad, lin.theta_rad, rtol=0, atol=1e-12 * scale)


def test_etd3_on_the_papers_run_against_a_tight_dop853_reference(paper):
    """The paper's pendulum on 20 s of its random drive (0.05 m/s^2 rms, held at 1 kHz, angles up
    to 0.08 rad): against fixed-step DOP853 at 2 steps per sample (itself within 1e-13 of 4 steps
    per sample, shown here), etd3 at one step per sample has a relative RMS angle error below
    1e-10 (measured 4e-12), over 1000 times smaller than RK4 at the same step (measured 6e-8),
    and its Richardson estimate is within a factor 1.5 of it."""
    base = paper_input(20.0)
    y0 = np.zeros(4)
    ref = dop_fixed(paper, base, y0, 2)[::10, :2]
    finer = dop_fixed(paper, base, y0, 4)[::10, :2]
    rms = np.sqrt(np.mean(ref**2, axis=0))

    def rel(theta):
        return float(np.max(np.sqrt(np.mean((theta - ref) ** 2, axis=0)) / rms))

    assert rel(finer) < 1e-13
    kw = dict(theta0=0.0, base=base, output_dt_s=0.01)
    etd = simulate(paper, 20.0, method="etd3", **kw)
    rk4 = simulate(paper, 20.0, method="rk4", estimate_error=False, **kw)
    assert etd.settings["dt_s"] == rk4.settings["dt_s"] == 1e-3
    e_etd, e_rk4 = rel(etd.theta_rad), rel(rk4.theta_rad)
    assert e_etd < 1e-10 and e_etd < 1e-3 * e_rk4, (e_etd, e_rk4)
    est = float(np.max(np.sqrt(np.mean(etd.error_estimate_rad**2, axis=0)) / rms))
    assert 1 / 1.5 < e_etd / est < 1.5, (e_etd, est)
    assert etd.error_method.startswith("Richardson") and "p = 3" in etd.error_method


# -- equivalences -------------------------------------------------------------------------------

def test_scalar_n2_kernel_equals_the_generic_kernel(paper):
    """The n = 2 scalar kernel (fused multiply-adds, other summation order) and the any-n kernel
    give the same trajectory to round-off (1e-12 of the largest angle over 5 s, zoh and linear)."""
    for hold in ("zoh", "linear"):
        ax = paper_input(5.001).ax_mps2
        ay = 0.3 * ax[::-1].copy()
        n_int = 5000
        h = 1e-3
        co = etd3_coefficients(paper, h, hold)
        outs = []
        for kernel in ("scalar", "generic"):
            if kernel == "scalar":
                run = integrate(paper, solver_named("etd3").init(paper, [0.01, -0.02, 0.0, 0.1]), ax, ay,
                                hold=hold, h_in=h, n_intervals=n_int, out_every=10,
                                solver=solver_named("etd3"))
                outs.append(run.y_out)
                continue
            y = np.array([0.01, -0.02, 0.0, 0.1])
            y_out = np.empty((n_int // 10 + 1, 4))
            hist = np.zeros((2, 6))
            etd3_kernel(chain_args(paper), co, (ax, ay, 1, int(hold == "linear")), h, 1, n_int,
                        10, y, y_out, hist, False)
            outs.append(y_out)
        scale = np.abs(outs[0][:, :2]).max()
        np.testing.assert_allclose(outs[0], outs[1], rtol=0, atol=1e-12 * scale)


def test_blockwise_etd3_runs_reproduce_the_one_shot_run_bit_for_bit():
    """The previous step's stage remainders travel in the native state, so blocks continue the
    predictor instead of restarting it."""
    joined, state, one = blockwise_and_one_shot(
        [(0, 150), (150, 320), (320, 500)], method="etd3", dt_s=0.005, output_dt_s=0.01,
        estimate_error=False)
    np.testing.assert_array_equal(joined, one.theta_rad)
    np.testing.assert_array_equal(state.native, one.final_state.native)
    assert state.native.size == 8 * 2 + 2 and state.native[2 * 2] == 1.0


def test_restart_with_a_different_step_restarts_the_predictor():
    """History from another step size is not used: continuing a dt = 5 ms run with dt = 2.5 ms
    gives exactly a fresh dt = 2.5 ms run from the same state."""
    chain = rod_chain(2, damping=0.02)
    a = simulate(chain, 1.0, theta0=(0.4, 0.1), method="etd3", dt_s=0.005, estimate_error=False)
    cont = simulate(chain, 1.0, start=a.final_state, method="etd3", dt_s=0.0025,
                    estimate_error=False)
    fresh = simulate(chain, 1.0, theta0=a.final_state.theta_rad,
                     omega0=a.final_state.omega_rad_s, method="etd3", dt_s=0.0025,
                     estimate_error=False)
    np.testing.assert_array_equal(cont.theta_rad, fresh.theta_rad)


def test_etd3_divergence_raises_with_time_and_last_finite_state():
    """A step far too long for the strongly nonlinear double rod: a DivergenceError with the
    output instant of the last finite state, which is finite."""
    with pytest.raises(DivergenceError, match="etd3: the state became non-finite") as info:
        simulate(rod_chain(2), 200.0, theta0=(2.0, 2.5), method="etd3", dt_s=0.5,
                 estimate_error=False)
    assert np.all(np.isfinite(info.value.state)) and info.value.state.shape == (4,)
