"""rig.linear: one linear system and one frequency-response type for rig and processing.

Tolerances: the modal form and the direct solve of the same sampled system differ by round-off
amplified by the eigenvector condition number (broad two-mode chain: < 1e-12 relative checked at
1e-10); the measured and model responses share one implementation of gain and phase, so they
agree exactly.
"""

import numpy as np
import pytest

from processing.frf import MeasuredResponse, frequency_response
from processing.plots import bode_figure
from processing.spectra import SpectralSettings, segment_ffts
from rig.bench import expected_response
from rig.errors import ConfigError
from rig.linear import FrequencyResponse, LinearSystem
from rig.scene import load_scene


@pytest.fixture(scope="module")
def system():
    scene = load_scene("ishizaki2009", ["pendulum.q1=20", "pendulum.q2=8"])
    return LinearSystem.from_scene(scene)


def test_the_modal_form_equals_the_direct_solve_of_the_sampled_system(system):
    sampled = system.discretise(100.0)
    f = np.concatenate([np.geomspace(0.01, 49.0, 400), system.modes()[0]])
    direct = sampled.frequency_response(f)
    modal = sampled.modal().frequency_response(f)
    np.testing.assert_allclose(modal, direct, rtol=1e-10, atol=0)
    # and both tend to the continuous response well below the rate (hold: ~ -pi f T in phase)
    cont = system.frequency_response([0.05])
    assert np.max(np.abs(sampled.frequency_response([0.05]) / cont - 1)) < 5e-3


def test_gain_and_phase_are_one_implementation_for_model_and_measurement(system):
    f = np.array([0.5, 1.0, 3.0])
    resp = system.response(f, "per m/s^2")
    x = resp.channel("x")
    np.testing.assert_array_equal(x.magnitude_db, 20 * np.log10(np.abs(resp.h[:, 0])))
    assert np.all((x.phase_deg > -180) & (x.phase_deg <= 180))
    with pytest.raises(ConfigError, match="'z' is not present"):
        resp.channel("z")
    rng = np.random.default_rng(0)
    a = rng.standard_normal((4, 256))
    ffts = segment_ffts({"a": a, "x": np.roll(a, 1, axis=1)}, SpectralSettings(fs=10.0,
                                                                             nperseg=256))
    m = frequency_response(ffts, "a", "x")
    assert isinstance(m, MeasuredResponse) and isinstance(m, FrequencyResponse)
    base = FrequencyResponse(m.freqs_hz, m.h)
    np.testing.assert_array_equal(m.magnitude_db, base.magnitude_db)
    np.testing.assert_array_equal(m.phase_deg, base.phase_deg)
    assert m.names == ("x",)


def test_bench_responses_are_frequency_responses_and_plots_take_either():
    scene = load_scene("ishizaki2009")
    f = np.geomspace(0.1, 10.0, 60)
    r = expected_response(scene, f)
    fr = r.response("h_t", "theta_2")
    np.testing.assert_array_equal(fr.channel("theta_2").h, r.theta_2)
    with pytest.raises(ConfigError, match="fields"):
        r.response("nope")
    fig = bode_figure(fr, what="H")
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 2
    rng = np.random.default_rng(1)
    a = rng.standard_normal((4, 512))
    m = frequency_response(segment_ffts({"a": a, "x": 0.5 * a + 0.1 * rng.standard_normal(a.shape)},
                                        SpectralSettings(fs=20.0, nperseg=512)), "a", "x")
    fig = bode_figure(m, what="x/a")
    assert len(fig.axes) == 3  # gain, phase, coherence
    with pytest.raises(TypeError, match="measured response only"):
        bode_figure(fr, k=2.0)
