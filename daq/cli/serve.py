"""``daq serve``: the emulated bench and analyzer as a virtual Agilent 35670A on a raw SCPI
socket (:mod:`processing.instrument`)."""

from __future__ import annotations

import sys

import click

from daq.cli.common import set_option

DEFAULT_ADDRESS = "127.0.0.1:5025"


def _address(value: str) -> tuple[str, int]:
    host, sep, port = value.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise click.BadParameter(f"{value!r} is not HOST:PORT (e.g. {DEFAULT_ADDRESS}; port 0 "
                                 "picks a free one)", param_hint="--scpi")
    return host.strip("[]"), int(port)


@click.command()
@click.argument("scene_name", metavar="SCENE")
@set_option
@click.option("--seed", type=click.IntRange(0, 2 ** 63 - 1),
              help="Seed of the first measurement; the n-th since the start uses seed + n - 1 "
                   "(default: a fresh random one, printed).")
@click.option("--scpi", "address", default=DEFAULT_ADDRESS, show_default=True,
              metavar="HOST:PORT", help="Where to listen (loopback unless you name another "
                                        "address; port 0: a free one).")
@click.option("--realtime", is_flag=True,
              help="Pace each measurement to the wall clock like the real bench (default: "
                   "as fast as it can; *OPC? returns when the averages are done).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False),
              help="Keep each measurement's run file in this directory.")
@click.option("--quiet", "-q", is_flag=True,
              help="Print only the resource string (no line per client and measurement).")
def serve(scene_name, overrides, seed, address, realtime, out_dir, quiet):
    """Serve SCENE's bench as a virtual 35670A on a raw SCPI socket until SIGINT or SIGTERM.

    Point VISA at the printed resource (TCPIP::HOST::PORT::SOCKET, '\\n' terminations). Each
    INIT is an acquisition and an analysis of this project (in INST:SEL SINE a stepped-sine
    sweep); the equivalent 'daq acquire' and 'daq analyze' (or 'daq sine') commands are printed
    for every measurement.
    """
    import secrets
    import signal

    from daq.signals import Stopped, stop_signals_interrupt
    from processing.instrument.analyzer35670a import Analyzer35670A
    from processing.instrument.measurement import equivalent_commands
    from processing.instrument.server import ScpiServer
    from rig.scene import load_scene

    host, port = _address(address)
    scene = load_scene(scene_name, list(overrides))
    if seed is None:
        seed = secrets.randbits(63)

    def log(line):
        if not quiet:
            click.echo(line, err=True)

    def describe(setup, s):
        return equivalent_commands(scene_name, overrides, s, setup, scene)

    instrument = Analyzer35670A(scene, seed=seed, realtime=realtime, out_dir=out_dir, log=log,
                                describe=describe)
    try:
        server = ScpiServer(instrument, host, port, log=log)
    except OSError as exc:
        raise click.ClickException(f"cannot listen on {host}:{port}: "
                                   f"{exc.strerror or exc}") from None
    click.echo(f"virtual 35670A ({scene.name}, seed {seed}"
               f"{', real time' if realtime else ''}) at {server.resource}")
    sys.stdout.flush()
    try:
        with stop_signals_interrupt():  # SIGTERM, SIGHUP end it like Ctrl-C
            server.serve_forever()
    except KeyboardInterrupt as exc:
        name = exc.name if isinstance(exc, Stopped) else "SIGINT"
        instrument.abort()
        server.close()
        click.echo(f"stopped ({name}) after {instrument.measurements} measurement"
                   f"{'s' if instrument.measurements != 1 else ''} for "
                   f"{server.clients_served} client{'s' if server.clients_served != 1 else ''}",
                   err=True)
        raise click.exceptions.Exit(128 + signal.Signals[name]) from None
    finally:
        server.close()
