"""``daq analyze``: a run file analysed like the paper's 35670A (spectra, H_t and Theta_2,
their errors, the exact model beside them)."""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import (UFF_SUFFIXES, force_option, plot_option, suffix_path,
                            verified_records)
from processing.choices import AVERAGING, ESTIMATORS, WINDOWS
from rig.output_files import check_writable


# -- analysis --------------------------------------------------------------------------------

@click.command()
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
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
@plot_option("the measured Bode diagrams over the model (like Figs. 9, 10)")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the Markdown report.")
@click.option("--spectra", "spectra_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write spectra, responses, coherence, model and E[H1] to a new HDF5 file "
                   "(xarray: group 'spectra', engine h5netcdf).")
@click.option("--uff", "uff_path", type=click.Path(dir_okay=False, path_type=Path),
              callback=suffix_path(UFF_SUFFIXES, "a UFF file"),
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
                   "estimate each time records land, then analyse the whole run once it ends. "
                   "RUN may not exist yet: it is waited for (--wait).")
@click.option("--wait", "wait_s", type=click.FloatRange(min=0), default=60.0, show_default=True,
              metavar="SECONDS", help="With --follow: how long to wait for RUN to appear and "
              "become readable.")
@click.option("--allow-incomplete", is_flag=True,
              help="Analyse a damaged run file (records failing their checksum, or fewer rows "
                   "than it counts) with only the records that verify, instead of refusing it.")
@force_option
def analyze(run, window, averaging, lines, span_hz, nperseg, overlap, csv_path, plot_path,
            report_path, spectra_path, uff_path, estimator, fmin_hz, fmax_hz, phase, view,
            force, allow_incomplete, follow, wait_s):
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

    if not follow and not run.exists():
        raise click.BadParameter(f"{str(run)!r} does not exist (--follow waits for a run that "
                                 "is about to be written)", param_hint="'RUN'")
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
    _check_band(run, fmax_hz)
    if follow:
        from processing.follow import follow_run

        if not run.exists():
            click.echo(f"waiting up to {wait_s:g} s for {run} to appear (--wait)", err=True)
        for update in follow_run(run, settings, open_timeout_s=wait_s):
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


def _check_band(run: Path, fmax_hz: float) -> None:
    """--fmax against the run's band (:func:`processing.analyzer.band_limit_hz`), read from its
    header before anything is analysed. A file that cannot be read yet (--follow of a run not
    started, a damaged file) is left to the steps that say why; the analysis checks the band
    again (:func:`processing.analyzer.check_band`)."""
    from daq.hdf5 import run_info
    from processing.analyzer import band_limit_hz
    from rig.errors import RigError

    try:
        aa = run_info(run)["antialias"]
    except (RigError, OSError, KeyError):
        return
    limit = band_limit_hz(aa["passband_hz"], aa["rate_hz"])
    if fmax_hz > limit:
        raise click.BadParameter(
            f"{fmax_hz:g} Hz is above this run's band: its anti-alias filter's passband ends at "
            f"{limit:g} Hz (the Nyquist frequency of its {aa['rate_hz']:g} Hz rate is "
            f"{aa['rate_hz'] / 2:g} Hz; above the passband the channels hold mostly leakage); "
            f"give --fmax {limit:g} or less", param_hint="--fmax")
