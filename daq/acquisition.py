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

The bench is anything with the :class:`daq.benches.Bench` interface; the default is the
emulated rig (:func:`daq.benches.rig_bench`); :class:`daq.benches.FunctionBench` turns functions
of time into a bench (tests, demos). The loop consumes filtered and decimated blocks
(:class:`rig.blocks.DecimatedBlock`) only: a bench that does not decimate itself is adapted by
:func:`daq.benches.decimating`.
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
from typing import Callable, Iterable, Iterator

import numpy as np

from daq.adc import ADC
from daq.antialias import AntiAliasFilter
from daq.benches import (Bench, FunctionBench, StreamError, check_finite_volts, decimating,
                         rig_bench)
from daq.channels import channels_for
from daq.records import (Block, Footer, Header, ModelResponse, RecordBuffer, RecordPlan,
                         TruthField)
from daq.sinks import Fanout, Sink
from rig.output_files import software_version
from rig.threads import prefetch, single_threaded_blas
from rig.acquisition_settings import AcquisitionSettings
from rig.blocks import DecimatedBlock
from rig.errors import ConfigError
from rig.model_info import ModelInfo
from rig.scene import Scene

#: re-exported here: the bench interface and the error of a broken block stream
__all__ = ["acquire", "AcquisitionSummary", "AcquisitionInterrupted", "StreamError", "Bench",
           "FunctionBench", "rig_bench", "model_response", "antialias_for", "check_seed",
           "utc_now_iso"]


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
    model_info: ModelInfo
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
        :data:`daq.benches.BLOCK_S` or the shortest any sink asks for (its ``block_s``: a paced
        sink's).

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
    the_bench = decimating(bench(scene, seed), plan.simulation_samples)
    if not math.isclose(the_bench.fs_hz, plan.simulation_rate_hz, rel_tol=1e-12):
        raise ConfigError(f"the bench runs at {the_bench.fs_hz:g} Hz but acquisition."
                          f"simulation_rate_hz = {plan.simulation_rate_hz:g} Hz")
    channels = channels_for(scene.settings["acquisition"], the_bench.calibrations())
    response = model_response(the_bench, aa, plan, channels)
    # the bench filters and decimates (no simulation-rate arrays reach the loop)
    blocks = iter(the_bench.decimated_blocks(aa))
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
        _run(header, _chain(first, prefetch(blocks, 2)), fan, progress, clips, sats)
        status = "complete"
    except KeyboardInterrupt as exc:
        status = "interrupted"
        message = f"{exc} received" if str(exc).startswith("SIG") else "SIGINT received (Ctrl-C)"
        raise
    except BaseException as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        message, failure = first or "an unexpected failure without a message", exc
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


def _run(header: Header, blocks: Iterator[DecimatedBlock], fan: Fanout, progress,
         clips: list, sats: list) -> None:
    """The acquisition loop over the bench's filtered and decimated blocks. Appends each
    finished record's clip counts to ``clips`` (and its saturation counts to ``sats``) in the
    same SIGINT-free section that hands the record to the sinks, so ``len(clips)`` is the number
    of records every sink has."""
    plan = header.plan
    names = header.names
    adcs = [c.adc for c in header.channels]
    truth_names = [t.name for t in header.truth]
    fs, n_rec, settle = plan.simulation_rate_hz, plan.samples, plan.settle_samples
    need = plan.simulation_samples
    buf = RecordBuffer(header)
    done_sim = 0  # simulation samples consumed
    done_out = 0  # output samples produced
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
        if ab.samples > need - done_sim:
            raise StreamError(f"bench block at t = {ab.t0_s:g} s has {ab.samples} samples; the "
                              f"run needs {need - done_sim} more")
        y = np.stack([np.asarray(ab.volts[k], dtype=float) for k in names])
        check_finite_volts(y, names, ab.t0_s, ab.decimation / ab.fs_hz)
        truth = {k: np.asarray(ab.truth[k]) for k in truth_names}
        saturated = {k: np.asarray(ab.saturated[k]) for k in names if k in ab.saturated}
        n, m = ab.samples, y.shape[1]
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
