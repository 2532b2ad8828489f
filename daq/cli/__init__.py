"""The ``daq`` command line: a thin click layer over the library API, and the one place that
composes rig, daq and processing. This package's ``__init__`` is the group; each command (or
command group) is a module of its own: :mod:`daq.cli.scene` (scene, model, simulate),
:mod:`daq.cli.acquire` (acquire, inspect), :mod:`daq.cli.live` (the live view, view),
:mod:`daq.cli.analyze`, :mod:`daq.cli.dataset`, :mod:`daq.cli.export`, :mod:`daq.cli.check`,
:mod:`daq.cli.design` (with :mod:`daq.cli.design_verify`),
:mod:`daq.cli.serve` (the virtual 35670A), :mod:`daq.cli.sine` (the stepped sine);
shared options in :mod:`daq.cli.common`.

Errors become one line and exit status 1 in one place, the group's class
(:class:`daq.cli.errors.ErrorsAsMessages`); ``daq --debug`` lets them through. The exit statuses
of every command are one table, :data:`daq.cli.errors.EXIT_CODES`.
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
from daq.cli import sine as _sine_cmd
from daq.cli.errors import ErrorsAsMessages, exit_codes_text


@click.group(cls=ErrorsAsMessages, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pendulum-daq")
@click.option("--debug", is_flag=True,
              help="Let errors through with their traceback (otherwise: one line, exit 1).")
@click.pass_context
def main(ctx, debug):
    """pendulum-daq: an emulated vibration-measurement rig (pendulum, bench, DAQ, analyzer)."""
    ctx.meta["daq.debug"] = debug
    if not debug:
        import warnings

        from daq.cli.common import warning_line

        warnings.showwarning = warning_line


main.help += ("\n\n\b\nExit status, the same for every command (daq.cli.errors.EXIT_CODES):\n"
              + exit_codes_text())


for _command in (_scene_cmds.scene, _scene_cmds.model, _scene_cmds.simulate, _live_cmds.view,
                 _acquire_cmds.acquire, _acquire_cmds.inspect, _analyze_cmd.analyze,
                 _dataset_cmd.dataset, _export_cmd.export, _check_cmd.check_cmd,
                 _design_cmd.design, _serve_cmd.serve, _sine_cmd.sine):
    main.add_command(_command)


def parse_only(argv: list[str]) -> int:
    """Parse ``daq COMMAND ARGS...`` as the command would (every option's type, range, choice
    and file extension), without running it: 0 if it parses, else click's message on stderr
    and the usage status 2. For a script that must refuse bad arguments before earlier, long
    steps run (``python3 tasks.py experiment --window ...``)."""
    if not argv or argv[0] not in main.commands:
        click.echo(f"Error: no command {argv[0] if argv else ''!r}: expected one of "
                   f"{', '.join(sorted(main.commands))}", err=True)
        return 2
    try:
        main.commands[argv[0]].make_context(f"daq {argv[0]}", list(argv[1:]))
    except click.exceptions.Exit as exc:  # --help
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    return 0


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

