"""benchmarks/run.py: the work-precision report's pieces (scoring, the time-limited solve_ivp driver, the
renderers) and the command itself on a stubbed benchmark (the real one takes minutes)."""

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import benchmarks.work_precision as rb
from benchmarks.report import bench, plot_scene, scene_table, to_markdown
from rig.chain import Chain
from rig.errors import ConfigError


def _report():
    e = [rb.Entry("paper", "rig", "etd3", "dt=1 ms", 0.2, (0.2, 0.21), 1.5e-9, 300.0, n_fev=600001,
                  extra=dict(estimated_error=1.4e-9)),
         rb.Entry("paper", "rig", "rk4", "dt=1 ms", 0.5, (0.5,), 4.6e-7, 300.0),
         rb.Entry("paper", "solve_ivp", "DOP853", "rtol=1e-9", 600.0, (5.0,), 1e-6, 10.0,
                  extrapolated=True, note="stopped by the limit"),
         rb.Entry("paper", "solve_ivp", "RK45", "defaults", 1.0, (1.0,), float("nan"), 0.0,
                  note="failed")]
    scene = rb.SceneResult("paper", "The paper's run", "desc", 300.0, "relative RMS angle error",
                           "DOP853 fixed", 1e-14, tuple(e), ("a note",))
    chains = rb.SceneResult(
        "chains", "Chains", "desc", 10.0, "energy drift", "none", 0.0,
        tuple(rb.Entry(f"chains/n={n}", "rig", "rk4", "dt=1 ms", 0.01 * n, (0.01 * n,), 1e-9 * n,
                       10.0) for n in (2, 5, 10)))
    return rb.BenchmarkReport("quick", (scene, chains), {"cold": {"rk4": 3.0}, "warm": {"rk4": 0.1}},
                              rb.machine_info(), dict(repeats=3, limit_s=5.0, chunk_s=10.0,
                                                      started="now"), 12.0)


def test_relative_rms_error_is_the_worst_body():
    ref = np.array([[1.0, 10.0], [-1.0, -10.0]])
    theta = ref + np.array([[0.1, 0.1], [-0.1, 0.1]])
    assert rb.rel_rms_error(theta, ref) == pytest.approx(0.1)


def test_continuous_solve_ivp_driver_stops_at_its_limit_and_says_how_far_it_got():
    """A tiny wall-clock limit stops after the first chunk (1 % of the run): the part run is
    reported, so the caller can extrapolate; without a limit the run completes."""
    chain = Chain((1.0,), (1.0,), (0.5,), (1 / 12,), (0.0,))
    fun = rb._ivp_fun(chain, None, 1.0)
    t_out = np.arange(1001) * 0.01
    rows, done, wall, nfev, note, cpu = rb._ivp_continuous(fun, [0.1, 0.0], 10.0, t_out, "RK45",
                                                      dict(rtol=1e-8, atol=1e-10), 1e-9, 10.0)
    assert done == pytest.approx(0.1) and rows.shape == (11, 2) and not note and nfev > 0
    rows, done, *_ = rb._ivp_continuous(fun, [0.1, 0.0], 10.0, t_out, "RK45",
                                        dict(rtol=1e-8, atol=1e-10), 1e9, 2.0)
    assert done == 10.0 and rows.shape == (1001, 2)
    # against the pendulum's own integrators: the same equations
    from rig.simulate import simulate
    tr = simulate(chain, 10.0, theta0=0.1, output_dt_s=0.01, estimate_error=False)
    np.testing.assert_allclose(rows[:, 0], tr.theta_rad[:, 0], atol=1e-7)


def test_solve_ivp_rhs_holds_the_sample_of_the_interval():
    chain = Chain((1.0,), (1.0,), (0.5,), (1 / 12,), (0.0,))
    fun = rb._ivp_fun(chain, np.array([0.0, 5.0, -5.0]), 10.0)
    a = fun(0.1, np.zeros(2))[1]   # t = 0.1 s is sample 1 (held on [0.1, 0.2))
    b = fun(0.1999, np.zeros(2))[1]
    c = fun(0.2, np.zeros(2))[1]
    assert a == b and a != 0.0 and c == -a


def test_run_benchmarks_refuses_unknown_scenes_and_modes():
    with pytest.raises(ConfigError, match="scenes = \\['orbit'\\] is invalid"):
        rb.run_benchmarks(["orbit"], compile_check=False)
    with pytest.raises(ConfigError, match="mode = 'slow' is invalid"):
        rb.run_benchmarks(["paper"], mode="slow", compile_check=False)


def test_degenerate_designs_are_degenerate():
    from rig.ishizaki import design_parameters
    assert design_parameters(rb.degenerate_chain("nu")).nu == pytest.approx(0.999, rel=1e-9)
    assert design_parameters(rb.degenerate_chain("sigma2")).sigma2 == pytest.approx(0.999,
                                                                                    rel=1e-9)
    assert design_parameters(rb.degenerate_chain("beta2")).beta2 > 0.996
    assert rb.degenerate_chain("beta2").natural_frequencies_hz().max() > 300


def test_markdown_has_every_entry_its_error_and_marks_extrapolation():
    report = _report()
    text = to_markdown(report, "python benchmarks/run.py --quick")
    assert "python benchmarks/run.py --quick" in text and "cores" in text and "a note" in text
    table = scene_table(report.scenes[0])
    assert table.count("\n") == 1 + 4
    assert "600 (extrap.)" in table and "1.5e-09" in table and "estimated_error = 1.4e-09" in table
    assert "| solve_ivp | RK45 | defaults | 1 | - | 1 | - | - |" in table  # failed: no error
    assert json.loads(report.to_json())["scenes"][0]["entries"][3]["error"] == "nan"


def test_plots_have_a_curve_per_method():
    figs = [plot_scene(s) for s in _report().scenes]
    # the legend is the figure's, outside the data: etd3, rk4, solve_ivp DOP853
    assert len(figs[0].legends[0].get_texts()) == 3
    assert len(figs[1].axes) == 2
    import matplotlib.pyplot as plt
    for f in figs:
        plt.close(f)


def test_bench_command_writes_its_outputs_and_refuses_to_overwrite(tmp_path, monkeypatch):
    calls = {}

    def fake(scenes, **kw):
        calls.update(kw, scenes=scenes)
        return _report()

    monkeypatch.setattr(rb, "run_benchmarks", fake)
    runner = CliRunner()
    args = ["--quick", "--scene", "paper", "--scene", "chains", "--out", str(tmp_path),
            "--repeats", "2", "--time-limit", "3"]
    res = runner.invoke(bench, args)
    assert res.exit_code == 0, res.output
    assert calls["scenes"] == ("paper", "chains") and calls["repeats"] == 2
    assert calls["limit_s"] == 3.0 and calls["mode"] == "quick"
    for name in ("bench.md", "bench.json", "bench_paper.png", "bench_chains.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert "python benchmarks/run.py --quick --scene paper --scene chains --repeats 2" in (
        tmp_path / "bench.md").read_text()
    res = runner.invoke(bench, args)
    assert res.exit_code == 1 and "exists; pass --force" in res.output
    assert runner.invoke(bench, args + ["--force"]).exit_code == 0
    # a stored run renders again without running
    again = tmp_path / "again"
    res = runner.invoke(bench, ["--from-json", str(tmp_path / "bench.json"), "--out",
                               str(again)])
    assert res.exit_code == 0, res.output
    first, second = (tmp_path / "bench.md").read_text(), (again / "bench.md").read_text()
    assert first.split("### ", 1)[1] == second.split("### ", 1)[1]  # same tables
    # the command shown is the stored run's (its repeats and limit)
    assert ("python benchmarks/run.py --quick --scene paper --scene chains --repeats 3 "
            "--time-limit 5") in second
    monkeypatch.setattr(rb, "run_benchmarks", None)  # not called


def test_entry_label_names_the_solver():
    e = rb.Entry("paper", "solve_ivp", "LSODA", "rtol=1e-8", 1.0, (1.0,), 1e-6, 1.0)
    assert e.label == "solve_ivp LSODA" and math.isfinite(e.wall_s)


def test_every_curve_of_the_stored_benchmark_plots_has_its_own_colour_and_marker():
    from pathlib import Path

    import matplotlib.pyplot as plt

    from benchmarks.report import plot_scene
    from benchmarks.work_precision import BenchmarkReport

    stored = Path(__file__).resolve().parents[1] / "docs" / "bench" / "bench.json"
    report = BenchmarkReport.from_json(stored.read_text())
    for scene in report.scenes:
        fig = plot_scene(scene)
        try:
            lines = [ln for ax in fig.axes[:1] for ln in ax.get_lines()
                     if not ln.get_label().startswith("_")]
            pairs = [(ln.get_color(), ln.get_marker()) for ln in lines]
            assert len(pairs) >= 2 and len(set(pairs)) == len(pairs), scene.name
            assert len(fig.legends) == 1 and fig.axes[0].get_legend() is None
        finally:
            plt.close(fig)
