"""The live view's options of ``daq acquire`` and ``daq view`` (rerun; imported only when one
of these options is used)."""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import force_option
from rig._io import check_writable


# -- live view (rerun; imported only when one of these options is used) ---------------------

def live_options(fn):
    for opt in reversed([
        click.option("--live", is_flag=True,
                     help="Spawn a rerun viewer (memory limit 2 GiB) and stream to it."),
        click.option("--connect", metavar="URL",
                     help="Stream to a running rerun viewer, e.g. "
                          "rerun+http://127.0.0.1:9876/proxy."),
        click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
                     help="Save the live view's stream to this .rrd file."),
        click.option("--magnify", type=click.FloatRange(min=0, min_open=True), default=None,
                     help="Factor on the angles in the bench drawing (the stage travel gets a sixth of it) "
                          "(default 30 for a run, 1 for free motion)."),
    ]):
        fn = opt(fn)
    return fn


def viewer_stream(live, connect, rrd, force):
    """A :class:`processing.live_view.ViewerStream`, or None without a live option."""
    if not (live or connect or rrd):
        return None
    from processing.live_view import ViewerOptions, ViewerStream

    try:
        return ViewerStream(ViewerOptions(spawn=live, connect=connect, rrd=rrd, force=force))
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def live_sinks(live, connect, rrd, force, magnify, pacer) -> list:
    """The live view as a sink of ``acquire``, or [] without a live option. Its options are
    checked now; rerun (~1 s to import) is imported on a thread while the bench starts."""
    if not (live or connect or rrd):
        return []
    if rrd is not None:
        check_writable(rrd, force=force)
    if connect:
        from processing.viewer_url import host_port

        try:
            host_port(connect)
        except ValueError as exc:
            raise click.BadParameter(str(exc)) from None
    from daq.sinks import Sink

    class DeferredLiveView(Sink):
        """processing.live_view.LiveView, made when the run starts (its import runs
        beside the bench's start-up)."""

        critical = False

        def __init__(self):
            import importlib
            import threading

            self.path, self._view = None, None
            self._import = threading.Thread(
                target=importlib.import_module, args=("processing.live_view",), daemon=True)
            self._import.start()

        def start(self, header):
            self._import.join()
            from processing.live_view import MAGNIFICATION, LiveView

            self._view = LiveView(viewer_stream(live, connect, rrd, force),
                                  magnification=magnify or MAGNIFICATION, pacer=pacer)
            self._view.start(header)

        def block(self, block):
            self._view.block(block)

        def record(self, record):
            self._view.record(record)

        def stop(self, footer):
            if self._view is not None:
                self._view.stop(footer)
                self.path = self._view.path

    return [DeferredLiveView()]


# -- live view: replay a run file (rerun) -------------------------------------------------

@click.command()
@click.argument("run", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--rrd", type=click.Path(dir_okay=False, path_type=Path),
              help="Save the replay to this .rrd file.")
@click.option("--connect", metavar="URL", help="Replay into a running rerun viewer.")
@click.option("--screenshot", "screenshot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Render the layout at the end of the run to a PNG, without a window.")
@click.option("--size", default="1600x900", show_default=True, metavar="WxH",
              help="Window size of --screenshot.")
@click.option("--magnify", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Factor on the angles in the bench drawing (the stage travel gets a sixth of it) [default 30].")
@force_option
def view(run, rrd, connect, screenshot_path, size, magnify, force):
    """Replay the run file RUN into rerun as the live view showed it: a spawned viewer by
    default, or --connect URL, --rrd FILE.rrd, --screenshot FILE.png (any combination). An
    interrupted run shows its finished records."""
    import tempfile

    from processing.live_view import (MAGNIFICATION, LiveViewError, ViewerOptions,
                                      ViewerStream, replay, screenshot)

    for p in (rrd, screenshot_path):
        if p is not None and p.resolve() == run.resolve():
            raise click.BadParameter(f"output {str(p)!r} is the run file: choose another path")
    if screenshot_path is not None:
        check_writable(screenshot_path, force=force)
    spawn = not (rrd or connect or screenshot_path)
    with tempfile.TemporaryDirectory() as tmp:
        target = rrd if rrd is not None or screenshot_path is None else Path(tmp) / "view.rrd"
        stream = ViewerStream(ViewerOptions(spawn=spawn, connect=connect, rrd=target,
                                            force=force))
        v = replay(run, stream, magnification=magnify or MAGNIFICATION)
        click.echo(f"replayed {v.footer.records_complete} of {v.header.plan.records} records "
                   f"of {run} ({v.footer.status})")
        if rrd is not None:
            click.echo(f"wrote {rrd} (rerun recording)")
        if screenshot_path is not None:
            try:
                screenshot(target, screenshot_path, size=size, force=force)
            except LiveViewError as exc:
                raise click.ClickException(str(exc)) from None
            click.echo(f"wrote {screenshot_path}")
