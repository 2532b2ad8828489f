"""The ``daq`` command line: a thin click layer over the library API.

Library errors (:class:`rig.errors.RigError`) become click errors here and only here.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import json
import os
import sys
from pathlib import Path

import click
import numpy as np

from daq.bench_cmd import bench
from daq.cli_errors import ErrorsAsMessages
from daq.files import atomic_output, check_writable
from rig.errors import RigError
from rig.solvers import PENDULUM, SOLVERS, names_for


def _library_errors(fn):
    """Turn library errors into a clean ``Error: ...`` message and exit status 1."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except RigError as exc:
            raise click.ClickException(str(exc)) from None

    return wrapper


def _set_option(fn):
    return click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                        help="Override a scene value, e.g. --set pendulum.q1=300 (repeatable).")(fn)


def _force_option(fn):
    return click.option("--force", is_flag=True, help="Overwrite existing output files.")(fn)


@click.group(cls=ErrorsAsMessages, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pendulum-daq")
@click.option("--debug", is_flag=True,
              help="Let errors through with their traceback (otherwise: one line, exit 1).")
@click.pass_context
def main(ctx, debug):
    """pendulum-daq: an emulated vibration-measurement rig (pendulum, bench, DAQ, analyzer).

    Exit status: 0 done; 1 an error (one line); 2 a usage error; 3 a run not as asked (over
    its error budget or saturated; acquire --allow-over-budget); 128+N ended by signal N.
    """
    ctx.meta["daq.debug"] = debug


# -- scenes ----------------------------------------------------------------------------------

@main.group()
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
@_set_option
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--toml", "as_toml", is_flag=True,
              help="Print a complete scene file (every key, documented) to edit and load back.")
@_library_errors
def scene_show(scene_name, overrides, as_json, as_toml):
    """Show SCENE fully resolved: every physical parameter in SI units, the derived design
    parameters and the natural frequencies (--toml: the scene as an editable file)."""
    from rig.summary import scene_summary

    from rig.scene import load_scene

    if as_json and as_toml:
        raise click.UsageError("give --json or --toml, not both")
    sc = load_scene(scene_name, overrides)
    if as_toml:
        from importlib.metadata import version

        from rig.scene_toml import scene_toml

        sets = "".join(f" --set {o}" for o in overrides)
        click.echo(scene_toml(sc, header=(
            f"scene {sc.name} resolved from {sc.source}{sets} by pendulum-daq "
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
                lines.append(f"{pad}  - " + ", ".join(f"{a}={_fmt(b)}" for a, b in item.items()))
        else:
            lines.append(f"{pad}{k}: {_fmt(v)}")
    return "\n".join(lines)


def _fmt(v) -> str:
    """A value as a person reads it: numbers to 6 digits, booleans and nothing as in JSON/TOML
    (true, false, null), lists in brackets."""
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


# -- analytic model --------------------------------------------------------------------------

@main.command()
@click.argument("scene_name", metavar="SCENE")
@_set_option
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the Bode data as CSV.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write gain/phase diagrams (PNG) like the paper's Figs. 9 and 10.")
@click.option("--fmin", default=0.1, show_default=True, type=float, help="Lowest frequency [Hz].")
@click.option("--fmax", default=10.0, show_default=True, type=float, help="Highest frequency [Hz].")
@click.option("--points", default=1000, show_default=True, type=click.IntRange(min=2),
              help="Number of log-spaced frequencies.")
@_force_option
@_library_errors
def model(scene_name, overrides, csv_path, plot_path, fmin, fmax, points, force):
    """Analytic Bode data of SCENE (exact linear model, direct complex solve).

    x is the mirror translation relative to the stage [m per m/s^2], y the mirror rotation [rad
    per m/s^2] (SPEC section 5).
    """
    from rig.response import gain_db, log_grid, mirror_response, phase_deg
    from rig.scene import load_scene

    sc = load_scene(scene_name, overrides)
    freqs = log_grid(fmin, fmax, points)
    for p in (csv_path, plot_path):
        if p is not None:
            check_writable(p, force=force)
    resp = mirror_response(sc, freqs)
    if csv_path is not None:
        with atomic_output(csv_path, force=force) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg",
                            "y_re", "y_im", "y_gain_db", "y_phase_deg"])
                cols = [freqs, resp.x.real, resp.x.imag, gain_db(resp.x), phase_deg(resp.x),
                        resp.y.real, resp.y.imag, gain_db(resp.y), phase_deg(resp.y)]
                for row in zip(*cols):
                    w.writerow([repr(float(v)) for v in row])
        click.echo(f"wrote {csv_path} ({points} frequencies, {fmin:g}-{fmax:g} Hz)")
    if plot_path is not None:
        from processing.plots import model_bode_figure

        fig = model_bode_figure(resp, title=f"{sc.name}: exact linear model",
                                paper_figures=sc.settings["pendulum"]["kind"] == "ishizaki")
        with atomic_output(plot_path, force=force) as tmp:
            fig.savefig(tmp, dpi=120, format="png")
        click.echo(f"wrote {plot_path}")
    from rig.summary import resonance_table

    click.echo(resonance_table(sc))


# -- live view (rerun; imported only when one of these options is used) ---------------------

def _live_options(fn):
    for opt in reversed([
        click.option("--live", is_flag=True,
                     help="Spawn a rerun viewer (memory limit 2 GiB) and stream to it."),
        click.option("--connect", metavar="URL",
                     help="Stream to a running rerun viewer, e.g. "
                          "rerun+http://127.0.0.1:9876/proxy."),
        click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
                     help="Save the live view's stream to this .rrd file."),
        click.option("--magnify", type=click.FloatRange(min=0, min_open=True), default=None,
                     help="Factor on the angles in the bench drawing (the stage travel gets a sixth of it) "
                          "(default 30 for a run, 1 for free motion)."),
    ]):
        fn = opt(fn)
    return fn


def _viewer_stream(live, connect, rrd, force):
    """A :class:`processing.live_view.ViewerStream`, or None without a live option."""
    if not (live or connect or rrd):
        return None
    from processing.live_view import ViewerOptions, ViewerStream

    try:
        return ViewerStream(ViewerOptions(spawn=live, connect=connect, rrd=rrd, force=force))
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def _live_sinks(live, connect, rrd, force, magnify, pacer) -> list:
    """The live view as a sink of ``acquire``, or [] without a live option. Its options are
    checked now; rerun (~1 s to import) is imported on a thread while the bench starts."""
    if not (live or connect or rrd):
        return []
    if rrd is not None:
        check_writable(rrd, force=force)
    if connect:
        from processing.viewer_url import host_port

        try:
            host_port(connect)
        except ValueError as exc:
            raise click.BadParameter(str(exc)) from None
    from daq.acquisition import Sink

    class DeferredLiveView(Sink):
        """processing.live_view.LiveView, made when the run starts (its import runs
        beside the bench's start-up)."""

        critical = False

        def __init__(self):
            import importlib
            import threading

            self.path, self._view = None, None
            self._import = threading.Thread(
                target=importlib.import_module, args=("processing.live_view",), daemon=True)
            self._import.start()

        def start(self, header):
            self._import.join()
            from processing.live_view import MAGNIFICATION, LiveView

            self._view = LiveView(_viewer_stream(live, connect, rrd, force),
                                  magnification=magnify or MAGNIFICATION, pacer=pacer)
            self._view.start(header)

        def block(self, block):
            self._view.block(block)

        def record(self, record):
            self._view.record(record)

        def stop(self, footer):
            if self._view is not None:
                self._view.stop(footer)
                self.path = self._view.path

    return [DeferredLiveView()]


# -- simulation ------------------------------------------------------------------------------

def _floats(ctx, param, value):
    """Parse "a,b,..." into floats (None stays None)."""
    if value is None:
        return None
    try:
        return [float(v) for v in value.split(",")]
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of numbers") from None


@main.command()
@click.argument("scene_name", metavar="SCENE")
@click.option("--duration", required=True, type=float, help="Simulated time [s].")
@click.option("--theta0", callback=_floats, metavar="A,B,...",
              help="Initial angles [rad], one per body (default: the scene's).")
@click.option("--omega0", callback=_floats, metavar="A,B,...",
              help="Initial angular velocities [rad/s] (default: the scene's).")
@click.option("--method", default="dop853", show_default=True,
              type=click.Choice(names_for(PENDULUM)),
              help="Integrator (rig.solvers.SOLVERS; etd3m and etd4m step over held input "
                   "samples, so they need a moving base: on this fixed base use etd3).")
@click.option("--rtol", type=float, help="Relative tolerance of dop853 [default 1e-10].")
@click.option("--dt", "dt_s", type=float, help="Step of the fixed-step methods [s].")
@click.option("--output-dt", "output_dt_s", type=float,
              help="Output interval [s] (default 1 s: a sample at every whole second).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Trajectory file: .csv, or .h5/.hdf5 for HDF5 (optional with --live/--rrd).")
@click.option("--no-error-estimate", is_flag=True, help="Skip the error estimate (one more run).")
@_set_option
@_force_option
@click.option("--live", is_flag=True,
              help="Show the motion in a spawned rerun viewer (memory limit 2 GiB).")
@click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
              help="Save the motion as a rerun recording (.rrd).")
@_library_errors
def simulate(scene_name, duration, theta0, omega0, method, rtol, dt_s, output_dt_s, out,
             no_error_estimate, overrides, force, live, rrd):
    """Simulate SCENE's pendulum on a fixed base from its initial state (free motion).

    Writes t, theta_1..theta_n, omega_1..omega_n and the energy, with the method and its error
    estimate (how it was obtained is recorded too).
    """
    from daq.files import check_writable
    from daq.trajectory_io import trajectory_format, write_trajectory
    from rig.scene import load_scene
    from rig.simulate import simulate as run_simulation

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
    stream = _viewer_stream(live, None, rrd, force)
    if stream is not None and output_dt_s is None:
        from processing.bench_geometry import FRAMES_PER_S

        output_dt_s = 1.0 / FRAMES_PER_S  # frames for the view, not one a second
    sc = load_scene(scene_name, overrides)
    kw = {} if rtol is None else {"rtol": rtol}
    traj = run_simulation(
        sc.chain, duration, theta0=sc.theta0_rad if theta0 is None else theta0,
        omega0=sc.omega0_rad_s if omega0 is None else omega0, method=method, dt_s=dt_s,
        output_dt_s=output_dt_s, estimate_error=not no_error_estimate, **kw)
    if out is not None:
        write_trajectory(out, traj, sc, force=force)
    if stream is not None:
        from processing.live_view import show_trajectory

        path = show_trajectory(traj, sc, stream)
        if path is not None:
            click.echo(f"wrote {path} (rerun recording)")
    e = traj.energy_j
    click.echo(f"{'wrote ' + str(out) if out else 'simulated'}: {traj.t_s.size} samples over {duration:g} s, {sc.chain.n} bodies, "
               f"method {traj.method} ({traj.n_steps} steps, {traj.wall_time_s:.3g} s)")
    click.echo(f"energy: {e[0]:.9g} J at t = 0, max |E - E0| = {np.max(np.abs(e - e[0])):.3g} J")
    if traj.error_estimate_rad is not None:
        click.echo(f"estimated max angle error: {traj.max_error_rad:.3g} rad "
                   f"({traj.error_method})")
    for text in traj.warnings:
        click.echo(f"WARNING: {text}", err=True)


# -- live view: replay a run file (rerun) -------------------------------------------------

@main.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
              help="Save the replay to this .rrd file.")
@click.option("--connect", metavar="URL", help="Replay into a running rerun viewer.")
@click.option("--screenshot", "screenshot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Render the layout at the end of the run to a PNG, without a window.")
@click.option("--size", default="1600x900", show_default=True, metavar="WxH",
              help="Window size of --screenshot.")
@click.option("--magnify", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Factor on the angles in the bench drawing (the stage travel gets a sixth of it) [default 30].")
@_force_option
@_library_errors
def view(run, rrd, connect, screenshot_path, size, magnify, force):
    """Replay the run file RUN into rerun as the live view showed it: a spawned viewer by
    default, or --connect URL, --rrd FILE.rrd, --screenshot FILE.png (any combination). An
    interrupted run shows its finished records."""
    import tempfile

    from processing.live_view import (MAGNIFICATION, LiveViewError, ViewerOptions,
                                      ViewerStream, replay, screenshot)

    for p in (rrd, screenshot_path):
        if p is not None and p.resolve() == run.resolve():
            raise click.BadParameter(f"output {str(p)!r} is the run file: choose another path")
    if screenshot_path is not None:
        check_writable(screenshot_path, force=force)
    spawn = not (rrd or connect or screenshot_path)
    with tempfile.TemporaryDirectory() as tmp:
        target = rrd if rrd is not None or screenshot_path is None else Path(tmp) / "view.rrd"
        stream = ViewerStream(ViewerOptions(spawn=spawn, connect=connect, rrd=target,
                                            force=force))
        v = replay(run, stream, magnification=magnify or MAGNIFICATION)
        click.echo(f"replayed {v.footer.records_complete} of {v.header.plan.records} records "
                   f"of {run} ({v.footer.status})")
        if rrd is not None:
            click.echo(f"wrote {rrd} (rerun recording)")
        if screenshot_path is not None:
            try:
                screenshot(target, screenshot_path, size=size, force=force)
            except LiveViewError as exc:
                raise click.ClickException(str(exc)) from None
            click.echo(f"wrote {screenshot_path}")


# -- acquisition -----------------------------------------------------------------------------

class _ProgressBar:
    """``progress(simulated_s, total_s)`` for :func:`daq.acquisition.acquire` as a click bar on
    stderr (created on the first call, when the total is known), with the analyzer's averaging
    display: "settling" and then "average n of N" (records finished), and the time left."""

    def __init__(self, label: str, *, records: int = 0, record_s: float = 0.0,
                 settle_s: float = 0.0):
        self.label, self.bar, self.last = label, None, 0
        self.records, self.record_s, self.settle_s = records, record_s, settle_s
        self.done_s = 0.0

    def status(self, done_s: float) -> str:
        """What the display shows after ``done_s`` simulated seconds."""
        if self.records <= 0 or self.record_s <= 0:
            return ""
        if done_s < self.settle_s:
            return f"settling, average 0 of {self.records}"
        n = min(self.records, int((done_s - self.settle_s + 1e-9) // self.record_s))
        return f"average {n} of {self.records}"

    def __call__(self, done_s: float, total_s: float) -> None:
        self.done_s = done_s
        if self.bar is None:
            self.bar = click.progressbar(length=max(1, round(total_s * 1000)), file=sys.stderr,
                                         label=f"{self.label} ({total_s:g} s simulated)",
                                         show_eta=True,
                                         item_show_func=lambda _: self.status(self.done_s))
            self.bar.__enter__()
        n = round(done_s * 1000)
        self.bar.update(n - self.last, current_item=done_s)
        self.last = n

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


def _size(n: int | None) -> str:
    if n is None:
        return "-"
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return str(n)


def _model_lines(info: dict) -> list[str]:
    """Which model ran, how, and its error estimate (the rest is in ``inspect --json``)."""
    est = info.get("error_estimate", "-")
    if isinstance(est, dict):
        est = ", ".join(f"{k} {_fmt(v)}" for k, v in est.items())
    lines = [f"model: {info.get('model', '-')}", f"  method: {info.get('method', '-')}",
             f"  error estimate: {_fmt(est)}"]
    if info.get("reason"):
        lines.append(f"  why this model: {info['reason']}")
    return lines


@main.command()
@click.argument("scene_arg", metavar="SCENE", required=False)
@click.option("--scene", "scene_name", metavar="SCENE",
              help="The same as the SCENE argument (preset name or scene TOML file).")
@click.option("--records", type=int, help="Number of records (acquisition.records).")
@click.option("--duration", type=float, help="Seconds per record (acquisition.record_s).")
@click.option("--rate", type=float, help="Sample rate of every channel [Hz] (acquisition.rate_hz).")
@click.option("--seed", type=click.IntRange(0, 2 ** 63 - 1),
              help="Seed of the run (default: a fresh random one, printed and stored).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="HDF5 run file to write (optional with a live option).")
@_set_option
@_force_option
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@_live_options
@click.option("--realtime", is_flag=True,
              help="Pace the run to the wall clock like the real bench (default: as fast as "
                   "it can).")
@click.option("--speed", type=float, default=None, metavar="K",
              help="With --realtime: K times real time (default 1).")
@click.option("--allow-over-budget", is_flag=True,
              help="Exit 0 even if the run's estimated error exceeds its error budget or a "
                   "channel clipped or saturated (otherwise a WARNING and exit status 3).")
@_library_errors
def acquire(scene_arg, scene_name, records, duration, rate, seed, out, overrides, force, quiet,
            live, connect, rrd, magnify, realtime, speed, allow_over_budget):
    """Acquire records of SCENE's bench into an HDF5 run file.

    --records, --duration and --rate override the scene's acquisition.records, .record_s and
    .rate_hz (after any --set). The file is written record by record and can be followed while
    it grows; Ctrl-C keeps every finished record (status "interrupted").
    """
    import secrets

    import signal

    from daq.acquisition import AcquisitionInterrupted
    from daq.acquisition import acquire as run_acquisition
    from daq.signals import stop_signals_interrupt
    from rig.scene import load_scene

    if scene_arg is not None and scene_name is not None and scene_arg != scene_name:
        raise click.UsageError(f"two scenes given: {scene_arg!r} and --scene {scene_name!r}; "
                               "give one (the SCENE argument, or --scene)")
    scene_name = scene_arg if scene_arg is not None else scene_name
    if scene_name is None:
        raise click.UsageError("missing the scene: daq acquire SCENE ... (a preset name or a "
                               "scene TOML file; see daq scene list)")
    extra = [f"acquisition.{key}={value!r}" for key, value in
             (("records", records), ("record_s", duration), ("rate_hz", rate))
             if value is not None]
    if out is None and not (live or connect or rrd):
        raise click.UsageError("give --out RUN.h5 and/or a live option (--live, --connect URL, "
                               "--rrd FILE.rrd)")
    if speed is not None and not realtime:
        raise click.UsageError(f"--speed {speed:g} needs --realtime")
    if out is not None and rrd is not None and out.resolve() == rrd.resolve():
        raise click.BadParameter(f"--rrd {str(rrd)!r} is the run file: choose another path")
    sc = load_scene(scene_name, [*overrides, *extra])
    if seed is None:
        seed = secrets.randbits(63)
    pacer = None
    if realtime:
        from daq.pacing import Pacer

        pacer = Pacer(1.0 if speed is None else speed)
    sinks = _live_sinks(live, connect, rrd, force, magnify, pacer)
    if pacer is not None and not sinks:
        from daq.pacing import PacingSink

        sinks = [PacingSink(pacer)]
    a = sc.settings["acquisition"]
    bar = None if quiet else _ProgressBar(f"acquiring {sc.name}", records=a["records"],
                                          record_s=a["record_s"], settle_s=a["settle_s"])
    try:
        with stop_signals_interrupt():  # SIGTERM, SIGHUP end the run like Ctrl-C
            summary = run_acquisition(sc, seed=seed, out=out, force=force, progress=bar,
                                      sinks=sinks)
    except AcquisitionInterrupted as exc:
        if bar is not None:
            bar.close()
        s = exc.summary
        by = s.message.split()[0] if s.message.startswith("SIG") else "SIGINT"
        where = f"{s.path} holds them (status interrupted)" if s.path else "no file was kept"
        click.echo(f"interrupted ({by}) after {s.records} of {s.records_planned} records; "
                   f"{where}", err=True)
        raise click.exceptions.Exit(128 + signal.Signals[by]) from None
    except Exception as exc:
        from daq.resources import is_disk_full

        s = getattr(exc, "acquisition_summary", None)
        if s is None or not is_disk_full(exc):
            raise
        raise click.ClickException(_disk_full_line(s)) from None
    finally:
        if bar is not None:
            bar.close()
    click.echo(_acquire_summary(summary))
    for sink in sinks:
        if getattr(sink, "path", None) is not None:
            click.echo(f"wrote {sink.path} (rerun recording)")
    warnings = _not_as_asked(summary)
    for w in warnings:
        click.echo(f"WARNING: {w}", err=True)
    if warnings and not allow_over_budget:
        from daq.cli_errors import EXIT_NOT_AS_ASKED

        raise click.exceptions.Exit(EXIT_NOT_AS_ASKED)


def _not_as_asked(s) -> list[str]:
    """Why a finished run is not what was asked: over its error budget, or saturated."""
    from daq.cli_errors import SATURATION_LIMIT

    out = []
    info = s.model_info
    if info.get("budget_met") is False:
        est = info.get("error_estimate")
        est = est.get("relative_rms_theta") if isinstance(est, dict) else est
        out.append(f"the run's estimated error {_fmt(est)} (relative RMS of the angles) exceeds "
                   f"its error budget {_fmt(info.get('error_budget'))} (acquisition."
                   "error_budget): the data are not as accurate as asked")
    n = max(1, s.records * s.samples_per_record)
    for what, totals in (("clipped by the ADC", s.clip_totals()),
                         ("beyond its sensor's range", s.saturation_totals())):
        for c, k in totals.items():
            if k > SATURATION_LIMIT * n:
                out.append(f"channel {c}: {k} of {n} samples ({100 * k / n:.3g} %) {what}, "
                           f"more than {100 * SATURATION_LIMIT:g} %: lower the drive "
                           "(source.level_vrms) or widen the range")
    return out


def _disk_full_line(s) -> str:
    """One line for a run ended by a full disk: the partial file and what it holds."""
    from daq.check import check_file

    if s.path is None or not s.path.exists():
        return (f"disk full after {s.records} of {s.records_planned} records; no file was kept")
    fc = check_file(s.path)
    held = (f"{fc.records_valid} finished records of {s.records_planned}, each verified"
            if fc.kind == "run" else f"no readable record ({fc.status})")
    repair = (f", then 'daq inspect --repair {s.path}' makes it plainly openable"
              if any("marked open for writing" in n for n in fc.notes) else "")
    return (f"disk full after {s.records} of {s.records_planned} records: {s.path} holds "
            f"{held} (status {fc.status}); free some space{repair}")


def _acquire_summary(s) -> str:
    clips = ", ".join(f"{c} {n}" for c, n in s.clip_totals().items())
    sats = ", ".join(f"{c} {n}" for c, n in s.saturation_totals().items())
    return "\n".join([
        f"{'wrote ' + str(s.path) if s.path else 'no run file'} ({_size(s.file_bytes)}): "
        f"{s.records} records x {s.samples_per_record} "
        f"samples at {s.rate_hz:g} Hz ({s.samples} samples per channel), channels "
        f"{', '.join(s.channels)}",
        f"seed: {s.seed}",
        f"clipped samples: {clips}",
        f"samples whose sensor saturated: {sats}",
        *_model_lines(s.model_info),
        f"wall time: {s.wall_s:.2f} s",
    ])


@main.command()
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--repair", is_flag=True,
              help="Clear the 'open for writing' mark a killed writer left in the file (like "
                   "h5clear -s) so that any HDF5 reader opens it.")
@_library_errors
def inspect(path, as_json, repair):
    """Show what the run file PATH holds: scene, seed, versions, status, channels, clipping,
    model."""
    from daq.check import check_file
    from daq.hdf5 import clear_write_flags, run_info

    if repair and clear_write_flags(path) and not as_json:
        click.echo(f"cleared the open-for-writing mark of {path}")
    fc = _run_check(path)
    info = run_info(path)
    info["check"] = fc.to_dict()
    if as_json:
        click.echo(json.dumps(info, indent=2))
    else:
        click.echo(_inspect_text(info))
    if not fc.ok:
        raise click.exceptions.Exit(1)


def _inspect_text(i: dict) -> str:
    n, planned = i["records_complete"], i["records_planned"]
    check = i.get("check")
    if check is not None and not check["ok"]:
        status = (f"{check['status'].upper()}: {check['records_valid']} of {planned} records "
                  f"verify; " + "; ".join(check["problems"]))
    elif i["complete"]:
        status = f"complete, {n} of {planned} records"
    else:
        why = {"acquiring": "writer killed or still running", "interrupted": "interrupted",
               "failed": "failed"}.get(i["status"], i["status"])
        status = f"INCOMPLETE ({why}), {n} of {planned} records"
        if i["message"]:
            status += f": {i['message']}"
    a, f = i["acquisition"], i["antialias"]
    lines = [
        f"{i['path']} ({_size(i['file_bytes'])}): {i['file_format']} {i['file_format_version']}, "
        f"written by pendulum-daq {i['software_version']}",
        f"scene: {i['scene']} ({i['scene_source']}), seed {i['seed']}, started {i['start_time']}",
        f"status: {status}",
        f"sampling: {a['rate_hz']:g} Hz (simulated at {a['simulation_rate_hz']:g} Hz, decimation "
        f"{a['decimation']}), {a['samples_per_record']} samples per record ({a['record_s']:g} s), "
        f"settling {a['settle_s']:g} s",
        f"anti-alias: {f['kind']} order {f['order']}, passband {f['passband_hz']:g} Hz "
        f"({f['ripple_db']:g} dB ripple), >= {f['attenuation_db']:.1f} dB from "
        f"{f['stopband_hz']:g} Hz",
        "channels:",
    ]
    names = list(i["clip_counts"])
    for name, c in zip(names, i["channels"]):
        per = i["clip_counts"][name]
        hit = sum(1 for x in per if x)
        sat = i["saturation_counts"][name]
        lines.append(
            f"  {name}: {c['long_name']} -- {c['quantity']} [{c['engineering_unit']}], "
            f"{_fmt(c['volts_per_unit'])} V per {c['engineering_unit']}, +-{_fmt(c['range_v'])} V, "
            f"{c['bits']} bit (LSB {_fmt(c['lsb_v'])} V), clipped {sum(per)} samples in {hit} "
            f"of {len(per)} records, sensor saturated in {sum(sat)} samples")
    lines.extend(_model_lines(i["model_info"]))
    lines.append(f"model responses: {', '.join(i['responses'])}")
    lines.append(f"ground truth: {', '.join(i['truth']) if i['truth'] else 'not recorded'}")
    if i["writer_flag_set"]:
        lines.append("note: the file is still marked open for writing (writer running or "
                     "killed); SWMR readers open it, others after 'daq inspect --repair'")
    return "\n".join(lines)


# -- analysis --------------------------------------------------------------------------------

def _processing_errors(fn):
    """Turn the analyzer's errors (:class:`processing.spectra.ProcessingError`) into a clean
    ``Error: ...`` message and exit status 1."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from processing.spectra import ProcessingError

        try:
            return fn(*args, **kwargs)
        except ProcessingError as exc:
            raise click.ClickException(str(exc)) from None

    return wrapper


@main.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--window", type=click.Choice(["hann", "uniform", "flattop", "force",
                                             "exponential"]), default="hann", show_default=True,
              help="FFT window (hann: the 35670A's for random noise; uniform: a plain FFT of "
                   "each record).")
@click.option("--averaging", type=click.Choice(["rms", "vector", "exponential", "peak"]),
              default="rms", show_default=True, help="Averaging of the spectra (peak hold has no "
              "cross spectra and is refused).")
@click.option("--lines", type=click.IntRange(min=1),
              help="Frequency lines (with --span): time record = lines / span.")
@click.option("--span", "span_hz", type=float, help="Frequency span [Hz] (with --lines).")
@click.option("--nperseg", type=click.IntRange(min=2),
              help="Samples per FFT (default: a whole record, one FFT per record).")
@click.option("--overlap", default=0.0, show_default=True,
              type=click.FloatRange(0.0, 1.0, max_open=True),
              help="Overlap of consecutive FFTs within a record, 0 <= F < 1.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the measured H_t and Theta_2 (0.1-10 Hz) as CSV.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the measured Bode diagrams over the model (PNG, like Figs. 9, 10).")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the Markdown report.")
@click.option("--spectra", "spectra_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write spectra, responses, coherence, model and E[H1] to a new HDF5 file "
                   "(xarray: group 'spectra', engine h5netcdf).")
@click.option("--uff", "uff_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write H_t and Theta_2 with their coherence as UFF 58 (.uff/.unv) for modal "
                   "software (processing.uff).")
@click.option("--estimator", type=click.Choice(["h1", "h2", "hv"]), default="h1",
              show_default=True, help="FRF estimator: H1 = G_ax/G_aa (noise on the output), "
                   "H2 = G_xx/G_xa (noise on the input), Hv (total least squares).")
@click.option("--fmin", "fmin_hz", type=float, default=0.1, show_default=True,
              help="Lowest frequency of the display band [Hz] (CSV, UFF, plots, statistics).")
@click.option("--fmax", "fmax_hz", type=float, default=10.0, show_default=True,
              help="Highest frequency of the display band [Hz].")
@click.option("--phase", type=click.Choice(["wrapped", "unwrapped"]), default="wrapped",
              show_default=True, help="Phase display of the plots: wrapped to (-180, 180] "
                   "(broken at each wrap) or unwrapped along frequency.")
@click.option("--view", type=click.Choice(["bode", "nyquist", "coherence", "all"]),
              default="bode", show_default=True, help="What --plot draws: Bode (gain, phase, "
              "coherence over the model), Nyquist with real and imaginary parts, the coherences; "
              "all: the three, as PLOT-bode.png, PLOT-nyquist.png, PLOT-coherence.png.")
@click.option("--follow", is_flag=True,
              help="Follow a run that is still being acquired (SWMR): print the averaged "
                   "estimate each time records land, then analyse the whole run once it ends.")
@click.option("--allow-incomplete", is_flag=True,
              help="Analyse a damaged run file (records failing their checksum, or fewer rows "
                   "than it counts) with only the records that verify, instead of refusing it.")
@_force_option
@_library_errors
@_processing_errors
def analyze(run, window, averaging, lines, span_hz, nperseg, overlap, csv_path, plot_path,
            report_path, spectra_path, uff_path, estimator, fmin_hz, fmax_hz, phase, view,
            force, allow_incomplete, follow):
    """Analyse the run file RUN like the paper's 35670A: averaged auto and cross spectra,
    H_t = W_ax/W_aa and Theta_2 = W_ay/W_aa with coherence and error bands, against the exact
    whole-chain model stored in the file, with the expected leakage bias, modal fits and the
    rotation-isolation reading.

    Default: one FFT per record, Hann window, RMS averaging of all finished records (an
    interrupted run is analysed with the records it holds). The run file is only read.
    """
    from daq.hdf5 import read_run
    from processing.analysis import AnalyzerSettings, write_csv, write_report
    from processing.analysis import analyze as run_analysis
    from processing.spectra_hdf5 import write_spectra
    from processing.uff import write_frf_uff
    from processing.views import view_paths, write_views

    settings = AnalyzerSettings(window=window, averaging=averaging, nperseg=nperseg, lines=lines,
                                span_hz=span_hz, overlap=overlap, estimator=estimator,
                                fmin_hz=fmin_hz, fmax_hz=fmax_hz)
    plots = [] if plot_path is None else list(view_paths(plot_path, view).values())
    outputs = [(p, w) for p, w in ((csv_path, write_csv), (report_path, write_report),
                                   (spectra_path, write_spectra), (uff_path, write_frf_uff))
               if p is not None]
    seen = {run.resolve(): "the run file being analysed"}
    for p in [q for q, _ in outputs] + plots:
        key = p.resolve()
        if key in seen:
            raise click.BadParameter(f"output {str(p)!r} is {seen[key]}: choose another path")
        seen[key] = "another output"
        check_writable(p, force=force)
    if follow:
        from processing.follow import follow_run

        for update in follow_run(run, settings):
            click.echo(update.line())
    records = _verified_records(run, allow_incomplete)
    analysis = run_analysis(read_run(run, records=records), settings, source=str(run))
    click.echo(analysis.summary())
    for p, write in outputs:
        write(analysis, p, force=force)
        click.echo(f"wrote {p}")
    if plot_path is not None:
        for p in write_views(analysis, plot_path, view, phase=phase, force=force):
            click.echo(f"wrote {p}")



# -- datasets --------------------------------------------------------------------------------

class _SweepProgressLine:
    """One progress line on stderr (rewritten in place on a terminal, a line per run otherwise):
    runs done, failed, rate and time left."""

    def __init__(self):
        self.tty = sys.stderr.isatty()

    def __call__(self, p) -> None:
        left = "-" if p.eta_s is None else (f"{p.eta_s:.0f} s" if p.eta_s < 90
                                            else f"{p.eta_s / 60:.1f} min")
        line = (f"runs: {p.done + p.failed}/{p.total} ({p.done} done, {p.failed} failed"
                + (f", {p.skipped} already there" if p.skipped else "")
                + f"), {p.rate_per_min:.1f} runs/min, {left} left")
        click.echo(("\r" + line.ljust(78)) if self.tty else line, err=True, nl=not self.tty)

    def close(self) -> None:
        if self.tty:
            click.echo("", err=True)


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM (``kill PID``) stops a sweep like Ctrl-C: finished runs stay, the manifest is
    written."""
    import signal

    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@main.command()
@click.argument("sweep_file", metavar="SWEEP.toml",
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory of the dataset (created; a rerun finishes it).")
@click.option("--workers", type=click.IntRange(min=1),
              help="Runs at once on local processes [default: the cores].")
@click.option("--scheduler", metavar="ADDRESS",
              help="Run on an existing Dask cluster (tcp://host:8786; needs the extra "
                   "pendulum-daq[dask]) instead of local processes.")
@click.option("--dry-run", is_flag=True, help="Print the runs, time and disk; run nothing.")
@click.option("--force", is_flag=True,
              help="Apply a changed sweep file to an existing dataset (changed runs are redone).")
@_library_errors
def dataset(sweep_file, out_dir, workers, scheduler, dry_run, force):
    """Run the parameter sweep SWEEP.toml: one HDF5 file per run (the run and its analysis), a
    manifest that xarray opens as one dataset (DIR/manifest.h5) and a table (DIR/manifest.csv).

    Rerunning the same command skips finished runs and redoes the rest; Ctrl-C stops cleanly.
    """
    from processing.dataset import (SweepInterrupted, dask_executor, default_workers,
                                    describe_plan, load_sweep, plan_runs, run_sweep)

    sweep = load_sweep(sweep_file)
    planned = plan_runs(sweep)
    if scheduler is not None and workers is not None:
        raise click.UsageError("give --workers (local processes) or --scheduler (a Dask "
                               "cluster), not both")
    with contextlib.ExitStack() as stack:
        if scheduler is not None:
            executor, slots = stack.enter_context(dask_executor(scheduler))
        else:
            executor, slots = None, workers or default_workers()
        click.echo(describe_plan(sweep, planned, workers=slots))
        if dry_run:
            return
        bar = _SweepProgressLine()
        stack.enter_context(_sigterm_as_interrupt())
        try:
            result = run_sweep(sweep, out_dir, executor=executor, workers=slots, force=force,
                               progress=bar, planned=planned)
        except SweepInterrupted as exc:
            bar.close()
            r = exc.result
            click.echo(f"interrupted: {r.complete} of {r.total} runs complete, {r.failed} "
                       f"failed, {r.missing} missing (listed in {r.table}); run the same "
                       "command again to finish", err=True)
            raise click.exceptions.Exit(130) from None
        bar.close()
    click.echo(f"{result.complete} of {result.total} runs complete ({result.skipped} already "
               f"there), {result.failed} failed, {result.missing} missing in "
               f"{result.wall_s:.1f} s")
    for r in sorted(result.results.values(), key=lambda r: r["index"]):
        if r["status"] == "failed":
            click.echo(f"  run {r['index']} failed: {r['error']}")
    click.echo(f"wrote {result.manifest} (xarray.open_dataset(..., engine=\"h5netcdf\")) and "
               f"{result.table}")


# -- export ----------------------------------------------------------------------------------

@main.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the channels as a netCDF-4/HDF5 file (.nc, .h5, .hdf5) that xarray "
                   "opens directly (daq.eu.to_xarray).")
@click.option("--units", type=click.Choice(["eu", "volts", "codes"]), default="eu",
              show_default=True, help="Units of --out: engineering units (m/s^2, m, rad), the "
              "sensors' volts or the raw ADC codes.")
@click.option("--uff", "uff_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write every record of every channel in engineering units as UFF 58 time "
                   "responses (.uff/.unv, daq.uff).")
@_force_option
@_library_errors
def export(run, out_path, units, uff_path, force):
    """Export the run file RUN's channels (finished records) in engineering units: to a netCDF
    file (--out) and/or to UFF 58 time records (--uff). The run file is only read."""
    from daq.eu import write_eu_file
    from daq.hdf5 import read_run
    from daq.uff import write_time_uff

    outputs = [p for p in (out_path, uff_path) if p is not None]
    if not outputs:
        raise click.UsageError("nothing to export: give --out FILE.nc and/or --uff FILE.uff")
    seen = {run.resolve()}
    for p in outputs:
        if p.resolve() in seen:
            raise click.BadParameter(f"output {str(p)!r} is the run file or another output: "
                                     "choose another path")
        seen.add(p.resolve())
        check_writable(p, force=force)
    recording = read_run(run)
    if out_path is not None:
        write_eu_file(recording, out_path, units=units, force=force)
        click.echo(f"wrote {out_path}: {recording.records} records of "
                   f"{', '.join(recording.header.names)} in {units}")
    if uff_path is not None:
        write_time_uff(recording, uff_path, source=run.name, force=force)
        click.echo(f"wrote {uff_path}: {recording.records * len(recording.header.names)} UFF 58 "
                   "time records in engineering units")


def _run_check(path: Path):
    """:func:`daq.check.check_file` of a file that must be a run file that opens: a ConfigError
    (not a run file, truncated, unreadable: the reader's own message) otherwise."""
    from daq.check import check_file
    from daq.hdf5 import open_run

    fc = check_file(path)
    if fc.kind != "run":
        with open_run(path):  # raises the reader's message
            pass
        raise click.ClickException(fc.line())
    return fc


def _verified_records(run: Path, allow_incomplete: bool):
    """The records of RUN to analyse: None (all it counts) for a sound file; a bad file is
    refused, or with ``allow_incomplete`` reduced to the records that verify."""
    fc = _run_check(run)
    if fc.ok:
        return None
    if not allow_incomplete or not fc.valid_records:
        hint = (f"; --allow-incomplete analyses the {fc.records_valid} records that verify"
                if fc.valid_records else "; no record of it verifies")
        raise click.ClickException(fc.line() + hint)
    click.echo(f"warning: {fc.line()}; analysing the {len(fc.valid_records)} records that "
               f"verify", err=True)
    return fc.valid_records


# -- file checks -----------------------------------------------------------------------------

@main.command("check")
@click.argument("paths", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list, one object per file.")
@click.option("--repair", is_flag=True,
              help="First clear the 'open for writing' mark a killed writer left (like h5clear "
                   "-s; never while the writer lives), so that any HDF5 reader opens the file.")
def check_cmd(paths, as_json, repair):
    """Check the files PATHS (run, spectra, trajectory files): structure and format version,
    completeness against the file's own plan, every record's checksum, calibrations and scene.

    One line per file (OK or BAD, kind, status, records that verify, format version, the first
    problem); exit status 0 only if every file is sound (an interrupted run whose records all
    verify is sound), 1 otherwise. The library call is daq.check.check_file.
    """
    from daq.check import check_file, superblock
    from daq.hdf5 import clear_write_flags
    from rig.errors import ConfigError

    if repair:
        for p in paths:
            sb = superblock(p)
            if sb and sb["flags"] and sb["version"] >= 2:
                try:
                    if clear_write_flags(p) and not as_json:
                        click.echo(f"cleared the open-for-writing mark of {p}")
                except ConfigError as exc:
                    click.echo(f"not repaired: {exc}", err=True)
    results = [check_file(p) for p in paths]
    if as_json:
        click.echo(json.dumps([r.to_dict() for r in results], indent=2))
    else:
        for r in results:
            click.echo(r.line())
    if not all(r.ok for r in results):
        raise click.exceptions.Exit(1)


main.add_command(bench)


def run() -> None:
    """The ``daq`` console script: :func:`main`, then leave without tearing the interpreter down.

    Finalising the interpreter after numba has been loaded (freeing its and LLVM's module
    objects one by one) takes about 0.25 s, a tenth of a whole ``daq acquire``. Every command
    closes its files itself, so once :func:`main` has returned (or exited), the output streams
    are flushed and the process ends with ``os._exit`` and the exit status. Set
    ``PENDULUM_DAQ_FULL_EXIT=1`` for a normal exit (e.g. to let coverage or a profiler write their
    data at exit).
    """
    try:
        main()
        code = 0
    except SystemExit as exc:  # click's standalone mode always ends here
        code = exc.code
    if os.environ.get("PENDULUM_DAQ_FULL_EXIT", "") not in ("", "0"):
        sys.exit(code)
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()
