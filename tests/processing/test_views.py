"""The analyzer's front panel (estimator, band, phase display, views) and figures drawn the way a
paper prints them: legend outside the data, decade labels, the wrapped phase broken at its wraps
(never a vertical line), unwrapped on request, quantities named, titles from the scene, an
incomplete run marked."""

from __future__ import annotations

import csv
import dataclasses

import matplotlib.pyplot as plt
import numpy as np
import pytest
from click.testing import CliRunner

from daq.acquisition import acquire
from daq.cli import main
from daq.hdf5 import Hdf5Sink, read_run
from processing.analyzer import AnalyzerSettings, analyze
from processing.views import bode_figures
from processing.views import view_figures, view_paths, write_views
from rig.scene import load_scene

SHORT = ["acquisition.records=3", "acquisition.record_s=20.0", "acquisition.settle_s=20.0"]


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("views") / "run.h5"
    acquire(load_scene("ishizaki2009", SHORT), seed=6, sinks=[Hdf5Sink(path)])
    return path


@pytest.fixture(scope="module")
def analysis(run_file):
    return analyze(read_run(run_file), AnalyzerSettings())


@pytest.fixture
def runner():
    return CliRunner()


def _rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize("estimator", ["h2", "hv"])
def test_estimator_option_gives_that_estimate(run_file, runner, tmp_path, estimator):
    out = tmp_path / "frf.csv"
    res = runner.invoke(main, ["analyze", str(run_file), "--estimator", estimator,
                               "--csv", str(out)])
    assert res.exit_code == 0, res.output
    assert estimator.upper() in res.output
    a = analyze(read_run(run_file), AnalyzerSettings(estimator=estimator))
    h1 = analyze(read_run(run_file), AnalyzerSettings())
    m = a.display
    rows = _rows(out)
    np.testing.assert_array_equal([float(r["x_re"]) for r in rows], a.h_t.h.real[m])
    assert not np.array_equal(a.h_t.h[m], h1.h_t.h[m])  # a different estimate indeed
    # the coherence and its explanation do not depend on the estimator
    np.testing.assert_array_equal(a.h_t.coherence, h1.h_t.coherence)
    assert [d.text for d in a.coherence_dips] == [d.text for d in h1.coherence_dips]


def test_band_options_set_the_lines_written(run_file, runner, tmp_path):
    out = tmp_path / "frf.csv"
    res = runner.invoke(main, ["analyze", str(run_file), "--fmin", "1", "--fmax", "4",
                               "--csv", str(out)])
    assert res.exit_code == 0, res.output
    f = np.array([float(r["frequency_hz"]) for r in _rows(out)])
    df = 1 / 20.0
    assert f.min() >= 1 and f.max() <= 4 and f.min() < 1 + df and f.max() > 4 - df
    res = runner.invoke(main, ["analyze", str(run_file), "--fmin", "4", "--fmax", "1"])
    assert res.exit_code == 1 and "expected fmin_hz < fmax_hz" in res.output


def test_view_all_writes_bode_nyquist_and_coherence_pngs(run_file, runner, tmp_path):
    out = tmp_path / "fig.png"
    res = runner.invoke(main, ["analyze", str(run_file), "--plot", str(out), "--view", "all",
                               "--phase", "unwrapped"])
    assert res.exit_code == 0, res.output
    for v in ("bode", "nyquist", "coherence"):
        p = tmp_path / f"fig-{v}.png"
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {p}" in res.output
    res = runner.invoke(main, ["analyze", str(run_file), "--plot", str(out), "--view", "all"])
    assert res.exit_code == 1 and "exists; pass --force" in res.output


def _labels(fig):
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


def test_every_view_has_its_legend_outside_and_decade_labels(analysis):
    for view in ("bode", "nyquist", "coherence"):
        for fig in view_figures(analysis, view):
            try:
                fig.canvas.draw()
                assert len(fig.legends) == 1 and all(ax.get_legend() is None for ax in fig.axes)
                log_axes = [ax for ax in fig.axes if ax.get_xscale() == "log"]
                assert log_axes
                for ax in log_axes:
                    ticks = {t.get_text() for t in ax.get_xticklabels() if t.get_text()}
                    assert {"0.1", "1", "10"} <= ticks, ticks
            finally:
                plt.close(fig)


def _phase_lines(fig):
    ax_p = fig.axes[1]
    return [ln.get_ydata() for ln in ax_p.get_lines() if ln.get_linestyle() != "None"]


def test_wrapped_phase_lines_break_at_the_wrap_and_unwrapped_do_not_wrap(analysis):
    wrapped = bode_figures(analysis)
    unwrapped = bode_figures(analysis, phase="unwrapped")
    try:
        rot = _phase_lines(wrapped[1])  # Theta_2: the model wraps at 2.48 Hz
        assert any(np.isnan(y).any() for y in rot)
        for fig in wrapped:
            for y in _phase_lines(fig):
                d = np.abs(np.diff(y))
                assert np.all(d[np.isfinite(d)] <= 180.0)
        for fig in unwrapped:
            for y in _phase_lines(fig):
                assert not np.isnan(y).any()
                assert np.max(np.abs(np.diff(y))) < 180.0
    finally:
        for fig in (*wrapped, *unwrapped):
            plt.close(fig)


def test_labels_name_the_quantity_and_titles_come_from_the_scene(analysis):
    figs = bode_figures(analysis)
    try:
        labels = _labels(figs[0]) + _labels(figs[1])
        assert "stage 1: translation of its centre of mass G1 (model)" in labels
        assert "stage 1: rotation θ₁ (model)" in labels
        assert figs[0].axes[0].get_ylabel() == "gain |H_t| [dB re 1 m/(m/s^2)]"
        title = figs[0].get_suptitle()
        assert title.startswith("ishizaki2009: mirror translation H_t") and "Fig. 9" in title
    finally:
        for fig in figs:
            plt.close(fig)


def test_an_incomplete_run_is_marked_on_every_view(analysis):
    cut = dataclasses.replace(analysis, run=dataclasses.replace(
        analysis.run, status="interrupted", records=2))
    for view in ("bode", "nyquist", "coherence"):
        for fig in view_figures(cut, view):
            try:
                assert fig.get_suptitle().startswith(
                    "INCOMPLETE RUN: 2 of 3 records (interrupted)")
            finally:
                plt.close(fig)
    for fig in view_figures(analysis, "coherence"):
        assert "INCOMPLETE" not in fig.get_suptitle()
        plt.close(fig)


def test_model_plot_of_another_pendulum_is_not_titled_like_the_papers_figures(runner, tmp_path):
    from processing.plots import model_bode_figure
    from rig.describe import log_grid, mirror_response

    sc = load_scene("rod-chain", ["pendulum.n=3"])
    fig = model_bode_figure(mirror_response(sc, log_grid(0.1, 10, 50)), title=sc.name)
    try:
        titles = [ax.get_title() for ax in fig.axes] + [fig.get_suptitle()]
        assert not any("Fig" in t for t in titles)
        assert titles[0] == "mirror translation x per stage acceleration"
    finally:
        plt.close(fig)


def test_view_paths_of_all_are_beside_the_given_path(tmp_path):
    p = view_paths(tmp_path / "b.png", "all")
    assert [q.name for q in p.values()] == ["b-bode.png", "b-nyquist.png", "b-coherence.png"]
    with pytest.raises(ValueError, match="view = 'polar' is invalid"):
        view_paths(tmp_path / "b.png", "polar")


def test_a_band_from_zero_hz_plots_every_view_on_its_log_axis(run_file, runner, tmp_path):
    out = tmp_path / "z.png"
    res = runner.invoke(main, ["analyze", str(run_file), "--fmin", "0", "--fmax", "5",
                               "--plot", str(out), "--view", "all"])
    assert res.exit_code == 0, res.output  # warnings are errors here: none was raised
    assert len(list(tmp_path.glob("z-*.png"))) == 3


def test_the_expected_estimate_is_drawn_per_line_over_its_bin_not_between_lines(
        run_file, analysis, tmp_path):
    """E[H1] exists at the analyzer's lines only: drawn as each line's value held over its bin
    (flat, then a vertical step at the bin edge), never a slope from line to line that would
    show values no line reads. Through the real CLI its SVG elements are there by id."""
    import subprocess
    import sys

    from processing.line_steps import line_steps

    a = analysis
    lines = a.freqs_hz
    for fig, e in zip(bode_figures(a), (a.expected.h_t, a.expected.theta_2)):
        gain = [ln for ln in fig.axes[0].get_lines() if ln.get_gid() == "expected-estimate-gain"]
        assert len(gain) == 1
        f, db = gain[0].get_xdata(), gain[0].get_ydata()
        f_want, h_want = line_steps(lines, e)
        keep = (f_want >= a.settings.fmin_hz) & (f_want <= a.settings.fmax_hz)
        np.testing.assert_array_equal(f, f_want[keep])
        np.testing.assert_array_equal(db, 20 * np.log10(np.abs(h_want[keep])))
        # every segment is flat (within a line's bin) or vertical (at a bin edge)
        flat = np.diff(db) == 0
        vertical = np.diff(f) == 0
        assert np.all(flat | vertical) and flat.sum() >= np.sum(
            (lines > a.settings.fmin_hz) & (lines < a.settings.fmax_hz)) - 1
        plt.close(fig)
    svg = tmp_path / "b.svg"
    res = subprocess.run([sys.executable, "-m", "daq.cli", "analyze", str(run_file), "--plot",
                          str(svg)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    text = svg.read_text()
    assert text.count('id="expected-estimate-gain"') == 2  # H_t and Theta_2
    assert text.count('id="expected-estimate-phase"') == 2


def test_views_draw_the_analysis_model_curves_and_build_no_bench_model(analysis, monkeypatch,
                                                                        tmp_path):
    import rig.bench.model
    import rig.bench.response
    import rig.bench.sampled

    def refuse(*args, **kw):
        raise AssertionError("a view built a bench model")

    for module in (rig.bench.model, rig.bench.response, rig.bench.sampled):
        monkeypatch.setattr(module, "build_model", refuse)
    paths = write_views(analysis, tmp_path / "v.png", "all")
    assert [p.name for p in paths] == ["v-bode.png", "v-nyquist.png", "v-coherence.png"]
    figs = bode_figures(analysis)
    try:
        model = [ln for ln in figs[0].axes[0].get_lines()
                 if ln.get_label() == "exact model of H_t (whole chain)"]
        assert len(model) == 1
        np.testing.assert_array_equal(model[0].get_xdata(), analysis.model_curves.freqs_hz)
    finally:
        for fig in figs:
            plt.close(fig)
