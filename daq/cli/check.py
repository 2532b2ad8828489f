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
                   "-s; never while the writer lives), so that any HDF5 reader opens the file, "
                   "and mark such a run interrupted (its records kept).")
def check_cmd(paths, as_json, repair):
    """Check the files PATHS (run, spectra, trajectory files): structure and format version,
    completeness against the file's own plan, every record's checksum, calibrations and scene.

    One line per file (OK or BAD, kind, status, records that verify, format version, the first
    problem or note, and how many more there are: --json lists them all); exit status 0 only if every file is sound (an interrupted run whose records all
    verify is sound), 1 otherwise. The library call is daq.check.check_file.
    """
    from daq.check import check_file
    from daq.cli.common import repair_file
    from rig.errors import ConfigError

    if repair:
        for p in paths:
            try:
                for line in repair_file(p):
                    if not as_json:
                        click.echo(line)
            except ConfigError as exc:
                click.echo(f"not repaired: {exc}", err=True)
    results = [check_file(p) for p in paths]
    if as_json:
        click.echo(json.dumps([r.to_dict() for r in results], indent=2))
    else:
        for r in results:
            click.echo(r.line())
        if any(len(r.problems or r.notes) > 1 for r in results):
            click.echo("(each line shows the first problem or note; --json lists them all)")
        if not repair and any("marked open for writing" in n for r in results for n in r.notes):
            click.echo("(--repair clears the open-for-writing mark of a file whose writer is "
                       "gone, and marks such a run interrupted)")
    if not all(r.ok for r in results):
        raise click.exceptions.Exit(1)
