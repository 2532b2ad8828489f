"""Free decay of the paper's pendulum reproduces the linear modes' Q (SPEC section 7, first hard
case: Q1 ~ 530 over thousands of seconds; the integrator must not change Q)."""

import numpy as np
import pytest

from benchmarks.work_precision import mode_start
from rig.solvers import SOLVERS
from rig.simulate import simulate

from chains import paper_pendulum

AMPLITUDE_RAD = 1e-6  # nonlinearity ~ theta^2 ~ 1e-12 relative


def fitted_q(tr, w):
    """Least-squares lambda from the modal coordinate q(t) = w . z(t) (log|q| and its unwrapped
    phase are straight lines in t) and Q = |lambda| / (-2 Re lambda)."""
    q = np.hstack([tr.theta_rad, tr.omega_rad_s]) @ w
    re = np.polyfit(tr.t_s, np.log(np.abs(q)), 1)[0]
    im = np.polyfit(tr.t_s, np.unwrap(np.angle(q)), 1)[0]
    lam = complex(re, im)
    return abs(lam) / (-2 * lam.real), lam


@pytest.fixture(scope="module")
def chain():
    return paper_pendulum()


def test_paper_pendulum_modes_are_the_papers(chain):
    f, q = chain.modes()
    np.testing.assert_allclose(f, [0.8268, 2.4783], rtol=5e-3)
    assert 500 < q[1] < 530 and 95 < q[0] < 105


@pytest.mark.parametrize("mode, method, kw, duration", [
    (1, "dop853", dict(rtol=1e-10, atol=1e-60), 3000.0),
    (0, "dop853", dict(rtol=1e-10, atol=1e-60), 3000.0),
    (1, "rk4", dict(dt_s=2e-3), 3000.0),
    (1, "gauss4", dict(dt_s=2e-3), 300.0),
], ids=["2.48Hz-dop853-3000s", "0.83Hz-dop853-3000s", "2.48Hz-rk4-3000s", "2.48Hz-gauss4-300s"])
def test_free_decay_keeps_the_modal_q(chain, mode, method, kw, duration):
    """Released along one damped mode (1e-6 rad: nonlinearity ~1e-12), the decay rate and
    frequency fitted to the modal coordinate give the Q of Chain.modes(). The allowed deviation is
    the integrator's own error estimate carried through the fit (the same run at dt/2 or at
    rtol/100: dQ = |Q - Q_ref| 2^p/(2^p - 1), or |Q - Q_ref|), doubled for the asymptotic
    assumption, plus 1e-10 for nonlinearity and round-off; and it must be below 1e-6.
    (atol = 1e-60 keeps dop853's control relative while the mode decays by e^-44 .. e^-79.)"""
    z0, w, lam = mode_start(chain, mode, AMPLITUDE_RAD)
    run = dict(theta0=z0[:2], omega0=z0[2:], method=method, output_dt_s=0.05,
               estimate_error=False)
    q_run, lam_run = fitted_q(simulate(chain, duration, **run, **kw), w)
    if method == "dop853":
        finer = dict(rtol=kw["rtol"] / 100, atol=kw["atol"] / 100)
        factor = 1.0
    else:
        finer = dict(dt_s=kw["dt_s"] / 2)
        p = SOLVERS[method].order
        factor = 2**p / (2**p - 1)
    q_fine, _ = fitted_q(simulate(chain, duration, **run, **finer), w)
    q_ref = chain.modes()[1][mode]
    tol = 2 * factor * abs(q_run - q_fine) / q_ref + 1e-10
    assert abs(q_run / q_ref - 1) <= tol, (q_run, q_ref, tol)
    assert abs(lam_run / lam - 1) <= tol
    assert tol < 1e-6
