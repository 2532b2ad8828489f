"""The ``daq`` command line: a thin click layer over the library API.

Library errors (:class:`rig.errors.RigError`) become click errors here and only here.
"""

from __future__ import annotations

import csv
import functools
import json
import sys
from pathlib import Path

import click
import numpy as np

from daq.files import atomic_output, check_writable
from rig.errors import RigError


def _library_errors(fn):
    """Turn library errors into a clean ``Error: ...`` message and exit status 1."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except RigError as exc:
            raise click.ClickException(str(exc)) from None

    return wrapper


def _set_option(fn):
    return click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                        help="Override a scene value, e.g. --set pendulum.q1=300 (repeatable).")(fn)


def _force_option(fn):
    return click.option("--force", is_flag=True, help="Overwrite existing output files.")(fn)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pendulum-daq")
def main():
    """pendulum-daq: an emulated vibration-measurement rig (pendulum, bench, DAQ, analyzer)."""


# -- scenes ----------------------------------------------------------------------------------

@main.group()
def scene():
    """Built-in and file scenes."""


@scene.command("list")
def scene_list():
    """List the built-in scene presets."""
    from rig.scene import load_scene, preset_names

    for name in preset_names():
        click.echo(f"{name:16s} {load_scene(name).description}")


@scene.command("show")
@click.argument("scene_name", metavar="SCENE")
@_set_option
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@_library_errors
def scene_show(scene_name, overrides, as_json):
    """Show SCENE fully resolved: every physical parameter in SI units, the derived design
    parameters and the natural frequencies."""
    from rig.summary import scene_summary

    from rig.scene import load_scene

    summary = scene_summary(load_scene(scene_name, overrides))
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(_format_summary(summary))


def _format_summary(s: dict, indent: int = 0) -> str:
    lines = []
    pad = "  " * indent
    for k, v in s.items():
        if isinstance(v, dict):
            lines.append(f"{pad}{k}:")
            lines.append(_format_summary(v, indent + 1))
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            lines.append(f"{pad}{k}:")
            for item in v:
                lines.append(f"{pad}  - " + ", ".join(f"{a}={_fmt(b)}" for a, b in item.items()))
        else:
            lines.append(f"{pad}{k}: {_fmt(v)}")
    return "\n".join(lines)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


# -- analytic model --------------------------------------------------------------------------

@main.command()
@click.argument("scene_name", metavar="SCENE")
@_set_option
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the Bode data as CSV.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write gain/phase diagrams (PNG) like the paper's Figs. 9 and 10.")
@click.option("--fmin", default=0.1, show_default=True, type=float, help="Lowest frequency [Hz].")
@click.option("--fmax", default=10.0, show_default=True, type=float, help="Highest frequency [Hz].")
@click.option("--points", default=1000, show_default=True, type=click.IntRange(min=2),
              help="Number of log-spaced frequencies.")
@_force_option
@_library_errors
def model(scene_name, overrides, csv_path, plot_path, fmin, fmax, points, force):
    """Analytic Bode data of SCENE (exact linear model, direct complex solve).

    x is the mirror translation relative to the stage [m per m/s^2], y the mirror rotation [rad
    per m/s^2] (SPEC section 5).
    """
    from rig.response import gain_db, log_grid, mirror_response, phase_deg
    from rig.scene import load_scene

    sc = load_scene(scene_name, overrides)
    freqs = log_grid(fmin, fmax, points)
    for p in (csv_path, plot_path):
        if p is not None:
            check_writable(p, force=force)
    resp = mirror_response(sc, freqs)
    if csv_path is not None:
        with atomic_output(csv_path, force=force) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg",
                            "y_re", "y_im", "y_gain_db", "y_phase_deg"])
                cols = [freqs, resp.x.real, resp.x.imag, gain_db(resp.x), phase_deg(resp.x),
                        resp.y.real, resp.y.imag, gain_db(resp.y), phase_deg(resp.y)]
                for row in zip(*cols):
                    w.writerow([repr(float(v)) for v in row])
        click.echo(f"wrote {csv_path} ({points} frequencies, {fmin:g}-{fmax:g} Hz)")
    if plot_path is not None:
        from processing.plots import model_bode_figure

        fig = model_bode_figure(resp, title=f"{sc.name}: exact linear model")
        with atomic_output(plot_path, force=force) as tmp:
            fig.savefig(tmp, dpi=120, format="png")
        click.echo(f"wrote {plot_path}")
    from rig.summary import resonance_table

    click.echo(resonance_table(sc))


if __name__ == "__main__":
    sys.exit(main())
