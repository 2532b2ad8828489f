"""The work-precision benchmark (:mod:`benchmarks.work_precision`) as Markdown, JSON and plots:
the command of ``python benchmarks/run.py`` (see that file).

Rendering lives here, computing in :func:`benchmarks.work_precision.run_benchmarks`:
:func:`to_markdown` and :func:`plot_scene` take its
:class:`benchmarks.work_precision.BenchmarkReport` and return text and matplotlib figures.
"""

from __future__ import annotations

import math
from pathlib import Path

import click

from rig.output_files import atomic_output, check_writable
from rig.errors import RigError


def _fmt_wall(s: float) -> str:
    if not math.isfinite(s):
        return "-"
    if s >= 100:
        return f"{s:,.0f}"
    return f"{s:.3g}"


def _fmt_rt(rt: float) -> str:
    if not math.isfinite(rt):
        return "-"
    return f"{rt:,.0f}" if rt >= 10 else f"{rt:.2g}"


def _fmt_err(e: float) -> str:
    return "-" if not math.isfinite(e) else f"{e:.2g}"


def _extra_text(extra: dict) -> str:
    parts = []
    for key in ("estimated_error", "q_rel_error", "energy_drift", "horizon_1mrad_s",
                "per_simulated_s", "max_omega"):
        v = extra.get(key)
        if v is None:
            continue
        if isinstance(v, float) and not math.isfinite(v):
            parts.append(f"{key} = {v}")
        elif key in ("horizon_1mrad_s",):
            parts.append(f"{key} = {v:.2f}")
        elif key == "per_simulated_s":
            parts.append(f"{v:.3g} s per simulated s")
        elif key == "max_omega":
            parts.append(f"max omega {v:.0f} rad/s")
        else:
            parts.append(f"{key} = {v:.2g}")
    return "; ".join(parts)


def scene_table(scene) -> str:
    """One scene's entries as a Markdown table (rig rows first, each group by error)."""
    lines = ["| solver | method | setting | wall [s] (median) | CPU [s] | repeats | x real time "
             "| error | evaluations | also | note |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    order = {}
    for e in scene.entries:
        order.setdefault(e.scene, len(order))
    rows = sorted(scene.entries, key=lambda e: (order[e.scene], e.solver != "rig", e.method,
                                                -e.error if math.isfinite(e.error) else 0))
    for e in rows:
        simulated = e.simulated_s if not e.extrapolated else scene.duration_s
        rt = simulated / e.wall_s if (math.isfinite(e.wall_s) and e.wall_s > 0
                                      and simulated > 0) else float("nan")
        sub = e.scene.split("/", 1)[1] + ": " if "/" in e.scene else ""
        wall = _fmt_wall(e.wall_s) + (" (extrap.)" if e.extrapolated else "")
        lines.append(
            f"| {e.solver} | {sub}{e.method} | {e.setting} | {wall} | {_fmt_wall(e.cpu_s)} | "
            f"{len(e.walls_s)} | "
            f"{_fmt_rt(rt)} | {_fmt_err(e.error)} | "
            f"{'-' if e.n_fev is None else f'{e.n_fev:,}'} | {_extra_text(e.extra)} | "
            f"{e.note} |")
    return "\n".join(lines)


def to_markdown(report, command: str = "") -> str:
    """The whole report as Markdown: machine, compile times, one section per scene."""
    m = report.machine
    out = [f"## Work-precision benchmark ({report.mode} mode)", ""]
    if command:
        out += ["Reproduce with:", "", "```", command, "```", ""]
    out += [f"Machine: {m.get('cpu')}, {m.get('cores')} cores, {m.get('platform')}; Python "
            f"{m.get('python')}, numpy {m.get('numpy')}, scipy {m.get('scipy')}, numba "
            f"{m.get('numba')}. Load average before {m.get('load_average')}, after "
            f"{m.get('load_average_after')} (other jobs share the machine: timings are noisy, "
            "medians of repeats are shown). Started "
            f"{report.settings.get('started')}; {report.total_wall_s:.0f} s in total; up to "
            f"{report.settings.get('repeats')} repeats; solve_ivp limit "
            f"{report.settings.get('limit_s'):g} s per configuration, in chunks of "
            f"{report.settings.get('chunk_s'):g} simulated seconds.", ""]
    if report.compile_s:
        out += ["Numba first-call times [s] (n = 2 and n = 5 per method, fresh process): ", ""]
        cold, warm = report.compile_s.get("cold", {}), report.compile_s.get("warm", {})
        keys = [k for k in cold if k != "error"]
        out += ["| | " + " | ".join(keys) + " |", "|---|" + "---|" * len(keys)]
        for label, d in (("cold cache (compile)", cold), ("warm cache (load)", warm)):
            out.append(f"| {label} | " + " | ".join(
                f"{d[k]:.2f}" if isinstance(d.get(k), float) else "-" for k in keys) + " |")
        out.append("")
    for sc in report.scenes:
        out += [f"### {sc.title}", "", sc.description, "",
                f"Error: {sc.error_metric}. Reference: {sc.reference}; its self-convergence "
                f"(same metric against the reference at half the step): "
                f"{_fmt_err(sc.reference_error)}.", ""]
        out += [f"- {n}" for n in sc.notes]
        out += ["", scene_table(sc), ""]
    return "\n".join(out)


#: Markers cycled with matplotlib's ten colours: 11 markers against 10 colours (coprime), so the
#: first 110 curves of a plot each get their own colour and marker pair.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h")


def curve_style(i: int) -> dict:
    """Colour and marker of the ``i``-th curve of a plot (distinct pairs for i < 110)."""
    return {"color": f"C{i % 10}", "marker": MARKERS[i % len(MARKERS)]}


def plot_scene(scene):
    """Log-log wall time against error, one curve per method (solve_ivp dashed; extrapolated
    points hollow). For ``chains``: cost per simulated second and energy drift against n.
    Returns the figure."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if scene.name == "chains":
        return _plot_chains(scene, plt)
    groups = {}
    for e in scene.entries:
        if not (math.isfinite(e.wall_s) and math.isfinite(e.error) and e.error > 0):
            continue
        key = (e.scene.split("/", 1)[1] + ": " if "/" in e.scene else "") + e.label
        groups.setdefault(key, []).append(e)
    fig, ax = plt.subplots(figsize=(8.5, 7.5), layout="constrained")
    for i, (key, es) in enumerate(sorted(groups.items())):
        es = sorted(es, key=lambda e: e.error)
        ivp = es[0].solver == "solve_ivp"
        line, = ax.loglog([e.wall_s for e in es], [e.error for e in es],
                          "--" if ivp else "-", label=key, **curve_style(i))
        for e in es:
            if e.extrapolated:
                ax.plot(e.wall_s, e.error, marker="o", ms=11, mfc="none", mec=line.get_color())
    ax.set_xlabel(f"wall time for {scene.duration_s:g} s simulated [s]")
    ax.set_ylabel("error: " + scene.error_metric.split(" (")[0])
    ax.set_title(scene.title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", fontsize=7,
               ncols=2, frameon=False,
               title="solve_ivp dashed; circled: extrapolated from a partial run (error of "
                     "that part)", title_fontsize=7)
    return fig


def _plot_chains(scene, plt):
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 5.8), layout="constrained")
    groups = {}
    for e in scene.entries:
        if not e.scene.startswith("chains/n=") or not math.isfinite(e.wall_s):
            continue
        n = int(e.scene.split("=")[1])
        groups.setdefault(f"{e.label} {e.setting}", []).append((n, e))
    for i, (key, pts) in enumerate(sorted(groups.items())):
        pts.sort(key=lambda p: p[0])
        ns = [p[0] for p in pts]
        ls = "--" if key.startswith("solve_ivp") else "-"
        a1.loglog(ns, [p[1].wall_s / scene.duration_s for p in pts], ls, label=key,
                  **curve_style(i))
        a2.loglog(ns, [max(p[1].error, 1e-17) for p in pts], ls, **curve_style(i))
    a1.set_xlabel("bodies n")
    a1.set_ylabel("wall time per simulated second [s]")
    a2.set_xlabel("bodies n")
    a2.set_ylabel("energy drift / (E0 - E_rest) over 10 s")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
    fig.legend(*a1.get_legend_handles_labels(), loc="outside lower center", fontsize=7,
               ncols=4, frameon=False)
    fig.suptitle(scene.title, fontsize=10)
    return fig


@click.command()
@click.option("--quick", "mode", flag_value="quick", default=True,
              help="Short runs (paper's run 300 s, solve_ivp limit 5 s): a few minutes.")
@click.option("--full", "mode", flag_value="full",
              help="The issue's durations (paper's run 3000 s, solve_ivp limit 20 s).")
@click.option("--scene", "scenes", multiple=True,
              type=click.Choice(["paper", "free-decay", "double-rod", "chains", "degenerate"]),
              help="Run only this scene (repeatable; default all).")
@click.option("--out", "out_dir", default=Path("out/bench"), show_default=True,
              type=click.Path(file_okay=False, path_type=Path),
              help="Directory for bench.md, bench.json and one PNG per scene.")
@click.option("--repeats", type=click.IntRange(min=1), help="Timed repeats per configuration.")
@click.option("--time-limit", "limit_s", type=click.FloatRange(min=0.1),
              help="Wall-clock limit per solve_ivp configuration [s].")
@click.option("--no-compile-times", is_flag=True, help="Skip measuring numba compile times.")
@click.option("--from-json", "from_json", type=click.Path(exists=True, dir_okay=False,
                                                          path_type=Path),
              help="Do not run: render a stored bench.json again (tables and plots).")
@click.option("--force", is_flag=True, help="Overwrite existing output files.")
def bench(mode, scenes, out_dir, repeats, limit_s, no_compile_times, from_json, force):
    """Work-precision benchmark: wall time against error for every rig integrator and for
    scipy's solve_ivp (RK45, DOP853, LSODA, Radau) on the same equations and held input.

    Scenes: the paper's run, free decay of the preset, the chaotic double rod, rod chains
    n = 2..100, near-degenerate designs. Writes OUT/bench.md (tables), OUT/bench.json and
    OUT/bench_<scene>.png (log-log wall time against error, one curve per method).
    """
    from benchmarks import work_precision as rb

    stored = None
    if from_json is not None:
        stored = rb.BenchmarkReport.from_json(from_json.read_text())
        mode = stored.mode
        scenes = tuple(s.name for s in stored.scenes)
    scenes = tuple(scenes) or rb.SCENES
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"md": out_dir / "bench.md", "json": out_dir / "bench.json"}
    paths.update({s: out_dir / f"bench_{s}.png" for s in scenes})
    try:
        for p in paths.values():
            check_writable(p, force=force)
        report = stored or rb.run_benchmarks(
            scenes, mode=mode, repeats=repeats, limit_s=limit_s,
            compile_check=not no_compile_times, progress=lambda s: click.echo(f"  {s}", err=True))
    except RigError as exc:
        from daq.cli.errors import user_message

        raise click.ClickException(user_message(exc)) from None  # with the --force hint
    command = "python benchmarks/run.py --" + mode + "".join(f" --scene {s}" for s in scenes
                                              if len(scenes) < len(rb.SCENES))
    repeats = repeats or (stored.settings.get("repeats") if stored else None)
    limit_s = limit_s or (stored.settings.get("limit_s") if stored else None)
    if repeats:
        command += f" --repeats {repeats}"
    if limit_s:
        command += f" --time-limit {limit_s:g}"
    text = to_markdown(report, command)
    with atomic_output(paths["md"], force=force) as tmp:
        tmp.write_text(text + "\n")
    with atomic_output(paths["json"], force=force) as tmp:
        tmp.write_text(report.to_json() + "\n")
    import matplotlib.pyplot as plt

    for sc in report.scenes:
        fig = plot_scene(sc)
        with atomic_output(paths[sc.name], force=force) as tmp:
            fig.savefig(tmp, dpi=110)
        plt.close(fig)
    for sc in report.scenes:
        click.echo(f"{sc.name}:")
        for n in sc.notes:
            click.echo(f"  - {n}")
    click.echo(f"wrote {paths['md']}, {paths['json']} and {len(report.scenes)} plot(s) in "
               f"{report.total_wall_s:.0f} s")
