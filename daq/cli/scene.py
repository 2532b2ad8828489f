"""``daq scene list|show``, ``daq model`` and ``daq simulate``: the scene and the pendulum alone
(no acquisition)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from daq.cli.common import fmt, force_option, plot_option, set_option
from daq.cli.live import viewer_stream
from rig.output_files import check_writable


# -- scenes ----------------------------------------------------------------------------------

@click.group()
def scene():
    """Built-in and file scenes."""


@scene.command("list")
def scene_list():
    """List the built-in scene presets."""
    from rig.scene import load_scene, preset_names

    for name in preset_names():
        click.echo(f"{name:16s} {load_scene(name).description}")


@scene.command("show")
@click.argument("scene_name", metavar="SCENE")
@set_option
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--toml", "as_toml", is_flag=True,
              help="Print a complete scene file (every key, documented) to edit and load back.")
def scene_show(scene_name, overrides, as_json, as_toml):
    """Show SCENE fully resolved: every physical parameter in SI units, the derived design
    parameters and the natural frequencies (--toml: the scene as an editable file)."""
    from rig.describe import scene_summary

    from rig.scene import load_scene

    if as_json and as_toml:
        raise click.UsageError("give --json or --toml, not both")
    sc = load_scene(scene_name, overrides)
    if as_toml:
        from importlib.metadata import version

        from rig.scene_toml import scene_toml

        sets = "".join(f" --set {o}" for o in overrides)
        click.echo(scene_toml(sc, header=(
            f"scene {sc.name} resolved from {sc.origin}{sets} by pendulum-daq "
            f"{version('pendulum-daq')}: every key, as loaded.\n"
            "Edit and load it as a scene file (or start a new file with base = \"NAME\" and "
            "only the keys that differ).")), nl=False)
        return
    summary = scene_summary(sc)
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(_format_summary(summary))


def _format_summary(s: dict, indent: int = 0) -> str:
    lines = []
    pad = "  " * indent
    for k, v in s.items():
        if isinstance(v, dict):
            lines.append(f"{pad}{k}:")
            lines.append(_format_summary(v, indent + 1))
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            lines.append(f"{pad}{k}:")
            for item in v:
                lines.append(f"{pad}  - " + ", ".join(f"{a}={fmt(b)}" for a, b in item.items()))
        else:
            lines.append(f"{pad}{k}: {fmt(v)}")
    return "\n".join(lines)


# -- analytic model --------------------------------------------------------------------------

@click.command()
@click.argument("scene_name", metavar="SCENE")
@set_option
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the Bode data as CSV.")
@plot_option("gain/phase diagrams like the paper's Figs. 9 and 10")
@click.option("--fmin", default=0.1, show_default=True, type=float, help="Lowest frequency [Hz].")
@click.option("--fmax", default=10.0, show_default=True, type=float, help="Highest frequency [Hz].")
@click.option("--points", default=1000, show_default=True, type=click.IntRange(min=2),
              help="Log-spaced frequencies of the base grid; the output has these plus the "
                   "points added at and around every mode and anti-resonance until each is "
                   "drawn within 0.1 dB.")
@force_option
def model(scene_name, overrides, csv_path, plot_path, fmin, fmax, points, force):
    """Analytic Bode data of SCENE (exact linear model, direct complex solve).

    x is the mirror translation relative to the stage [m per m/s^2], y the mirror rotation [rad
    per m/s^2] (SPEC section 5). The frequencies are --points log-spaced ones from --fmin to
    --fmax plus those added where the response is sharp (each mode's peak and each
    anti-resonance's notch exactly, and until linear interpolation between neighbours is within
    0.1 dB), so no resonance or notch is missed.
    """
    from rig.describe import log_grid, mirror_response, model_grid, write_csv
    from rig.scene import load_scene

    for p in (csv_path, plot_path):
        if p is not None:
            check_writable(p, force=force)
    log_grid(fmin, fmax, points)  # the range, before the scene is built
    sc = load_scene(scene_name, overrides)
    freqs = model_grid(sc, fmin, fmax, points)
    resp = mirror_response(sc, freqs)
    if csv_path is not None:
        write_csv(resp, csv_path, force=force)
        click.echo(f"wrote {csv_path} ({freqs.size} frequencies, {fmin:g}-{fmax:g} Hz: {points} "
                   f"log-spaced and {freqs.size - points} at the modes and anti-resonances)")
    if plot_path is not None:
        from processing.figure_files import save_figure
        from processing.plots import model_bode_figure

        fig = model_bode_figure(resp, title=f"{sc.name}: exact linear model",
                                paper_figures=sc.pendulum_kind == "ishizaki")
        save_figure(fig, plot_path, force=force, dpi=120)
        click.echo(f"wrote {plot_path}")
    from rig.describe import resonance_table

    click.echo(resonance_table(sc))


# -- simulation ------------------------------------------------------------------------------

def _frame_grid(traj) -> dict:
    """``dt_s`` and ``output_dt_s`` of a run drawing ``traj`` at about the view's frame rate:
    a fixed-step method keeps its step (a frame every whole number of steps, so the frames are
    the run's own states), an adaptive one its tolerance."""
    from processing.bench_geometry import FRAMES_PER_S

    dt = traj.settings.get("dt_s")
    if dt:
        return {"dt_s": dt, "output_dt_s": max(1, round(1.0 / (FRAMES_PER_S * dt))) * dt}
    return {"dt_s": None, "output_dt_s": 1.0 / FRAMES_PER_S}


def _floats(ctx, param, value):
    """Parse "a,b,..." into floats (None stays None)."""
    if value is None:
        return None
    try:
        return [float(v) for v in value.split(",")]
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of numbers") from None


class PendulumMethods(click.Choice):
    """The methods of :data:`rig.solvers.SOLVERS` that step the pendulum on a prescribed base, as
    a choice read from the registry when first needed (``daq simulate``'s help, completion or
    parse), so that the command line's start-up does not import the solvers (and numpy)."""

    def __init__(self):
        super().__init__(())

    @property
    def choices(self) -> tuple:
        from rig.solvers import PENDULUM, names_for

        return tuple(names_for(PENDULUM))

    @choices.setter
    def choices(self, value) -> None:  # click.Choice.__init__ sets it; the registry decides
        pass


@click.command()
@click.argument("scene_name", metavar="SCENE")
@click.option("--duration", required=True, type=float, help="Simulated time [s].")
@click.option("--theta0", callback=_floats, metavar="A,B,...",
              help="Initial angles [rad], one per body (default: the scene's).")
@click.option("--omega0", callback=_floats, metavar="A,B,...",
              help="Initial angular velocities [rad/s] (default: the scene's).")
@click.option("--method", default="dop853", show_default=True,
              type=PendulumMethods(),
              help="Integrator (rig.solvers.SOLVERS; etd3m and etd4m step over held input "
                   "samples, so they need a moving base: on this fixed base use etd3).")
@click.option("--rtol", type=float, help="Relative tolerance of dop853 [default 1e-10].")
@click.option("--dt", "dt_s", type=float, help="Step of the fixed-step methods [s].")
@click.option("--output-dt", "output_dt_s", type=float,
              help="Output interval [s] (default 1 s: a sample at every whole second).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Trajectory file: .csv, or .h5/.hdf5 for HDF5 (optional with --live/--rrd).")
@click.option("--no-error-estimate", is_flag=True, help="Skip the error estimate (one more run).")
@set_option
@force_option
@click.option("--live", is_flag=True,
              help="Show the motion in a spawned rerun viewer (memory limit 2 GiB).")
@click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
              help="Save the motion as a rerun recording (.rrd).")
def simulate(scene_name, duration, theta0, omega0, method, rtol, dt_s, output_dt_s, out,
             no_error_estimate, overrides, force, live, rrd):
    """Simulate SCENE's pendulum on a fixed base from its initial state (free motion).

    Writes t, theta_1..theta_n, omega_1..omega_n and the energy, with the method and its error
    estimate (how it was obtained is recorded too).
    """
    from rig.output_files import check_writable
    from daq.trajectory import trajectory_format, write_trajectory
    from rig.scene import load_scene
    from rig.simulate import simulate as run_simulation
    from rig.solvers import SOLVERS

    if rtol is not None and dt_s is not None:
        raise click.UsageError("give --rtol (adaptive dop853) or --dt (fixed step), not both")
    if SOLVERS[method].multisample:
        raise click.UsageError(f"--method {method} steps over several held samples of a moving "
                               "base's input; daq simulate runs the pendulum on a fixed base: "
                               "use --method etd3 (the same exponential integrator)")
    if out is None and not (live or rrd):
        raise click.UsageError("give --out FILE (.csv, .h5) and/or --live / --rrd FILE.rrd")
    if out is not None:
        trajectory_format(out)
        check_writable(out, force=force)
    stream = viewer_stream(live, None, rrd, force)
    sc = load_scene(scene_name, overrides)
    kw = {} if rtol is None else {"rtol": rtol}
    start = dict(theta0=sc.theta0_rad if theta0 is None else theta0,
                 omega0=sc.omega0_rad_s if omega0 is None else omega0, method=method, **kw)
    traj = run_simulation(sc.chain, duration, dt_s=dt_s, output_dt_s=output_dt_s,
                          estimate_error=not no_error_estimate, **start)
    if out is not None:
        write_trajectory(out, traj, sc, force=force)
    if stream is not None:
        from processing.live_view import show_trajectory

        frames = traj
        if output_dt_s is None:  # the run samples each second: the view gets its own frames
            frames = run_simulation(sc.chain, duration, estimate_error=False,
                                    **_frame_grid(traj), **start)
            gap = frames.settings["output_dt_s"]
            click.echo(f"the view draws {frames.t_s.size} frames ({gap:.3g} s apart) of a "
                       "second run of the same method and step; the samples and the error "
                       "estimate are the run's (--output-dt sets both)")
        path = show_trajectory(frames, sc, stream)
        if path is not None:
            click.echo(f"wrote {path} (rerun recording)")
    e = traj.energy_j
    click.echo(f"{'wrote ' + str(out) if out else 'simulated'}: {traj.t_s.size} samples over {duration:g} s, {sc.chain.n} bodies, "
               f"method {traj.method} ({traj.n_steps} steps, {traj.wall_time_s:.3g} s)")
    click.echo(f"energy: {e[0]:.9g} J at t = 0, max |E - E0| = {abs(e - e[0]).max():.3g} J")
    if traj.error_estimate_rad is not None:
        click.echo(f"estimated max angle error: {traj.max_error_rad:.3g} rad "
                   f"({traj.error_method})")
    for text in traj.warnings:
        click.echo(f"WARNING: {text}", err=True)
