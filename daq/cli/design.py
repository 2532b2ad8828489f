"""``daq design``: from a targets file to a pendulum design (:mod:`rig.design`), its report,
figure, trade-offs, tolerance Monte Carlo and a virtual measurement of it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import click

from daq.cli.common import figure_path, force_option
from rig.output_files import atomic_output, check_writable


def _read_text(path: Path, what: str) -> str:
    from rig.errors import ConfigError

    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{what} file {str(path)!r} does not exist") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{what} file {str(path)!r} is not a TOML text file (byte {exc.start} "
                          "is not UTF-8)") from None
    except OSError as exc:
        raise ConfigError(f"{what} file {str(path)!r} cannot be read: {exc.strerror}") from None


def _write_text(path: Path, text: str, force: bool) -> None:
    with atomic_output(path, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")


@click.command("design")
@click.argument("targets_path", metavar="TARGETS.toml", type=click.Path(dir_okay=False,
                                                                        path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the designed scene (TOML that daq acquire takes).")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the design report (markdown).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
              callback=figure_path,
              help="Write the design's responses against its targets (.png, .pdf or .svg: the "
                   "format follows the extension).")
@click.option("--tradeoffs", "tradeoffs_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Write the trade-off sweeps (alpha, f2/f1, sigma^2) and policy (i) against "
                   "(ii) into this directory: tradeoffs.png, tradeoffs_*.csv, policies.png, "
                   "policies.csv.")
@click.option("--tolerances", "tolerances_path", type=click.Path(dir_okay=False, path_type=Path),
              help="A tolerance file: Monte Carlo of the design over it (yield, sensitivities).")
@click.option("--samples", default=10000, show_default=True, type=click.IntRange(min=10),
              help="Monte Carlo samples (with --tolerances).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the Monte Carlo and of the virtual measurement.")
@click.option("--mc-out", "mc_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Write the Monte Carlo's figure and samples (tolerances.png, .csv) here.")
@click.option("--verify", is_flag=True,
              help="Acquire and analyse the designed scene (the emulated experiment) and report "
                   "its measured modes and rotation suppression beside the designed ones.")
@click.option("--verify-records", type=click.IntRange(min=3),
              help="Records of the virtual measurement (default: the base scene's).")
@click.option("--verify-record-s", type=click.FloatRange(min=10.0, min_open=False),
              help="Seconds per record of the virtual measurement (default: the base's).")
@click.option("--json", "as_json", is_flag=True, help="Print the design as JSON.")
@force_option
def design(targets_path, out, report_path, plot_path, tradeoffs_dir, tolerances_path, samples,
           seed, mc_dir, verify, verify_records, verify_record_s, as_json, force):
    """Design a double physical pendulum (Ishizaki et al. 2009) from TARGETS.toml.

    The paper's relations are solved exactly where the targets determine the design; what they
    leave free is optimised against the performance targets on the exact linear model; targets
    that cannot all be met give the nearest feasible design and what binds it.
    """
    from rig.design import design as make_design
    from rig.design import design_dict, design_markdown, design_scene_toml, parse_targets
    from rig.scene import load_scene

    for p in (out, report_path, plot_path):
        if p is not None:
            check_writable(p, force=force)
    if mc_dir is not None and tolerances_path is None:
        raise click.UsageError("--mc-out needs --tolerances FILE")
    targets = parse_targets(_read_text(targets_path, "targets"), source=str(targets_path))
    tol = None
    if tolerances_path is not None:
        from rig.design.tolerance import parse_tolerances

        tol = parse_tolerances(_read_text(tolerances_path, "tolerance"),
                               source=str(tolerances_path))
    d = make_design(targets)
    scene_text = design_scene_toml(d, header=f"designed by daq design from {targets_path}")
    if out is not None:
        _write_text(out, scene_text, force)
        sc = load_scene(out)
        if sc.chain != d.chain:
            raise click.ClickException(f"{out}: its base {targets.base!r} changes the designed "
                                       "pendulum (e.g. sets l_m); give [design] base = "
                                       "\"ishizaki2009\"")
    if plot_path is not None:
        from processing.design_plots import design_figure
        from rig.design.report import design_curves, design_grid

        f_hi = max([10.0 * d.inputs.f1_hz] + [s.band_hz[1] for s in targets.suppression]
                   + [t.freq_hz * 2 for t in targets.translation])
        curves = design_curves(d.chain, design_grid(d.chain, 0.05 * d.inputs.f2_hz, f_hi))
        fig = design_figure(d, curves)
        from processing.figure_files import save_figure

        save_figure(fig, plot_path, force=force, dpi=120)
    written = []
    mc_text, mc_data = "", None
    if tol is not None:
        mc_text, mc_data, files = run_tolerances(d, tol, samples, seed, mc_dir, force=force)
        written += files
    if tradeoffs_dir is not None:
        written += write_tradeoffs(d, tradeoffs_dir, force=force)
    ver = None
    if verify:
        from daq.cli.design_verify import verify_design

        ver = verify_design(d, scene_text, seed=seed, records=verify_records,
                            record_s=verify_record_s)
        mc_text += ver.markdown()
    if report_path is not None:
        fig_ref = plot_path.name if plot_path is not None else None
        _write_text(report_path, design_markdown(d, figure=fig_ref) + mc_text, force)
    if as_json:
        data = design_dict(d)
        if mc_data is not None:
            data["tolerances"] = mc_data
        if ver is not None:
            data["verification"] = dataclasses.asdict(ver)
        click.echo(json.dumps(data, indent=2))
        return
    click.echo(_summary(d))
    if tol is not None:
        click.echo(f"  tolerances: yield {100 * mc_data['yield']:.2f} % (95 % "
                   f"{100 * mc_data['yield_ci95'][0]:.2f}-{100 * mc_data['yield_ci95'][1]:.2f} %) "
                   f"of {samples} samples; most sensitive: " + ", ".join(
                       f"{k} to {v[0]['parameter']}" for k, v in mc_data["sensitivities"].items()
                       if v and k.startswith(("suppression", "f_mode"))))
    if ver is not None:
        click.echo("\n".join("  " + x for x in ver.lines()))
    for p in (out, report_path, plot_path, *written):
        if p is not None:
            click.echo(f"wrote {p}")


def write_tradeoffs(d, folder: Path, *, force: bool) -> list[Path]:
    """The sweeps and the policy pair of design ``d`` as figures and CSV in ``folder``."""
    import numpy as np

    from processing.design_plots import policy_figure, tradeoff_figure
    from rig.output_files import write_columns_csv
    from rig.design.report import design_curves, design_grid
    from rig.design.tradeoffs import SWEEPS, policy_pair, sweep
    from rig.ishizaki import design_parameters

    folder.mkdir(parents=True, exist_ok=True)
    names = ["tradeoffs.png", "policies.png", "policies.csv"] + [f"tradeoffs_{g}.csv"
                                                                for g in SWEEPS]
    for n in names:
        check_writable(folder / n, force=force)
    band = d.targets.suppression[0].band_hz if d.targets.suppression else None
    sweeps = [sweep(d.inputs, g, band_hz=band) for g in SWEEPS]
    out = []
    for s in sweeps:
        cols = s.columns()
        out.append(write_columns_csv(folder / f"tradeoffs_{s.group}.csv", list(cols),
                                     list(cols.values()), force=force))
    fig = tradeoff_figure(sweeps, title=f"{d.targets.name}: trade-offs on the exact linear model "
                          "(others held: α, ν, σ², ε, f1)")
    with atomic_output(folder / "tradeoffs.png", force=force) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    out.append(folder / "tradeoffs.png")
    chains = [x.chain() for x in policy_pair(d.inputs)]
    grid = design_grid(chains, 0.05 * d.inputs.f2_hz, 20 * d.inputs.f1_hz)
    ci, cii = (design_curves(c, grid) for c in chains)
    s2 = design_parameters(chains[0]).sigma2
    fig = policy_figure(ci, cii, labels=(f"policy (i): σ² = {s2:.3f}",
                                         "policy (ii): σ² = 1 (J1 = 0)"),
                        title=f"{d.targets.name}: policy (i) against (ii), α, ν, ε, f1 held")
    with atomic_output(folder / "policies.png", force=force) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    out.append(folder / "policies.png")
    cols = {"frequency_hz": grid}
    for tag, c in (("i", ci), ("ii", cii)):
        with np.errstate(divide="ignore"):
            cols[f"x_db_{tag}"] = 20 * np.log10(np.abs(c["x"]))
            cols[f"theta2_db_{tag}"] = 20 * np.log10(np.abs(c["theta2"]))
            cols[f"suppression_db_{tag}"] = -20 * np.log10(np.abs(c["ratio"]))
    out.append(write_columns_csv(folder / "policies.csv", list(cols), list(cols.values()),
                                 force=force))
    return out


def run_tolerances(d, tol, samples, seed, folder, *, force):
    """The Monte Carlo and sensitivities of ``d``: (markdown text, data, files written)."""
    import numpy as np

    from rig.output_files import write_columns_csv
    from rig.design.tolerance import monte_carlo, sensitivities

    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        for n in ("tolerances.png", "tolerances.csv"):
            check_writable(folder / n, force=force)
    mc = monte_carlo(d, tol, samples=samples, seed=seed)
    sens = sensitivities(d, tol)
    summ = mc.summary()
    lines = ["", f"## Tolerances: Monte Carlo of {samples} pendulums (seed {seed})", "",
             f"Yield {100 * mc.yield_:.2f} % (95 % interval {100 * mc.yield_ci[0]:.2f}-"
             f"{100 * mc.yield_ci[1]:.2f} %); {int((~mc.physical).sum())} samples not rigid "
             "bodies.", "", "| output | mean | std | 5 % | 50 % | 95 % |", "|---|---|---|---|---|---|"]
    for k, v in summ.items():
        if v.get("finite"):
            lines.append(f"| {k} [{mc.units[k]}] | {v['mean']:.5g} | {v['std']:.3g} | "
                         f"{v['p5']:.5g} | {v['p50']:.5g} | {v['p95']:.5g} |")
    lines += ["", "| output | most sensitive to (d output/d p, x spread) |", "|---|---|"]
    for k, rows in sens.items():
        lines.append(f"| {k} | " + "; ".join(f"{r.parameter}: {r.derivative:.3g} x "
                                             f"{r.spread:.3g} = {r.contribution:.3g}"
                                             for r in rows[:3]) + " |")
    files = []
    if folder is not None:
        from processing.design_plots import tolerance_figure

        fig = tolerance_figure(mc, sens, d, tol)
        with atomic_output(folder / "tolerances.png", force=force) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        cols = {**{f"p_{k}": v for k, v in mc.samples.items()}, **mc.outputs,
                "passed": mc.passed.astype(float)}
        files = [folder / "tolerances.png",
                 write_columns_csv(folder / "tolerances.csv", list(cols), list(cols.values()),
                                   force=force)]
    data = {"samples": samples, "seed": seed, "yield": mc.yield_, "yield_ci95": list(mc.yield_ci),
            "not_rigid": int((~mc.physical).sum()), "summary": summ,
            "sensitivities": {k: [r.__dict__ for r in rows] for k, rows in sens.items()}}
    return "\n".join(lines) + "\n", data, files


def _summary(d) -> str:
    i, c = d.inputs, d.chain
    head = "every target met" if d.status == "met" else "NEAREST FEASIBLE DESIGN (not every target met)"
    lines = [f"{d.targets.name}: {head}, policy ({d.targets.policy})",
             f"  r1 = {i.r1_m * 1e3:.5g} mm, r2 = {i.r2_m * 1e3:.5g} mm, f1 = {i.f1_hz:.5g} Hz, "
             f"f2 = {i.f2_hz:.5g} Hz, eps = {i.eps:.5g}",
             f"  m1 = {c.mass_kg[0] * 1e3:.5g} g, m2 = {c.mass_kg[1] * 1e3:.5g} g, "
             f"J1 = {c.inertia_kgm2[0]:.4g} kg m^2, J2 = {c.inertia_kgm2[1]:.4g} kg m^2"]
    p = d.params
    lines.append(f"  alpha = {p.alpha:.4g}, beta^2 = {p.beta2:.4g}, mu = {p.mu:.4g}, "
                 f"nu = {p.nu:.4g}, sigma^2 = {p.sigma2:.4g}, delta = {p.delta:.4g}")
    lines.append("  modes: " + ", ".join(f"{f:.5g} Hz (Q = {q:.4g})"
                                          for f, q in zip(d.modes_hz, d.modes_q)))
    notch = ("none at a finite frequency (J1 = 0)" if d.notch_hz == float("inf")
             else f"{d.notch_hz:.5g} Hz, depth {d.notch_depth_db:.3g} dB")
    lines.append(f"  Theta_2 notch: {notch}")
    for perf in d.performance:
        lines.append(f"  {perf.what}: {perf.value_db:.4g} dB"
                     + ("" if perf.limit_db is None else
                        f" (limit {perf.limit_db:g} dB, margin {perf.margin_db:+.3g} dB)"))
    for n in d.notes:
        lines.append(f"  note: {n}")
    if d.binding:
        lines.append("  binding: " + "; ".join(d.binding))
    return "\n".join(lines)
