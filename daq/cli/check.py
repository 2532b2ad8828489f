"""``daq check``: is every file whole (run, spectra, trajectory files)?"""

from __future__ import annotations

import json
from pathlib import Path

import click


@click.command("check")
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
    from daq.check import check_file
    from daq.repair import clear_write_flags, superblock
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
