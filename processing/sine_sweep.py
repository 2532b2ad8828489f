"""The stepped-sine measurement: plan, settle, integrate, analyse, point after point.

:func:`measure_sine` ``(scene, settings, seed, sinks=())`` runs a sweep as the 35670A's
swept-sine mode does (SPEC section 6), on the emulated bench through the acquisition chain of
every run (:class:`daq.sine.SineAcquisition`), and returns a :class:`SineSweep` of
:class:`processing.sine.SinePointResult` s, each with the exact truth beside it.

Per point (:class:`SineSettings`):

- **frequency**: a log or linear grid of ``points`` from ``fmin_hz`` to ``fmax_hz`` (up or
  down); each placed where its window holds whole cycles in whole output samples
  (:func:`rig.devices.stepped_sine.whole_cycle_frequency`). With ``auto_resolution = (dB, deg)``
  the grid's step is the largest; a point whose H_t or Theta_2 differs from the previous point's
  by more than that much gain or phase is discarded (the bench ran it: its time counts) and the
  step halved, down to ``min_step_hz``; after a point that changed by less than half of both,
  the step doubles again, up to the grid's (``SENS:FREQ:RES:AUTO``).
- **settle**: ``settle_cycles`` or ``settle_s`` if given; otherwise the settle rule from the
  bench's poles (:func:`rig.bench.sine.settle_samples`: until every channel's transient bound
  is ``settle_tolerance`` of its steady amplitude), at most ``max_settle_s``.
- **integrate**: the window, at least ``integrate_cycles`` cycles and ``integrate_s`` seconds;
  with ``random_error_db`` the window is continued (a whole multiple of itself, the phase
  running on) until the random error of H_t and Theta_2 (1 sigma, dB) is at most that, or the
  window would exceed ``max_integrate_s``.
- **level**: ``level_vrms``, or with ``auto_level = (channel, target, tolerance)`` the level
  that brings the channel's fundamental [its unit] within ``tolerance`` (relative) of
  ``target``: a point whose reference missed is measured again at the level scaled by target /
  measured (capped at ``level_limit_vrms``), up to ``auto_level_tries`` times in all, and the
  next point starts at the level that held (the 35670A's ``SOUR:VOLT:AUTO``).

``mode = "swept"`` sweeps continuously instead (:mod:`processing.swept_sine`: the rule's rate
from the poles, ``sweep_tolerance``, or a chirp of ``sweep_s``; auto level as a profile from the
model; no auto resolution).

Sinks receive ``start(info)`` (settings, seed, model, channels, filter, scene, the row's
columns), ``point(row, record)`` (:func:`processing.sine.point_row` and the
:class:`daq.sine.PointRecord`) for every accepted point and ``stop(status)`` (the sine run file,
:class:`daq.sine_file.SineFileSink`, is one); each sink's ``check()``, if it has one, runs
before anything is simulated.

Public API: :class:`SineSettings`, :class:`SineSweep`, :func:`measure_sine`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rig.errors import ConfigError
from processing.sine import POINT_COLUMNS, SinePointResult, analyze_point, point_row

CHANNELS = ("a", "x", "y")


@dataclass(frozen=True)
class SineSettings:
    """A sine sweep, stepped or swept (``mode``; module docstring). Frequencies [Hz], times
    [s], levels [V rms]; ``sweep_tolerance`` [1], ``sweep_s`` and ``max_sweep_s`` [s] apply to
    the swept mode."""

    fmin_hz: float = 0.1
    fmax_hz: float = 10.0
    points: int = 101
    spacing: str = "log"
    direction: str = "up"
    auto_resolution: tuple | None = None
    min_step_hz: float = 0.0005
    settle_cycles: float | None = None
    settle_s: float | None = None
    settle_tolerance: float = 1e-3
    max_settle_s: float = 3600.0
    integrate_cycles: int = 20
    integrate_s: float = 10.0
    random_error_db: float | None = None
    max_integrate_s: float = 600.0
    level_vrms: float | None = None
    auto_level: tuple | None = None
    level_limit_vrms: float = 1.0
    auto_level_tries: int = 4
    harmonics: int = 5
    mode: str = "stepped"
    sweep_tolerance: float = 0.005
    sweep_s: float | None = None
    max_sweep_s: float = 2e6

    def __post_init__(self):
        def pos(name, lo=0.0, strict=True):
            v = getattr(self, name)
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) \
                and (v > lo if strict else v >= lo)
            if not ok:
                raise ConfigError(f"{name} = {v!r} is invalid: expected a finite number "
                                  f"{'>' if strict else '>='} {lo:g}")

        pos("fmin_hz")
        pos("fmax_hz")
        if not self.fmin_hz < self.fmax_hz:
            raise ConfigError(f"fmin_hz = {self.fmin_hz!r} is invalid: expected fmin_hz < "
                              f"fmax_hz = {self.fmax_hz!r}")
        if isinstance(self.points, bool) or not isinstance(self.points, int) or self.points < 2:
            raise ConfigError(f"points = {self.points!r} is invalid: expected an integer >= 2")
        if self.spacing not in ("log", "lin"):
            raise ConfigError(f"spacing = {self.spacing!r} is invalid: expected log or lin")
        if self.direction not in ("up", "down"):
            raise ConfigError(f"direction = {self.direction!r} is invalid: expected up or down")
        if self.auto_resolution is not None:
            ar = self.auto_resolution
            if not (isinstance(ar, tuple) and len(ar) == 2
                    and all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                            for v in ar)):
                raise ConfigError(f"auto_resolution = {ar!r} is invalid: expected two numbers "
                                  "> 0, the maximum change in dB and in degrees")
        pos("min_step_hz")
        for name in ("settle_cycles", "settle_s"):
            if getattr(self, name) is not None:
                pos(name, strict=False)
        pos("settle_tolerance")
        pos("max_settle_s")
        if isinstance(self.integrate_cycles, bool) or not isinstance(self.integrate_cycles, int) \
                or self.integrate_cycles < 1:
            raise ConfigError(f"integrate_cycles = {self.integrate_cycles!r} is invalid: "
                              "expected an integer >= 1")
        pos("integrate_s", strict=False)
        if self.random_error_db is not None:
            pos("random_error_db")
        pos("max_integrate_s")
        if self.level_vrms is not None:
            pos("level_vrms")
        pos("level_limit_vrms")
        if self.auto_level is not None:
            al = self.auto_level
            if not (isinstance(al, tuple) and len(al) == 3 and al[0] in CHANNELS
                    and all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                            for v in al[1:])):
                raise ConfigError(f"auto_level = {al!r} is invalid: expected (channel a|x|y, "
                                  "target > 0 in the channel's unit, relative tolerance > 0)")
        if isinstance(self.harmonics, bool) or not isinstance(self.harmonics, int) or \
                not 1 <= self.harmonics <= 20:
            raise ConfigError(f"harmonics = {self.harmonics!r} is invalid: expected an integer "
                              "1..20")
        if self.mode not in ("stepped", "swept"):
            raise ConfigError(f"mode = {self.mode!r} is invalid: expected stepped or swept")
        pos("sweep_tolerance")
        if self.sweep_s is not None:
            pos("sweep_s")
        pos("max_sweep_s")
        if self.mode == "swept":
            for name, what in (("auto_resolution", "auto resolution"),
                               ("random_error_db", "a random-error target")):
                if getattr(self, name) is not None:
                    raise ConfigError(f"{name} = {getattr(self, name)!r} is invalid in swept "
                                      f"mode: {what} is a stepped-sine option (the swept "
                                      "source cannot go back or stay); expected None")

    def grid(self) -> np.ndarray:
        """The nominal frequencies [Hz] in the sweep's order."""
        f = (np.geomspace if self.spacing == "log" else np.linspace)(self.fmin_hz,
                                                                      self.fmax_hz, self.points)
        return f if self.direction == "up" else f[::-1]


@dataclass(frozen=True, eq=False)
class SineSweep:
    """What a sweep produced: the accepted points in order, the discarded ones (auto
    resolution), the simulated bench time [s], the CPU time [s], the model info and status."""

    points: tuple
    discarded: tuple
    bench_s: float
    cpu_s: float
    model_info: dict
    status: str = "complete"
    settings: SineSettings = field(default_factory=SineSettings)
    warnings: tuple = ()

    def column(self, name: str) -> np.ndarray:
        """One attribute of every accepted point as an array."""
        return np.array([getattr(p, name) for p in self.points])


def _worst_frequency(scene, settings: SineSettings) -> float:
    """The grid frequency with the largest pendulum response per source volt (any body), found
    on a fine log grid that holds every mode within the band."""
    import rig

    f = np.geomspace(settings.fmin_hz, settings.fmax_hz, 4000)
    modes = np.asarray(scene.chain.modes()[0], float)
    f = np.sort(np.concatenate([f, modes[(modes >= settings.fmin_hz)
                                         & (modes <= settings.fmax_hz)]]))
    r = rig.expected_response(scene, f)
    return float(f[int(np.argmax(np.max(np.abs(r.theta), axis=1)))])


def _worst_level(scene, settings: SineSettings, level0: float, worst_hz: float) -> float:
    """The level the sweep drives at its worst point: the fixed level, or the auto level's
    (the target over the reference channel's exact response per volt there, capped)."""
    if settings.auto_level is None:
        return level0
    import rig

    ch, target, _ = settings.auto_level
    r = rig.expected_response(scene, [worst_hz])
    from rig.bench import calibrations

    per_volt = abs(getattr(r, ch)[0]) / abs(calibrations(scene)[ch].volts_per_unit)
    if not per_volt > 0:
        return settings.level_limit_vrms
    return min(settings.level_limit_vrms, target / per_volt)


def _worst_duration(scene, settings: SineSettings, worst_hz: float) -> float:
    """How long the worst point is held [s] for the model choice: its settle (the fixed one,
    or 8 amplitude time constants of the slowest mode, at most ``max_settle_s``) and window."""
    rate = scene.acquisition.rate_hz
    if settings.settle_s is not None:
        settle = settings.settle_s
    elif settings.settle_cycles is not None:
        settle = settings.settle_cycles / worst_hz
    else:
        f, q = scene.chain.modes()
        with np.errstate(divide="ignore", invalid="ignore"):
            tau = np.where(np.isfinite(q), q / (np.pi * f), settings.max_settle_s)
        settle = min(settings.max_settle_s, 8 * float(np.max(tau, initial=0.0)))
    window = max(settings.integrate_s, settings.integrate_cycles / worst_hz)
    return math.ceil((settle + window) * rate) / rate


def _settle(settings, acq, point, error, rate) -> int:
    from rig.bench.sine import settle_samples

    if settings.settle_s is not None:
        return int(round(settings.settle_s * rate))
    if settings.settle_cycles is not None:
        return int(math.ceil(settings.settle_cycles * rate / point.frequency_hz))
    return settle_samples(acq.chain, error, point, settings.settle_tolerance, 0,
                          int(round(settings.max_settle_s * rate)))


def _point(settings, f, level, rate):
    from rig.devices.stepped_sine import SinePoint, whole_cycle_frequency

    fq, k, n = whole_cycle_frequency(f, rate, settings.integrate_cycles,
                                     int(math.ceil(settings.integrate_s * rate)))
    return SinePoint(frequency_hz=fq, level_vrms=float(level), settle_samples=0,
                     integrate_samples=n, cycles=k)


def _measured(settings, acq, point, e0, settling_bias):
    """Run ``point`` (state error ``e0`` at its start) and analyse it; with a random-error
    target, continue its window (whole multiples) until the target is met or the window
    reaches ``max_integrate_s``: ``(record, truth, result)``."""
    rate = acq.rate_hz
    rec = acq.point(point)
    while True:
        truth = settling_bias(acq.chain, e0, rec.point, rec.phase_cycles)
        res = analyze_point(rec, truth, acq.chain, acq.scene.lever, settings.harmonics)
        if settings.random_error_db is None:
            return rec, truth, res
        worst = max(res.error_db_deg("h_t")[0], res.error_db_deg("theta_2")[0])
        n = rec.point.integrate_samples
        room = int(settings.max_integrate_s * rate) // n
        if not worst > settings.random_error_db or room < 2:
            return rec, truth, res
        times = min(room, math.ceil(1.2 * (worst / settings.random_error_db) ** 2))
        rec = acq.extend(rec, max(times, 2))


def _change(a: SinePointResult, b: SinePointResult) -> tuple[float, float]:
    """Largest gain [dB] and phase [deg] change between two points over H_t and Theta_2."""
    db = deg = 0.0
    for name in ("h_t", "theta_2"):
        r = getattr(b, name) / getattr(a, name)
        db = max(db, abs(20 * math.log10(abs(r))))
        deg = max(deg, abs(math.degrees(math.atan2(r.imag, r.real))))
    return db, deg


def _next_level(settings: SineSettings, level: float, res: SinePointResult) -> float:
    if settings.auto_level is None:
        return level
    ch, target, tol = settings.auto_level
    got = abs(res.harmonics[CHANNELS.index(ch), 0])
    if not (math.isfinite(got) and got > 0):
        return min(level * 2, settings.level_limit_vrms)
    if abs(got / target - 1) <= tol:
        return level
    return min(level * target / got, settings.level_limit_vrms)


def measure_sine(scene, settings: SineSettings = SineSettings(), seed: int = 0, *,
                 sinks=(), progress=None) -> SineSweep:
    """Run a stepped-sine sweep of ``scene`` (module docstring); ``sinks`` receive every point
    as it is measured; ``progress(point_index, frequency_hz, bench_s)`` is called after each.

    Raises ConfigError for invalid settings or a scene whose chain cannot settle (before any
    point is run)."""
    from rig.threads import single_threaded_blas

    with single_threaded_blas():  # thin products: more threads only contend
        return _measure(scene, settings, seed, sinks, progress)


def _measure(scene, settings, seed, sinks, progress) -> SineSweep:
    """:func:`measure_sine` with one BLAS thread."""
    from daq.sine import SineAcquisition
    from rig.bench.sine import settling_bias, step_error

    if not isinstance(settings, SineSettings):
        raise ConfigError(f"settings = {settings!r} is invalid: expected a SineSettings")
    t_cpu = time.process_time()
    rate = scene.acquisition.rate_hz
    if settings.fmax_hz >= rate / 2:
        raise ConfigError(f"fmax_hz = {settings.fmax_hz!r} is invalid: expected < "
                          f"{rate / 2:g} Hz (half the output rate acquisition.rate_hz)")
    level0 = scene.source.level_vrms if settings.level_vrms is None else settings.level_vrms
    if level0 > settings.level_limit_vrms:
        raise ConfigError(f"level_vrms = {level0!r} is invalid: expected at most "
                          f"level_limit_vrms = {settings.level_limit_vrms!r} V")
    for s in sinks:
        if hasattr(s, "check"):
            s.check()
    worst = _worst_frequency(scene, settings)
    worst_level = _worst_level(scene, settings, level0, worst)
    acq = SineAcquisition(scene, seed, worst_hz=worst, level_vrms=worst_level,
                          duration_s=_worst_duration(scene, settings, worst),
                          fmax_hz=settings.fmax_hz)
    info = {"settings": _settings_dict(settings), "seed": int(seed), "worst_hz": worst,
            "model": acq.model_info, "channels": acq.channels, "antialias": acq.antialias,
            "scene": scene, "columns": POINT_COLUMNS, "harmonics": settings.harmonics,
            "mode": settings.mode}
    plan = None
    if settings.mode == "swept":
        from processing.swept_sine import run_swept, swept_plan

        # swept: the fixed level, or the auto level's profile along the sweep
        plan = swept_plan(settings, acq, level0)
        info["sweep_s"] = plan.duration_s
    for s in sinks:
        s.start(info)
    accepted, discarded = [], []
    status = "failed"
    try:
        if plan is None:
            _sweep(settings, acq, rate, level0, accepted, discarded, sinks, progress,
                   settling_bias, step_error)
        else:
            run_swept(plan, acq, accepted, sinks, progress)
        status = "complete"
    except KeyboardInterrupt:
        status = "interrupted"
        raise
    finally:
        for s in sinks:
            s.stop(status)
    bench_s = (sum(p.settle_s + p.integrate_s for p in accepted + discarded) if plan is None
               else plan.duration_s)
    return SineSweep(points=tuple(accepted), discarded=tuple(discarded), bench_s=bench_s,
                     cpu_s=time.process_time() - t_cpu, model_info=acq.model_info,
                     status=status, settings=settings,
                     warnings=() if plan is None else plan.warnings)


def _sweep(settings, acq, rate, level, accepted, discarded, sinks, progress, settling_bias,
           step_error):
    """The loop of :func:`measure_sine` (appends to ``accepted`` and ``discarded``)."""
    grid = settings.grid()
    up = settings.direction == "up"
    lever = acq.scene.lever
    error = np.zeros(acq.chain.a.shape[0])
    prev_point = None
    f, i_grid = grid[0], 0
    factor = 1.0  # the current step as a fraction of the grid's
    last, last_nominal = None, f
    tries = 1
    while True:
        point = _point(settings, f, level, rate)
        phase = acq.bench.source.phase_cycles
        e0 = step_error(acq.chain, error, prev_point, point, phase)
        point = dataclasses.replace(point, settle_samples=_settle(settings, acq, point, e0,
                                                                  rate))
        rec, truth, res = _measured(settings, acq, point, e0, settling_bias)
        error, prev_point = truth.error_end, rec.point
        new_level = _next_level(settings, level, res)
        if new_level != level and tries < settings.auto_level_tries:
            # the reference missed its target: the same frequency again at the new level
            discarded.append(res)
            level, tries = new_level, tries + 1
            continue
        tries = 1
        ok = True
        if settings.auto_resolution is not None and last is not None:
            db, deg = _change(last, res)
            max_db, max_deg = settings.auto_resolution
            step = abs(res.frequency_hz - last.frequency_hz)
            if (db > max_db or deg > max_deg) and step > 2 * settings.min_step_hz:
                ok = False
                factor /= 2
            elif db < max_db / 2 and deg < max_deg / 2:
                factor = min(1.0, factor * 2)
        if ok:
            accepted.append(res)
            for s in sinks:
                s.point(point_row(res), rec)
            last, last_nominal = res, f
        else:
            discarded.append(res)
        if progress is not None:
            progress(len(accepted), res.frequency_hz, rec.t0_s + point.samples / rate)
        if settings.auto_resolution is None:
            i_grid += 1
            if i_grid >= len(grid):
                return
            f = grid[i_grid]
            continue
        if last_nominal == grid[-1]:
            return
        f = _stepped(settings, last_nominal, factor, up)


def _stepped(settings: SineSettings, f: float, factor: float, up: bool) -> float:
    """The next frequency from ``f``: ``factor`` of the grid's step (log: of its ratio's
    exponent), at least ``min_step_hz``, never beyond the band's end."""
    n = settings.points - 1
    sign = 1 if up else -1
    if settings.spacing == "log":
        ratio = (settings.fmax_hz / settings.fmin_hz) ** (factor / n)
        nxt = f * ratio if up else f / ratio
    else:
        nxt = f + sign * factor * (settings.fmax_hz - settings.fmin_hz) / n
    if abs(nxt - f) < settings.min_step_hz:
        nxt = f + sign * settings.min_step_hz
    return min(nxt, settings.fmax_hz) if up else max(nxt, settings.fmin_hz)


def _settings_dict(settings: SineSettings) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v)
            for k, v in settings.__dict__.items()}
