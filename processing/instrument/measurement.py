"""The analyzer's measurement modes: what ``INIT`` runs, as an acquisition and an analysis of
this project (``daq.acquire`` into a ``daq.MemorySink``, then ``processing.analyze``).

A mode is a :class:`processing.instrument.measurement_mode.MeasurementMode` (``check``,
``run``, ``summary``, ``overloads``). :data:`MODES` maps ``INST:SEL`` names to modes: FFT is
:class:`FftMode`, SINE the swept sine (:mod:`processing.instrument.sine_mode`).

FFT mode (the 35670A's semantics, SPEC section 6): a baseband span ``102.4 kHz / 2^k`` with
``lines`` in 100 .. 1600 gives the time record ``lines / span`` and the sample rate
``2.56 span`` (``nperseg = 2.56 lines``). The emulated bench samples at that rate; its DAC
(the simulation rate) runs at the smallest whole multiple ``q >= 2`` of it that is at least
the scene's ``acquisition.simulation_rate_hz``, and a span whose sample rate exceeds half the
scene's DAC rate is refused, naming the limit. The random source is band-limited to the span
and chirp and burst periods are one time record, as the instrument's source does. Without
overlap each average is one record of one time record; with overlap ``o`` one record holds
the overlapped time records. :func:`bench_overrides` and :func:`analyzer_settings` give the
``daq acquire --set ...`` and ``daq analyze`` options of the same measurement. An autoranging
input's range is found by measuring: after a measurement that clipped it, its range rises by
10 dB and the measurement is repeated; then the range becomes the smallest whole dBVpk above
the recorded peak (the same seed: the same signals) and, if it changed, the measurement is made
once more with it (:data:`RANGES_DBVPK`; at most :data:`MAX_RANGING` measurements).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from daq.sinks import Sink
from processing.instrument.measurement_mode import (Aborted, MeasurementMode, ModeConflict,
                                                    RunControl)
from processing.instrument.sine_mode import SineMode, SineSetup
from processing.instrument.sine_mode import equivalent_commands as sine_commands
from processing.instrument.status import OPER_AVERAGING, OPER_MEASURING, OPER_SETTLING

__all__ = ["FftSetup", "SourceSetup", "ModeConflict", "MeasurementMode", "FftMode", "FftResult",
           "MODES", "baseband_span", "SPANS_HZ", "LINES", "bench_overrides",
           "analyzer_settings", "equivalent_commands", "CHANNELS"]

#: The 35670A's baseband spans: 102.4 kHz / 2^k down to 195.3125 mHz [Hz].
SPANS_HZ = tuple(102400.0 / 2 ** k for k in range(20))
#: Its line counts.
LINES = (100, 200, 400, 800, 1600)
#: The inputs' ranges: whole dBVpk from -51 to +27.
RANGES_DBVPK = (-51, 27)
#: Measurements an autoranging INIT makes at most.
MAX_RANGING = 10
#: Input channels 1..4 -> the run's channel names (4: the source drive, a truth field).
CHANNELS = {1: "a", 2: "x", 3: "y", 4: "source_v"}


def baseband_span(requested_hz: float) -> float:
    """The smallest baseband span >= ``requested_hz`` (the instrument rounds a span up);
    ValueError outside 0 < span <= 102.4 kHz."""
    if not (math.isfinite(requested_hz) and 0 < requested_hz <= SPANS_HZ[0] * (1 + 1e-12)):
        raise ValueError(f"span {requested_hz:g} Hz is out of range: expected 0 < span <= "
                         "102.4 kHz")
    fitting = [s for s in SPANS_HZ if s >= requested_hz * (1 - 1e-12)]
    return fitting[-1] if fitting else SPANS_HZ[-1]


@dataclass(frozen=True)
class SourceSetup:
    """The source: ``function`` a ``source.type`` of the bench; ``level_vrms`` [V rms];
    ``frequency_hz`` of the fixed sine; ``burst_percent`` of burst random; ``enabled`` (OUTP)."""

    enabled: bool = False
    function: str = "random"
    level_vrms: float = 0.1
    frequency_hz: float = 2.0
    burst_percent: float = 50.0


@dataclass(frozen=True)
class FftSetup:
    """One FFT measurement's settings (SI units): span [Hz], lines, window, averaging
    ("rms", "vector", "exponential"), averages, overlap fraction, source, ADC ranges per
    channel 1..3 [V peak] and whether each autoranges."""

    span_hz: float = 12.5
    lines: int = 800
    window: str = "hann"
    averaging: str = "rms"
    averages: int = 10
    overlap: float = 0.0
    source: SourceSetup = field(default_factory=SourceSetup)
    ranges_v: tuple = (1.0, 10.0, 10.0)
    autorange: tuple = (False, False, False)

    @property
    def rate_hz(self) -> float:
        return 2.56 * self.span_hz

    @property
    def nperseg(self) -> int:
        return int(round(2.56 * self.lines))

    @property
    def record_s(self) -> float:
        """The time record, lines / span [s]."""
        return self.lines / self.span_hz

    @property
    def step(self) -> int:
        return self.nperseg - int(round(self.overlap * self.nperseg))


def _dac_rate(scene, rate_hz: float) -> float:
    base = float(scene.acquisition.simulation_rate_hz)
    if rate_hz > base / 2 * (1 + 1e-12):
        span = rate_hz / 2.56
        largest = max(s for s in SPANS_HZ if 2.56 * s <= base / 2)
        raise ModeConflict(
            f"span {span:g} Hz needs a sample rate of {rate_hz:g} Hz, above half the bench's DAC "
            f"rate {base:g} Hz (acquisition.simulation_rate_hz): the largest span is "
            f"{largest:g} Hz (or serve with --set acquisition.simulation_rate_hz=...)")
    return max(2, math.ceil(base / rate_hz - 1e-9)) * rate_hz


def bench_overrides(scene, setup: FftSetup) -> list[str]:
    """The scene overrides (``daq acquire --set``) that make the bench this measurement."""
    rate = setup.rate_hz
    dac = _dac_rate(scene, rate)
    settle = math.ceil(float(scene.acquisition.settle_s) * rate - 1e-9) / rate
    if setup.overlap > 0:
        records, samples = 1, setup.nperseg + (setup.averages - 1) * setup.step
    else:
        records, samples = setup.averages, setup.nperseg
    src = setup.source
    level = src.level_vrms if src.enabled else 0.0
    out = [f"acquisition.rate_hz={rate!r}", f"acquisition.simulation_rate_hz={dac!r}",
           f"acquisition.records={records}", f"acquisition.record_s={samples / rate!r}",
           f"acquisition.settle_s={settle!r}",
           *(f"acquisition.range_{c}_v={r!r}" for c, r in zip("axy", setup.ranges_v)),
           f"source.type={src.function}", f"source.level_vrms={float(level)!r}",
           "source.fmin_hz=0.0", f"source.fmax_hz={setup.span_hz!r}"]
    if src.function == "sine":
        out.append(f"source.frequency_hz={float(src.frequency_hz)!r}")
    if src.function in ("periodic-chirp", "burst-random"):
        out.append(f"source.period_s={setup.record_s!r}")
    if src.function == "burst-random":
        out.append(f"source.burst_fraction={src.burst_percent / 100.0!r}")
    return out


def analyzer_settings(setup: FftSetup):
    """The :class:`processing.AnalyzerSettings` of this measurement: display band clipped to the
    span, and no modal fits (they change no trace and cost seconds on a few lines)."""
    from processing.analyzer import AnalyzerSettings

    return AnalyzerSettings(window=setup.window, averaging=setup.averaging, lines=setup.lines,
                            span_hz=setup.span_hz, overlap=setup.overlap,
                            exp_averages=setup.averages, fmin_hz=min(0.1, setup.span_hz / 8),
                            fmax_hz=min(10.0, setup.span_hz), fit_methods=())


def equivalent_commands(scene_arg: str, base_overrides, seed: int, setup, scene) -> str:
    """The ``daq`` command lines that measure the same numbers as ``setup``: ``daq acquire`` +
    ``daq analyze`` for an :class:`FftSetup`, ``daq sine`` for a swept-sine
    :class:`processing.instrument.sine_mode.SineSetup`."""
    if isinstance(setup, SineSetup):
        return sine_commands(scene_arg, base_overrides, seed, setup, scene)
    sets = " ".join(f"--set {o}" for o in [*base_overrides, *bench_overrides(scene, setup)])
    a = analyzer_settings(setup)
    opts = (f"--lines {a.lines} --span {a.span_hz!r} --window {a.window} --averaging "
            f"{a.averaging} --overlap {a.overlap!r} --fmin {a.fmin_hz!r} --fmax {a.fmax_hz!r}")
    return (f"daq acquire {scene_arg} --seed {seed} {sets} --out run.h5\n"
            f"daq analyze run.h5 {opts}")


@dataclass(frozen=True, eq=False)
class FftResult:
    """One FFT measurement: the setup, the recording and its :class:`processing.Analysis`
    (None with the source off: there is no response to compare with the model; the traces then
    come from the segment FFTs alone)."""

    setup: FftSetup
    recording: object
    analysis: object
    seed: int
    _ffts: dict = field(default_factory=dict, repr=False)

    @property
    def spectral(self):
        """The analyzer's :class:`processing.spectra.SpectralSettings` of this measurement."""
        if self.analysis is not None:
            return self.analysis.spectral
        plan = self.recording.header.plan
        return analyzer_settings(self.setup).spectral(plan.rate_hz, plan.samples)

    @property
    def freqs_hz(self) -> np.ndarray:
        return self.spectral.freqs_hz

    def volts_per_unit(self, ch: int) -> float:
        """Channel ``ch``'s signed calibration [V per EU] (1 for the source drive)."""
        return 1.0 if ch == 4 else float(self.recording.header.channel(CHANNELS[ch])
                                         .volts_per_unit)

    def unit(self, ch: int) -> str:
        return "V" if ch == 4 else self.recording.header.channel(CHANNELS[ch]).unit

    def values(self, ch: int) -> np.ndarray:
        """Channel ``ch`` in engineering units, (records, samples) (the drive in volts)."""
        name = CHANNELS[ch]
        if ch == 4:
            if name not in self.recording.truth:
                raise ModeConflict("channel 4 (the source drive) is recorded only with "
                                   "acquisition.truth = true")
            return self.recording.truth[name]
        return self.recording.values(name)

    def ffts(self):
        """The segment FFTs of all four channels with the analysis's settings (computed once;
        :func:`processing.spectra.segment_ffts`, the analyzer's own)."""
        if "all" not in self._ffts:
            from processing.spectra import segment_ffts

            chans = {ch: self.values(ch) for ch in CHANNELS}
            self._ffts["all"] = segment_ffts(chans, self.spectral,
                                             units={ch: self.unit(ch) for ch in CHANNELS})
        return self._ffts["all"]

    def frf(self, out: int, inp: int):
        """H1 ``out / inp`` in engineering units: the analysis's own H_t (2,1), Theta_2 (3,1)."""
        a = self.analysis
        if a is not None and inp == 1 and out in (2, 3):
            return a.h_t if out == 2 else a.theta_2
        from processing.frf import frequency_response

        return frequency_response(self.ffts(), inp, out)

    def cross(self, m: int, n: int, scaling: str) -> np.ndarray:
        from processing.spectra import auto_spectrum, cross_spectrum

        if m == n:
            return auto_spectrum(self.ffts(), m, scaling=scaling).values
        return cross_spectrum(self.ffts(), m, n, scaling=scaling).values

    def time_record(self, ch: int) -> np.ndarray:
        """The last time record of channel ``ch`` (EU; the drive in volts)."""
        v = self.values(ch)
        n = self.setup.nperseg
        return np.asarray(v[-1, v.shape[1] - n:], dtype=float)

    @property
    def times_s(self) -> np.ndarray:
        """The time record's sample times [s]."""
        return np.arange(self.setup.nperseg) / self.setup.rate_hz


class FftMode:
    """The FFT mode: ``daq.acquire`` of the bench this setup makes, then ``processing.analyze``."""

    name = "FFT"

    def check(self, scene, setup: FftSetup) -> None:
        _dac_rate(scene, setup.rate_hz)
        if setup.averages < 2:
            raise ModeConflict(f"{setup.averages} average: coherence and the error bands need "
                               "at least 2 (AVER ON; AVER:COUN >= 2)")

    def run(self, scene, setup: FftSetup, *, seed: int,
            control: RunControl = RunControl()) -> FftResult:
        from daq.acquisition import acquire
        from daq.sinks import MemorySink
        from processing.analyzer import analyze
        from rig.errors import RigError
        from rig.scene import load_scene

        self.check(scene, setup)
        try:
            bench_scene = load_scene(scene.to_dict(), bench_overrides(scene, setup))
        except RigError as exc:
            raise ModeConflict(str(exc)) from None
        sinks = _sinks(control)
        settle_s = float(scene.acquisition.settle_s)

        def progress(done_s, total_s):
            control.oper(OPER_MEASURING | (OPER_SETTLING if done_s < settle_s
                                           else OPER_AVERAGING))

        for _ in range(MAX_RANGING):
            mem = MemorySink()
            acquire(bench_scene, seed=seed, sinks=[*sinks, mem], progress=progress)
            ranges = _autoranged(mem.recording, setup)
            if ranges == setup.ranges_v:
                break
            setup = dataclasses.replace(setup, ranges_v=ranges)
            bench_scene = load_scene(scene.to_dict(), bench_overrides(scene, setup))
        analysis = None
        if setup.source.enabled and setup.source.level_vrms > 0:
            analysis = analyze(mem.recording, analyzer_settings(setup),
                               source="SCPI measurement")
        return FftResult(setup, mem.recording, analysis, seed)

    @staticmethod
    def summary(result: FftResult) -> str:
        s = result.setup
        return f"{s.averages} averages, {s.lines} lines, span {s.span_hz:g} Hz"

    @staticmethod
    def overloads(result: FftResult) -> int:
        """Inputs 1..3 that clipped or saturated (bit ``2^(n-1)``)."""
        rec = result.recording
        over = 0
        for i, name in enumerate(("a", "x", "y")):
            k = rec.header.names.index(name)
            if rec.clip_counts()[:, k].any() or rec.saturation_counts()[:, k].any():
                over |= 1 << i
        return over


class _AbortSink(Sink):
    """A critical sink that ends the run at the next block once ``event`` is set."""

    def __init__(self, event):
        self.event = event

    def block(self, block):
        if self.event.is_set():
            raise Aborted("measurement aborted")


def _sinks(control: RunControl) -> list:
    """The acquisition's sinks: abort, pacing (``realtime``), the run file (``path``)."""
    sinks = [_AbortSink(control.abort)]
    if control.realtime:
        from daq.pacing import Pacer, PacingSink

        sinks.append(PacingSink(Pacer(1.0)))
    if control.path is not None:
        from daq.hdf5 import Hdf5Sink

        sinks.insert(0, Hdf5Sink(control.path))
    return sinks


def _autoranged(recording, setup: FftSetup) -> tuple:
    """The ranges the autoranging inputs take after ``recording`` (module docstring)."""
    lo, hi = RANGES_DBVPK
    out = []
    for name, rng, auto in zip("axy", setup.ranges_v, setup.autorange):
        if not auto:
            out.append(rng)
            continue
        k = recording.header.names.index(name)
        db = round(20 * math.log10(rng))
        if recording.clip_counts()[:, k].any():
            db = min(hi, db + 10)
        else:
            peak = float(np.max(np.abs(recording.volts(name))))
            db = max(lo, min(hi, math.ceil(20 * math.log10(max(peak, 1e-300)) + 1e-9)))
        out.append(10.0 ** (db / 20.0))
    return tuple(out)


#: INST:SEL name -> mode (an absent name is a settings conflict: not emulated yet).
MODES = {"FFT": FftMode(), "SINE": SineMode()}
