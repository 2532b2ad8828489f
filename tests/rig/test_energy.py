"""Energy conservation of the undamped double rod released from large angles (SPEC section 7:
Takeno n = 2, theta = (2.0, 2.5) rad, chaotic)."""

import numpy as np
import pytest

from rig.chain import Chain
from rig.simulate import simulate

THETA0 = (2.0, 2.5)


@pytest.fixture(scope="module")
def rod():
    """Two uniform 1 m rods of 1 kg/m: m = 1, l = 1, c = 0.5, J = 1/12, no damping."""
    return Chain((1.0, 1.0), (1.0, 1.0), (0.5, 0.5), (1 / 12, 1 / 12), (0.0, 0.0), "relative")


@pytest.mark.parametrize("kw", [
    dict(method="rk4", dt_s=2e-3),
    dict(method="gauss4", dt_s=2e-3),
    dict(method="midpoint", dt_s=1e-3),
    dict(method="dop853", rtol=1e-8),
    dict(method="dop853", rtol=1e-10),
], ids=lambda kw: f"{kw['method']}-{kw.get('dt_s', kw.get('rtol'))}")
def test_energy_error_stays_within_the_methods_own_estimate(rod, kw):
    """Over 20 s of chaotic motion (far past the horizon where trajectories at different
    tolerances agree) the energy drift max |E(t) - E(0)| stays within 1.5 times the run's stated
    energy-error estimate (Richardson at dt/2, or rtol/100 for dop853; 1.5 allows for the
    reference run's own error, 2^-p or ~1/100 of the main run's), and the estimate is not
    pessimistic by more than a factor 2."""
    tr = simulate(rod, 20.0, theta0=THETA0, output_dt_s=0.1, **kw)
    drift = np.abs(tr.energy_j - tr.energy_j[0]).max()
    bound = tr.energy_error_estimate_j.max()
    assert 0.5 * bound <= drift <= 1.5 * bound, (drift, bound)
    # and the state itself has lost all accuracy (chaos), which the estimate says too
    assert tr.max_error_rad > 1e3 * drift / abs(tr.energy_j[0])


def _drift_and_amplitude(tr):
    """Fitted linear trend of E(t) - E(0) over the run (times the run length), and max |dE|."""
    de = tr.energy_j - tr.energy_j[0]
    trend = np.polyfit(tr.t_s, de, 1)[0] * (tr.t_s[-1] - tr.t_s[0])
    return abs(trend), np.abs(de).max()


@pytest.mark.parametrize("method, dt_s", [("gauss4", 2e-3), ("midpoint", 1e-3)])
def test_symplectic_gauss_methods_have_bounded_energy_error_without_drift(rod, method, dt_s):
    """200 s (1e5 to 2e5 steps) of chaotic motion: the energy error of a symplectic method
    oscillates about zero, so its fitted linear trend over the run is < 10 % of its amplitude,
    and the error in the last quarter is no larger than twice that in the first."""
    tr = simulate(rod, 200.0, theta0=THETA0, method=method, dt_s=dt_s, output_dt_s=0.1,
                  estimate_error=False)
    trend, amplitude = _drift_and_amplitude(tr)
    assert trend < 0.1 * amplitude, (trend, amplitude)
    de = np.abs(tr.energy_j - tr.energy_j[0])
    quarter = de.size // 4
    assert de[-quarter:].max() <= 2 * de[:quarter].max()


@pytest.mark.parametrize("kw", [dict(method="rk4", dt_s=2e-3), dict(method="dop853", rtol=1e-9)],
                         ids=["rk4", "dop853"])
def test_non_symplectic_methods_drift_so_the_drift_test_can_tell(rod, kw):
    """The same measure on RK4 and DOP853: their energy error is a secular drift (trend > half
    the amplitude), so the symplectic test above is not passing by construction."""
    tr = simulate(rod, 200.0, theta0=THETA0, output_dt_s=0.1, estimate_error=False, **kw)
    trend, amplitude = _drift_and_amplitude(tr)
    assert trend > 0.5 * amplitude, (trend, amplitude)
