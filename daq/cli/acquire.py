"""``daq acquire`` and ``daq inspect``: a run into a run file (and live sinks), and what a run
file holds."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from daq.cli.common import (fmt, force_option, model_lines, note_cold_kernels, repair_file,
                            run_check, set_option, size_text)
from daq.cli.live import live_options, live_sinks, rrd_preflight
from rig.model_info import ModelInfo
from rig.output_files import check_writable


# -- acquisition -----------------------------------------------------------------------------

class _ProgressBar:
    """``progress(simulated_s, total_s)`` for :func:`daq.acquisition.acquire` as a click bar on
    stderr (created on the first call, when the total is known), with the analyzer's averaging
    display: "settling" and then "average n of N" (records finished), and the time left."""

    def __init__(self, label: str, *, records: int = 0, record_s: float = 0.0,
                 settle_s: float = 0.0):
        self.label, self.bar, self.last = label, None, 0
        self.records, self.record_s, self.settle_s = records, record_s, settle_s
        self.done_s = 0.0

    def status(self, done_s: float) -> str:
        """What the display shows after ``done_s`` simulated seconds."""
        if self.records <= 0 or self.record_s <= 0:
            return ""
        if done_s < self.settle_s:
            return f"settling, average 0 of {self.records}"
        n = min(self.records, int((done_s - self.settle_s + 1e-9) // self.record_s))
        return f"average {n} of {self.records}"

    def __call__(self, done_s: float, total_s: float) -> None:
        self.done_s = done_s
        if self.bar is None:
            self.bar = click.progressbar(length=max(1, round(total_s * 1000)), file=sys.stderr,
                                         label=f"{self.label} ({total_s:g} s simulated)",
                                         show_eta=True,
                                         item_show_func=lambda _: self.status(self.done_s))
            self.bar.__enter__()
        n = round(done_s * 1000)
        self.bar.update(n - self.last, current_item=done_s)
        self.last = n

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


@click.command()
@click.argument("scene_arg", metavar="SCENE", required=False)
@click.option("--scene", "scene_name", metavar="SCENE",
              help="The same as the SCENE argument (preset name or scene TOML file).")
@click.option("--records", type=int, help="Number of records (acquisition.records).")
@click.option("--duration", type=float, help="Seconds per record (acquisition.record_s).")
@click.option("--rate", type=float, help="Sample rate of every channel [Hz] (acquisition.rate_hz).")
@click.option("--seed", type=click.IntRange(0, 2 ** 63 - 1),
              help="Seed of the run (default: a fresh random one, printed and stored).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="HDF5 run file to write (optional with a live option).")
@set_option
@force_option
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@live_options
@click.option("--realtime", is_flag=True,
              help="Pace the run to the wall clock like the real bench (default: as fast as "
                   "it can).")
@click.option("--speed", type=float, default=None, metavar="K",
              help="With --realtime: K times real time (default 1).")
@click.option("--allow-over-budget", is_flag=True,
              help="Exit 0 even if the run's estimated error exceeds its error budget or a "
                   "channel clipped or saturated (otherwise a WARNING and exit status 3).")
def acquire(scene_arg, scene_name, records, duration, rate, seed, out, overrides, force, quiet,
            live, connect, rrd, magnify, realtime, speed, allow_over_budget):
    """Acquire records of SCENE's bench into an HDF5 run file.

    --records, --duration and --rate override the scene's acquisition.records, .record_s and
    .rate_hz (after any --set). The file is written record by record and can be followed while
    it grows; Ctrl-C keeps every finished record (status "interrupted").
    """
    import secrets

    import signal

    from daq.acquisition import AcquisitionInterrupted
    from daq.acquisition import acquire as run_acquisition
    from daq.hdf5 import Hdf5Sink
    from daq.signals import stop_signals_interrupt
    from rig.scene import load_scene

    if scene_arg is not None and scene_name is not None and scene_arg != scene_name:
        raise click.UsageError(f"two scenes given: {scene_arg!r} and --scene {scene_name!r}; "
                               "give one (the SCENE argument, or --scene)")
    scene_name = scene_arg if scene_arg is not None else scene_name
    if scene_name is None:
        raise click.UsageError("missing the scene: daq acquire SCENE ... (a preset name or a "
                               "scene TOML file; see daq scene list)")
    extra = [f"acquisition.{key}={value!r}" for key, value in
             (("records", records), ("record_s", duration), ("rate_hz", rate))
             if value is not None]
    if out is None and not (live or connect or rrd):
        raise click.UsageError("give --out RUN.h5 and/or a live option (--live, --connect URL, "
                               "--rrd FILE.rrd)")
    if speed is not None and not realtime:
        raise click.UsageError(f"--speed {speed:g} needs --realtime")
    if out is not None and rrd is not None and out.resolve() == rrd.resolve():
        raise click.BadParameter(f"--rrd {str(rrd)!r} is the run file: choose another path")
    sc = load_scene(scene_name, [*overrides, *extra])
    if seed is None:
        seed = secrets.randbits(63)
    pacer = None
    if realtime:
        from daq.pacing import Pacer

        pacer = Pacer(1.0 if speed is None else speed)
    if rrd is not None:
        check_writable(rrd, force=force)
        rrd_preflight(rrd, sc, out)
    sinks = live_sinks(live, connect, rrd, force, magnify, pacer)
    if pacer is not None and not sinks:
        from daq.pacing import PacingSink

        sinks = [PacingSink(pacer)]
    a = sc.acquisition
    note_cold_kernels()
    bar = None if quiet else _ProgressBar(f"acquiring {sc.name}", records=a.records,
                                          record_s=a.record_s, settle_s=a.settle_s)
    try:
        with stop_signals_interrupt():  # SIGTERM, SIGHUP end the run like Ctrl-C
            files = [] if out is None else [Hdf5Sink(out, force=force)]  # the file first
            summary = run_acquisition(sc, seed=seed, progress=bar, sinks=[*files, *sinks])
    except AcquisitionInterrupted as exc:
        if bar is not None:
            bar.close()
        s = exc.summary
        by = s.message.split()[0] if s.message.startswith("SIG") else "SIGINT"
        kept = [f"{s.path} holds them (status interrupted)"] if s.path else []
        kept += [f"{k.path} holds the live view of them (rerun recording)" for k in sinks
                 if getattr(k, "path", None) is not None and Path(k.path).exists()]
        where = "; ".join(kept) or "no file was kept"
        click.echo(f"interrupted ({by}) after {s.records} of {s.records_planned} records; "
                   f"{where}", err=True)
        raise click.exceptions.Exit(128 + signal.Signals[by]) from None
    except Exception as exc:
        from daq.resources import is_disk_full

        s = getattr(exc, "acquisition_summary", None)
        if s is None or not is_disk_full(exc):
            raise
        raise click.ClickException(_disk_full_line(s)) from None
    finally:
        if bar is not None:
            bar.close()
    click.echo(_acquire_summary(summary))
    for sink in sinks:
        if getattr(sink, "path", None) is not None:
            click.echo(f"wrote {sink.path} (rerun recording)")
    warnings = _not_as_asked(summary)
    for w in warnings:
        click.echo(f"WARNING: {w}", err=True)
    if warnings and not allow_over_budget:
        from daq.cli.errors import EXIT_NOT_AS_ASKED

        raise click.exceptions.Exit(EXIT_NOT_AS_ASKED)


def _not_as_asked(s) -> list[str]:
    """Why a finished run is not what was asked: over its error budget, or saturated."""
    from daq.cli.errors import SATURATION_LIMIT

    out = []
    info = s.model_info
    if info.budget_met is False:
        est = info.error_estimate
        est = est.get("relative_rms_theta") if isinstance(est, dict) else est
        out.append(f"the run's estimated error {fmt(est)} (relative RMS of the angles) exceeds "
                   f"its error budget {fmt(info.error_budget)} (acquisition."
                   "error_budget): the data are not as accurate as asked")
    n = max(1, s.records * s.samples_per_record)
    for what, totals in (("clipped by the ADC", s.clip_totals()),
                         ("beyond its sensor's range", s.saturation_totals())):
        for c, k in totals.items():
            if k > SATURATION_LIMIT * n:
                out.append(f"channel {c}: {k} of {n} samples ({100 * k / n:.3g} %) {what}, "
                           f"more than {100 * SATURATION_LIMIT:g} %: lower the drive "
                           "(source.level_vrms) or widen the range")
    return out


def _disk_full_line(s) -> str:
    """One line for a run ended by a full disk: the partial file and what it holds."""
    from daq.check import check_file

    if s.path is None or not s.path.exists():
        return (f"disk full after {s.records} of {s.records_planned} records; no file was kept")
    fc = check_file(s.path)
    held = (f"{fc.records_valid} finished records of {s.records_planned}, each verified"
            if fc.kind == "run" else f"no readable record ({fc.status})")
    repair = (f", then 'daq inspect --repair {s.path}' makes it plainly openable"
              if any("marked open for writing" in n for n in fc.notes) else "")
    return (f"disk full after {s.records} of {s.records_planned} records: {s.path} holds "
            f"{held} (status {fc.status}); free some space{repair}")


def _acquire_summary(s) -> str:
    clips = ", ".join(f"{c} {n}" for c, n in s.clip_totals().items())
    sats = ", ".join(f"{c} {n}" for c, n in s.saturation_totals().items())
    return "\n".join([
        f"{'wrote ' + str(s.path) if s.path else 'no run file'} ({size_text(s.file_bytes)}): "
        f"{s.records} records x {s.samples_per_record} "
        f"samples at {s.rate_hz:g} Hz ({s.samples} samples per channel), channels "
        f"{', '.join(s.channels)}",
        f"seed: {s.seed}",
        f"clipped samples: {clips}",
        f"samples whose sensor saturated: {sats}",
        *model_lines(s.model_info),
        f"wall time: {s.wall_s:.2f} s",
    ])


@click.command()
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--repair", is_flag=True,
              help="Clear the 'open for writing' mark a killed writer left in the file (like "
                   "h5clear -s) so that any HDF5 reader opens it, and mark the run interrupted "
                   "(its records kept); never while the writer lives.")
def inspect(path, as_json, repair):
    """Show what the run file PATH holds: scene, seed, versions, status, channels, clipping,
    model."""
    from daq.hdf5 import run_info

    for line in repair_file(path) if repair else ():
        if not as_json:
            click.echo(line)
    fc = run_check(path, sine_ok=True)
    if fc.kind == "sine":  # a stepped-sine run file (daq sine)
        from daq.sine_file import sine_info

        info = sine_info(path)
        info["check"] = fc.to_dict()
        click.echo(json.dumps(info, indent=2) if as_json else _sine_text(info))
        if not fc.ok:
            raise click.exceptions.Exit(1)
        return
    info = run_info(path)
    info["check"] = fc.to_dict()
    if as_json:
        click.echo(json.dumps(info, indent=2))
    else:
        click.echo(_inspect_text(info))
    if not fc.ok:
        raise click.exceptions.Exit(1)


def _sine_text(i: dict) -> str:
    m = i["model"]
    band = (f"{i['fmin_hz']:.4g}-{i['fmax_hz']:.4g} Hz" if i["points"] else "no point")
    return "\n".join([
        f"{i['path']}: {i['file_format']} {i['file_format_version']}, written by pendulum-daq "
        f"{i.get('software_version', '?')}",
        f"scene: {i.get('scene_name', '?')}, seed {i.get('seed', '?')}, started "
        f"{i.get('start_time', '?')}",
        f"status: {i['status']}, {i.get('mode', 'stepped')} sine, {i['points']} points, "
        f"{band}, "
        f"{i['bench_s_accepted_points'] / 3600:.2f} h of bench time"
        + (" in the kept points" if i.get("mode", "stepped") == "stepped" else "")
        + (", time records kept" if i["records_kept"] else ""),
        f"model: {m.get('model')} ({m.get('reason', 'forced')})",
        f"check: {'OK' if i['check']['ok'] else 'BAD: ' + '; '.join(i['check']['problems'])}",
    ])


def _inspect_text(i: dict) -> str:
    n, planned = i["records_complete"], i["records_planned"]
    check = i.get("check")
    if check is not None and not check["ok"]:
        status = (f"{check['status'].upper()}: {check['records_valid']} of {planned} records "
                  f"verify; " + "; ".join(check["problems"]))
    elif i["complete"]:
        status = f"complete, {n} of {planned} records"
    else:
        why = {"acquiring": "writer killed or still running", "interrupted": "interrupted",
               "failed": "failed"}.get(i["status"], i["status"])
        status = f"INCOMPLETE ({why}), {n} of {planned} records"
        if i["message"]:
            status += f": {i['message']}"
    a, f = i["acquisition"], i["antialias"]
    lines = [
        f"{i['path']} ({size_text(i['file_bytes'])}): {i['file_format']} {i['file_format_version']}, "
        f"written by pendulum-daq {i['software_version']}",
        f"scene: {i['scene']} ({i['scene_source']}), seed {i['seed']}, started {i['start_time']}",
        f"status: {status}",
        f"sampling: {a['rate_hz']:g} Hz (simulated at {a['simulation_rate_hz']:g} Hz, decimation "
        f"{a['decimation']}), {a['samples_per_record']} samples per record ({a['record_s']:g} s), "
        f"settling {a['settle_s']:g} s",
        f"anti-alias: {f['kind']} order {f['order']}, passband {f['passband_hz']:g} Hz "
        f"({f['ripple_db']:g} dB ripple), >= {f['attenuation_db']:.1f} dB from "
        f"{f['stopband_hz']:g} Hz",
        "channels:",
    ]
    names = list(i["clip_counts"])
    for name, c in zip(names, i["channels"]):
        per = i["clip_counts"][name]
        hit = sum(1 for x in per if x)
        sat = i["saturation_counts"][name]
        lines.append(
            f"  {name}: {c['long_name']} -- {c['quantity']} [{c['engineering_unit']}], "
            f"{fmt(c['volts_per_unit'])} V per {c['engineering_unit']}, +-{fmt(c['range_v'])} V, "
            f"{c['bits']} bit (LSB {fmt(c['lsb_v'])} V), clipped {sum(per)} samples in {hit} "
            f"of {len(per)} records, sensor saturated in {sum(sat)} samples")
    lines.extend(model_lines(ModelInfo.from_dict(i["model_info"])))
    lines.append(f"model responses: {', '.join(i['responses'])}")
    lines.append(f"ground truth: {', '.join(i['truth']) if i['truth'] else 'not recorded'}")
    if i["writer_flag_set"]:
        lines.append("note: the file is still marked open for writing (writer running or "
                     "killed); SWMR readers open it, others after 'daq inspect --repair'")
    return "\n".join(lines)
