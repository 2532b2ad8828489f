"""``daq sine``: a stepped- or swept-sine measurement of a scene's bench (the 35670A's
swept-sine option).

Defaults: the accuracy sweep of the README (auto resolution 2 dB / 20 deg from a 50-point log
grid, the mirror's rotation held at 3e-4 rad up to 1 V, windows continued to a 0.02 dB random
error, the settle from the bench's poles); ``--points N`` alone gives a fixed grid, ``--level V``
a fixed level, ``--random-error 0`` the windows as given. ``--mode swept``: the frequency moves
continuously at the rule's rate (:mod:`rig.bench.swept`), 200 points read as it passes them,
the auto level a profile from the model along the sweep; auto resolution and the random-error
target are stepped-only.

A thin layer over :func:`processing.sine_sweep.measure_sine`: every option is validated and
every output path checked before anything is simulated; errors are one line naming the value.
"""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import force_option, set_option
from rig.errors import ConfigError


#: the defaults of the README's accuracy sweep (tests/processing/test_sine.py)
DEFAULT_AUTO_RESOLUTION = "2,20"
DEFAULT_AUTO_LEVEL = "y,3e-4,0.2"
DEFAULT_RANDOM_ERROR_DB = 0.02
#: swept: points cost no bench time (each is read as the sweep passes it)
DEFAULT_SWEPT_POINTS = 200


def _numbers(text: str | None, n: int, option: str, what: str) -> tuple | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) != n or len(parts) != n:
        raise ConfigError(f"{option} {text!r} is invalid: expected {what}")
    return vals


def _auto_level(text: str | None) -> tuple | None:
    if text is None:
        return None
    parts = text.split(",")
    what = "CHANNEL,TARGET,TOL (channel a, x or y; target > 0 in its unit; tolerance > 0)"
    if len(parts) != 3 or parts[0].strip() not in ("a", "x", "y"):
        raise ConfigError(f"--auto-level {text!r} is invalid: expected {what}")
    try:
        return (parts[0].strip(), float(parts[1]), float(parts[2]))
    except ValueError:
        raise ConfigError(f"--auto-level {text!r} is invalid: expected {what}") from None


def _exclusive(a, b, names: str) -> None:
    if a is not None and b is not None:
        raise ConfigError(f"{names} are alternatives: give one of them")


@click.command("sine")
@click.argument("scene_arg", metavar="SCENE")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Sine run file to write (HDF5: .h5, .hdf5, .nxs).")
@click.option("--mode", type=click.Choice(["stepped", "swept"]), default="stepped",
              show_default=True,
              help="stepped: settle and integrate at each point; swept: the frequency moves "
                   "continuously (phase continuous) at the rule's rate from the bench's poles "
                   "and zeros, each point read as the sweep passes it.")
@click.option("--sweep-tolerance", type=float, default=0.005, show_default=True,
              help="Swept: the rule's tolerance, the fraction of the distance to the nearest "
                   "pole or zero the frequency may move during that singularity's memory or "
                   "the window (about the relative sweep bias).")
@click.option("--sweep-s", type=float, default=None,
              help="Swept: a plain log or linear chirp (--spacing) of this duration [s] "
                   "instead of the rule's path (a WARNING if it is faster than the rule).")
@click.option("--max-sweep-s", type=float, default=2e6, show_default=True,
              help="Swept: refuse a sweep longer than this [s] of bench time.")
@click.option("--fmin", type=float, default=0.1, show_default=True, help="First frequency [Hz].")
@click.option("--fmax", type=float, default=10.0, show_default=True, help="Last frequency [Hz].")
@click.option("--points", type=int, default=None,
              help="Points of a fixed grid (no auto resolution unless it is given too: then "
                   "the grid's step is the largest; default grid 50 points).")
@click.option("--auto-resolution", metavar="DB,DEG", default=None,
              help="Finer steps where gain or phase changes fast: the largest change between "
                   "neighbouring points (SENS:FREQ:RES:AUTO); default 2,20 unless --points "
                   "is given.")
@click.option("--min-step", type=float, default=0.0005, show_default=True,
              help="Smallest auto-resolution step [Hz].")
@click.option("--spacing", type=click.Choice(["log", "lin"]), default="log", show_default=True)
@click.option("--direction", type=click.Choice(["up", "down"]), default="up", show_default=True)
@click.option("--settle-cycles", type=float, default=None,
              help="Settle time in cycles (default: the rule from the bench's poles).")
@click.option("--settle-s", type=float, default=None, help="Settle time [s].")
@click.option("--settle-tolerance", type=float, default=1e-3, show_default=True,
              help="The settle rule's bound on the transient, relative to each channel's "
                   "steady amplitude.")
@click.option("--integrate-cycles", type=int, default=20, show_default=True,
              help="Window: at least this many whole cycles.")
@click.option("--integrate-s", type=float, default=10.0, show_default=True,
              help="Window: at least this long [s].")
@click.option("--random-error", "random_error_db", type=float, default=None, metavar="DB",
              help="Stepped: continue each window until the random error of H_t and Theta_2 "
                   "(1 sigma) is at most DB dB (up to --max-integrate-s); 0: windows as "
                   "given. Default 0.02 (stepped mode only).")
@click.option("--max-integrate-s", type=float, default=20000.0, show_default=True,
              help="Longest window with --random-error [s].")
@click.option("--level", "level_vrms", type=float, default=None,
              help="A fixed source level [V rms] (no auto level).")
@click.option("--auto-level", metavar="CHANNEL,TARGET,TOL", default=None,
              help="Hold a channel's fundamental at TARGET (its unit: a m/s^2, x m, y rad) "
                   "within TOL (relative) (SOUR:VOLT:AUTO); default y,3e-4,0.2 unless --level "
                   "is given.")
@click.option("--level-limit", type=float, default=1.0, show_default=True,
              help="Highest source level [V rms].")
@click.option("--harmonics", type=int, default=5, show_default=True,
              help="Harmonics measured per channel (1..20).")
@click.option("--seed", type=click.IntRange(0, 2 ** 63 - 1), default=0, show_default=True)
@click.option("--keep-records", is_flag=True, help="Store every point's ADC codes in the file.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path),
              help="Bode PNG: the points over the exact model.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path),
              help="CSV, one row per point.")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path),
              help="Markdown report.")
@click.option("--uff", "uff_path", type=click.Path(dir_okay=False, path_type=Path),
              help="H_t and Theta_2 at the points as UFF 58 (.uff or .unv).")
@set_option
@force_option
@click.option("--quiet", "-q", is_flag=True, help="No progress line.")
def sine(scene_arg, out, mode, sweep_tolerance, sweep_s, max_sweep_s, fmin, fmax, points,
         auto_resolution, min_step, spacing, direction,
         settle_cycles, settle_s, settle_tolerance, integrate_cycles, integrate_s,
         random_error_db, max_integrate_s, level_vrms, auto_level, level_limit, harmonics,
         seed, keep_records, plot, csv_path, report, uff_path, overrides, force, quiet):
    """Measure H_t and Theta_2 of SCENE with a stepped or swept sine (phase continuous), each
    point read by a synchronous (tracking) DFT over whole cycles, with its exact steady state,
    settling or sweep bias, random error and harmonics beside it."""
    import rig
    from processing.sine_sweep import SineSettings, measure_sine
    from rig.output_files import check_writable

    _exclusive(settle_cycles, settle_s, "--settle-cycles and --settle-s")
    _exclusive(level_vrms, auto_level, "--level and --auto-level")
    swept = mode == "swept"
    if auto_resolution is None and points is None and not swept:
        auto_resolution = DEFAULT_AUTO_RESOLUTION
    if auto_level is None and level_vrms is None:
        auto_level = DEFAULT_AUTO_LEVEL
    if random_error_db is None and not swept:
        random_error_db = DEFAULT_RANDOM_ERROR_DB
    if random_error_db is not None and random_error_db == 0:
        random_error_db = None
    ar = _numbers(auto_resolution, 2, "--auto-resolution", "DB,DEG: two numbers > 0")
    settings = SineSettings(
        fmin_hz=fmin, fmax_hz=fmax,
        points=points if points is not None else (DEFAULT_SWEPT_POINTS if swept else 50),
        spacing=spacing, direction=direction, auto_resolution=ar, min_step_hz=min_step,
        settle_cycles=settle_cycles, settle_s=settle_s, settle_tolerance=settle_tolerance,
        integrate_cycles=integrate_cycles, integrate_s=integrate_s,
        random_error_db=random_error_db, max_integrate_s=max_integrate_s,
        level_vrms=level_vrms, auto_level=_auto_level(auto_level), level_limit_vrms=level_limit,
        harmonics=harmonics, mode=mode, sweep_tolerance=sweep_tolerance, sweep_s=sweep_s,
        max_sweep_s=max_sweep_s)
    scene = rig.load_scene(scene_arg, list(overrides))
    outputs = [p for p in (plot, csv_path, report, uff_path) if p is not None]
    for p in outputs:
        check_writable(p, force=force)
    if plot is not None and plot.suffix.lower() != ".png":
        raise ConfigError(f"--plot {str(plot)!r}: expected a .png file")
    if uff_path is not None and uff_path.suffix.lower() not in (".uff", ".unv"):
        raise ConfigError(f"--uff {str(uff_path)!r}: expected a .uff or .unv file")
    from rig.errors import import_extra

    if plot is not None:  # an optional extra missing is said before the sweep runs
        import_extra("matplotlib", "plot", "drawing figures (--plot)")
    if uff_path is not None:
        import_extra("pyuff", "uff", "writing UFF files (--uff)")
    sinks = []
    if out is not None:
        from daq.sine_file import SineFileSink

        sinks.append(SineFileSink(out, force=force, keep_records=keep_records))
    elif not outputs:
        raise ConfigError("nothing to write: give --out, --plot, --csv, --report or --uff")

    def progress(n, f_hz, bench_s):
        if not quiet:
            click.echo(f"\rpoint {n}: {f_hz:.5g} Hz, bench {bench_s / 3600:.2f} h   ", nl=False,
                       err=True)

    sweep = measure_sine(scene, settings, seed, sinks=sinks, progress=progress)
    if not quiet:
        click.echo("", err=True)
    from processing import sine_writers as sw

    if csv_path is not None:
        sw.write_sine_csv(sweep, csv_path, force=force)
    if plot is not None:
        sw.write_sine_bode_png(sweep, scene, plot, force=force)
    if report is not None:
        sw.write_sine_report(sweep, scene, report, force=force)
    if uff_path is not None:
        sw.write_sine_uff(sweep, scene, uff_path, force=force)
    for w in sweep.warnings:
        click.echo(f"WARNING: {w}", err=True)
    click.echo(f"{len(sweep.points)} points {settings.fmin_hz:g}-{settings.fmax_hz:g} Hz, "
               f"{mode} ({sweep.model_info.get('model')} model): "
               f"{sweep.bench_s / 3600:.2f} h of bench "
               f"time in {sweep.cpu_s:.1f} s CPU ({sweep.bench_s / max(sweep.cpu_s, 1e-9):,.0f}"
               " x)")
    for name, what in (("h_t", "H_t"), ("theta_2", "Theta_2")):
        d = [p.gain_phase_error(name) for p in sweep.points]
        b = [p.bias_db_deg(name) for p in sweep.points]
        click.echo(f"{what}: max |measured - exact| {max(abs(x[0]) for x in d):.4f} dB, "
                   f"{max(abs(x[1]) for x in d):.3f} deg; max |"
                   f"{'sweep' if swept else 'settling'} bias| "
                   f"{max(abs(x[0]) for x in b):.4f} dB, {max(abs(x[1]) for x in b):.3f} deg")
    sat = sum(int(p.saturated.sum() + p.clipped.sum()) for p in sweep.points)
    if sat:
        click.echo(f"WARNING: {sat} samples clipped or over a sensor's range (see the report); "
                   "lower --level or use --auto-level", err=True)
    for p in [out, *outputs]:
        if p is not None:
            click.echo(f"wrote {p}")
