"""Small-angle limit: the nonlinear chain tends to the linear model as amplitude^3, and the
steady state under a held sine base acceleration is the FRF of Chain.frf_angles seen through the
hold (SPEC sections 2 and 8)."""

import numpy as np
import pytest

from rig.simulate import BaseInput, simulate

from chains import paper_pendulum


@pytest.fixture(scope="module")
def chain():
    return paper_pendulum()


def test_nonlinear_tends_to_linear_as_amplitude_cubed(chain):
    """Free oscillation from theta0 = A (1, -0.5) for 20 s: max |theta_nonlinear - theta_linear|
    grows as A^3 (cubic terms: sin, cos(th_j - th_k), sin(th_j - th_k) w^2), i.e. the relative
    difference as A^2. The log-log slope is 3 within 0.05 (the next term is ~A^2 smaller), and the
    integrator's own error estimate is < 1 % of each difference."""
    amps = np.array([1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2])
    diffs = []
    for a in amps:
        kw = dict(theta0=(a, -0.5 * a), output_dt_s=0.01)
        nl = simulate(chain, 20.0, method="dop853", rtol=1e-12, atol=1e-30, **kw)
        lin = simulate(chain, 20.0, method="linear", estimate_error=False, **kw)
        diff = np.abs(nl.theta_rad - lin.theta_rad).max()
        assert nl.max_error_rad < 0.01 * diff
        diffs.append(diff)
    slope = np.polyfit(np.log(amps), np.log(diffs), 1)[0]
    assert abs(slope - 3) < 0.05, (diffs, slope)


def held_frf(chain, f_hz, dt_s, hold, images=500):
    """Angles per unit complex base-acceleration amplitude *at the sample instants* for samples
    a e^{i w t_k} held by the DAC: the held signal is sum_m c_m e^{i w_m t}, w_m = w + 2 pi m/dt,
    with c_m = (1 - e^{-i w dt}) / (i w_m dt) (zoh) or sinc^2(w_m dt / 2) (linear); at t_k every
    image e^{i w_m t_k} equals e^{i w t_k}, so the response is sum_m c_m Theta(i w_m) (the sum
    converges like m^-3; 500 images leave < 1e-15)."""
    m = np.arange(-images, images + 1)
    wm = 2 * np.pi * (f_hz + m / dt_s)
    if hold == "zoh":
        c = (1 - np.exp(-1j * 2 * np.pi * f_hz * dt_s)) / (1j * wm * dt_s)
    else:
        c = np.sinc(wm * dt_s / (2 * np.pi)) ** 2
    return (c[:, None] * chain.frf_angles(wm / (2 * np.pi))).sum(axis=0)


def fitted_phasors(tr, freqs_hz):
    """Least-squares X_j with theta(t) = sum_j Im(X_j e^{i w_j t}) over the trajectory (whole
    periods of every frequency, so the columns are orthogonal)."""
    w = 2 * np.pi * np.asarray(freqs_hz)
    cols = np.hstack([np.sin(np.outer(tr.t_s, w)), np.cos(np.outer(tr.t_s, w))])
    coef = np.linalg.lstsq(cols, tr.theta_rad, rcond=None)[0]
    k = len(freqs_hz)
    return coef[:k] + 1j * coef[k:]  # (nf, n)


FREQS_HZ = [0.5, 1.25, 4.0]  # common period 4 s = 4000 samples at 1 kHz
SETTLE_S, WINDOW_S, DT_S = 1996.0, 4.0, 1e-3


def sine_base(amplitude, hold):
    n = round((SETTLE_S + WINDOW_S) / DT_S) + (1 if hold == "linear" else 0)
    t = np.arange(n) * DT_S
    return BaseInput(amplitude * np.sum([np.sin(2 * np.pi * f * t) for f in FREQS_HZ], axis=0),
                     DT_S, hold)


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_linear_steady_state_is_the_frf_through_the_hold_exactly(chain, hold):
    """Three held sines (0.5, 1.25, 4 Hz) from rest, 1996 s to settle (the slowest transient,
    tau = 2 Q1 / w1 = 68 s, is down to e^-29 = 2e-13), then 4 s at 1 kHz: the fitted amplitude and
    phase equal the held-input FRF to 1e-10 (transient 2e-13, 2e6 steps of round-off). Against the
    FRF alone, the zoh is a half-sample delay and the linear hold a sinc^2 loss, visible at 4 Hz."""
    amp = 0.01
    base = sine_base(amp, hold)
    k_settle = round(SETTLE_S / DT_S)
    settled = simulate(chain, SETTLE_S, theta0=0.0, base=base.block(0, k_settle), method="linear",
                       estimate_error=False)
    tr = simulate(chain, WINDOW_S, start=settled.final_state, method="linear", output_dt_s=DT_S,
                  base=base.block(k_settle, base.n_intervals))
    x = fitted_phasors(tr, FREQS_HZ) / amp
    for j, f in enumerate(FREQS_HZ):
        expect = held_frf(chain, f, DT_S, hold)
        np.testing.assert_allclose(x[j], expect, rtol=1e-10)
    wh = 2 * np.pi * 4.0 * DT_S
    ratio = x[2] / chain.frf_angles(4.0)[0]
    if hold == "zoh":  # a delay of half a sample (and a sinc loss)
        np.testing.assert_allclose(np.angle(ratio), -wh / 2, rtol=1e-3)
    else:  # no delay, a sinc^2 loss of (w dt)^2 / 12
        np.testing.assert_allclose(np.abs(ratio), 1 - wh**2 / 12, rtol=1e-6)
        np.testing.assert_allclose(np.angle(ratio), 0, atol=1e-7)


def test_nonlinear_steady_state_at_small_amplitude_is_the_frf_within_its_bounds(chain):
    """Continue the settled linear state with RK4 (1 ms, one step per sample) under the same
    held sines: the fitted amplitude and phase match the held-input FRF within the nonlinearity,
    10 theta_max^2 relative (cubic terms with coefficients <= 1/2 summed over a few terms, x2 for
    dynamic amplification; no harmonic 3 f lands on a mode), plus 3 times the integrator's
    estimated error (Richardson) relative to the amplitude."""
    amp = 1e-3
    base = sine_base(amp, "zoh")
    k_settle = round(SETTLE_S / DT_S)
    settled = simulate(chain, SETTLE_S, theta0=0.0, base=base.block(0, k_settle), method="linear",
                       estimate_error=False)
    tr = simulate(chain, WINDOW_S, start=settled.final_state, method="rk4", dt_s=DT_S,
                  output_dt_s=DT_S, base=base.block(k_settle, base.n_intervals))
    x = fitted_phasors(tr, FREQS_HZ) / amp
    theta_max = np.abs(tr.theta_rad).max()
    for j, f in enumerate(FREQS_HZ):
        expect = held_frf(chain, f, DT_S, "zoh")
        tol = 10 * theta_max**2 + 3 * tr.max_error_rad / (amp * np.abs(expect).min())
        np.testing.assert_allclose(x[j], expect, rtol=tol)
        assert tol < 1e-5  # small amplitude: the comparison is sharp
