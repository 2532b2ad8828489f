"""``daq dataset``: a parameter sweep of runs, one run file each, and a manifest
(``daq dataset SWEEP.toml``, the same as ``daq dataset run SWEEP.toml``); ``daq dataset export``
writes a finished dataset as flat shards for ML tools."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import click


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


def _failures(results: dict) -> None:
    """One line per failed run."""
    for r in sorted(results.values(), key=lambda r: r.index):
        if r.status == "failed":
            click.echo(f"  run {r.index} failed: {r.error}")


class _SweepOrSubcommand(click.Group):
    """A group whose first argument, when it names no subcommand, is a sweep file for ``run``."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = ["run", *args]
        return super().parse_args(ctx, args)


@click.group(cls=_SweepOrSubcommand)
def dataset():
    """Datasets of runs: DIR from a sweep file (daq dataset SWEEP.toml --out DIR, i.e. the run
    subcommand), and flat exports of DIR for other tools (export)."""


@dataset.command("run")
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
              help="Apply a changed sweep file to an existing dataset (changed runs are redone; run "
                   "files the new sweep does not list are removed).")
def run_cmd(sweep_file, out_dir, workers, scheduler, dry_run, force):
    """Run the parameter sweep SWEEP.toml: one HDF5 file per run (the run and its analysis), a
    manifest that xarray opens as one dataset (DIR/manifest.h5) and a table (DIR/manifest.csv).

    Rerunning the same command skips finished runs and redoes the rest; Ctrl-C stops cleanly.
    """
    from daq.cli.common import note_cold_kernels
    from daq.cli.errors import EXIT_PARTIAL
    from daq.signals import exit_status, signal_name, stop_signals_interrupt
    from processing.dataset import (SweepInterrupted, SweepStopped, dask_executor,
                                    describe_plan, load_sweep, plan_runs, run_sweep, worker_limit)

    if scheduler is not None and workers is not None:
        raise click.UsageError("give --workers (local processes) or --scheduler (a Dask "
                               "cluster), not both")
    sweep = load_sweep(sweep_file)
    planned = plan_runs(sweep, progress=lambda k, n: click.echo(
        f"checking the runs' parameter sets: {k} of {n}", err=True))
    with contextlib.ExitStack() as stack:
        if scheduler is not None:
            executor, slots, why = stack.enter_context(dask_executor(scheduler))
            if why:
                click.echo(f"warning: {why}: keeping {slots} run{'s' if slots != 1 else ''} in "
                           "flight", err=True)
        else:
            slots, why = worker_limit(workers)
            if why:
                click.echo(f"warning: {why}: running {slots} worker{'s' if slots != 1 else ''}",
                           err=True)
            executor = None
        click.echo(describe_plan(sweep, planned, workers=slots))
        if dry_run:
            return
        note_cold_kernels()
        bar = _SweepProgressLine()
        stack.enter_context(stop_signals_interrupt())  # SIGTERM, SIGHUP stop it like Ctrl-C
        try:
            result = run_sweep(sweep, out_dir, executor=executor, workers=slots, force=force,
                               progress=bar, planned=planned)
        except SweepInterrupted as exc:
            bar.close()
            r = exc.result
            click.echo(f"interrupted ({signal_name(exc)}): {r.complete} of {r.total} runs "
                       f"complete, {r.failed} failed, {r.missing} missing (listed in {r.table}); "
                       "run the same command again to finish", err=True)
            raise click.exceptions.Exit(exit_status(exc)) from None
        except SweepStopped as exc:  # partly done (a full disk): the partial sweep's status
            bar.close()
            _failures(exc.results)
            click.echo(f"Error: {exc}", err=True)
            raise click.exceptions.Exit(EXIT_PARTIAL) from None
        bar.close()
    click.echo(f"{result.complete} of {result.total} runs complete ({result.skipped} already "
               f"there), {result.failed} failed, {result.missing} missing in "
               f"{result.wall_s:.1f} s")
    _failures(result.results)
    if result.removed:
        click.echo(f"removed {len(result.removed)} run files of the earlier plan that this sweep "
                   f"does not list ({', '.join(result.removed[:3])}"
                   f"{', ...' if len(result.removed) > 3 else ''})")
    click.echo(f"wrote {result.manifest} (xarray.open_dataset(..., engine=\"h5netcdf\")) and "
               f"{result.table}")
    if result.failed or result.missing:
        click.echo(f"partial sweep: {result.failed + result.missing} of {result.total} runs "
                   f"failed or missing (listed in {result.table}); exit status {EXIT_PARTIAL}",
                   err=True)
        raise click.exceptions.Exit(EXIT_PARTIAL)


@dataset.command("export")
@click.argument("ds_dir", metavar="DIR", type=click.Path(exists=True, file_okay=False,
                                                         path_type=Path))
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory of the export (new or empty): data/<split>-*.parquet|npz, README.md "
                   "(the dataset card), export.json.")
@click.option("--format", "fmt", type=click.Choice(["parquet", "npz"]), default="parquet",
              show_default=True, help="Shard format: Parquet (pyarrow, pandas, Hugging Face "
              "datasets) or NumPy .npz.")
@click.option("--window-s", type=float, default=None,
              help="Rows are windows of this many seconds (whole samples) [default: one row per "
                   "record].")
@click.option("--hop-s", type=float, default=None,
              help="Step between windows [s] [default: the window, no overlap].")
@click.option("--split", "split_text", default="train=0.8,val=0.1,test=0.1", show_default=True,
              metavar="NAME=FRACTION,...", help="Splits, by run (no run in two splits).")
@click.option("--split-by", metavar="PARAM",
              help="Split by the values of this varied parameter instead of by run (runs that "
                   "share a value share a split).")
@click.option("--truth", is_flag=True, help="Add the ground truth (stage acceleration, mirror "
              "translation and rotation) as columns (the sweep must keep truth).")
@click.option("--drive", is_flag=True, help="Add the source's drive voltage as a column.")
def export_cmd(ds_dir, out_dir, fmt, window_s, hop_s, split_text, split_by, truth, drive):
    """Export the finished dataset DIR as flat shards, one row per window (or record) of every
    complete run, a/x/y in engineering units with the run's parameters and seed, and a dataset
    card: loadable by pyarrow, pandas and datasets.load_dataset("parquet", data_dir=OUT)."""
    from processing.dataset.export import ExportSettings, export_dataset, parse_split

    settings = ExportSettings(format=fmt, window_s=window_s, hop_s=hop_s,
                              split=parse_split(split_text), split_by=split_by, truth=truth,
                              drive=drive)
    res = export_dataset(ds_dir, out_dir, settings)
    for name, files in res.shards.items():
        click.echo(f"{name}: {res.rows[name]} rows from {len(res.runs[name])} runs in "
                   f"{len(files)} shard(s)")
    click.echo(f"wrote {res.out_dir} (card: {res.card.name})")


@dataset.command("index")
@click.argument("ds_dir", metavar="DIR", type=click.Path(exists=True, file_okay=False,
                                                         path_type=Path))
@click.option("--chunks-url", metavar="URL",
              help="Where readers find the run files: a folder URL ending in '/' "
                   "(s3://bucket/ds/runs/ after copying DIR/runs there) [default: "
                   "file://DIR/runs/].")
@click.option("--force", is_flag=True, help="Replace an existing index.")
def index_cmd(ds_dir, chunks_url, force):
    """Index the finished dataset DIR as a Zarr v3 store of virtual references to its run
    files' chunks (an Icechunk repository, DIR/index.icechunk; nothing is copied), which
    xarray.open_zarr reads as one dataset. Needs pendulum-daq[zarr]."""
    from processing.dataset.zarr_index import write_zarr_index

    out = write_zarr_index(ds_dir, chunks_url=chunks_url, force=force)
    click.echo(f"wrote {out} (xarray.open_zarr(icechunk session store); "
               "processing.dataset.open_zarr_index)")
