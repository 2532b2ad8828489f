"""The analyzer's reading of an emulated run (processing.analyzer), against the exact model.

One emulated run of the ishizaki2009 bench, 6 records of 100 s (the paper's 10 mHz lines with 6
instead of 30 averages), analysed once with the default settings. What each test proves:

* the estimated H_t and Theta_2 agree with the exact whole-chain model away from the resonance
  peaks: the fraction of lines whose gain and phase lie within 2 sigma of the Bendat-Piersol band
  agrees with compare's Student-t prediction within 4 standard errors (a seed study of 6 runs gave
  at most 3.0);
* the expected estimate E[H1] of this bench explains the sharp peaks (the measurement is within
  4 sigma of it there while the bias itself is > 10 dB), and reduces to the established
  white-input E[H1] (processing.compare) when the input is white up to a smooth band (stage
  reaction off, the stage's spring-damper corner moved to 0.01 Hz, accelerometer flat, no sensor
  noise): 3e-5 relative (measured 1.3e-5 at 0.1 Hz, where the corner still tilts the input, and
  below 2e-6 above 0.3 Hz: the sampled bench against the continuous model);
* its correlation functions are converged: doubling n_fft changes it by < 1e-9;
* the spectra, H_t and Theta_2 come from one shared set of FFTs in engineering units and signs
  (low-frequency phase 180 deg, gain -l/g resp. -1/g with the accelerometer's high-pass);
* coherence lies in [0, 1]; the model at the lines is the file's, equal to a recomputation;
* the leakage-aware modal fits agree with the same fit of the noiseless E[H1] within 4 sigma (so
  their uncertainties are honest) and the rotation reading extrapolates to the exact limit;
* with the bench's input spectrum (notched by the pendulum's reaction) the leakage-aware fit of
  the noiseless E[H1] returns the exact modes within 0.1 of the fit's standard deviation (a bias
  that small moves the coverage of +-2 sigma by < 0.2 percentage points; measured < 0.01 sigma),
  where a white-input model is off by more; the fits' reduced chi^2 lies within 4 sqrt(2 / dof)
  of its expectation n_d / (n_d - 2);
* an analysis builds the bench's model once (its rig.bench.SampledResponse), which its figures'
  model curves reuse, and it runs BLAS single-threaded, restoring the setting afterwards;
* settings are validated with errors naming the field, the value and what is valid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daq.acquisition import acquire
from daq.hdf5 import Hdf5Sink, read_run
from daq.sinks import MemorySink
from processing.analyzer import AnalyzerSettings, analyze, model_at_lines
from processing.frf import MeasuredResponse
from processing.leakage import expected_estimate, impulse_expected_h1
from processing.modal import fit_modes
from processing.spectra import SettingsError, SpectralSettings
from rig.bench import expected_response
from rig.linear import LinearSystem
from rig.scene import load_scene

G = 9.80665


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    path = tmp_path_factory.mktemp("analysis") / "run.h5"
    acquire(load_scene("ishizaki2009", ["acquisition.records=6"]), seed=11, sinks=[Hdf5Sink(path)])
    rec = read_run(path)
    return rec, analyze(rec, source=str(path))


def test_estimates_agree_with_the_whole_chain_model_away_from_the_peaks(run):
    _, a = run
    assert a.h_t.n_averages == 6 and a.h_t.n_effective == pytest.approx(6.0)
    for name, c in a.comparisons.items():
        b = c.bands[0]
        assert b.name == "away" and b.n_lines > 800
        assert b.expected_fraction == pytest.approx(0.90, abs=0.01)  # Student-t, nu = 10
        for frac in (b.frac_gain_total, b.frac_phase_total):
            assert abs(frac - b.expected_fraction) <= 4 * b.fraction_se, (name, frac)
        # rms of t_10 * sqrt(6/5): sqrt(1.25 * 1.2) = 1.22
        assert 1.0 < b.rms_gain_total < 1.45 and 1.0 < b.rms_phase_total < 1.45
    assert "agrees with the exact model within its random error" in a.report()


def test_expected_estimate_explains_the_leakage_bias_at_the_peaks(run):
    _, a = run
    for name, c in a.comparisons.items():
        f1 = [p for p in c.peaks if abs(p.f_hz - 2.4794) < 1e-3][0]
        assert f1.leakage_limited and f1.lines_per_bw == pytest.approx(0.47, abs=0.01)
        assert f1.bias_db < -12.0 and f1.bias_sigma > 3.0
        for p in c.peaks:
            assert abs(p.random_z_gain) < 4.0 and abs(p.random_z_phase) < 4.0, (name, p)
    # The input is coloured: the pendulum's reaction notches the stage acceleration at f1.
    notch = a.expected.input_notch_db
    assert notch[min(notch, key=lambda f: abs(f - 2.479))] < -10.0
    assert a.expected.alias_bound < 1e-12


def test_expected_estimate_reduces_to_the_white_input_one_for_a_white_input():
    # A stage without reaction whose spring-damper corner is at 0.01 Hz (critically damped), a
    # flat accelerometer without noise: the input is the flat source band above ~0.1 Hz.
    sc = load_scene("ishizaki2009", ["stage.reaction=false", "stage.stiffness_npm=7.9e-3",
                                     "stage.damping_nspm=0.25", "accelerometer.highpass_hz=0",
                                     "accelerometer.noise_mps2_rthz=0", "acquisition.records=1",
                                     "acquisition.record_s=1.0", "acquisition.settle_s=0.0"])
    sink = MemorySink()
    acquire(sc, seed=1, sinks=[sink])
    s = SpectralSettings(fs=100.0, nperseg=10_000, window="hann", noverlap=0, detrend=None)
    e = expected_estimate(sink.recording.header, s)
    white = LinearSystem.from_scene(sc).impulse_response(100.0, s.nperseg, method="bandlimited")
    w = impulse_expected_h1(white, s)
    sel = (s.freqs_hz >= 0.1) & (s.freqs_hz <= 10.0)
    for k, est in enumerate((e.h_t, e.theta_2)):
        rel = np.abs(est[sel] / w[sel, k] - 1.0)
        assert rel.max() < 3e-5, rel.max()
    # Converged: twice the correlation length changes nothing.
    e2 = expected_estimate(sink.recording.header, s, n_fft=2 * e.n_fft)
    assert np.max(np.abs(e2.theta_2[sel] / e.theta_2[sel] - 1.0)) < 1e-9


def test_one_shared_set_of_ffts_in_engineering_units(run):
    rec, a = run
    sp = a.spectra
    np.testing.assert_allclose(a.h_t.h[1:], sp["ax"].values[1:] / sp["a"].values[1:], rtol=1e-12)
    np.testing.assert_allclose(a.theta_2.h[1:], sp["ay"].values[1:] / sp["a"].values[1:],
                               rtol=1e-12)
    assert sp["a"].units == ("m/s^2",) and sp["ax"].units == ("m/s^2", "m")
    assert a.h_t.units == "(m)/(m/s^2)" and a.theta_2.units == "(rad)/(m/s^2)"
    # Low frequency: -l/g and -1/g (phase 180 deg), seen through the accelerometer's high-pass
    # (the model within 1 % resp. 7 % at 0.2 Hz: the 0.83 Hz mode's skirt), measured within 4
    # sigma of the model.
    j = int(np.argmin(np.abs(a.freqs_hz - 0.2)))
    hp = 1.0 - 1j * 0.05 / 0.2  # 1 / (s / (s + w_c)) at 0.2 Hz
    l1 = rec.header.scene.chain.length_m[0]
    assert a.model.h_t[j] == pytest.approx(-l1 / G * hp, rel=0.01)
    assert a.model.theta_2[j] == pytest.approx(-1 / G * hp, rel=0.07)
    for frf, model in ((a.h_t, a.model.h_t), (a.theta_2, a.model.theta_2)):
        assert abs(frf.h[j] - model[j]) < 4 * frf.relative_error[j] * abs(frf.h[j])
    assert a.highpass_at_fmin == pytest.approx((0.97, -26.57), abs=0.01)


def test_coherence_lies_between_0_and_1(run):
    _, a = run
    for frf in (a.h_t, a.theta_2):
        g = frf.coherence[1:]
        assert np.all(np.isfinite(g)) and np.all((g >= 0.0) & (g <= 1.0))
        assert math.isnan(frf.coherence[0])  # the detrend removed 0 Hz


def test_model_at_the_lines_is_the_files_and_equals_a_recomputation(run):
    rec, a = run
    assert a.model.source == "file"
    f = a.freqs_hz[10:1001]
    r = expected_response(rec.header.scene, f, sampled=True)
    np.testing.assert_allclose(a.model.h_t[10:1001], r.h_t, rtol=1e-12)
    np.testing.assert_allclose(a.model.theta_2[10:1001], r.theta_2, rtol=1e-12)
    off = model_at_lines(rec.header, f + 0.003)  # off the file's grid: recomputed, exactly
    assert off.source == "recomputed"
    np.testing.assert_allclose(off.theta_2,
                               expected_response(rec.header.scene, f + 0.003,
                                                 sampled=True).theta_2, rtol=1e-12)


def test_modal_fits_are_consistent_with_the_fit_of_the_expected_estimate(run):
    _, a = run
    assert set(a.fits) == {"Theta_2 leakage-aware", "Theta_2 direct", "H_t leakage-aware",
                           "H_t direct"}
    assert [len(a.fits[k].modes) for k in a.fits] == [2, 2, 1, 1]
    for key in ("Theta_2 leakage-aware", "H_t leakage-aware"):
        fit, check = a.fits[key], a.fit_checks[key]
        for md, cm in zip(fit.modes, check.modes):
            assert abs(md.f_hz - cm.f_hz) < 4 * md.f_std_hz, (key, md, cm)
            assert abs(md.q - cm.q) < 4 * md.q_std, (key, md, cm)
    # Q2 of the 0.83 Hz mode: the leakage-aware method is unbiased on this bench.
    q2 = a.fit_checks["Theta_2 leakage-aware"].modes[0]
    assert q2.f_hz == pytest.approx(0.82676, abs=2e-5) and q2.q == pytest.approx(100.0, abs=1.0)
    md = "## Systematic error of the modal fits on this bench"
    assert md in a.report()


def test_input_aware_fits_return_the_exact_modes_from_the_expected_estimate(run):
    _, a = run
    assert a.expected.input_spectrum is not None
    for key in ("Theta_2 leakage-aware", "H_t leakage-aware"):
        fit, check = a.fits[key], a.fit_checks[key]
        assert fit.input_spectrum is a.expected.input_spectrum
        assert abs(fit.reduced_chi2 - fit.expected_reduced_chi2) < 4 * math.sqrt(2 / fit.dof)
        assert fit.expected_reduced_chi2 == pytest.approx(1.5)  # 6 averages: 6 / 4
        for md, cm in zip(fit.modes, check.modes):
            fe, qe = min(a.exact_modes, key=lambda m: abs(m[0] - cm.f_hz))
            assert abs(cm.f_hz - fe) < 0.1 * md.f_std_hz, (key, cm, fe)
            assert abs(cm.q - qe) < 0.1 * md.q_std, (key, cm, qe)
    # The same fit of the same E[H1] with a white input fails that criterion (-0.5 sigma here).
    fit = a.fits["Theta_2 leakage-aware"]
    hp = a.model.highpass
    ideal = MeasuredResponse(a.freqs_hz, a.expected.theta_2 * hp, coherence=a.theta_2.coherence,
                             n_averages=a.theta_2.n_averages,
                             n_effective=a.theta_2.n_effective, estimator="h1")
    white = fit_modes(ideal, a.settings.theta2_fit_band_hz, initial=[0.83, 2.48],
                      settings=a.spectral, method="leakage")
    assert abs(white.modes[1].q - a.exact_modes[1][1]) > 0.1 * fit.modes[1].q_std


def test_an_analysis_builds_the_bench_model_once_and_its_figures_reuse_it(run, monkeypatch):
    """One evaluator per analysis: E[H1], the coherence budget, the comparisons and the figures'
    model curves all ask the analysis's rig.bench.SampledResponse (the model at the lines is the
    run file's here)."""
    import rig.bench.model
    import rig.bench.response
    import rig.bench.sampled

    rec, _ = run
    calls = []
    real = rig.bench.model.build_model

    def counted(*args, **kw):
        calls.append(args[0].name)
        return real(*args, **kw)

    for module in (rig.bench.model, rig.bench.response, rig.bench.sampled):
        monkeypatch.setattr(module, "build_model", counted)
    a = analyze(rec)
    assert a.model.source == "file" and len(calls) == 1
    curves = a.model_curves
    assert a.model_curves is curves and len(calls) == 1
    assert curves.freqs_hz[0] >= a.settings.fmin_hz and curves.freqs_hz[-1] <= a.settings.fmax_hz


def test_blas_runs_single_threaded_inside_the_analysis_and_is_restored_after():
    from rig.threads import _openblas_controls, single_threaded_blas

    controls = _openblas_controls()
    before = [get() for get, _ in controls]
    with single_threaded_blas() as n:
        assert n == len(controls)
        assert all(get() == 1 for get, _ in controls)
    assert [get() for get, _ in controls] == before


def test_rotation_reading_extrapolates_to_the_exact_limit(run):
    _, a = run
    rot = a.rotation
    assert rot.exact_limit_db == pytest.approx(-30.02, abs=0.01)
    assert rot.alpha_db == pytest.approx(-30.70, abs=0.01)
    assert abs(rot.limit_db - rot.exact_limit_db) < 4 * rot.limit_std_db + 0.05
    assert abs(rot.mean_db - rot.model_mean_db) < 4 * rot.mean_std_db + 0.05


def test_report_and_summary_say_what_was_compared(run):
    _, a = run
    md = a.report()
    for text in ("## Run", "## Model", "*whole* sampled chain", "+0.97 dB, -26.6 deg",
                 "The input is not white", "## Leakage bias and random error at the peaks",
                 "## Rotation isolation"):
        assert text in md
    s = a.summary()
    assert "6 of 6 records x 100 s at 100 Hz (complete)" in s
    assert "hann window, 10000-sample FFT (100 s, 10 mHz lines)" in s
    assert "mode 2: exact 2.47939 Hz, Q 528.9" in s


@pytest.mark.parametrize("kwargs, match", [
    (dict(window="blackman"), r"window = 'blackman' is invalid: expected one of uniform, hann"),
    (dict(averaging="peak"), r"averaging = 'peak' is invalid for this analysis: peak hold"),
    (dict(lines=800), r"lines = 800, span_hz = None: give both"),
    (dict(lines=800, span_hz=10.0, nperseg=8000), r"nperseg = 8000 and lines = 800 both given"),
    (dict(overlap=1.0), r"overlap = 1.0 is invalid: expected a finite number >= 0 and < 1$"),
    (dict(span_hz=-1.0, lines=800), r"span_hz = -1.0 is invalid: expected a finite number >= 0$"),
    (dict(nperseg=True), r"nperseg = True is invalid: expected an integer >= 2$"),
    (dict(fmin_hz=10.0, fmax_hz=1.0), r"fmin_hz = 10.0, fmax_hz = 1.0: expected fmin_hz < "),
    (dict(estimator="h3"), r"estimator = 'h3' is invalid: expected one of h1, h2, hv"),
    (dict(fit_methods=("exact",)), r"fit_methods = \('exact',\) is invalid"),
    (dict(theta2_fit_band_hz=(6.0, 0.3)), r"theta2_fit_band_hz = \(6.0, 0.3\) is invalid"),
    (dict(detrend="quadratic"), r"detrend = 'quadratic' is invalid"),
])
def test_bad_settings_name_the_field_the_value_and_what_is_valid(kwargs, match):
    with pytest.raises(SettingsError, match=match):
        AnalyzerSettings(**kwargs)


def test_settings_that_do_not_fit_the_run(run):
    rec, _ = run
    with pytest.raises(SettingsError, match=r"nperseg = 20000 \(200 s\), longer than a record "
                                            r"\(10000 samples = 100 s\): expected 2 <= nperseg "
                                            r"<= 10000"):
        analyze(rec, AnalyzerSettings(nperseg=20_000))
    with pytest.raises(SettingsError, match=r"give a time record of 11428.6 samples"):
        analyze(rec, AnalyzerSettings(lines=800, span_hz=7.0))
