"""daq design (CliRunner): the scene, report, figure and JSON it writes, and one-line refusals."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from daq.cli import main
from rig.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "examples" / "design" / "ishizaki2009_targets.toml"


def test_design_writes_a_scene_acquire_takes_a_report_and_a_figure(tmp_path):
    out, rep, png = tmp_path / "s.toml", tmp_path / "d.md", tmp_path / "d.png"
    res = CliRunner().invoke(main, ["design", str(PAPER), "--out", str(out), "--report",
                                    str(rep), "--plot", str(png)])
    assert res.exit_code == 0, res.output
    assert "every target met" in res.output and "mu = 0.0918 is inconsistent" in res.output
    sc = load_scene(out)
    assert sc.pendulum_kind == "ishizaki" and sc.name == "ishizaki2009-designed"
    text = rep.read_text()
    assert "| mu | 0.0918 |" in text and "inconsistent" in text and "![design](d.png)" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_design_json_is_plain_data():
    res = CliRunner().invoke(main, ["design", str(PAPER), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["status"] == "met" and data["groups"]["mu"] > 0.12
    assert data["checks"][-1]["status"] == "inconsistent"


def test_bad_targets_file_is_one_line(tmp_path):
    bad = tmp_path / "t.toml"
    bad.write_text("[targets]\nf1_hz = \"fast\"\n")
    res = CliRunner().invoke(main, ["design", str(bad)])
    assert res.exit_code == 1
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "targets.f1_hz = 'fast' is invalid" in lines[0]
    assert "Traceback" not in res.output
    res = CliRunner().invoke(main, ["design", str(tmp_path / "missing.toml")])
    assert res.exit_code == 1 and "does not exist" in res.output


def test_design_does_not_overwrite_without_force(tmp_path):
    out = tmp_path / "s.toml"
    out.write_text("keep")
    res = CliRunner().invoke(main, ["design", str(PAPER), "--out", str(out)])
    assert res.exit_code == 1 and "exists; pass --force" in res.output
    assert out.read_text() == "keep"


def test_tradeoffs_write_figures_and_csv(tmp_path):
    res = CliRunner().invoke(main, ["design", str(PAPER), "--tradeoffs", str(tmp_path / "t")])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in (tmp_path / "t").iterdir())
    assert names == ["policies.csv", "policies.png", "tradeoffs.png", "tradeoffs_alpha.csv",
                     "tradeoffs_nu.csv", "tradeoffs_sigma2.csv"]
    head = (tmp_path / "t" / "tradeoffs_nu.csv").read_text().splitlines()[0]
    assert head.startswith("nu,suppression_db,limit_db,claim29_alpha_db")


def test_tolerances_give_yield_sensitivities_and_files(tmp_path):
    targets = ROOT / "examples" / "design" / "suppression_targets.toml"
    tol = ROOT / "examples" / "design" / "tolerances.toml"
    res = CliRunner().invoke(main, ["design", str(targets), "--tolerances", str(tol),
                                    "--samples", "500", "--seed", "4", "--mc-out",
                                    str(tmp_path / "mc"), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)["tolerances"]
    assert data["samples"] == 500 and 0 <= data["yield"] <= 1
    assert data["sensitivities"]["suppression1_db"][0]["parameter"] == "r2_m"
    assert (tmp_path / "mc" / "tolerances.png").exists()
    rows = (tmp_path / "mc" / "tolerances.csv").read_text().splitlines()
    assert len(rows) == 501 and rows[0].startswith("p_r1_m,")


def test_verify_measures_what_was_designed():
    """The emulated experiment (4 x 100 s) on the designed scene: the fitted modes within 5 of
    their standard deviations of the design's exact modes once the fit method's own bias (its
    fit of the noiseless E[H1]) is taken off, the rotation reading within 5 of its standard
    deviation (Bendat-Piersol with line correlation) of the model's mean over the same lines."""
    from daq.cli.design_verify import verify_design
    from rig.design import design, design_scene_toml, parse_targets

    d = design(parse_targets((ROOT / "examples/design/suppression_targets.toml").read_text()))
    v = verify_design(d, design_scene_toml(d), seed=3, records=4)
    assert len(v.modes) == 2
    for fd, _, fm, fs, _, _, _, bias in v.modes:
        assert abs(fm - fd - bias) <= 5 * fs
    assert abs(v.suppression_db - v.suppression_model_db) <= 5 * v.suppression_std_db
    assert v.band_hz[0] > d.notch_hz and v.band_hz[1] == 20.0
    assert any("source span raised" in n for n in v.notes)


def test_design_curves_are_sampled_so_no_peak_or_notch_is_missed_by_a_tenth_of_a_db(tmp_path):
    """policies.csv (written by the real CLI) against the exact responses of both policies:
    every extremum the model has (the modes' peaks, the notches of x and theta2, the ratio's
    peak at theta1's zero) is read off the table within 0.1 dB, and so is every geometric
    midpoint between its rows by linear interpolation (the drawn line on a log axis). The
    design figure (--plot) is sampled on the same kind of grid (rig.design.report.design_grid)."""
    import csv
    import subprocess
    import sys

    import numpy as np
    from scipy.optimize import minimize_scalar

    from rig.design import design as make_design
    from rig.design import parse_targets
    from rig.design.report import design_curves
    from rig.design.tradeoffs import policy_pair

    res = subprocess.run([sys.executable, "-m", "daq.cli", "design", str(PAPER), "--tradeoffs",
                          str(tmp_path / "t")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    with open(tmp_path / "t" / "policies.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    f = np.array([float(r["frequency_hz"]) for r in rows])
    d = make_design(parse_targets(PAPER.read_text(), source=str(PAPER)))
    columns = (("x_db", "x", 1.0), ("theta2_db", "theta2", 1.0), ("suppression_db", "ratio", -1.0))
    for tag, chain in zip(("i", "ii"), (p.chain() for p in policy_pair(d.inputs))):

        def exact_db(ff, key, sign):
            with np.errstate(divide="ignore"):
                return sign * 20 * np.log10(np.abs(design_curves(chain, np.atleast_1d(ff))[key]))

        fm = np.sqrt(f[1:] * f[:-1])
        features = list(chain.modes()[0]) + [float(z) for w in np.eye(2)
                                             for z in chain.antiresonances_hz(w)]
        for col, key, sign in columns:
            table = np.array([float(r[f"{col}_{tag}"]) for r in rows])
            dev = np.abs(0.5 * (table[1:] + table[:-1]) - exact_db(fm, key, sign))
            assert np.nanmax(dev) <= 0.1, (tag, col, f[np.nanargmax(dev)])
            for f0 in (x for x in features if f[0] < x < f[-1]):
                for s in (1.0, -1.0):  # the peak and the dip near each feature
                    lo, hi = f0 * (1 - 2e-2), f0 * (1 + 2e-2)
                    r = minimize_scalar(lambda x: -s * exact_db(x, key, sign)[0],
                                        bounds=(lo, hi), method="bounded",
                                        options={"xatol": 1e-10 * f0})
                    if not lo * (1 + 1e-6) < r.x < hi * (1 - 1e-6):
                        continue  # no extremum of that sign inside (the window's edge)
                    near = (f >= lo) & (f <= hi)
                    seen = (table[near].max() if s > 0 else table[near].min())
                    assert abs(seen - (-r.fun * s)) <= 0.1, (tag, col, f0, s)
