"""etd4m, three Gauss nodes and a quadratic stage prediction over m held samples: its error on
the paper's drive below etd3m's at the same step and within its Richardson estimate, its order
from a step-halving sequence, the linear limit, the n = 2 kernel against the generic one,
block-wise runs, registration."""

import numpy as np
import pytest

from benchmarks.work_precision import paper_input, rel_rms_error
from rig.solvers import SOLVERS
from rig.solvers.etd4m import etd4m_kernel
from rig.solvers.primitives import chain_args
from rig.solvers.etd4m import etd4m_coefficients
from rig.simulate import BaseInput, simulate

from chains import (assert_blocks_reproduce_one_shot, dop853_fixed, multisample_run,
                    scalar_and_generic_rows, swinging_rods)


def test_etd4m_is_registered_as_a_multisample_exponential_method_of_order_4():
    info = SOLVERS["etd4m"]
    assert (info.order, info.kind, info.multisample) == (4, "exponential", True)
    assert "etd3m" in SOLVERS  # today's method stays


@pytest.mark.parametrize("m", [5, 10])
def test_etd4m_error_on_the_papers_drive_is_below_etd3m_at_the_same_step(paper, piece, m):
    """100 s of the paper's run against DOP853: etd4m's relative RMS angle error is at least 4
    times below etd3m's at the same m (measured 2.4e-9 against 1.6e-8 at m = 5, 3.4e-8 against
    2.1e-7 at m = 10) and below 1e-7 at m = 10 (the 1e-6 target with a margin of 10 for the
    growth over the 3000 s run, measured 8.2e-8 there)."""
    base, ref = piece
    e4 = rel_rms_error(multisample_run(paper, base, "etd4m", m, 10).y_out[:, :2], ref[:, :2])
    e3 = rel_rms_error(multisample_run(paper, base, "etd3m", m, 10).y_out[:, :2], ref[:, :2])
    assert e4 * 4 < e3, (e4, e3)
    if m == 10:
        assert e4 < 1e-7, e4


def test_etd4m_error_falls_with_the_step_at_order_3_to_5(paper, piece):
    """m = 1, 2, 4, 5, 10, 20 on 100 s of the paper's drive: the fitted slope of log error
    against log H is between 3 and 5 (measured 3.9; etd3m's 3.4) and the error falls with every
    shorter step."""
    base, ref = piece
    ms = np.array([1, 2, 4, 5, 10, 20])
    errors = np.array([rel_rms_error(multisample_run(paper, base, "etd4m", m, 20).y_out[:, :2],
                                     ref[::2, :2]) for m in ms])
    slope = np.polyfit(np.log(ms), np.log(errors), 1)[0]
    assert 3.0 <= slope <= 5.0, (errors, slope)
    assert np.all(np.diff(errors) > 0), errors


def test_etd4m_on_the_papers_drive_within_its_richardson_estimate(paper, piece):
    """simulate at m = 10 (dt_s = 10 ms): the Richardson estimate against m = 5 (ratio 2, order
    4) is within a factor 3 of the error measured against DOP853."""
    base, ref = piece
    tr = simulate(paper, 100.0, theta0=0.0, base=base, method="etd4m", dt_s=0.01,
                  output_dt_s=0.01)
    assert tr.settings["samples_per_step"] == 10 and tr.n_steps == 10_000
    err = rel_rms_error(tr.theta_rad, ref[:, :2])
    rms = np.sqrt(np.mean(ref[:, :2] ** 2, axis=0))
    est = float(np.max(np.sqrt(np.mean(tr.error_estimate_rad**2, axis=0)) / rms))
    assert 1 / 3 < err / est < 3.0, (err, est)
    assert "2^4/(2^4 - 1)" in tr.error_method


def test_etd4m_is_the_lifted_linear_method_when_the_motion_is_tiny(paper):
    """At 1e-7 rad the remainder is negligible: with m = 10 samples per step etd4m equals the
    lifted exact discretisation to round-off, for both holds (the staircase and the straight
    lines integrated exactly)."""
    ax = 1e-6 * paper_input(10.0).ax_mps2
    for hold in ("zoh", "linear"):
        base = BaseInput(ax, 1e-3, hold)
        kw = dict(theta0=0.0, base=base, output_dt_s=0.01, estimate_error=False)
        dur = round(base.duration_s - (base.duration_s % 0.01 if hold == "linear" else 0.0), 6)
        lin = simulate(paper, dur, method="linear", **kw)
        etd = simulate(paper, dur, method="etd4m", dt_s=0.01, **kw)
        scale = np.abs(lin.theta_rad).max()
        np.testing.assert_allclose(etd.theta_rad, lin.theta_rad, rtol=0, atol=1e-12 * scale)


def test_scalar_n2_kernel_equals_the_generic_kernel(paper):
    """The n = 2 scalar kernel and the any-n kernel agree to round-off (1e-12 of the largest
    angle over 5 s; both holds, with a vertical input, m = 1, 5, 10)."""
    for m in (1, 5, 10):
        for hold in ("zoh", "linear"):
            def kernel(ax, ay, h, n_int, y, y_out):
                co = etd4m_coefficients(paper, h, m, hold)
                etd4m_kernel(chain_args(paper), co, ax, ay, 1, m, n_int // m, 10 // m, y, y_out,
                             np.zeros((3, 6)), False)

            generic, scalar = scalar_and_generic_rows(paper, "etd4m", m, hold, kernel)
            scale = np.abs(scalar[:, :2]).max()
            np.testing.assert_allclose(generic, scalar, rtol=0, atol=1e-12 * scale)


def test_blockwise_etd4m_runs_reproduce_the_one_shot_run_bit_for_bit():
    """Blocks that end on output rows continue the three-stage predictor from the native
    state."""
    assert_blocks_reproduce_one_shot([(0, 160), (160, 320), (320, 500)], method="etd4m",
                                     dt_s=0.02, output_dt_s=0.04, estimate_error=False)


def test_strongly_nonlinear_chain_converges_at_order_4_with_the_generic_kernel():
    """A 3-body chain (the any-n kernel) swinging to 0.3 rad on a linearly interpolated x and y
    input at 200 Hz, against fixed-step DOP853: halving the step from m = 4 to 2 and from 2 to 1
    divides the error by 12 to 40 (order 4: 16; measured 25 and 22), and at every m the error is
    below etd3m's by at least 20 times at m = 1 and 2 and 5 times at m = 4 (measured 91, 33,
    9)."""
    chain, base, y0, ref = swinging_rods()
    e4 = [rel_rms_error(multisample_run(chain, base, "etd4m", m, 20, y0).y_out[:, :3], ref)
          for m in (1, 2, 4)]
    e3 = [rel_rms_error(multisample_run(chain, base, "etd3m", m, 20, y0).y_out[:, :3], ref)
          for m in (1, 2, 4)]
    assert 12 < e4[2] / e4[1] < 40 and 12 < e4[1] / e4[0] < 40, e4
    assert e3[0] > 20 * e4[0] and e3[1] > 20 * e4[1] and e3[2] > 5 * e4[2], (e3, e4)


def test_one_sample_per_step_estimates_against_a_tight_dop853_run(paper):
    """etd4m at m = 1 cannot halve its step: its error estimate is the difference to dop853 at
    rtol 1e-12 (said in error_method), which on 2 s of the paper's drive is within a factor 3 of
    the difference to fixed-step DOP853 at 2 steps per sample."""
    base = paper_input(2.0)
    tr = simulate(paper, 2.0, theta0=0.0, base=base, method="etd4m", dt_s=1e-3,
                  output_dt_s=0.01)
    assert "dop853 at rtol = 1e-12" in tr.error_method
    ref = dop853_fixed(paper, base, out_every=10)[:, :2]
    err = np.sqrt(np.mean((tr.theta_rad - ref) ** 2))
    est = np.sqrt(np.mean(tr.error_estimate_rad ** 2))
    assert 1 / 3 < err / est < 3, (err, est)
