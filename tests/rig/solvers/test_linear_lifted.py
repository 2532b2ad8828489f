"""The linear method lifted to the output rate: one step of Phi^L and a FIR of the held input per
output row (rig.solvers.exact.lift_linear) is the per-substep recursion composed, so it must give the
per-substep run to round-off, fail the same way, and leave the partial last row per substep."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from benchmarks.work_precision import paper_input, rel_rms_error
from rig.chain import Chain
from rig.errors import DivergenceError
from rig.solvers import integrate, solver_named
from rig.solvers.exact import lifted_kernel, lifted_kernel2, linear_kernel
from rig.linear import discretise
from rig.solvers.exact import lift_linear
from rig.scene import load_scene
from rig.simulate import BaseInput, simulate


@pytest.fixture(scope="module")
def paper():
    return load_scene("ishizaki2009").chain


@pytest.fixture(scope="module")
def drive():
    """The paper's 3000 s of random base acceleration at 1 kHz (benchmarks.work_precision), and one more
    sample for the linear hold."""
    return paper_input(3000.001)


def _base(drive, hold, seconds):
    """The paper's samples over ``seconds``, held as asked (a linear hold takes one more)."""
    n = round(seconds / drive.dt_s) + (1 if hold == "linear" else 0)
    return BaseInput(drive.ax_mps2[:n], drive.dt_s, hold)


def _per_substep(chain, base, seconds, out_every, substeps, y0=None):
    """The reference: the per-substep kernel (integrate(..., lift=False)), (theta, omega) rows."""
    y0 = np.zeros(2 * chain.n) if y0 is None else np.asarray(y0, float)
    return integrate(chain, y0, base.ax_mps2, None, hold=base.hold, h_in=base.dt_s,
                     n_intervals=round(seconds / base.dt_s), out_every=out_every,
                     solver=solver_named("linear", substeps=substeps, lift=False)).y_out


# -- the lifted map ------------------------------------------------------------------------------

@pytest.mark.parametrize("hold", ["zoh", "linear"])
@pytest.mark.parametrize("substeps", [1, 3])
def test_lifted_taps_are_the_per_substep_response_to_each_input_sample(paper, hold, substeps):
    """Over one output row of m = 10 intervals, column j of Phi^L is the per-substep run from the
    unit state e_j and tap q its run from rest under the unit sample at q (the map is linear):
    equal to a few ulp per step (L = 10 substeps x 3: 1e-14 of the largest entry). Phi^L is also
    e^{A L h} (expm over the whole row) to the discretisation's round-off, 1e-12."""
    a, b = paper.state_space()
    h_in, m = 1e-3, 10
    phi, g0, g1 = discretise(a, b, h_in / substeps, hold)
    p, taps = lift_linear(phi, g0, g1, hold, substeps, m)
    la = int(hold == "linear")
    assert taps.shape == (m + la, 4)
    out = np.empty((2, 4))
    for j in range(4):
        y = np.eye(4)[j]
        linear_kernel(phi, g0, g1, np.zeros(m + 1), la, substeps, m, m, y, out)
        np.testing.assert_allclose(p[:, j], y, rtol=0, atol=1e-14 * np.abs(p).max())
    for q in range(m + la):
        y = np.zeros(4)
        linear_kernel(phi, g0, g1, np.eye(m + 1)[q], la, substeps, m, m, y, out)
        np.testing.assert_allclose(taps[q], y, rtol=0, atol=1e-14 * np.abs(taps).max())
    np.testing.assert_allclose(p, scipy.linalg.expm(a * m * h_in), rtol=0,
                               atol=1e-12 * np.abs(p).max())


# -- the paper's run -----------------------------------------------------------------------------

@pytest.mark.parametrize("hold", ["zoh", "linear"])
@pytest.mark.parametrize("substeps", [1, 2])
def test_lifted_run_equals_the_per_substep_run_over_the_papers_3000_s(paper, drive, hold,
                                                                       substeps):
    """The paper's run (3000 s, 1 kHz input, 100 Hz output: L = 10 x substeps): the lifted run
    and the per-substep run differ by round-off only, no more than the method's own round-off
    estimate (the same run at dt/2) and below 1e-11 relative RMS (a few ulp per row accumulated
    over the 2.48 Hz mode's decay time, Q1/(pi f1) ~ 200 s ~ 2e4 rows: ~1e-12)."""
    base = _base(drive, hold, 3000.0)
    tr = simulate(paper, 3000.0, theta0=0.0, base=base, method="linear", output_dt_s=0.01,
                  dt_s=base.dt_s / substeps)
    ref = _per_substep(paper, base, 3000.0, 10, substeps)
    assert tr.settings["linear_step"].startswith(
        f"lifted to the output rate: one step of Phi^{10 * substeps} ")
    assert tr.n_steps == 3_000_000 * substeps
    for value, estimate, rows in ((tr.theta_rad, tr.error_estimate_rad, ref[:, :2]),
                                  (tr.omega_rad_s, tr.error_estimate_rad_s, ref[:, 2:])):
        rel_estimate = rel_rms_error(value + estimate, value)
        assert 0.0 < rel_estimate < 1e-11
        assert rel_rms_error(value, rows) <= rel_estimate


def test_n2_kernel_equals_the_generic_lifted_kernel(paper, drive):
    """The scalar n = 2 kernel (fused multiply-adds) and the generic one take the same sums in the
    same order: equal to a few ulp per row over 300 s (1e-12 of the largest state)."""
    a, b = paper.state_space()
    phi, g0, g1 = discretise(a, b, 1e-3, "linear")
    p, taps = lift_linear(phi, g0, g1, "linear", 1, 10)
    ax = drive.ax_mps2[:300_001]
    outs = []
    for kernel in (lifted_kernel, lifted_kernel2):
        y, y_out = np.zeros(4), np.empty((30_001, 4))
        assert kernel(p, taps, ax, 10, 30_000, y, y_out) == (0, 30_001, 300_000)
        np.testing.assert_array_equal(y, y_out[-1])
        outs.append(y_out)
    np.testing.assert_allclose(outs[1], outs[0], rtol=0, atol=1e-12 * np.abs(outs[0]).max())


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_lifted_run_of_a_three_body_chain_equals_the_per_substep_run(hold):
    """The generic kernel (6 states), 0.05 s output rows of a 1 ms input, 60 s from an initial
    swing: round-off only, 1e-12 of the largest angle."""
    chain = Chain((1.0, 0.5, 0.3), (0.4, 0.3, 0.2), (0.2, 0.15, 0.1), (0.01, 0.004, 0.001),
                  (0.01, 0.005, 0.002), "relative")
    extra = 1 if hold == "linear" else 0
    base = BaseInput(np.random.default_rng(3).standard_normal(60_000 + extra), 1e-3, hold)
    tr = simulate(chain, 60.0, theta0=(0.01, -0.02, 0.03), base=base, method="linear",
                  output_dt_s=0.05, estimate_error=False)
    ref = _per_substep(chain, base, 60.0, 50, 1, y0=[0.01, -0.02, 0.03, 0, 0, 0])
    scale = np.abs(ref[:, :3]).max()
    np.testing.assert_allclose(tr.theta_rad, ref[:, :3], rtol=0, atol=1e-12 * scale)
    assert "Phi^50" in tr.settings["linear_step"]


# -- grids, blocks, input ------------------------------------------------------------------------

@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_partial_last_output_interval_is_stepped_per_substep(paper, drive, hold):
    """100.005 s at 10 ms rows: 10000 lifted rows, then the last 5 ms per substep; the rows and
    the final state are the per-substep run's to round-off (1e-12 of the largest angle)."""
    base = _base(drive, hold, 100.005)
    tr = simulate(paper, 100.005, theta0=0.0, base=base, method="linear", output_dt_s=0.01,
                  estimate_error=False)
    ref = _per_substep(paper, base, 100.005, 10, 1)
    assert tr.t_s.size == 10_002 and tr.t_s[-2] == 100.0 and tr.t_s[-1] == 100.005
    assert tr.settings["linear_step"].endswith("the partial last output interval every substep")
    scale = np.abs(ref[:, :2]).max()
    np.testing.assert_allclose(tr.theta_rad, ref[:, :2], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(tr.final_state.native, ref[-1], rtol=0,
                               atol=1e-12 * np.abs(ref).max())


def test_output_at_every_input_sample_steps_every_substep(paper, drive):
    """Nothing to lift when a row is one substep: the per-substep kernel runs, bit for bit."""
    base = _base(drive, "zoh", 1.0)
    tr = simulate(paper, 1.0, theta0=0.0, base=base, method="linear", output_dt_s=1e-3,
                  estimate_error=False)
    assert tr.settings["linear_step"] == "every substep"
    np.testing.assert_array_equal(tr.theta_rad, _per_substep(paper, base, 1.0, 1, 1)[:, :2])


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_blocks_ending_on_output_rows_reproduce_the_lifted_one_shot_bit_for_bit(paper, drive,
                                                                                hold):
    """Each row's FIR and product are taken in a fixed order, so 1.5 s + 1.7 s + 1.8 s blocks at
    10 ms rows give exactly the one-shot 5 s run."""
    base = _base(drive, hold, 5.0)
    kw = dict(method="linear", output_dt_s=0.01, estimate_error=False)
    one = simulate(paper, 5.0, theta0=0.0, base=base, **kw)
    parts, state = [], None
    for k0, k1 in [(0, 1500), (1500, 3200), (3200, 5000)]:
        blk = base.block(k0, k1)
        if state is None:
            tr = simulate(paper, blk.duration_s, theta0=0.0, base=blk, **kw)
        else:
            tr = simulate(paper, blk.duration_s, start=state, base=blk, **kw)
        parts.append(tr if state is None else dataclasses.replace(tr, theta_rad=tr.theta_rad[1:]))
        state = tr.final_state
    np.testing.assert_array_equal(np.concatenate([p.theta_rad for p in parts]), one.theta_rad)
    np.testing.assert_array_equal(state.native, one.final_state.native)


def test_vertical_input_drops_out_of_the_lifted_linear_model(paper, drive):
    """y0'' enters the linearised chain only at second order: giving it changes nothing."""
    base = _base(drive, "zoh", 10.0)
    with_ay = BaseInput(base.ax_mps2, base.dt_s, ay_mps2=0.3 * base.ax_mps2[::-1])
    kw = dict(theta0=0.0, method="linear", output_dt_s=0.01, estimate_error=False)
    np.testing.assert_array_equal(simulate(paper, 10.0, base=with_ay, **kw).theta_rad,
                                  simulate(paper, 10.0, base=base, **kw).theta_rad)


# -- divergence ----------------------------------------------------------------------------------

@pytest.mark.parametrize("seconds, t_bad", [(2.0, "0.09 s"), (0.085, "0.085 s")])
def test_overflow_raises_divergence_error_at_the_per_substep_runs_instant(paper, seconds, t_bad):
    """Released from 1.2e307 rad the 2.48 Hz mode's angular velocity outgrows the largest float
    between 0.08 s and 0.09 s: the lifted run reports the same output instant and the same last
    finite state as the per-substep run, also when the overflow falls in the partial last row."""
    n = round(seconds * 1000)
    base = BaseInput(np.zeros(n), 1e-3)
    y0 = [1.2e307, -1.2e307, 0.0, 0.0]
    with pytest.raises(DivergenceError, match=f"linear: the state became non-finite between "
                                              f"t = 0.08 s and {t_bad}") as lifted:
        simulate(paper, seconds, theta0=y0[:2], base=base, method="linear", output_dt_s=0.01,
                 estimate_error=False)
    with pytest.raises(DivergenceError) as per_substep:
        integrate(paper, y0, base.ax_mps2, None, hold="zoh", h_in=1e-3, n_intervals=n,
                  out_every=10, solver=solver_named("linear", lift=False))
    assert lifted.value.time_s == per_substep.value.time_s == 0.08
    np.testing.assert_allclose(lifted.value.state, per_substep.value.state, rtol=1e-13)
