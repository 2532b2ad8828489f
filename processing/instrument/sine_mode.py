"""The swept-sine mode (``INST:SEL SINE``, the 35670A's option 1D2): the instrument's swept-sine
settings in front of :func:`processing.sine_sweep.measure_sine`, the code behind ``daq sine``.

:class:`SineSetup` holds the settings as the instrument keeps them (a value and the unit it was
sent in); :func:`sine_settings` is the one translation into a
:class:`processing.sine_sweep.SineSettings` (programmer's reference, ``[SENSe:]FREQuency``,
``[SENSe:]SWEep`` and ``SOURce:VOLTage``):

- ``FREQ:STAR``/``STOP`` [Hz] -> ``fmin_hz``/``fmax_hz``; ``SWE:SPAC LIN|LOG``,
  ``SWE:DIR UP|DOWN`` -> ``spacing``, ``direction``;
- ``FREQ:RES`` n ``PNT/SWP`` (default unit; n points), ``PNT/DEC``, ``PNT/OCT`` (log), ``HZ``
  (lin: the step), ``PCT`` (the step in % of the span) -> ``points`` (rounded, at least 2);
- ``FREQ:RES:AUTO ON``: the grid of ``FREQ:RES:AUTO:MIN`` (same units; the sweep's first and
  largest step, as the reference describes it) with ``FREQ:RES:AUTO:MCH`` p % as the maximum
  change between neighbouring points: a ratio within p % of 1 changes the gain by at most
  ``20 log10(1 + p/100)`` dB and the phase by at most ``asin(p/100)`` -> ``auto_resolution``;
  the smallest step is the library's ``min_step_hz`` (the instrument has no command for it);
- ``SWE:STIM`` t ``S`` | k ``CYCLE`` -> ``settle_s`` | ``settle_cycles`` (a number without a
  unit is seconds; at most :data:`MAX_SETTLE_S` per point);
- ``SWE:DWEL`` t ``S`` | k ``CYCLE`` -> ``integrate_s`` (and 1 cycle) | ``integrate_cycles``
  (rounded up to whole cycles, as the window holds whole cycles); windows are not continued;
- ``SOUR:VOLT`` [V rms] -> ``level_vrms``; ``SOUR:VOLT:AUTO ON`` with ``REF:CHAN INP1|2|3``
  (a, x, y), ``REF`` (the input's fundamental, peak: VPK or V, VRMS, DBVPK, DBVRMS or DBV
  through the sensor's calibration, EU or DBEU in its engineering unit) and ``REF:TOL`` d dB
  (relative ``1 - 10^(-d/20)``) -> ``auto_level``; ``SOUR:VOLT:LIM`` -> ``level_limit_vrms``.

Defaults (``*RST``): the instrument's swept-sine preset (101 points linear, up, auto resolution
off with 2 % and 401 points, settle and integrate 5 cycles, autolevel off holding input 2 at
2 Vpk within 2 dB, limit 2 Vpk) over the bench's band 0.1-10 Hz (the preset's 102.4 kHz is
beyond it). :class:`SineMode` refuses (``-221``) the source off, input autorange, a stop at or
above half the bench's sample rate, a resolution unit the spacing has no meaning for, and a
level above the limit. :class:`SineResult` gives the traces at the accepted points in
ascending frequency: ratios and powers of the channels' fundamentals (H_t and Theta_2 as
measured), the coherence-like ``XFR:POW:COH m,n`` as the product of the two channels'
fundamental shares of their power.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from processing.instrument.measurement_mode import Aborted, ModeConflict, RunControl
from processing.instrument.status import OPER_MEASURING, OPER_SWEEPING

__all__ = ["SineSetup", "SineMode", "SineResult", "sine_settings", "bench_overrides",
           "equivalent_commands", "planned_points", "max_change", "INPUTS", "MAX_SETTLE_S"]

#: Inputs 1..3 -> the bench's channels (input 4, the drive, cannot hold a level).
INPUTS = {1: "a", 2: "x", 3: "y"}
#: The longest settle per point the emulator runs [s] (the library's ``max_settle_s``).
MAX_SETTLE_S = 3600.0
_SQRT2 = math.sqrt(2.0)
_DRIVE = ("input 4 (the source drive) is not measured in the swept-sine mode: its traces are "
          "inputs 1-3")


@dataclass(frozen=True)
class SineSetup:
    """The swept-sine settings (module docstring): frequencies [Hz], levels [V rms], value-unit
    pairs as sent; ``level_vrms``, ``output``, ``ranges_v`` and ``autorange`` are the source's and
    the inputs' (shared with the FFT mode, filled in at ``INIT``)."""

    start_hz: float = 0.1
    stop_hz: float = 10.0
    resolution: tuple = (101.0, "PNT/SWP")
    auto_resolution: bool = False
    max_change_pct: float = 2.0
    auto_minimum: tuple = (401.0, "PNT/SWP")
    spacing: str = "LIN"
    direction: str = "UP"
    settle: tuple = (5.0, "CYCLE")
    dwell: tuple = (5.0, "CYCLE")
    auto_level: bool = False
    reference: tuple = (2.0, "VPK")
    reference_input: int = 2
    tolerance_db: float = 2.0
    limit_vrms: float = 2.0 / _SQRT2
    level_vrms: float = 0.1
    output: bool = False
    ranges_v: tuple = (1.0, 10.0, 10.0)
    autorange: tuple = (False, False, False)


def max_change(pct: float) -> tuple[float, float]:
    """``FREQ:RES:AUTO:MCH`` p % as the library's ``(dB, deg)`` maximum change."""
    p = pct / 100.0
    return 20.0 * math.log10(1.0 + p), math.degrees(math.asin(min(p, 1.0)))


def _points(setup: SineSetup, value_unit: tuple) -> int:
    v, unit = value_unit
    lo, hi = setup.start_hz, setup.stop_hz
    log = setup.spacing == "LOG"
    if unit in ("PNT/DEC", "PNT/OCT") and not log or unit == "HZ" and log:
        raise ModeConflict(f"a resolution in {unit} has no meaning with SWE:SPAC "
                           f"{setup.spacing} (LIN: HZ, PNT/SWP, PCT; LOG: PNT/SWP, PNT/DEC, "
                           "PNT/OCT, PCT)")
    n = {"PNT/SWP": lambda: v, "PCT": lambda: 100.0 / v + 1,
         "HZ": lambda: (hi - lo) / v + 1,
         "PNT/DEC": lambda: v * math.log10(hi / lo) + 1,
         "PNT/OCT": lambda: v * math.log2(hi / lo) + 1}[unit]()
    return max(2, int(round(n)))


def planned_points(setup: SineSetup) -> int | None:
    """The fixed grid's points (``FREQ:RES``), or None with auto resolution (known after)."""
    return None if setup.auto_resolution else _points(setup, setup.resolution)


def _reference_eu(setup: SineSetup, volts_per_unit: float) -> float:
    """``SOUR:VOLT:REF`` as the reference input's fundamental amplitude (peak) in its unit."""
    v, unit = setup.reference
    if unit in ("EU", "DBEU"):
        return v if unit == "EU" else 10.0 ** (v / 20.0)
    peak_v = {"VPK": v, "V": v, "VRMS": v * _SQRT2, "DBVPK": 10.0 ** (v / 20.0),
              "DBVRMS": 10.0 ** (v / 20.0) * _SQRT2, "DBV": 10.0 ** (v / 20.0) * _SQRT2}[unit]
    return peak_v / abs(volts_per_unit)


def sine_settings(scene, setup: SineSetup):
    """The :class:`processing.sine_sweep.SineSettings` of ``setup`` on ``scene``'s sensors
    (module docstring); :class:`ModeConflict` for settings the library refuses."""
    from processing.sine_sweep import SineSettings
    from rig.bench import calibrations
    from rig.errors import RigError

    grid = _points(setup, setup.auto_minimum if setup.auto_resolution else setup.resolution)
    settle, unit = setup.settle
    dwell, dunit = setup.dwell
    auto_level = None
    if setup.auto_level:
        ch = INPUTS[setup.reference_input]
        target = _reference_eu(setup, calibrations(scene)[ch].volts_per_unit)
        auto_level = (ch, target, 1.0 - 10.0 ** (-setup.tolerance_db / 20.0))
    try:
        return SineSettings(
            fmin_hz=setup.start_hz, fmax_hz=setup.stop_hz, points=grid,
            spacing=setup.spacing.lower(), direction=setup.direction.lower(),
            auto_resolution=max_change(setup.max_change_pct) if setup.auto_resolution else None,
            settle_s=settle if unit == "S" else None,
            settle_cycles=settle if unit == "CYCLE" else None,
            integrate_cycles=max(1, math.ceil(dwell - 1e-9)) if dunit == "CYCLE" else 1,
            integrate_s=dwell if dunit == "S" else 0.0, random_error_db=None,
            level_vrms=setup.level_vrms, auto_level=auto_level,
            level_limit_vrms=setup.limit_vrms)
    except RigError as exc:
        raise ModeConflict(str(exc)) from None


def bench_overrides(setup: SineSetup) -> list[str]:
    """The scene overrides (``daq sine --set``) that make the bench these inputs."""
    return [f"acquisition.range_{c}_v={r!r}" for c, r in zip("axy", setup.ranges_v)]


def equivalent_commands(scene_arg: str, base_overrides, seed: int, setup: SineSetup,
                        scene) -> str:
    """The ``daq sine`` command line that measures the same numbers."""
    s = sine_settings(scene, setup)
    sets = " ".join(f"--set {o}" for o in [*base_overrides, *bench_overrides(setup)])
    opts = [f"--fmin {s.fmin_hz!r} --fmax {s.fmax_hz!r} --points {s.points} --spacing "
            f"{s.spacing} --direction {s.direction}"]
    if s.auto_resolution is not None:
        opts.append(f"--auto-resolution {s.auto_resolution[0]!r},{s.auto_resolution[1]!r} "
                    f"--min-step {s.min_step_hz!r}")
    opts.append(f"--settle-s {s.settle_s!r}" if s.settle_s is not None
                else f"--settle-cycles {s.settle_cycles!r}")
    opts.append(f"--integrate-cycles {s.integrate_cycles} --integrate-s {s.integrate_s!r} "
                "--random-error 0")
    if s.auto_level is not None:
        ch, target, tol = s.auto_level
        opts.append(f"--auto-level {ch},{target!r},{tol!r}")
    else:
        opts.append(f"--level {s.level_vrms!r}")
    opts.append(f"--level-limit {s.level_limit_vrms!r} --harmonics {s.harmonics}")
    return f"daq sine {scene_arg} --seed {seed} {sets} {' '.join(opts)} --out sweep.h5"


@dataclass(frozen=True)
class SineResponse:
    """A ratio trace: ``h`` (complex, per point) and its ``coherence`` (module docstring)."""

    h: np.ndarray
    coherence: np.ndarray


@dataclass(frozen=True, eq=False)
class SineResult:
    """One swept-sine measurement: the setup, the :class:`processing.sine_sweep.SineSweep`, the
    seed and inputs 1..3's calibrations (``{n: (signed V per EU, unit)}``)."""

    setup: SineSetup
    sweep: object
    seed: int
    calibration: dict

    @property
    def points(self) -> tuple:
        """The accepted points in ascending frequency."""
        pts = self.sweep.points
        return tuple(pts[i] for i in np.argsort([p.frequency_hz for p in pts], kind="stable"))

    @property
    def freqs_hz(self) -> np.ndarray:
        return np.array([p.frequency_hz for p in self.points], dtype=float)

    @property
    def times_s(self) -> np.ndarray:
        raise ModeConflict("a swept-sine measurement has no time record (XTIM feeds are the "
                           "FFT mode's)")

    def time_record(self, ch: int) -> np.ndarray:
        return self.times_s

    def _input(self, ch: int) -> int:
        if ch not in INPUTS:
            raise ModeConflict(_DRIVE)
        return ch - 1

    def volts_per_unit(self, ch: int) -> float:
        self._input(ch)
        return float(self.calibration[ch][0])

    def unit(self, ch: int) -> str:
        self._input(ch)
        return self.calibration[ch][1]

    def fundamental(self, ch: int) -> np.ndarray:
        """Input ``ch``'s fundamental at every point, complex peak amplitude [EU]."""
        i = self._input(ch)
        return np.array([p.harmonics[i, 0] for p in self.points], dtype=complex)

    def frf(self, out: int, inp: int) -> SineResponse:
        """``out / inp`` of the fundamentals: H_t (2,1) and Theta_2 (3,1) as measured."""
        i, j = self._input(out), self._input(inp)
        pts = self.points
        if (out, inp) in ((2, 1), (3, 1)):
            h = np.array([p.h_t if out == 2 else p.theta_2 for p in pts], dtype=complex)
        else:
            h = self.fundamental(out) / self.fundamental(inp)
        share = np.array([p.fundamental_ratio for p in pts], dtype=float).reshape(-1, 3)
        return SineResponse(h, share[:, i] * share[:, j])

    def cross(self, m: int, n: int, scaling: str) -> np.ndarray:
        """``conj(X_m) X_n / 2`` of the fundamentals [EU^2] (the power of a sine)."""
        if scaling == "density":
            raise ModeConflict("a swept-sine measurement has no spectral density: use "
                               "CALC:UNIT:VOLT V2 or V")
        return np.conj(self.fundamental(m)) * self.fundamental(n) / 2.0


class _SweepClock:
    """Starts a paced sweep's wall clock as its first point starts (a sweep sink)."""

    def __init__(self, pacer):
        self.pacer = pacer

    def start(self, info) -> None:
        self.pacer.wait(0.0)

    def point(self, row, record) -> None:
        return None

    def stop(self, status) -> None:
        return None


class SineMode:
    """The swept-sine mode: :func:`processing.sine_sweep.measure_sine` of ``sine_settings``."""

    name = "SINE"

    def check(self, scene, setup: SineSetup) -> None:
        if not setup.output:
            raise ModeConflict("the source is off: a swept-sine measurement drives the bench "
                               "(OUTP ON)")
        auto = [n for n, on in enumerate(setup.autorange, 1) if on]
        if auto:
            raise ModeConflict(f"input autorange (VOLT{auto[0]}:RANG:AUTO ON) is not emulated "
                               "in the swept-sine mode: set the input's range")
        if not setup.start_hz < setup.stop_hz:
            raise ModeConflict(f"start {setup.start_hz:g} Hz is not below stop "
                               f"{setup.stop_hz:g} Hz (FREQ:STAR, FREQ:STOP)")
        rate = float(scene.acquisition.rate_hz)
        if setup.stop_hz >= rate / 2:
            raise ModeConflict(f"stop {setup.stop_hz:g} Hz: the bench samples at {rate:g} Hz "
                               f"(acquisition.rate_hz), so a sweep ends below {rate / 2:g} Hz")
        settle, unit = setup.settle
        longest = settle if unit == "S" else settle / setup.start_hz
        if longest > MAX_SETTLE_S:
            raise ModeConflict(f"a settle time of {longest:g} s per point: the emulator settles "
                               f"at most {MAX_SETTLE_S:g} s (SWE:STIM)")
        if setup.level_vrms > setup.limit_vrms:
            raise ModeConflict(f"source level {setup.level_vrms:g} V rms is above the autolevel "
                               f"limit {setup.limit_vrms:g} V rms (SOUR:VOLT:LIM)")
        sine_settings(scene, setup)

    def run(self, scene, setup: SineSetup, *, seed: int,
            control: RunControl = RunControl()) -> SineResult:
        from processing.sine_sweep import measure_sine
        from rig.bench import calibrations
        from rig.errors import RigError
        from rig.scene import load_scene

        self.check(scene, setup)
        sinks, pacer = [], None
        if control.realtime:
            from daq.pacing import Pacer

            pacer = Pacer(1.0, sleep=control.abort.wait)  # ABOR wakes it
            sinks.append(_SweepClock(pacer))

        def progress(n, frequency_hz, bench_s):  # after every point, kept or discarded
            if pacer is not None:
                pacer.wait(bench_s)
            if control.abort.is_set():
                raise Aborted("measurement aborted")

        try:
            bench = load_scene(scene.to_dict(), bench_overrides(setup))
            settings = sine_settings(bench, setup)
            if control.path is not None:
                from daq.sine_file import SineFileSink

                sinks.append(SineFileSink(control.path))
            control.oper(OPER_MEASURING | OPER_SWEEPING)
            sweep = measure_sine(bench, settings, seed, sinks=sinks, progress=progress)
        except RigError as exc:
            raise ModeConflict(str(exc)) from None
        cal = calibrations(bench)
        return SineResult(setup, sweep, seed, {n: (float(cal[c].volts_per_unit), cal[c].unit)
                                               for n, c in INPUTS.items()})

    @staticmethod
    def summary(result: SineResult) -> str:
        s, sw = result.setup, result.sweep
        return (f"{len(sw.points)} points {s.start_hz:g}-{s.stop_hz:g} Hz "
                f"({sw.model_info.get('model')} model), {sw.bench_s:,.0f} s of bench time")

    @staticmethod
    def overloads(result: SineResult) -> int:
        """Inputs 1..3 that clipped or saturated at any point (bit ``2^(n-1)``)."""
        over = 0
        for p in result.sweep.points:
            for i in range(3):
                if p.clipped[i] or p.saturated[i]:
                    over |= 1 << i
        return over
