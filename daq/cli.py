"""The ``daq`` command line: a thin click layer over the library API, and the one module that
composes rig, daq and processing. This module is the group (and ``daq check``); each command
group is a module of its own: :mod:`daq.cli_scene` (scene, model, simulate),
:mod:`daq.cli_acquire` (acquire, inspect), :mod:`daq.cli_live` (the live view, view),
:mod:`daq.cli_analyze` (analyze, dataset, export), :mod:`daq.cli_serve` (serve: the virtual
35670A); shared options in :mod:`daq.cli_common`.

Errors become one line and exit status 1 in one place, the group's class
(:class:`daq.cli_errors.ErrorsAsMessages`); ``daq --debug`` lets them through.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import click

from daq.cli_acquire import acquire, inspect
from daq.cli_analyze import analyze, dataset, export
from daq.cli_errors import ErrorsAsMessages
from daq.cli_live import view
from daq.cli_scene import model, scene, simulate
from daq.cli_serve import serve


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


for _command in (scene, model, simulate, view, acquire, inspect, analyze, dataset, export,
                 serve):
    main.add_command(_command)


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
