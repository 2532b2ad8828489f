"""``daq analyze``, ``daq dataset`` and ``daq export``: run files analysed, sweeps of runs, and
run files in other formats."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import click

from daq.cli_common import force_option, verified_records
from processing.choices import AVERAGING, ESTIMATORS, WINDOWS
from rig._io import check_writable


# -- analysis --------------------------------------------------------------------------------

@click.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--window", type=click.Choice(WINDOWS), default="hann", show_default=True,
              help="FFT window (hann: the 35670A's for random noise; uniform: a plain FFT of "
                   "each record).")
@click.option("--averaging", type=click.Choice(AVERAGING),
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
@click.option("--estimator", type=click.Choice(ESTIMATORS), default="h1",
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
@force_option
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
    from processing.analyzer import AnalyzerSettings
    from processing.analyzer import analyze as run_analysis
    from processing.writers import write_csv, write_report, write_spectra
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
    records = verified_records(run, allow_incomplete)
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


@click.command()
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

@click.command()
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
@force_option
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
