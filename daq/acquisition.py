"""The acquisition: bench -> anti-alias filter -> ADC -> records, as a stream fanned out to sinks.

:func:`acquire` runs one continuous acquisition of a scene and sends every sink
(:mod:`daq.sinks`), in order::

    start(Header) -> block(Block) ... record(Record) ... -> stop(Footer)

The loop knows nothing about files or viewers: it is handed its sinks (a run file is a
``daq.hdf5.Hdf5Sink``), and a critical sink's failure stops the run while a live one's only drops
it. Every sink receives ``stop`` whatever happens: with status "complete", "interrupted"
(KeyboardInterrupt, e.g. Ctrl-C) or "failed" (an exception; re-raised after the sinks are
closed). Records are handed to the sinks with SIGINT deferred, so a sink sees a whole record or
none.

The bench is anything with the :class:`Bench` interface; the default is the emulated rig
(:func:`rig_bench`, ``rig.bench``); :class:`FunctionBench` turns functions of time into a bench
(tests, demos).
"""

from __future__ import annotations

import contextlib
import functools
import math
import signal
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Iterable, Iterator, Protocol

import numpy as np

from daq.adc import ADC
from daq.antialias import AntiAliasFilter
from daq.channels import channels_for
from daq.records import (Block, Footer, Header, ModelResponse, RecordBuffer, RecordPlan,
                         Recording, TruthField)
from daq.sinks import Fanout, Sink
from rig._check import positive
from rig._io import software_version
from rig._threads import prefetch, single_threaded_blas
from rig.acquisition_settings import AcquisitionSettings
from rig.blocks import AnalogBlock, Calibration, DecimatedBlock
from rig.errors import ConfigError, RigError
from rig.scene import Scene

class StreamError(RigError, RuntimeError):
    """The bench broke the block contract (gap, wrong rate, missing channel, non-finite volts)."""


class AcquisitionInterrupted(KeyboardInterrupt):
    """The run was interrupted (KeyboardInterrupt); the sinks hold every finished record.

    Still a :class:`KeyboardInterrupt`. ``summary`` is the :class:`AcquisitionSummary` so far.
    """

    def __init__(self, summary: "AcquisitionSummary"):
        super().__init__(f"acquisition interrupted after {summary.records} of "
                         f"{summary.records_planned} records")
        self.summary = summary


def utc_now_iso() -> str:
    """Current UTC time, ISO 8601 with microseconds and a ``Z`` (fixed length 27)."""
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


# -- benches ---------------------------------------------------------------------------------

class Bench(Protocol):
    """What :func:`acquire` needs from a bench.

    ``blocks()`` yields consecutive :class:`rig.blocks.AnalogBlock` s at ``fs_hz`` from t = 0, with
    one volts entry per calibrated channel; it may be endless (the acquisition stops pulling).
    ``expected_response(freqs_hz)`` gives exact complex responses (name -> (nf,) array): those
    named like a channel are the analog chain up to that channel's ADC input (the anti-alias
    filter is applied by the acquisition); ``units`` and ``long_names`` (optional dicts) say what
    they are. ``model_info()`` says what was simulated (model, method, error estimate...) and,
    for the rig, why (``reason``, ``selection``: the model chosen for the scene's error budget).

    Optional members (the acquisition reads them with these defaults when a bench lacks them):

    - ``truth_keys``: the truth series to record, in order (default: every key of the first
      block's ``truth``);
    - ``saturation_keys``: channel -> truth key of its sensor's saturation flag (bool at the
      simulation rate: e.g. the spot off the PSD, the accelerometer over its range); the
      acquisition stores, per sample, whether it was set within the sample's decimation
      interval (default: none);
    - ``units``, ``long_names``: response name -> unit / description of ``expected_response``
      (default: none; a response dict may also carry its own ``"units"`` and ``"long_names"``).
    """

    fs_hz: float
    truth_keys: tuple[str, ...] | None = None
    saturation_keys: dict[str, str] | None = None
    units: dict[str, str] | None = None
    long_names: dict[str, str] | None = None

    def blocks(self) -> Iterator[AnalogBlock]: ...

    def calibrations(self) -> dict[str, Calibration]: ...

    def expected_response(self, freqs_hz: np.ndarray) -> dict: ...

    def model_info(self) -> dict: ...


class FunctionBench:
    """A bench whose signals are a function of time (sines, seeded noise...): tests and demos.

    Parameters
    ----------
    fs_hz : simulation rate [Hz].
    signals : ``signals(t_s, rng) -> (volts, truth)``, both dicts of arrays over the samples of
        ``t_s`` (exact sample instants ``k / fs_hz``); ``rng`` is a :class:`numpy.random.Generator`
        consumed in time order, so the stream does not depend on the block size.
    calibrations : per channel name.
    seed : seeds ``rng``.
    block_samples : samples per block.
    response : optional ``response(freqs_hz) -> dict`` of exact responses (see :class:`Bench`).
    info : model description returned by :meth:`model_info`.
    """

    def __init__(self, fs_hz: float, signals: Callable, calibrations: dict[str, Calibration], *,
                 seed: int = 0, block_samples: int = 1000, response: Callable | None = None,
                 info: dict | None = None, units: dict | None = None):
        self.fs_hz = float(fs_hz)
        self._signals, self._cal, self._seed = signals, dict(calibrations), seed
        self._block, self._response = int(block_samples), response
        self._info = dict(info or {"model": "function", "method": "exact",
                                   "error_estimate": 0.0})
        self.units = dict(units or {})

    def blocks(self) -> Iterator[AnalogBlock]:
        rng = np.random.default_rng(self._seed)
        k0 = 0
        while True:
            t = (k0 + np.arange(self._block)) / self.fs_hz
            volts, truth = self._signals(t, rng)
            yield AnalogBlock(t0_s=k0 / self.fs_hz, fs_hz=self.fs_hz, volts=volts, truth=truth)
            k0 += self._block

    def calibrations(self) -> dict[str, Calibration]:
        return dict(self._cal)

    def expected_response(self, freqs_hz) -> dict:
        return {} if self._response is None else self._response(np.asarray(freqs_hz, float))

    def model_info(self) -> dict:
        return dict(self._info)


def rig_bench(scene: Scene, seed: int, **bench_kw) -> Bench:
    """The emulated rig of ``scene`` (:class:`rig.bench.BenchSimulation`) as a :class:`Bench`;
    ``bench_kw`` (e.g. ``method="lawson4"``) go to the simulation, except ``lifted`` (the fused
    chain, default True) and ``block_s`` (its block length [s], default :data:`BLOCK_S`; the
    same samples whatever it is) (``functools.partial`` of this is an ``acquire(bench=...)``)."""
    from rig import bench as rb

    return _RigBench(rb, scene, seed, **bench_kw)


#: Units of the responses of :func:`rig.bench.expected_response` (per source volt unless stated).
RIG_RESPONSE_UNITS = {
    "a": "V/V", "x": "V/V", "y": "V/V", "stage_accel": "(m/s^2)/V", "stage_disp": "m/V",
    "mirror_x": "m/V", "mirror_rot": "rad/V", "h_t": "m/(m/s^2)", "theta_2": "rad/(m/s^2)",
    "h_t_pendulum": "m/(m/s^2)", "theta_2_pendulum": "rad/(m/s^2)",
    "h_t_pendulum_continuous": "m/(m/s^2)", "theta_2_pendulum_continuous": "rad/(m/s^2)",
}
RIG_RESPONSE_NAMES = {
    "a": "channel a per source volt: DAC hold, amplifier, coil, stage, accelerometer",
    "x": "channel x per source volt: ... stage, pendulum, optical lever (linearised)",
    "y": "channel y per source volt: ... stage, pendulum, optical lever (linearised)",
    "stage_accel": "stage acceleration per source volt",
    "stage_disp": "stage displacement per source volt",
    "mirror_x": "mirror translation relative to the stage per source volt",
    "mirror_rot": "mirror rotation per source volt",
    "h_t": "H_t = (x / cal_x) / (a / cal_a): what the analyzer measures (accelerometer high-pass "
           "in the denominator)",
    "theta_2": "Theta_2 = (y / cal_y) / (a / cal_a): what the analyzer measures",
    "h_t_pendulum": "mirror translation / stage acceleration of the sampled bench",
    "theta_2_pendulum": "mirror rotation / stage acceleration of the sampled bench",
    "h_t_pendulum_continuous": "mirror translation / stage acceleration, continuous linear "
                               "pendulum (rig.response.mirror_response)",
    "theta_2_pendulum_continuous": "mirror rotation / stage acceleration, continuous linear "
                                   "pendulum",
}
#: The ground truth recorded from the rig (the contract of rig.blocks.AnalogBlock); the bench's
#: other truth series (coil current, stage velocity, spot positions, flags) are not stored.
RIG_TRUTH = ("stage_accel_mps2", "theta_rad", "mirror_x_m", "mirror_rot_rad", "source_v")
#: bench block length [s] (at most; a record if shorter): the paper's 100 s records come as one
#: block each. Blocks of any length give the same samples (tests/rig/bench/test_fused.py); longer
#: ones spread the per-block work (digitising, slicing, queueing) over more samples.
BLOCK_S = 100.0


class _RigBench:
    """:class:`rig.bench.BenchSimulation` behind the :class:`Bench` interface.

    ``expected_response`` is the exact discrete-time response of the simulated samples
    (``sampled=True``: DAC hold and folding included) for every (nf,) response of the bench, plus
    the continuous pendulum alone (``*_continuous``, from ``sampled=False``).
    """

    units = RIG_RESPONSE_UNITS
    long_names = RIG_RESPONSE_NAMES
    truth_keys = RIG_TRUTH
    saturation_keys = {"a": "a_overrange", "x": "psd_off_detector", "y": "psd_off_detector"}

    def __init__(self, rb, scene: Scene, seed: int, *, lifted: bool = True,
                 block_s: float = BLOCK_S, **bench_kw):
        self._rb, self._scene = rb, scene
        acq = scene.acquisition
        block_s = positive("block_s", block_s, valid=f"a bench block length > 0 s (default "
                                                     f"{BLOCK_S:g} s)")
        n = min(round(block_s * acq.rate_hz), round(acq.record_s * acq.rate_hz))
        self._block_s = max(1, n) / acq.rate_hz  # a whole number of ADC samples
        # exactly what the run consumes (nothing simulated beyond it, even when prefetching)
        plan = RecordPlan.from_acquisition(acq)
        self._duration_s = plan.simulation_samples / plan.simulation_rate_hz
        # the source is made from now on, while the model is chosen and the kernels load
        self._sim = rb.BenchSimulation(scene, seed, ahead=(self._block_s, self._duration_s),
                                       **bench_kw)
        self.fs_hz = float(self._sim.fs_hz)
        self._lifted = bool(lifted)  # the fused chain (rig.bench.fused), either model

    def blocks(self) -> Iterator[AnalogBlock]:
        return self._sim.blocks(self._block_s, self._duration_s)

    def decimated_blocks(self, sos: np.ndarray, decimation: int
                         ) -> Iterator[DecimatedBlock] | None:
        """The run through the anti-alias sections ``sos`` and kept every ``decimation``
        samples by the fused chain (:mod:`rig.bench.fused`: the linear model lifted, the nonlinear
        one fused after its per-sample bench), not with ``lifted=False`` (None: use
        :meth:`blocks`)."""
        if not self._lifted or decimation != self._sim.model.decimation:
            return None
        return self._sim.decimated_blocks(self._block_s, self._duration_s, sos)

    def calibrations(self) -> dict[str, Calibration]:
        return dict(self._sim.calibrations())

    def expected_response(self, freqs_hz) -> dict:
        exact = self._rb.expected_response(self._scene, freqs_hz, sampled=True)
        cont = self._rb.expected_response(self._scene, freqs_hz, sampled=False)
        out = {k: v for k, v in _as_dict(exact).items()
               if isinstance(v, np.ndarray) and v.ndim == 1 and k != "freqs_hz"}
        out["h_t_pendulum_continuous"] = cont.h_t_pendulum
        out["theta_2_pendulum_continuous"] = cont.theta_2_pendulum
        return out

    def model_info(self) -> dict:
        info = dict(self._sim.model_info())
        if self._lifted:
            info.update(self._rb.fused_model_info(self._sim.model))
        return info


def _as_dict(obj) -> dict:
    if isinstance(obj, dict):
        return dict(obj)
    import dataclasses

    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


@contextlib.contextmanager
def _sigint_deferred():
    """Hold a SIGINT (Ctrl-C) until the block exits, then raise KeyboardInterrupt; likewise a
    stop signal (SIGTERM, SIGHUP) whose handler is a Python function (daq.signals), which is
    then called."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from daq.signals import STOP_SIGNALS

    caught, old = [], {}
    try:
        old[signal.SIGINT] = signal.signal(signal.SIGINT, lambda sig, frame: caught.append(sig))
        for s in STOP_SIGNALS:
            if callable(signal.getsignal(s)):
                old[s] = signal.signal(s, lambda sig, frame: caught.append(sig))
    except ValueError:  # pragma: no cover - no signals here
        yield
        return
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    for s in caught:
        if s != signal.SIGINT:
            old[s](s, None)  # raises (daq.signals.Stopped)
    if caught:
        raise KeyboardInterrupt


# -- the run ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class AcquisitionSummary:
    """What a run produced.

    Attributes
    ----------
    status : "complete", "interrupted" or "failed".
    records, records_planned, samples_per_record, rate_hz : the records taken.
    channels : channel names; ``clip_counts`` is (records, channels): samples the ADC clipped;
        ``saturation_counts`` the same shape: samples whose sensor saturated (:class:`Block`).
    model_info : what the bench simulated.
    seed : the seed of the run.
    wall_s : wall time of :func:`acquire` [s].
    path : the file written (the first sink with a ``target``; None without one);
        ``file_bytes`` its size.
    """

    status: str
    records: int
    records_planned: int
    samples_per_record: int
    rate_hz: float
    channels: tuple
    clip_counts: np.ndarray
    model_info: dict
    seed: int
    wall_s: float
    path: Path | None = None
    file_bytes: int | None = None
    message: str = ""
    saturation_counts: np.ndarray | None = None

    @property
    def samples(self) -> int:
        """Samples per channel recorded."""
        return self.records * self.samples_per_record

    def clip_totals(self) -> dict:
        """Clipped samples per channel over all records."""
        return {c: int(self.clip_counts[:, i].sum()) for i, c in enumerate(self.channels)}

    def saturation_totals(self) -> dict:
        """Samples per channel over all records whose sensor saturated."""
        counts = self.saturation_counts
        if counts is None:
            return {c: 0 for c in self.channels}
        return {c: int(counts[:, i].sum()) for i, c in enumerate(self.channels)}


def check_seed(seed) -> int:
    """A seed is an integer 0 <= seed < 2**63 (stored in the file as int64)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not (
            0 <= seed < 2 ** 63):
        raise ConfigError(f"seed = {seed!r} is invalid: expected an integer 0 <= seed < 2**63")
    return int(seed)


def antialias_for(acquisition: AcquisitionSettings, plan: RecordPlan) -> AntiAliasFilter:
    """The anti-alias filter of ``Scene.acquisition``."""
    return AntiAliasFilter.design(
        plan.simulation_rate_hz, plan.rate_hz, bits=acquisition.adc_bits,
        kind=acquisition.antialias, passband=acquisition.antialias_passband,
        ripple_db=acquisition.antialias_ripple_db,
        attenuation_db=acquisition.antialias_attenuation_db)


def acquire(scene: Scene, *, seed: int, sinks: Iterable[Sink] = (),
            progress: Callable[[float, float], None] | None = None,
            bench: Callable[[Scene, int], Bench] | None = None) -> AcquisitionSummary:
    """Acquire ``scene.acquisition.records`` records of the scene's bench.

    Parameters
    ----------
    scene : the resolved scene; its ``[acquisition]`` section sets rates, records, ADC and filter.
    seed : seeds the bench (0 <= seed < 2**63); written into every record.
    sinks : where the stream goes, in order (:mod:`daq.sinks`): e.g. a run file first
        (``daq.hdf5.Hdf5Sink(path, force=...)``), a :class:`daq.sinks.MemorySink`, a live view.
        Each sink's ``check()`` runs before anything is simulated; the free space is checked
        beside the first sink's ``target`` file.
    progress : called as ``progress(simulated_s, total_s)`` after every bench block.
    bench : ``bench(scene, seed) -> Bench``; default :func:`rig_bench`, in blocks of
        :data:`BLOCK_S` or the shortest any sink asks for (its ``block_s``: a paced sink's).

    Returns
    -------
    AcquisitionSummary

    Raises
    ------
    rig.errors.ConfigError : invalid settings, seed or output path, or a run whose file could
        exceed the free space or whose records exceed the machine's memory
        (:func:`daq.resources.preflight`); raised before anything is simulated or written.
    AcquisitionInterrupted : on KeyboardInterrupt (a KeyboardInterrupt; also SIGTERM and SIGHUP
        within :func:`daq.signals.stop_signals_interrupt`), after closing the sinks.
    Any other exception that ends the run is re-raised after the sinks are closed, carrying the
    :class:`AcquisitionSummary` so far as ``acquisition_summary`` (e.g. a full disk: what the
    file holds).
    """
    # One BLAS thread throughout: the model's and the bench's matrix products are thin and gain
    # nothing from more, and OpenBLAS's spinning threads take the core that the pipeline's other
    # stage runs on (the process's CPU time drops by ~0.7 s).
    with single_threaded_blas():
        return _acquire(scene, seed=seed, sinks=sinks, progress=progress, bench=bench)


def _acquire(scene: Scene, *, seed: int, sinks: Iterable[Sink] = (),
             progress: Callable[[float, float], None] | None = None,
             bench: Callable[[Scene, int], Bench] | None = None) -> AcquisitionSummary:
    """:func:`acquire` (with one BLAS thread)."""
    t_start = time.perf_counter()
    acq = scene.acquisition
    plan = RecordPlan.from_acquisition(acq)
    ADC(1.0, acq.adc_bits)  # the resolution, before the filter design that depends on it
    aa = antialias_for(acq, plan)
    seed = check_seed(seed)
    sinks = list(sinks)
    from daq.resources import preflight

    for s in sinks:
        s.check()
    file_sink = next((s for s in sinks if getattr(s, "target", None) is not None), None)
    # file size and memory, before anything is simulated
    preflight(plan, scene, None if file_sink is None else file_sink.target)
    if bench is None:
        wanted = [s.block_s for s in sinks if getattr(s, "block_s", None) is not None]
        bench = functools.partial(rig_bench, block_s=min(wanted)) if wanted else rig_bench
    the_bench = bench(scene, seed)
    if not math.isclose(the_bench.fs_hz, plan.simulation_rate_hz, rel_tol=1e-12):
        raise ConfigError(f"the bench runs at {the_bench.fs_hz:g} Hz but acquisition."
                          f"simulation_rate_hz = {plan.simulation_rate_hz:g} Hz")
    channels = channels_for(scene.settings["acquisition"], the_bench.calibrations())
    response = model_response(the_bench, aa, plan, channels)
    fused = getattr(the_bench, "decimated_blocks", None)
    blocks = None
    if fused is not None and tuple(c.name for c in channels) == ("a", "x", "y"):
        # the bench filters and decimates itself (no simulation-rate arrays)
        blocks = fused(np.zeros((0, 6)) if aa.kind == "none" else aa.sos, aa.decimation)
    blocks = iter(the_bench.blocks() if blocks is None else blocks)
    # before the first block: the model's error probe takes its source samples from the blocks
    # made ahead, which the run then consumes (after it they would be made a second time)
    model_info = the_bench.model_info()
    first = next(blocks, None)
    if first is None:
        raise StreamError("the bench yielded no block")
    keys = getattr(the_bench, "truth_keys", None) or tuple(first.truth)
    truth = tuple(TruthField.from_array(k, np.asarray(first.truth[k])) for k in keys
                  if k in first.truth) if acq.truth else ()
    header = Header(scene=scene, seed=seed, plan=plan, channels=channels, antialias=aa,
                    truth=truth, model_info=model_info, response=response,
                    software_version=software_version(), start_time=utc_now_iso())

    fan = Fanout(sinks)
    clips: list[list[int]] = []
    sats: list[list[int]] = []
    status, message, failure = "failed", "", None
    try:
        fan.send("start", header)
        # the bench simulates the next blocks on one core while this thread filters, digitises
        # and writes the previous one on the other (same blocks, same order)
        _run(header, _chain(first, prefetch(blocks, 2)), fan, progress, clips, sats,
             dict(getattr(the_bench, "saturation_keys", None) or {}))
        status = "complete"
    except KeyboardInterrupt as exc:
        status = "interrupted"
        message = f"{exc} received" if str(exc).startswith("SIG") else "KeyboardInterrupt"
        raise
    except BaseException as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        message, failure = f"{type(exc).__name__}: {first}", exc
        raise
    finally:
        clip_counts = np.array(clips, dtype=np.int64).reshape(len(clips), len(channels))
        sat_counts = np.array(sats[:len(clips)], dtype=np.int64).reshape(len(clips),
                                                                          len(channels))
        footer = Footer(status=status, records_complete=len(clips), clip_counts=clip_counts,
                        message=message, wall_s=time.perf_counter() - t_start)
        with _sigint_deferred():
            errors = fan.stop_all(footer)
        path = file_sink.path if file_sink is not None else None
        summary = AcquisitionSummary(
            status=status, records=len(clips), records_planned=plan.records,
            samples_per_record=plan.samples, rate_hz=plan.rate_hz, channels=header.names,
            clip_counts=clip_counts, saturation_counts=sat_counts,
            model_info=header.model_info, seed=seed,
            wall_s=time.perf_counter() - t_start, path=path,
            file_bytes=path.stat().st_size if path is not None and path.exists() else None,
            message=message)
        if failure is not None:  # what the run left, for whoever reports the failure
            with contextlib.suppress(AttributeError, TypeError):
                failure.acquisition_summary = summary
        if status == "interrupted":
            raise AcquisitionInterrupted(summary) from None
        if errors and status == "complete":
            raise errors[0]
    return summary


def _chain(first, rest):
    yield first
    yield from rest


def model_response(bench: Bench, aa: AntiAliasFilter, plan: RecordPlan,
                   channels: tuple) -> ModelResponse:
    """Exact responses of the whole chain on the record's FFT grid (0 .. rate/2).

    Responses named like a channel are multiplied by the anti-alias response (the channel passes
    through it); the others (e.g. H_t = x/a, Theta_2 = y/a, where the filter cancels) are kept as
    the bench gives them; ``antialias`` is the filter itself.
    """
    f = plan.frequencies_hz()
    raw = bench.expected_response(f)
    units = dict(getattr(bench, "units", {}) or {})
    long_names = dict(getattr(bench, "long_names", {}) or {})
    if "units" in raw and isinstance(raw["units"], dict):
        units.update(raw.pop("units"))
    if "long_names" in raw and isinstance(raw["long_names"], dict):
        long_names.update(raw.pop("long_names"))
    h_aa = aa.response(f)
    values, names = {}, {c.name for c in channels}
    for k, v in raw.items():
        if k in ("freqs_hz", "frequency_hz", "freqs"):
            continue
        v = np.asarray(v)
        if v.shape != f.shape:
            continue  # not a response on this grid (e.g. a scalar note)
        v = v.astype(complex)
        if k in names:
            v = v * h_aa
            long_names.setdefault(k, f"channel {k}: analog chain x anti-alias filter")
        values[k] = v
    values["antialias"] = h_aa
    units["antialias"] = "1"
    long_names["antialias"] = f"anti-alias filter ({aa.kind}, order {aa.order})"
    return ModelResponse(freqs_hz=f, values=values, units=units, long_names=long_names)


def _interval_any(flags: np.ndarray, kept: slice, carry: bool) -> tuple[np.ndarray, bool]:
    """Per kept instant j of a block: whether ``flags`` was set since the previous kept instant
    (up to and including j; ``carry``: set after the previous block's last kept instant), and the
    carry for the next block."""
    flags = np.asarray(flags, bool)
    idx = np.arange(kept.start, flags.size, kept.step)
    if idx.size == 0:
        return np.zeros(0, bool), bool(carry or flags.any())
    starts = np.concatenate([[0], idx[:-1] + 1])
    out = np.logical_or.reduceat(flags[:idx[-1] + 1], starts)
    out[0] |= carry
    return out, bool(flags[idx[-1] + 1:].any())


def _run(header: Header, blocks: Iterator[AnalogBlock], fan: Fanout, progress,
         clips: list, sats: list, saturation_keys: dict) -> None:
    """The acquisition loop. Appends each finished record's clip counts to ``clips`` (and its
    saturation counts to ``sats``) in the same SIGINT-free section that hands the record to the
    sinks, so ``len(clips)`` is the number of records every sink has."""
    plan, aa = header.plan, header.antialias
    names = header.names
    adcs = [c.adc for c in header.channels]
    truth_names = [t.name for t in header.truth]
    fs, n_rec, settle = plan.simulation_rate_hz, plan.samples, plan.settle_samples
    need = plan.simulation_samples
    state = aa.initial_state(len(names))
    buf = RecordBuffer(header)
    done_sim = 0  # simulation samples consumed
    done_out = 0  # output samples produced
    sat_keys = {k: v for k, v in saturation_keys.items() if k in names}
    carry = {k: False for k in sat_keys}
    for ab in blocks:
        if not math.isclose(ab.fs_hz, fs, rel_tol=1e-12):
            raise StreamError(f"bench block at t = {ab.t0_s:g} s has fs = {ab.fs_hz:g} Hz; "
                              f"expected {fs:g} Hz")
        if abs(ab.t0_s - done_sim / fs) > 1e-9 * max(1.0, done_sim / fs) + 0.1 / fs:
            raise StreamError(f"bench block starts at t = {ab.t0_s!r} s; expected the next sample "
                              f"at t = {done_sim / fs!r} s (blocks must be consecutive)")
        missing = [k for k in names if k not in ab.volts]
        if missing:
            raise StreamError(f"bench block at t = {ab.t0_s:g} s has no volts for channel(s) "
                              f"{', '.join(missing)}")
        if isinstance(ab, DecimatedBlock):  # filtered and decimated by the bench itself
            n, y, truth, saturated = _decimated(ab, names, truth_names, sat_keys, need - done_sim)
        else:
            n = min(ab.samples, need - done_sim)
            y, truth, saturated, state = _filter_block(ab, n, names, aa, state, truth_names,
                                                       sat_keys, carry)
        m = y.shape[1]
        codes, clipped = {}, {}
        for i, (k, adc) in enumerate(zip(names, adcs)):
            codes[k], clipped[k] = adc.digitize(y[i])
        pos = 0
        while pos < m:
            g = done_out + pos
            if g < settle:
                pos += min(m - pos, settle - g)
                continue
            r, off = divmod(g - settle, n_rec)
            take = min(m - pos, n_rec - off)
            sl = slice(pos, pos + take)
            blk = Block(record=r, start=off, t0_s=g / plan.rate_hz,
                        codes={k: v[sl] for k, v in codes.items()},
                        clipped={k: v[sl] for k, v in clipped.items()},
                        truth={k: v[sl] for k, v in truth.items()},
                        saturated={k: v[sl] for k, v in saturated.items()})
            fan.send("block", blk)
            rec = buf.add(blk)
            if rec is not None:
                with _sigint_deferred():
                    fan.send("record", rec)
                    counts, sat = rec.clip_counts(), rec.saturation_counts()
                    sats.append([sat[c] for c in header.names])
                    clips.append([counts[c] for c in header.names])
            pos += take
        done_out += m
        done_sim += n
        if progress is not None:
            progress(done_sim / fs, need / fs)
        if done_sim >= need:
            return
    raise StreamError(f"the bench stopped at t = {done_sim / fs:g} s; the run needs "
                      f"{need / fs:g} s")


def _check_finite_volts(x: np.ndarray, names, t0_s: float, dt_s: float) -> None:
    if not np.isfinite(x).all():
        bad = [k for i, k in enumerate(names) if not np.isfinite(x[i]).all()]
        i = int(np.argmin(np.isfinite(x).all(axis=0)))
        raise StreamError(f"non-finite volts on channel(s) {', '.join(bad)} at t = "
                          f"{t0_s + i * dt_s:.6g} s")


def _filter_block(ab: AnalogBlock, n: int, names, aa: AntiAliasFilter, state, truth_names,
                  sat_keys: dict, carry: dict):
    """The first ``n`` samples of a block at the simulation rate through the anti-alias filter
    and the decimation: (filtered volts (channels, kept), truth and saturation flags at the kept
    instants, the filter state after it); updates ``carry``."""
    x = np.empty((len(names), n))
    for i, k in enumerate(names):
        x[i] = ab.volts[k][:n]
    _check_finite_volts(x, names, ab.t0_s, 1 / ab.fs_hz)
    kept = aa.kept(state, n)
    y, state = aa.step(state, x)
    truth = {k: np.asarray(ab.truth[k])[:n][kept] for k in truth_names}
    saturated = {}
    for k, key in sat_keys.items():
        if key in ab.truth:
            saturated[k], carry[k] = _interval_any(np.asarray(ab.truth[key])[:n], kept,
                                                   carry[k])
    return y, truth, saturated, state


def _decimated(ab: DecimatedBlock, names, truth_names, sat_keys: dict, left: int):
    """A block the bench filtered and decimated (:class:`rig.blocks.DecimatedBlock`): (its
    samples, volts (channels, kept), truth, saturation flags), or StreamError if it runs past
    the run or carries non-finite volts."""
    if ab.samples > left:
        raise StreamError(f"bench block at t = {ab.t0_s:g} s has {ab.samples} samples; the run "
                          f"needs {left} more")
    y = np.stack([np.asarray(ab.volts[k], dtype=float) for k in names])
    _check_finite_volts(y, names, ab.t0_s, ab.decimation / ab.fs_hz)
    truth = {k: np.asarray(ab.truth[k]) for k in truth_names}
    saturated = {k: np.asarray(ab.saturated[k]) for k in sat_keys if k in ab.saturated}
    return ab.samples, y, truth, saturated
