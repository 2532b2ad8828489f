"""etd4m's n = 2 kernel for runs without a vertical input (etd4m_kernel2h): the same numbers as
the kernel with the vertical terms (etd4m_kernel2 at sa = 0) bit for bit, on the paper's drive,
a strongly driven chain (angles past the polynomial sines' range), a near-degenerate design and
both holds, its native state included, with its input FIR in the loop and as BLAS products of
any number of steps; simulate takes it for n = 2 without a vertical input and
continues blocks bit for bit; the paper's run through it within 1e-6. (The method's order and
error estimate are etd4m's: tests/rig/solvers/test_etd4m.py, which now runs through this
kernel.)"""

import math
from unittest import mock

import numpy as np
import pytest

from benchmarks.work_precision import paper_input, rel_rms_error
from rig.scene import load_scene
from rig.simulate import BaseInput, simulate
from rig.solvers import integrate, solver_named
from rig.solvers.etd4m import etd4m_kernel2, etd4m_kernel2h
from rig.solvers.primitives import SINCOS_POLY_MAX, chain_args
from rig.solvers.etd4m import (BLAS_ONE_THREAD_MULADDS, FIR_CHUNK_STEPS, etd4m_coefficients,
                               fir_chunk_steps)

from chains import blockwise_and_one_shot, rod_chain

#: a design with a 316 Hz mode of Q 5.4 (nu, sigma^2, beta^2 near 1; as tests/rig/solvers/
#: test_coupled_etdab.py)
NEAR_DEGENERATE = [f"pendulum.r1_m={0.999 * 9.80665 / (2 * math.pi * 2.4783) ** 2!r}",
                   "pendulum.eps=1.001",
                   f"pendulum.f2_hz={math.sqrt(0.999 * 9.80665 / 0.000846) / (2 * math.pi)!r}"]


#: the horizontal kernel's input FIR: in the loop (0: the same numbers as etd4m_kernel2), and as
#: BLAS products of 1, 7 steps and of the default chunk (rig.solvers.etd4m.FIR_CHUNK_STEPS,
#: longer than some runs here: one padded product)
FIR_CHUNKS = (0, 1, 7, FIR_CHUNK_STEPS)
#: the BLAS products' bound: BLAS may order or fuse each sum's (<= 21) terms otherwise than the
#: loop, a few ulp of each sum, which the stable chain carries at about that size (more in a
#: strongly driven run, whose remainder is a small difference of larger terms): every value
#: within 1e-10 of its scale (:func:`_scales`). Measured: the loop's numbers from chunks 7 and
#: 256 (the default) on every run here; from chunk 1 (a one-row product, another BLAS kernel) up to 2.3e-12
#: (strongly driven), 7e-12 (the near-degenerate design) and 5e-14 (the paper's drive)
FIR_ROUND_OFF = 1e-10


def _both(chain, ax, m, hold, y0, hist0, have, n_int, out_every):
    """(result, y, y_out, hist) of etd4m_kernel2 at sa = 0, then of etd4m_kernel2h with each of
    :data:`FIR_CHUNKS`."""
    co = etd4m_coefficients(chain, 1e-3, m, hold)
    out = []
    for kernel, chunk in [(etd4m_kernel2, None)] + [(etd4m_kernel2h, c) for c in FIR_CHUNKS]:
        y = np.array(y0, float)
        y_out = np.empty((n_int // out_every + 1, 4))
        hist = hist0.copy()
        args = (chain_args(chain), co)
        if kernel is etd4m_kernel2:
            res = kernel(*args, ax, np.zeros(1), 0, m, n_int // m, out_every // m, y, y_out, hist,
                         have)
        else:
            res = kernel(*args, ax, m, n_int // m, out_every // m, y, y_out, hist, have, chunk)
        out.append((res, y, y_out, hist))
    return out


def _assert_same(runs):
    """The loop's FIR (runs[1]) gives etd4m_kernel2's numbers (runs[0]) bit for bit; the BLAS
    products (runs[2:]) the same status, rows and evaluations, their values within
    :data:`FIR_ROUND_OFF` of each column's largest |value|."""
    a = runs[0]
    assert FIR_CHUNKS[0] == 0
    assert runs[1][0] == a[0]
    for x, y in zip(a[1:], runs[1][1:]):
        np.testing.assert_array_equal(x, y)
    for b in runs[2:]:
        assert b[0] == a[0]
        for x, y, scale in zip(a[1:], b[1:], _scales(a)):
            assert np.all(np.abs(x - y) <= FIR_ROUND_OFF * scale)


def _scales(run):
    """What :data:`FIR_ROUND_OFF` is relative to: each end state component, each output column's
    largest |value|, the history's largest |value| (its columns, N0, N1 and N2 of both bodies,
    differ by orders of magnitude)."""
    _, y, y_out, hist = run
    return (np.abs(y), np.max(np.abs(y_out), axis=0), np.max(np.abs(hist)))


@pytest.mark.parametrize("m", [1, 2, 5, 10])
@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_horizontal_kernel_equals_the_kernel_with_vertical_terms_bit_for_bit(m, hold):
    """The paper's chain on 20 s of its drive from rest, and strongly driven (20 times the drive
    from 0.9 rad: angles beyond SINCOS_POLY_MAX, so both sine branches run), from a fresh start
    and from a given history: every output row, the end state and the three stages' remainder
    (N2 included) are the same numbers."""
    chain = load_scene("ishizaki2009").chain
    ax = paper_input(20.001).ax_mps2
    hist0 = np.random.default_rng(1).standard_normal((3, 6)) * 0.01
    for y0, gain in (((0.0, 0.0, 0.0, 0.0), 1.0), ((0.9, -0.5, 0.3, 0.0), 20.0)):
        for have in (False, True):
            runs = _both(chain, gain * ax, m, hold, y0, hist0, have, 20_000, 10)
            if gain > 1.0:
                assert np.abs(runs[0][2][:, :2]).max() > SINCOS_POLY_MAX
            _assert_same(runs)


def test_horizontal_kernel_equals_it_on_a_near_degenerate_design():
    """A 316 Hz mode (Q 5.4) beside the 2.5 Hz one, m = 1 and 5, 5 s of the paper's drive."""
    chain = load_scene("ishizaki2009", NEAR_DEGENERATE).chain
    assert np.max(chain.natural_frequencies_hz()) > 300
    ax = paper_input(5.001).ax_mps2
    for m in (1, 5):
        _assert_same(_both(chain, ax, m, "zoh", (0.01, -0.02, 0.0, 0.1), np.zeros((3, 6)),
                           False, 5000, 10))


def test_simulate_takes_the_horizontal_kernel_without_a_vertical_input():
    """n = 2 without a vertical input never calls etd4m_kernel2; with one, it does (and the
    longer chains the any-n kernel)."""
    chain = load_scene("ishizaki2009").chain
    base = paper_input(1.0)
    with mock.patch("rig.solvers.etd4m.etd4m_kernel2", side_effect=AssertionError("called")):
        tr = simulate(chain, 1.0, theta0=0.0, base=base, method="etd4m", dt_s=0.01,
                      output_dt_s=0.01, estimate_error=False)
    assert tr.n_steps == 100
    vertical = BaseInput(base.ax_mps2, base.dt_s, ay_mps2=0.5 * base.ax_mps2)
    with mock.patch("rig.solvers.etd4m.etd4m_kernel2", side_effect=AssertionError("called")):
        with pytest.raises(AssertionError, match="called"):
            simulate(chain, 1.0, theta0=0.0, base=vertical, method="etd4m", dt_s=0.01,
                     output_dt_s=0.01, estimate_error=False)
    with mock.patch("rig.solvers.etd4m.etd4m_kernel2h", side_effect=AssertionError("called")):
        simulate(rod_chain(3, damping=0.05), 1.0, theta0=0.1, base=base, method="etd4m",
                 dt_s=0.01, output_dt_s=0.01, estimate_error=False)


def test_a_block_with_a_vertical_input_continues_from_the_horizontal_kernels_state():
    """The native state the horizontal kernel leaves (N2 at the last stages included) is the
    one etd4m_kernel2 leaves, so a next block with a vertical input continues identically."""
    chain = load_scene("ishizaki2009").chain
    ax = paper_input(2.001).ax_mps2
    sol = solver_named("etd4m", samples_per_step=5)
    kw = dict(hold="zoh", h_in=1e-3, n_intervals=1000, out_every=10, solver=sol)
    y0 = sol.init(chain, (0.05, -0.02, 0.0, 0.0))
    first = integrate(chain, y0, ax[:1000], None, **kw)
    with mock.patch("rig.solvers.etd4m.HORIZONTAL_KERNEL", False):
        before = integrate(chain, y0, ax[:1000], None, **kw)
    np.testing.assert_array_equal(first.native_end, before.native_end)
    nxt = integrate(chain, first.native_end, ax[1000:], 0.3 * ax[1000:], **kw)
    ref = integrate(chain, before.native_end, ax[1000:], 0.3 * ax[1000:], **kw)
    np.testing.assert_array_equal(nxt.y_out, ref.y_out)


def test_blockwise_runs_through_the_horizontal_kernel_reproduce_the_one_shot_run():
    """Blocks of a horizontal-only input (the damped double rod from (1.0, -0.5) rad, the same
    splits as etd4m's block test) join to the one-shot run bit for bit, the final native state
    included; with the vertical input as well (the kernel with the vertical terms) too."""
    kw = dict(method="etd4m", dt_s=0.02, output_dt_s=0.04, estimate_error=False)
    for vertical in (False, True):
        joined, state, one = blockwise_and_one_shot([(0, 160), (160, 320), (320, 500)],
                                                    vertical=vertical, **kw)
        np.testing.assert_array_equal(joined, one.theta_rad)
        np.testing.assert_array_equal(state.native, one.final_state.native)


def test_papers_shortened_run_through_the_horizontal_kernel_is_within_1e6():
    """300 s of the paper's run at m = 10 (dt_s = 10 ms), against fixed-step DOP853 at 2 steps
    per sample: relative RMS angle error below 3e-7 (the 1e-6 target with a margin of 3 for
    the longer run; measured 1.1e-7 here, 8.2e-8 over the 3000 s run, BENCHMARKS.md), and the
    Richardson estimate (against m = 5) within a factor 3 of it."""
    chain = load_scene("ishizaki2009").chain
    base = paper_input(300.0)
    ref = integrate(chain, np.zeros(4), base.ax_mps2, None, hold="zoh", h_in=base.dt_s,
                    n_intervals=base.n_intervals, out_every=10,
                    solver=solver_named("dop853", substeps=2, adaptive_steps=False)).y_out
    tr = simulate(chain, 300.0, theta0=0.0, base=base, method="etd4m", dt_s=0.01,
                  output_dt_s=0.01)
    err = rel_rms_error(tr.theta_rad, ref[:, :2])
    rms = np.sqrt(np.mean(ref[:, :2] ** 2, axis=0))
    est = float(np.max(np.sqrt(np.mean(tr.error_estimate_rad ** 2, axis=0)) / rms))
    assert err < 3e-7, err
    assert 1 / 3 < err / est < 3, (err, est)


def test_the_fir_products_stay_within_one_blas_thread():
    """The chunk is the default where a (steps, window) by (window, 48) product stays within
    BLAS_ONE_THREAD_MULADDS, fewer steps for wider windows, at least one; 0 turns it off."""
    for window in (1, 10, 11, 21, 40, 200, 10_000):
        steps = fir_chunk_steps(window)
        assert 1 <= steps <= FIR_CHUNK_STEPS
        assert steps * window * 48 <= BLAS_ONE_THREAD_MULADDS or steps == 1
        assert steps == FIR_CHUNK_STEPS or (steps + 1) * window * 48 > BLAS_ONE_THREAD_MULADDS
    assert fir_chunk_steps(10) == FIR_CHUNK_STEPS
    with mock.patch("rig.solvers.etd4m.FIR_CHUNK_STEPS", 0):
        assert fir_chunk_steps(10) == 0
