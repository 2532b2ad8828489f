"""The emulated Agilent 35670A: its state, its command table and its measurement, behind one
:meth:`Analyzer35670A.execute` (a program message in, the query responses out).

The instrument is four-channel (option AY6): input 1 is the stage accelerometer a, 2 the PSD's
translation x, 3 its rotation y, 4 the source drive. Settings follow the instrument's semantics
and limits (:mod:`processing.instrument.measurement`); what the emulated bench cannot carry, or
a feature that is not emulated, is ``-221,"Settings conflict; <why>"``; a value outside the
instrument's range is ``-222``; an unknown header ``-113``.

``INIT`` starts a measurement on a worker thread (one at a time: another ``INIT`` meanwhile is
``-213,"Init ignored"``); ``*OPC?`` and ``*WAI`` wait for it (in slices of 0.1 s, so a signal
still reaches the caller), ``ABOR`` ends it at the next bench block or sweep point. The
measurement is the mode's ``run`` (FFT: ``daq.acquire`` + ``processing.analyze``; SINE:
``processing.sine_sweep.measure_sine``), with the ``n``-th measurement since the start seeded
``seed + n``; selecting another mode drops the last measurement's traces. ``realtime`` paces it to the wall clock like the bench
(``daq.pacing``); ``out_dir`` keeps each measurement's run file. The status registers follow
the measurement (:mod:`processing.instrument.status`).

*RST presets the emulator's defaults, which differ from the instrument's where the bench needs
it: span 12.5 Hz (the instrument's 102.4 kHz is beyond the bench), 800 lines, Hann, RMS
averaging of 10 averages switched on, source random 0.1 V rms with its output off, ranges and
transducer units from the scene; the swept-sine settings of
:class:`processing.instrument.sine_mode.SineSetup`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from processing.instrument import blocks
from processing.instrument.measurement import LINES, MODES, FftSetup, baseband_span
from processing.instrument.measurement_mode import Aborted, ModeConflict, RunControl
from processing.instrument.scpi import Command, CommandTable, Engine, ErrorQueue, ScpiError
from processing.instrument.sine_mode import SineSetup
from processing.instrument.status import OPER_MEASURING, QUES_VOLTAGE, Status
from processing.instrument.traces import Feed, parse_feed, trace_data, x_data

__all__ = ["Analyzer35670A", "Aborted"]

DEFAULT_TRACES = ("XFR:POW 1", "XFR:POW 2", "XFR:POW:RAT 2,1", "XFR:POW:COH 2,1")


@dataclass(frozen=True)
class InputSetup:
    """One input: on (INP{n}) and its transducer (engineering) units on (its ADC range and
    autorange are the measurement's: :class:`FftSetup`)."""

    on: bool = True
    xdcr: bool = True


@dataclass(frozen=True)
class TraceSetup:
    """One trace (CALC{n}): its feed, format (CALC:FORM) and power unit (CALC:UNIT:VOLT)."""

    feed: Feed
    form: str = "MLOG"
    volt_unit: str = "V2"


class Analyzer35670A:
    """The emulated instrument over ``scene`` (a resolved :class:`rig.scene.Scene`).

    ``log(line)`` receives a line per measurement (done, aborted, refused, failed) and, after
    one that is done, the equivalent ``daq`` commands that ``describe(setup, seed)`` gives.
    """

    def __init__(self, scene, *, seed: int = 0, realtime: bool = False, out_dir=None,
                 log=lambda line: None, describe=None, modes=None):
        self.scene, self.seed, self.realtime = scene, int(seed), realtime
        self.out_dir = None if out_dir is None else Path(out_dir)
        self.log, self.describe = log, describe
        self.modes = MODES if modes is None else modes
        self.status = Status()
        self.errors = ErrorQueue(30)
        self.engine = Engine(CommandTable(self._commands()), self.errors, self._on_error)
        self._idle = threading.Event()
        self._idle.set()
        self._abort = threading.Event()
        self._worker = None
        self._opc_pending = False
        self.measurements = 0
        self.result, self.mode = None, "FFT"
        self.reset()

    # -- the outside ------------------------------------------------------------------------

    def execute(self, line: str) -> list:
        """Run one program message; the responses of its queries in order (str or bytes)."""
        return self.engine.execute(line)

    def push_error(self, code: int, detail: str = "") -> None:
        self.engine.error(ScpiError(code, detail))

    def wait(self, timeout: float | None = None) -> bool:
        """Wait (in 0.1 s slices) until no measurement runs; False on timeout."""
        remaining = math.inf if timeout is None else timeout
        while not self._idle.wait(min(0.1, remaining)):
            remaining -= 0.1
            if remaining <= 0:
                return False
        return True

    def abort(self, timeout: float = 10.0) -> None:
        """End a running measurement (bounded wait)."""
        if self._worker is not None and self._worker.is_alive():
            self._abort.set()
            self._worker.join(timeout)

    def request_opc(self) -> None:
        """``*OPC``: set the operation-complete event bit now, or when the measurement ends."""
        if self.measuring:
            self._opc_pending = True
        else:
            self.status.event(1)

    @property
    def measuring(self) -> bool:
        return not self._idle.is_set()

    def _on_error(self, code: int) -> None:
        from processing.instrument.scpi import event_bit

        self.status.event(event_bit(code))

    # -- state ------------------------------------------------------------------------------

    def reset(self) -> None:
        """The preset state (*RST, SYST:PRES; see the module docstring)."""
        acq = self.scene.acquisition
        self.select("FFT")
        self.setup = FftSetup(ranges_v=(float(acq.range_a_v), float(acq.range_x_v),
                                        float(acq.range_y_v)))
        self.sine = SineSetup()
        self.aver_on, self.aver_type, self.aver_tcon = True, "RMS", "NORM"
        self.inputs = {n: InputSetup(xdcr=n != 4) for n in range(1, 5)}
        self.traces = {n: TraceSetup(parse_feed(DEFAULT_TRACES[n - 1])) for n in range(1, 5)}
        self.degrees = True
        self.form, self.digits, self.swapped = "ASC", 17, False
        self.display, self.beeper = True, True
        self.init_continuous = False

    def update(self, **changes) -> None:
        self.setup = dataclasses.replace(self.setup, **changes)

    def update_sine(self, **changes) -> None:
        self.sine = dataclasses.replace(self.sine, **changes)

    def select(self, mode: str) -> None:
        """``INST:SEL``: another mode drops the last measurement's traces."""
        if mode != self.mode:
            self.result = None
        self.mode = mode

    def update_source(self, **changes) -> None:
        self.update(source=dataclasses.replace(self.setup.source, **changes))

    def update_input(self, n: int, **changes) -> None:
        self.inputs[n] = dataclasses.replace(self.inputs[n], **changes)

    def update_trace(self, n: int, **changes) -> None:
        self.traces[n] = dataclasses.replace(self.traces[n], **changes)

    def _effective_setup(self):
        if self.mode == "SINE":  # the source and the inputs are the instrument's, shared
            src = self.setup.source
            return dataclasses.replace(self.sine, level_vrms=src.level_vrms, output=src.enabled,
                                       ranges_v=self.setup.ranges_v,
                                       autorange=self.setup.autorange)
        avg = "exponential" if self.aver_tcon == "EXP" else {
            "RMS": "rms", "VECT": "vector"}.get(self.aver_type)
        if avg is None:
            raise ModeConflict(f"averaging type {self.aver_type} is not emulated (the analysis "
                               "averages RMS, VECT or, with AVER:TCON EXP, exponentially)")
        return dataclasses.replace(self.setup, averaging=avg,
                                   averages=self.setup.averages if self.aver_on else 1)

    # -- the command table ------------------------------------------------------------------

    def _commands(self) -> list[Command]:
        from processing.instrument import commands

        return commands.table(self)

    # -- measuring --------------------------------------------------------------------------

    def initiate(self) -> None:
        if self.measuring:
            raise ScpiError(-213, "a measurement is running (ABOR ends it)")
        mode = self.modes.get(self.mode)
        if mode is None:
            raise ScpiError(-221, f"INST:SEL {self.mode} is not emulated yet")
        try:
            setup = self._effective_setup()
            mode.check(self.scene, setup)
        except ModeConflict as exc:
            raise ScpiError(-221, str(exc)) from None
        seed = self.seed + self.measurements
        self.measurements += 1
        self._abort.clear()
        self._idle.clear()
        with self.status.lock:
            self.status.oper.set_condition(OPER_MEASURING)
        self._worker = threading.Thread(target=self._measure, args=(mode, setup, seed),
                                        name="35670A measurement", daemon=True)
        self._worker.start()

    def _run_path(self, n: int):
        """Where measurement ``n`` keeps its run file (``out_dir``), or None."""
        if self.out_dir is None:
            return None
        self.out_dir.mkdir(parents=True, exist_ok=True)
        path = self.out_dir / f"measurement_{n:04d}.h5"
        k = n
        while path.exists():
            k += 1000
            path = self.out_dir / f"measurement_{k:04d}.h5"
        return path

    def _oper(self, bits: int) -> None:
        with self.status.lock:
            self.status.oper.set_condition(bits)

    def _measure(self, mode, setup, seed) -> None:
        n = self.measurements
        try:
            control = RunControl(abort=self._abort, realtime=self.realtime,
                                 path=self._run_path(n), oper=self._oper)
            result = mode.run(self.scene, setup, seed=seed, control=control)
            self.result = result
            over = mode.overloads(result)
            with self.status.lock:
                self.status.dev.set_condition(over)
                self.status.ques.set_condition(QUES_VOLTAGE if over else 0)
            if mode.name == "FFT" and result.setup.ranges_v != setup.ranges_v:  # autoranged
                self.update(ranges_v=result.setup.ranges_v)
            self.log(f"measurement {n} done (seed {seed}): {mode.summary(result)}")
            if self.describe is not None:
                self.log("the same with daq:\n" + self.describe(result.setup, seed))
        except Aborted:
            self.log(f"measurement {n} aborted")
        except ModeConflict as exc:
            self.push_error(-221, str(exc))
            self.log(f"measurement {n} refused: {exc}")
        except Exception as exc:  # the console and the queue get one line, never a traceback
            self.push_error(-200, f"the measurement failed: {exc}")
            self.log(f"measurement {n} failed: {exc}")
        finally:
            with self.status.lock:
                self.status.oper.set_condition(0)
            if self._opc_pending:
                self._opc_pending = False
                self.status.event(1)
            self._idle.set()

    # -- trace data -------------------------------------------------------------------------

    def trace_values(self, n: int, x: bool = False):
        if self.result is None:
            raise ScpiError(-230, "no measurement yet (INIT, then *OPC?)")
        t = self.traces[n]
        off = [c for c in t.feed.channels if not self.inputs[c].on]
        if off:
            raise ScpiError(-221, f"input {off[0]} is off (INP{off[0]} ON)")
        try:
            if x:
                return x_data(self.result, t.feed)
            eu = {c: self.inputs[c].xdcr for c in range(1, 5)}
            y = trace_data(self.result, t.feed, t.form, volt_unit=t.volt_unit, eu=eu,
                           degrees=self.degrees)
        except ModeConflict as exc:
            raise ScpiError(-221, str(exc)) from None
        return y

    def encode(self, values):
        fmt = "ASC" if self.form == "ASC" else self.form
        if fmt != "ASC" and self.swapped:
            import numpy as np

            raw = blocks.encode(values, fmt)
            head = raw[: 2 + int(raw[1:2])]
            dtype = ">f4" if fmt.endswith("32") else ">f8"
            data = np.frombuffer(raw[len(head):], dtype=dtype).astype(dtype.replace(">", "<"))
            return head + data.tobytes()
        return blocks.encode(values, fmt, self.digits)

    # -- identity ---------------------------------------------------------------------------

    @staticmethod
    @functools.cache
    def identity() -> str:
        """``*IDN?``: maker, model, serial, firmware (which says the instrument is emulated)."""
        try:
            version = metadata.version("pendulum-daq")
        except metadata.PackageNotFoundError:  # pragma: no cover - run from a source tree
            version = "0"
        return f"Agilent Technologies,35670A,EMULATED,pendulum-daq-{version}-emulated"

    def check_span(self, span: float) -> float:
        """The rounded span, or -222 / -221 (the bench's limit) for one it cannot use."""
        try:
            s = baseband_span(span)
        except ValueError as exc:
            raise ScpiError(-222, str(exc)) from None
        try:
            self.modes["FFT"].check(self.scene, dataclasses.replace(self.setup, span_hz=s,
                                                                    averages=2))
        except ModeConflict as exc:
            raise ScpiError(-221, str(exc)) from None
        return s

    def scene_units(self) -> dict:
        """Input 1..3's engineering unit (the emulated sensors', :func:`rig.bench.calibrations`)."""
        from rig.bench import calibrations

        cal = calibrations(self.scene)
        return {n: cal[c].unit for n, c in zip((1, 2, 3), "axy")}

    def scene_volts_per_unit(self) -> dict:
        """Input 1..3's signed calibration [V per unit]; 4 (the drive) 1."""
        from rig.bench import calibrations

        cal = calibrations(self.scene)
        return {**{n: float(cal[c].volts_per_unit) for n, c in zip((1, 2, 3), "axy")}, 4: 1.0}

    @staticmethod
    def lines_for(value: float) -> int:
        for n in LINES:
            if value <= n * (1 + 1e-12):
                return n
        raise ScpiError(-222, f"{value:g} lines: expected at most 1600 (100, 200, 400, 800, "
                        "1600)")
