"""The Markdown report and the measured Bode figure, from one synthetic 30 x 100 s measurement of
the ishizaki2009 bench (ZOH-exact, as in tests/processing/test_compare.py).

The report is checked for its sections and for numbers that are exact properties of the model and
the analyzer settings (bias at the 2.48 Hz peak -8.35 dB, exact Q 528.9, 0.47 lines per
bandwidth, 10 mHz lines, n_eff = 30), and for the reading a careful experimenter gives.
"""

from __future__ import annotations

import re

import matplotlib.pyplot as plt
import numpy as np
import pytest

from lti import simulate_records
from processing.compare import compare
from processing.leakage import impulse_expected_h1
from rig.linear import LinearSystem
from processing.frf import frequency_response
from processing.modal import fit_modes
from processing.rotation import rotation_reading
from processing.plots import Curve, measured_bode_figure
from processing.report import report_markdown
from processing.spectra import SpectralSettings, segment_ffts
from rig.ishizaki import design_parameters, rotation_isolation
from rig.scene import load_scene

FS = 100.0
SETTINGS = SpectralSettings(fs=FS, nperseg=10_000, window="hann")


@pytest.fixture(scope="module")
def results():
    scene = load_scene("ishizaki2009")
    model = LinearSystem.from_scene(scene)
    dm = model.discretise(FS)
    ch = simulate_records(dm, n_records=30, n_samples=10_000, seed=5,
                          output_noise={"x": 5e-5, "y": 2e-4})
    ff = segment_ffts(ch, SETTINGS, units={"a": "m/s^2", "x": "m", "y": "rad"})
    hx, hy = frequency_response(ff, "a", "x"), frequency_response(ff, "a", "y")
    f = SETTINGS.freqs_hz
    h = dm.frequency_response(f)
    e = impulse_expected_h1(model.impulse_response(FS, SETTINGS.nperseg), SETTINGS)
    modes = list(zip(*model.modes()))
    notch = [float(scene.chain.antiresonances_hz(np.eye(2)[1])[0])]
    cmps = {
        "H_t": compare(hx, h[:, 0], expected=e[:, 0], resonances=modes, settings=SETTINGS),
        "Theta_2": compare(hy, lambda fr: dm.frequency_response(fr, "y"), expected=e[:, 1],
                           resonances=modes, antiresonances_hz=notch, settings=SETTINGS),
    }
    fits = {
        "Theta_2 direct": fit_modes(hy, (0.3, 6.0), initial=[0.83, 2.48], settings=SETTINGS),
        "Theta_2 leakage-aware": fit_modes(hy, (0.3, 6.0), initial=[0.83, 2.48],
                                           settings=SETTINGS, method="leakage"),
    }
    ri = rotation_isolation(design_parameters(scene.chain))
    lever = scene.mirror_weights()[0]
    rot = rotation_reading(hy, hx, band_hz=(6.0, 10.0), theta1_scale=lever,
                           model_ratio=h[:, 1] / (h[:, 0] / lever), exact_limit=ri.ratio,
                           alpha=ri.alpha, settings=SETTINGS)
    md = report_markdown(cmps, fits=fits, exact_modes=modes, settings=SETTINGS, rotation=rot)
    return {"md": md, "cmps": cmps, "fits": fits, "rot": rot, "dm": dm, "e": e, "hy": hy,
            "lever": lever}


def test_report_sections(results):
    md = results["md"]
    for heading in ("# Measured frequency responses against the exact model",
                    "## Analyzer settings", "## Coherence", "## Modal fit",
                    "## Leakage bias and random error at the peaks", "## Residual statistics",
                    "## Rotation isolation", "## Reading"):
        assert heading in md
    order = [md.index(h) for h in ("## Analyzer settings", "## Coherence", "## Modal fit",
                                   "## Leakage bias", "## Residual statistics", "## Reading")]
    assert order == sorted(order)


def test_report_numbers(results):
    md = results["md"]
    assert "line spacing 10 mHz" in md and "30 averages, n_eff = 30" in md
    assert "window hann" in md
    # Exact modes next to the fitted ones, and the bias at the 2.48 Hz line.
    assert "Q = 528.9" in md and "f = 2.47939 Hz" in md
    assert "| 2.48 | 3.58 | -4.78 |" in md  # line, exact and E[H1] gain of H_t at the peak
    assert "-8.35" in md and "0.47" in md
    for fit in results["fits"].values():
        for m in fit.modes:
            assert f"{m.q:.4g} ± {m.q_std:.2g}" in md
    rot = results["rot"]
    assert f"{rot.mean_db:.2f} ± {rot.mean_std_db:.2f} dB" in md
    assert "-30.02 dB" in md and "-30.70 dB" in md
    # Residual statistics rows for every band of both channels.
    for name, c in results["cmps"].items():
        for b in c.bands:
            assert f"| {name} | {b.name} | {b.n_lines} |" in md


def test_report_reading(results):
    reading = results["md"].split("## Reading", 1)[1]
    assert re.search(r"Theta_2 direct: Q at 2\.479 Hz cannot be measured with 10 mHz lines by a "
                     r"direct curve fit \(f/Q = 0\.\d+ lines < 8\): the fitted "
                     r"Q = [\d.]+ ± [\d.]+ is leakage-limited", reading)
    assert "the exact Q = 528.9" in reading
    assert "Theta_2 leakage-aware: the leakage-aware fit gives Q = " in reading
    assert "a systematic deficit, not noise" in reading
    assert "agrees with the exact model within its random error" in reading
    assert "claim (29) is a near-coincidence of 0.7 dB, not an identity" in reading


def test_measured_bode_figure(results):
    dm, hy, lever = results["dm"], results["hy"], results["lever"]
    fine = np.geomspace(0.1, 10.0, 2000)
    fig = measured_bode_figure(
        hy, model=Curve("model", fine, dm.frequency_response(fine, "y")),
        stage1=Curve("stage 1", fine, dm.frequency_response(fine, "x") / lever),
        expected=Curve("E[H1]", SETTINGS.freqs_hz, results["e"][:, 1]), title="Theta_2")
    try:
        axes = fig.get_axes()
        assert len(axes) == 3
        ax_g, ax_p, ax_c = axes
        assert ax_g.get_xscale() == "log" and ax_g.get_xlim() == pytest.approx((0.1, 10.0))
        assert "coherence" in ax_c.get_ylabel()
        assert ax_g.get_legend() is None and len(fig.legends) == 1  # outside the data
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert any("measured" in t for t in labels) and "model" in labels
        assert any("2σ" in t for t in labels)
        styles = {ln.get_label(): ln.get_linestyle() for ln in ax_g.get_lines()}
        assert styles["stage 1"] == ":" and styles["model"] == "-"
        assert len(ax_g.collections) == 1 and len(ax_p.collections) == 1  # the error bands
        fig.canvas.draw()
    finally:
        plt.close(fig)
