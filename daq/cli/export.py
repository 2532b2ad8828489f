"""``daq export``: a run file's channels in other formats (netCDF, UFF 58)."""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import force_option
from rig._io import check_writable


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
