"""What a command-line user sees when a command fails: one or two lines, never a traceback and
never an exception class name.

:class:`ErrorsAsMessages` is the ``daq`` click group's class: every exception a command lets
escape, library error or not, becomes ``Error: <one line>`` and exit status 1
(:func:`user_message` writes the line: the bad value and what is valid for the library's own
errors, with the command line's way of forcing for a refusal to replace something
(:class:`rig.errors.ForceRequired`: "pass --force to ..."), the file and the reason for a failed
write or read, a plain statement for the rest); ``daq --debug COMMAND`` lets the exception and
its traceback through.

Exit statuses of every ``daq`` command (:data:`EXIT_CODES`; the README's table and ``daq
--help`` say the same):

- 0 (:data:`EXIT_OK`): done;
- 1 (:data:`EXIT_ERROR`): an error (bad input, unreadable or damaged file, full disk ...), on
  one line;
- 2 (:data:`EXIT_USAGE`): a usage error (unknown option, bad option value: click's message);
- 3 (:data:`EXIT_NOT_AS_ASKED`): finished and written, but not what was asked: ``daq acquire``'s
  run exceeds its error budget, or a channel clipped or saturated in more than
  :data:`SATURATION_LIMIT` of its samples (a WARNING says which); ``--allow-over-budget`` makes
  that exit 0;
- 4 (:data:`EXIT_PARTIAL`): partly done: ``daq dataset`` ran, but some runs failed or are
  missing (a line says how many; the manifest lists them), or it stopped part way because its
  journal or manifest could not be written (a full disk; the line says so);
- 128 + N (:data:`EXIT_SIGNAL_BASE` + N): ended by signal N (130 Ctrl-C, 143 SIGTERM, 129
  SIGHUP), everything finished kept."""

from __future__ import annotations

import re

import click

__all__ = ["EXIT_OK", "EXIT_ERROR", "EXIT_USAGE", "EXIT_NOT_AS_ASKED", "EXIT_PARTIAL",
           "EXIT_SIGNAL_BASE", "EXIT_CODES", "SATURATION_LIMIT", "ErrorsAsMessages",
           "user_message"]

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_NOT_AS_ASKED = 3
EXIT_PARTIAL = 4
EXIT_SIGNAL_BASE = 128
#: (status, meaning): the table of the module docstring, the README and ``daq --help``
EXIT_CODES = (
    ("0", "done"),
    ("1", "an error, said on one line"),
    ("2", "a usage error (unknown option, bad option value)"),
    ("3", "finished and written but not as asked (over its error budget, or saturated)"),
    ("4", "partly done (a sweep some of whose runs failed or are missing, or that stopped "
          "part way: a full disk)"),
    ("128+N", "ended by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), all finished work "
              "kept"),
)
#: Fraction of a channel's samples clipped by the ADC or beyond its sensor's range above which a
#: run is not what was asked.
SATURATION_LIMIT = 1e-3


def exit_codes_text() -> str:
    """:data:`EXIT_CODES` as the lines of ``daq --help``."""
    return "\n".join(f"  {code:6s} {meaning}" for code, meaning in EXIT_CODES)


def _first_line(text: str) -> str:
    lines = [s.strip() for s in str(text).strip().splitlines() if s.strip()]
    return lines[0] if lines else ""


def user_message(exc: BaseException) -> str:
    """One line saying what went wrong, for a person (see the module docstring)."""
    from daq.resources import is_disk_full
    from processing import ProcessingError
    from rig.errors import ForceRequired, RigError

    if isinstance(exc, ForceRequired):  # the library's refusal, and the command line's remedy
        return f"{_first_line(exc)}; pass --force to {exc.action}"
    if isinstance(exc, (RigError, ProcessingError)):  # the library's own errors: the one line
        return _first_line(exc)
    if is_disk_full(exc):
        m = re.search(r"filename = '([^']*)'", str(exc))
        name = getattr(exc, "filename", None) or (m.group(1) if m else None)
        return f"disk full: no space left on the device{f' writing {name}' if name else ''}"
    if isinstance(exc, BrokenPipeError):
        return "the output's reader closed it (a pipe into head?); the rest was not printed"
    if isinstance(exc, PermissionError):
        return f"permission denied: {exc.filename or _first_line(exc)}"
    if isinstance(exc, FileExistsError) and exc.filename:
        return f"{exc.filename}: exists (or is a link); pass --force to replace it"
    if isinstance(exc, OSError) and exc.filename:
        return f"{exc.filename}: {exc.strerror or _first_line(exc)}"
    if isinstance(exc, MemoryError):
        what = _first_line(exc)
        return (f"out of memory{f' ({what})' if what else ''}: ask for less (shorter records, "
                "fewer points)")
    if isinstance(exc, RecursionError):
        return ("the input nests too deeply to follow (Python's recursion limit); make it "
                "shallower")
    if isinstance(exc, OverflowError):
        return f"a number too large to use ({_first_line(exc)}); give a smaller one"
    what = _first_line(exc)
    return (f"an unexpected failure{f': {what}' if what else ''} (not a case this command "
            "expects; 'daq --debug ...' shows where it happened)")


class ErrorsAsMessages(click.Group):
    """A click group whose commands' exceptions reach the user as one line (module docstring);
    with ``ctx.meta["daq.debug"]`` set (``--debug``) they propagate with their traceback.
    SIGTERM and SIGHUP stop a command like Ctrl-C (:func:`daq.signals.stop_signals_interrupt`:
    its temporary files are removed) and an interruption the command does not report itself
    is one line and exit status 128 + N."""

    def invoke(self, ctx):
        from daq.signals import stop_signals_interrupt

        try:
            with stop_signals_interrupt():  # SIGTERM, SIGHUP: like Ctrl-C, finally blocks run
                return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit,
                click.exceptions.Abort, SystemExit):
            raise
        except KeyboardInterrupt as exc:  # a command that does not say more itself
            if ctx.meta.get("daq.debug"):
                raise
            from daq.signals import exit_status, signal_name

            name = ctx.invoked_subcommand or ctx.info_name
            click.echo(f"interrupted ({signal_name(exc)}): daq {name} stopped; files it had "
                       "finished are kept, none is left half-written", err=True)
            raise click.exceptions.Exit(exit_status(exc)) from None
        except Exception as exc:
            if ctx.meta.get("daq.debug"):
                raise
            raise click.ClickException(user_message(exc)) from None
