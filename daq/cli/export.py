"""``daq export``: a run file's channels in other formats (netCDF, UFF 58)."""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import UFF_SUFFIXES, force_option, suffix_path
from rig.output_files import check_writable


@click.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path),
              callback=suffix_path((".nc", ".h5", ".hdf5"), "a netCDF-4/HDF5 file"),
              help="Write the channels as a netCDF-4/HDF5 file (.nc, .h5, .hdf5) that xarray "
                   "opens directly (daq.eu.to_xarray).")
@click.option("--units", type=click.Choice(["eu", "volts", "codes"]), default="eu",
              show_default=True, help="Units of --out: engineering units (m/s^2, m, rad), the "
              "sensors' volts or the raw ADC codes.")
@click.option("--uff", "uff_path", type=click.Path(dir_okay=False, path_type=Path),
              callback=suffix_path(UFF_SUFFIXES, "a UFF file"),
              help="Write every record of every channel in engineering units as UFF 58 time "
                   "responses (.uff/.unv, daq.uff).")
@click.option("--oma", "oma_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the responses x [m], y [rad] only, records joined, as an output-only "
                   "(OMA) data set (.npz: data, fs, and the bench's exact modes) that pyOMA2's "
                   "SingleSetup(data, fs) takes (daq.oma).")
@click.option("--sysid", "sysid_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write a system-identification benchmark (.npz: u = the drive [V], y = a, x, "
                   "y, sampling_time, train/test by whole records, the noiseless oracle output "
                   "and the predicted noise floor; daq.sysid).")
@click.option("--test-fraction", type=float, default=0.2, show_default=True,
              help="Fraction of the records (the last ones) in --sysid's test part.")
@force_option
def export(run, out_path, units, uff_path, oma_path, sysid_path, test_fraction, force):
    """Export the run file RUN's channels (finished records) in engineering units: to a netCDF
    file (--out), to UFF 58 time records (--uff) and/or as an output-only data set (--oma). The
    run file is only read."""
    from daq.eu import write_eu_file
    from daq.hdf5 import read_run
    from daq.uff import write_time_uff

    outputs = [p for p in (out_path, uff_path, oma_path, sysid_path) if p is not None]
    if not outputs:
        raise click.UsageError("nothing to export: give --out FILE.nc, --uff FILE.uff, --oma "
                               "FILE.npz and/or --sysid FILE.npz")
    if sysid_path is not None and sysid_path.suffix != ".npz":
        raise click.BadParameter(f"{str(sysid_path)!r}: a system-identification file is a "
                                 "NumPy .npz file", param_hint="--sysid")
    if not 0.0 < test_fraction < 1.0:
        raise click.BadParameter(f"{test_fraction!r}: expected 0 < fraction < 1",
                                 param_hint="--test-fraction")
    if oma_path is not None and oma_path.suffix != ".npz":
        raise click.BadParameter(f"{str(oma_path)!r}: an output-only data set is a NumPy .npz "
                                 "file", param_hint="--oma")
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
    if oma_path is not None:
        from daq.oma import write_oma_file

        write_oma_file(recording, oma_path, force=force)
        click.echo(f"wrote {oma_path}: x, y of {recording.records} records joined, with the "
                   "bench's exact modes (pyOMA2: SingleSetup(z['data'], z['fs']))")
    if sysid_path is not None:
        from daq.sysid import write_sysid_file

        write_sysid_file(recording, sysid_path, test_fraction=test_fraction, force=force)
        click.echo(f"wrote {sysid_path}: u (drive), y (a, x, y), train/test, the noiseless "
                   "oracle output and the noise floor")
