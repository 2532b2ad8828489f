"""The ``daq`` commands' shared options, number formatting and run-file check."""

from __future__ import annotations

import json
from pathlib import Path

import click

from rig.model_info import ModelInfo


def set_option(fn):
    return click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                        help="Override a scene value, e.g. --set pendulum.q1=300 (repeatable).")(fn)


def force_option(fn):
    return click.option("--force", is_flag=True, help="Overwrite existing output files.")(fn)


def figure_path(ctx, param, value):
    """A click callback: a figure path whose extension names a format matplotlib writes
    (:func:`processing.figure_files.figure_format`), checked while the command line is parsed,
    so a bad one is a usage error before any work."""
    from processing.figure_files import figure_format

    return _format_checked(ctx, param, value, figure_format)


def image_path(ctx, param, value):
    """A click callback: an image path (a screenshot) whose extension names PNG or JPEG
    (:func:`processing.figure_files.image_format`), checked while the command line is parsed."""
    from processing.figure_files import image_format

    return _format_checked(ctx, param, value, image_format)


def _format_checked(ctx, param, value, check):
    if value is None:
        return None
    from processing.errors import SettingsError

    try:
        check(value)
    except SettingsError as exc:
        raise click.BadParameter(str(exc), ctx=ctx, param=param) from None
    return value


def suffix_path(suffixes: tuple[str, ...], what: str):
    """A click callback: a path whose extension is one of ``suffixes`` (case-insensitive),
    checked while the command line is parsed (a usage error naming the valid ones before any
    work)."""
    def check(ctx, param, value):
        if value is not None and Path(value).suffix.lower() not in suffixes:
            said = (f"has the extension {Path(value).suffix!r}" if Path(value).suffix
                    else "has no extension")
            raise click.BadParameter(f"{str(value)!r} {said}: {what} is one of "
                                     f"{', '.join(suffixes)}", ctx=ctx, param=param)
        return value
    return check


#: extensions of a UFF file (rig.uff.write_uff)
UFF_SUFFIXES = (".uff", ".unv")


def fmt(v) -> str:
    """A value as a person reads it: numbers to 6 digits, booleans and nothing as in JSON/TOML
    (true, false, null), lists in brackets."""
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    return str(v)


def size_text(n: int | None) -> str:
    if n is None:
        return "-"
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return str(n)


def model_lines(info: ModelInfo) -> list[str]:
    """Which model ran, how, and its error estimate (the rest is in ``inspect --json``)."""
    est = "-" if info.error_estimate is None else info.error_estimate
    if isinstance(est, dict):
        est = ", ".join(f"{k} {fmt(v)}" for k, v in est.items())
    lines = [f"model: {info.model or '-'}", f"  method: {info.method or '-'}",
             f"  error estimate: {fmt(est)}"]
    if info.reason:
        lines.append(f"  why this model: {info.reason}")
    per = info.per_sample
    if isinstance(per, dict) and per.get("what"):
        rate = per.get("rate_hz")
        at = f" (at {fmt(rate)} Hz)" if rate else ""
        lines.append(f"  per DAC sample{at}: {per['what']}")
        if per.get("why"):
            lines.append(f"  why: {per['why']}")
    return lines


def run_check(path: Path, *, sine_ok: bool = False):
    """:func:`daq.check.check_file` of a file that must be a run file that opens: a ConfigError
    (not a run file, truncated, unreadable: the reader's own message) otherwise; with
    ``sine_ok`` a stepped-sine run file (:mod:`daq.sine_file`) is accepted too."""
    from daq.check import check_file
    from daq.hdf5 import open_run

    fc = check_file(path)
    if fc.kind == "sine" and sine_ok:
        return fc
    if fc.kind != "run":
        with open_run(path):  # raises the reader's message
            pass
        raise click.ClickException(fc.line())
    return fc


def verified_records(run: Path, allow_incomplete: bool):
    """The records of RUN to analyse: None (all it counts) for a sound file; a bad file is
    refused, or with ``allow_incomplete`` reduced to the records that verify."""
    fc = run_check(run)
    if fc.ok:
        return None
    if not allow_incomplete or not fc.valid_records:
        hint = (f"; --allow-incomplete analyses the {fc.records_valid} records that verify"
                if fc.valid_records else "; no record of it verifies")
        raise click.ClickException(fc.line() + hint)
    click.echo(f"warning: {fc.line()}; analysing the {len(fc.valid_records)} records that "
               f"verify", err=True)
    return fc.valid_records


def repair_file(path: Path) -> list[str]:
    """``--repair`` of ``daq check`` and ``daq inspect``: clear the open-for-writing mark a killed
    writer left (:func:`daq.repair.clear_write_flags`), then mark such a run "interrupted"
    (:func:`daq.hdf5.mark_interrupted`; its records kept). Returns what was done, one line each;
    a file whose writer is alive is left alone (a ConfigError saying so)."""
    from daq.hdf5 import mark_interrupted
    from daq.repair import clear_write_flags, superblock, writer_alive

    done = []
    sb = superblock(path)
    if sb is None:
        return done
    if sb["flags"] and sb["version"] >= 2 and clear_write_flags(path):
        done.append(f"cleared the open-for-writing mark of {path}")
    if not writer_alive(path):
        n = mark_interrupted(path)
        if n is not None:
            done.append(f"marked {path} interrupted: its writer stopped without closing it "
                        f"(killed); its {n} finished records kept")
    return done


def warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` of the CLI: ``warning: <message>`` on one line of stderr (no
    source file, line or warning class)."""
    click.echo(f"warning: {str(message).strip()}", err=True)


def display_missing() -> bool:
    """True on Linux without a display (DISPLAY and WAYLAND_DISPLAY unset): no viewer window
    can open there."""
    import os
    import sys

    return (sys.platform.startswith("linux") and not os.environ.get("DISPLAY")
            and not os.environ.get("WAYLAND_DISPLAY"))


NO_DISPLAY = ("there is no display here (DISPLAY and WAYLAND_DISPLAY are unset) to open a viewer "
              "window: save the stream with --rrd FILE.rrd (open it later with 'rerun "
              "FILE.rrd'), stream to a viewer elsewhere with --connect URL")


def check_viewer_url(url: str) -> None:
    """Refuse, before any work, a ``--connect`` URL where no rerun viewer answers (bounded:
    :data:`processing.viewer_url.ANSWER_TIMEOUT_S`)."""
    from processing.viewer_url import host_port, viewer_silence

    try:
        host_port(url)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--connect") from None
    why = viewer_silence(url)
    if why is not None:
        raise click.ClickException(f"--connect {url}: no rerun viewer there ({why}); start one "
                                   "(rerun --port PORT) or leave out --connect")


def note_cold_kernels() -> None:
    """Say on stderr, before a run, that the simulation kernels will be compiled now (numba's
    on-disk cache for these kernel sources is empty: a fresh install or changed kernels); the
    compilation happens once, later runs load it."""
    import os
    import sys

    import daq.acquisition  # noqa: F401 - registers the kernels, whose sources name the cache
    from rig.jit import cache_dir

    if "numba" in sys.modules:
        return
    path = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_dir())
    if not (path.is_dir() and any(path.rglob("*.nbi"))):
        click.echo(f"compiling the simulation kernels, once (about {COMPILE_TEXT}; later runs "
                   f"load them from {path})", err=True)


#: How long the first compilation takes (BENCHMARKS.md "First run": ~1 min on a loaded 2-core
#: host, a fresh NUMBA_CACHE_DIR, one acquisition).
COMPILE_TEXT = "a minute"


def plot_option(what: str):
    """The ``--plot PATH`` option (parameter ``plot_path``): write ``what`` as a figure whose
    format follows the extension (checked by :func:`figure_path` before any work)."""
    return click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
                        callback=figure_path,
                        help=f"Write {what}; the format follows the extension: .png, .pdf or "
                             ".svg.")
