"""The ``daq`` command line: a thin click layer over the library API, and the one place that
composes rig, daq and processing. This package's ``__init__`` is the group; each command (or
command group) is a module of its own: :mod:`daq.cli.scene` (scene, model, simulate),
:mod:`daq.cli.acquire` (acquire, inspect), :mod:`daq.cli.live` (the live view, view),
:mod:`daq.cli.analyze`, :mod:`daq.cli.dataset`, :mod:`daq.cli.export`, :mod:`daq.cli.check`,
:mod:`daq.cli.design` (with :mod:`daq.cli.design_verify`),
:mod:`daq.cli.serve` (the virtual 35670A);
shared options in :mod:`daq.cli.common`.

Errors become one line and exit status 1 in one place, the group's class
(:class:`daq.cli.errors.ErrorsAsMessages`); ``daq --debug`` lets them through.
"""

from __future__ import annotations

import os
import sys

import click

from daq.cli import acquire as _acquire_cmds
from daq.cli import analyze as _analyze_cmd
from daq.cli import check as _check_cmd
from daq.cli import dataset as _dataset_cmd
from daq.cli import design as _design_cmd
from daq.cli import export as _export_cmd
from daq.cli import live as _live_cmds
from daq.cli import scene as _scene_cmds
from daq.cli import serve as _serve_cmd
from daq.cli.errors import ErrorsAsMessages


@click.group(cls=ErrorsAsMessages, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pendulum-daq")
@click.option("--debug", is_flag=True,
              help="Let errors through with their traceback (otherwise: one line, exit 1).")
@click.pass_context
def main(ctx, debug):
    """pendulum-daq: an emulated vibration-measurement rig (pendulum, bench, DAQ, analyzer).

    Exit status: 0 done; 1 an error (one line); 2 a usage error; 3 a run not as asked (over
    its error budget or saturated; acquire --allow-over-budget); 4 a sweep with failed or
    missing runs (dataset); 128+N ended by signal N.
    """
    ctx.meta["daq.debug"] = debug
    if not debug:
        import warnings

        from daq.cli.common import warning_line

        warnings.showwarning = warning_line


for _command in (_scene_cmds.scene, _scene_cmds.model, _scene_cmds.simulate, _live_cmds.view,
                 _acquire_cmds.acquire, _acquire_cmds.inspect, _analyze_cmd.analyze,
                 _dataset_cmd.dataset, _export_cmd.export, _check_cmd.check_cmd,
                 _design_cmd.design, _serve_cmd.serve):
    main.add_command(_command)


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

