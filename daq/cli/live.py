"""The live view's options of ``daq acquire`` and ``daq view`` (rerun; imported only when one
of these options is used)."""

from __future__ import annotations

from pathlib import Path

import click

from daq.cli.common import (NO_DISPLAY, check_viewer_url, display_missing, force_option,
                            image_path)
from rig.output_files import check_writable


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
    if live and display_missing():
        raise click.ClickException(f"--live: {NO_DISPLAY}")
    from processing.live_view import ViewerOptions, ViewerStream

    try:
        return ViewerStream(ViewerOptions(spawn=live, connect=connect, rrd=rrd, force=force))
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


def rrd_preflight(rrd: Path, scene, out: Path | None) -> None:
    """Refuse, before the run, an ``--rrd`` that could exceed the free space of its directory
    (with the run file's own need when both go to one file system), as ``--out`` is refused."""
    import os
    import shutil

    from daq.cli.common import size_text
    from daq.resources import estimate_needs
    from processing.rrd_size import rrd_bytes_estimate

    a = scene.acquisition
    need = rrd_bytes_estimate(records=a.records, record_s=a.record_s, rate_hz=a.rate_hz)
    parent = rrd.resolve().parent
    also = 0
    if out is not None and os.stat(out.resolve().parent).st_dev == os.stat(parent).st_dev:
        also = estimate_needs(records=a.records, samples=round(a.record_s * a.rate_hz),
                              channels=3, bodies=scene.chain.n, truth=a.truth).file_bytes
    free = shutil.disk_usage(parent).free
    if need + also > free:
        beside = f" beside the run file's {size_text(also)}" if also else ""
        raise click.ClickException(
            f"--rrd {rrd}: the recording could need up to {size_text(need)}{beside} "
            f"({a.records} records of {a.record_s:g} s at {a.rate_hz:g} Hz) but {str(parent)!r} "
            f"has {size_text(free)} free: free some space, write elsewhere or take fewer or "
            "shorter records")


def live_sinks(live, connect, rrd, force, magnify, pacer) -> list:
    """The live view as a sink of ``acquire``, or [] without a live option. Its options are
    checked now; rerun (~1 s to import) is imported on a thread while the bench starts."""
    if not (live or connect or rrd):
        return []
    if rrd is not None:
        check_writable(rrd, force=force)
    if live and display_missing():
        raise click.ClickException(f"--live: {NO_DISPLAY}")
    if connect:
        check_viewer_url(connect)
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
              callback=image_path,
              help="Render the layout at the end of the run to an image, without a window: "
                   ".png, or .jpg/.jpeg (the format follows the extension).")
@click.option("--size", default="1600x900", show_default=True, metavar="WxH",
              help="Window size of --screenshot.")
@click.option("--magnify", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Factor on the angles in the bench drawing (the stage travel gets a sixth of it) [default 30].")
@force_option
def view(run, rrd, connect, screenshot_path, size, magnify, force):
    """Replay the run file RUN into rerun as the live view showed it: a spawned viewer by
    default, or --connect URL, --rrd FILE.rrd, --screenshot FILE.png (any combination). An
    interrupted run shows its finished records. A stepped-sine run file (daq sine) shows its
    points landing one by one over the exact model (and, with its records, the bench and the
    signals of each point)."""
    import tempfile

    from processing.live_view import (MAGNIFICATION, LiveViewError, ViewerOptions,
                                      ViewerStream, replay, screenshot)

    for p in (rrd, screenshot_path):
        if p is not None and p.resolve() == run.resolve():
            raise click.BadParameter(f"output {str(p)!r} is the run file: choose another path")
    if screenshot_path is not None:
        check_writable(screenshot_path, force=force)
    spawn = not (rrd or connect or screenshot_path)
    if spawn and display_missing():
        raise click.ClickException(f"{NO_DISPLAY}, or render a picture with --screenshot "
                                   "FILE.png")
    if connect:
        check_viewer_url(connect)
    from daq.sine_file import is_sine_file

    sine = is_sine_file(run)
    with tempfile.TemporaryDirectory() as tmp:
        target = rrd if rrd is not None or screenshot_path is None else Path(tmp) / "view.rrd"
        stream = ViewerStream(ViewerOptions(spawn=spawn, connect=connect, rrd=target,
                                            force=force))
        if sine:  # a stepped- or swept-sine run file (daq sine)
            from processing.live_view import replay_sine

            v = replay_sine(run, stream, magnification=magnify or MAGNIFICATION)
        else:
            v = replay(run, stream, magnification=magnify or MAGNIFICATION)
        if (spawn or connect) and (stream.url is None or stream.viewer_lost):
            raise click.ClickException(f"the replay of {run} did not reach a viewer (the "
                                       "warning above says why); --rrd FILE.rrd saves it")
        if sine:
            kept = "with" if v.records_kept else "without"
            click.echo(f"replayed {v.points} points of the {v.mode} sine {run} ({v.status}; "
                       f"{kept} records)")
        else:
            click.echo(f"replayed {v.footer.records_complete} of {v.header.plan.records} "
                       f"records of {run} ({v.footer.status})")
        if rrd is not None:
            click.echo(f"wrote {rrd} (rerun recording)")
        if screenshot_path is not None:
            try:
                screenshot(target, screenshot_path, size=size, force=force)
            except LiveViewError as exc:
                raise click.ClickException(str(exc)) from None
            click.echo(f"wrote {screenshot_path}")
