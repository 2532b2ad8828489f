"""The coherence dips are predicted, not just noted: the expected coherence with the optical
lever's second-order geometry matches the paper-length run where the geometry acts, and without
the geometric term it does not.

The measured quantity is the incoherent fraction summed over the dip's lines,
``sum (1 - gamma^2)``. Its stated error is the sum of the Bendat-Piersol standard deviations of
the single-line estimates, ``sigma(gamma^2) = sqrt(2) |gamma| (1 - gamma^2) / sqrt(n_d)``
(n_d = 30), evaluated at the expected gamma^2: an upper bound on the sum's standard deviation
(neighbouring Hann lines are correlated, at most fully). Prediction and measurement must agree
within 2 such sigma; the prediction without the geometry must miss by more than 2.5 sigma.
(Over seeds 1-4 and 2009 the first stayed within 1.2 sigma and the second was 3.1-5.3 sigma off.)
"""

import math

import numpy as np
import pytest

from daq.acquisition import acquire
from daq.hdf5 import Hdf5Sink, read_run
from processing.analyzer import AnalyzerSettings, analyze
from processing.coherence_model import quadratic_spectra
from rig.scene import load_scene


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    path = tmp_path_factory.mktemp("coh") / "paper.h5"
    acquire(load_scene("ishizaki2009"), seed=2009, sinks=[Hdf5Sink(path)])
    return analyze(read_run(path), AnalyzerSettings())


@pytest.mark.parametrize("channel, lo, hi", [("x", 1.62, 1.69), ("y", 3.32, 3.39)])
def test_lever_geometry_predicts_the_coherence_dip_within_its_error(paper, channel, lo, hi):
    b = paper.coherence_budget
    f = b.freqs_hz
    m = (f >= lo) & (f <= hi)
    frf = paper.h_t if channel == "x" else paper.theta_2
    n_d = frf.n_effective
    g2 = b.expected[channel][m]
    sigma = float(np.sum(math.sqrt(2) * np.sqrt(g2) * (1 - g2) / math.sqrt(n_d)))
    measured = float(np.sum(1 - frf.coherence[m]))
    predicted = float(np.sum(1 - g2))
    without = float(np.sum(1 - b.without[channel]["geometry"][m]))
    assert abs(measured - predicted) < 2 * sigma, (measured, predicted, sigma)
    assert measured - without > 2.5 * sigma, (measured, without, sigma)


def test_summary_and_report_name_the_dips_with_their_mechanism(paper):
    summary, report = paper.summary(), paper.report()
    assert "## Coherence dips explained" in report
    dips = {(d.channel, round(d.frequency_hz, 2)): d for d in paper.coherence_dips}
    geo_x = dips[("x", 1.65)]
    assert geo_x.causes[0][0] == "geometry" and "2 x 0.8268 = 1.654 Hz" in geo_x.text
    geo_y = [d for d in paper.coherence_dips if d.channel == "y" and 3.3 < d.frequency_hz < 3.4]
    assert geo_y and geo_y[0].causes[0][0] == "geometry" and "0.8268 + 2.479" in geo_y[0].text
    assert dips[("x", 2.48)].causes[0][0] == "leakage"
    for d in (geo_x, geo_y[0]):
        assert d.text in summary and d.text in report


def test_quadratic_spectra_of_a_sine_pair_land_at_the_sum_and_double():
    # theta and dx as narrow Gaussian lines at 1 Hz and 3 Hz: theta^2 has power at 2 Hz (and
    # 0 Hz, removed with the mean), dx theta at 2 and 4 Hz; variances follow Isserlis:
    # var(theta^2) = 2 var(theta)^2, var(dx theta) = var(dx) var(theta) (uncorrelated).
    # Half of theta^2's variance is at 2 Hz, half at 0 Hz; every bin (DC too) holds the
    # one-sided density at f_k, so the DC half counts twice in the plain sum.
    fs, n = 16.0, 4096
    f = np.arange(n // 2 + 1) * fs / n
    df = fs / n
    g_tt = np.where(np.isclose(f, 1.0), 0.5 / df, 0.0)   # var(theta) = 0.5
    g_dd = np.where(np.isclose(f, 3.0), 2.0 / df, 0.0)   # var(dx) = 2
    q_tt, q_dt = quadratic_spectra(f, fs, n, g_tt, g_dd, np.zeros(f.size))
    assert np.sum(q_tt) * df == pytest.approx(2 * 0.5 ** 2 * 1.5, rel=1e-9)  # 2 Hz + DC parts
    assert np.sum(q_tt[f > 0.5]) * df == pytest.approx(2 * 0.5 ** 2 * 0.5 * 1.0, rel=1e-9)
    assert set(np.round(f[q_tt > 1e-9 * q_tt.max()], 6)) == {0.0, 2.0}
    assert set(np.round(f[q_dt > 1e-9 * q_dt.max()], 6)) == {2.0, 4.0}
    assert np.sum(q_dt) * df == pytest.approx(2.0 * 0.5, rel=1e-9)
