"""Benches: what the acquisition reads from, and the emulated rig behind that interface.

:func:`daq.acquisition.acquire` consumes one kind of block, :class:`rig.blocks.DecimatedBlock`
(the channels already through the anti-alias filter and the decimation), through one
capability, :class:`DecimatingBench`. A bench that decimates itself (the rig's fused chain,
:mod:`rig.bench.fused`) is one; any other :class:`Bench` (analog blocks at the simulation rate)
is adapted once, by :class:`Decimator` (:func:`decimating`), which runs the acquisition's filter
(:class:`daq.antialias.AntiAliasFilter`) over its blocks.

- :func:`rig_bench`: the emulated rig (``rig.bench``), fused by default (``lifted=False``: its
  per-sample blocks through the :class:`Decimator`, the path the fused chain is tested against);
- :class:`FunctionBench`: functions of time as a bench (tests, demos).

:class:`StreamError` is what a bench that breaks the block contract (gap, wrong rate, missing
channel, non-finite volts) raises through the acquisition.

Public API: :class:`Bench`, :class:`DecimatingBench`, :class:`Decimator`, :func:`decimating`,
:class:`FunctionBench`, :func:`rig_bench`, :class:`StreamError`, :func:`interval_any`,
:data:`BLOCK_S`, :data:`RIG_TRUTH`.
"""

from __future__ import annotations

from typing import Callable, Iterator, Protocol, runtime_checkable

import numpy as np

from daq.antialias import AntiAliasFilter
from daq.records import RecordPlan
from rig import bench as rb
from rig.model_info import ModelInfo
from rig.validation import positive
from rig.blocks import AnalogBlock, Calibration, DecimatedBlock
from rig.errors import ConfigError, RigError
from rig.scene import Scene


class StreamError(RigError, RuntimeError):
    """The bench broke the block contract (gap, wrong rate, missing channel, non-finite volts)."""


class Bench(Protocol):
    """What :func:`daq.acquisition.acquire` needs from a bench.

    ``blocks()`` yields consecutive :class:`rig.blocks.AnalogBlock` s at ``fs_hz`` from t = 0, with
    one volts entry per calibrated channel; it may be endless (the acquisition stops pulling).
    ``expected_response(freqs_hz)`` gives exact complex responses (name -> (nf,) array): those
    named like a channel are the analog chain up to that channel's ADC input (the anti-alias
    filter is applied by the acquisition); ``units`` and ``long_names`` (optional dicts) say what
    they are. ``model_info()`` says what was simulated (a :class:`rig.model_info.ModelInfo`: model,
    method, error estimate...) and,
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

    def model_info(self) -> ModelInfo: ...


@runtime_checkable
class DecimatingBench(Bench, Protocol):
    """A :class:`Bench` that filters and decimates its own channels.

    ``decimated_blocks(aa)`` yields consecutive :class:`rig.blocks.DecimatedBlock` s from t = 0:
    every calibrated channel through the anti-alias filter ``aa`` and kept at every
    ``aa.decimation``-th simulation sample (the kept instants are the run's samples ``0, q, 2q,
    ...``), the truth at those instants, and per channel whether its sensor saturated within
    each kept instant's interval (``saturated``). Equal to :class:`Decimator` over
    :meth:`blocks` up to the filter's round-off.
    """

    def decimated_blocks(self, aa: AntiAliasFilter) -> Iterator[DecimatedBlock]: ...


def decimating(bench: Bench, samples: int | None = None) -> DecimatingBench:
    """``bench`` itself if it is a :class:`DecimatingBench`, else adapted by a
    :class:`Decimator` (which stops after ``samples`` simulation samples; None: never)."""
    if isinstance(bench, DecimatingBench):
        return bench
    return Decimator(bench, samples)


class Decimator:
    """A :class:`Bench` as a :class:`DecimatingBench`: its analog blocks through the anti-alias
    filter and the decimation (:meth:`daq.antialias.AntiAliasFilter.step`, the state carried
    between blocks), the truth and the saturation flags kept at the same instants
    (:func:`interval_any`). ``samples``: the simulation samples to take (the last block cut
    there; None: all). Every other member is the bench's."""

    def __init__(self, bench: Bench, samples: int | None = None):
        self.bench = bench
        self.samples = samples
        self.fs_hz = bench.fs_hz
        self.truth_keys = getattr(bench, "truth_keys", None)
        self.saturation_keys = getattr(bench, "saturation_keys", None)
        self.units = getattr(bench, "units", None)
        self.long_names = getattr(bench, "long_names", None)

    def blocks(self) -> Iterator[AnalogBlock]:
        return self.bench.blocks()

    def calibrations(self) -> dict[str, Calibration]:
        return self.bench.calibrations()

    def expected_response(self, freqs_hz) -> dict:
        return self.bench.expected_response(freqs_hz)

    def model_info(self) -> ModelInfo:
        return self.bench.model_info()

    def decimated_blocks(self, aa: AntiAliasFilter) -> Iterator[DecimatedBlock]:
        names = tuple(self.calibrations())
        sat_keys = dict(self.saturation_keys or {})
        carry = {k: False for k in sat_keys}
        state = aa.initial_state(len(names))
        left = self.samples
        for ab in self.bench.blocks():
            n = ab.samples if left is None else min(ab.samples, left)
            missing = [k for k in names if k not in ab.volts]
            if missing:
                raise StreamError(f"bench block at t = {ab.t0_s:g} s has no volts for "
                                  f"channel(s) {', '.join(missing)}")
            x = np.empty((len(names), n))
            for i, k in enumerate(names):
                x[i] = ab.volts[k][:n]
            check_finite_volts(x, names, ab.t0_s, 1 / ab.fs_hz)
            kept = aa.kept(state, n)
            y, state = aa.step(state, x)
            truth = {k: np.asarray(v)[:n][kept] for k, v in ab.truth.items()
                     if self.truth_keys is None or k in self.truth_keys}
            saturated = {}
            for k, key in sat_keys.items():
                if key in ab.truth:
                    saturated[k], carry[k] = interval_any(np.asarray(ab.truth[key])[:n], kept,
                                                          carry[k])
            yield DecimatedBlock(t0_s=ab.t0_s, fs_hz=ab.fs_hz, decimation=aa.decimation,
                                 samples=n, volts={k: y[i] for i, k in enumerate(names)},
                                 truth=truth, saturated=saturated)
            if left is not None:
                left -= n
                if left <= 0:
                    return


def interval_any(flags: np.ndarray, kept: slice, carry: bool) -> tuple[np.ndarray, bool]:
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


def check_finite_volts(x: np.ndarray, names, t0_s: float, dt_s: float) -> None:
    """StreamError naming the channels and the first instant if ``x`` (channels, samples at
    ``dt_s`` from ``t0_s``) holds a non-finite volt."""
    if not np.isfinite(x).all():
        bad = [k for i, k in enumerate(names) if not np.isfinite(x[i]).all()]
        i = int(np.argmin(np.isfinite(x).all(axis=0)))
        raise StreamError(f"non-finite volts on channel(s) {', '.join(bad)} at t = "
                          f"{t0_s + i * dt_s:.6g} s")
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
    info : model description returned by :meth:`model_info` (a dict of its keys is made a
        :class:`rig.model_info.ModelInfo`).
    """

    def __init__(self, fs_hz: float, signals: Callable, calibrations: dict[str, Calibration], *,
                 seed: int = 0, block_samples: int = 1000, response: Callable | None = None,
                 info: ModelInfo | dict | None = None, units: dict | None = None):
        self.fs_hz = float(fs_hz)
        self._signals, self._cal, self._seed = signals, dict(calibrations), seed
        self._block, self._response = int(block_samples), response
        self._info = (info if isinstance(info, ModelInfo) else ModelInfo.from_dict(
            info or {"model": "function", "method": "exact", "error_estimate": 0.0}))
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

    def model_info(self) -> ModelInfo:
        return self._info




#: The ground truth recorded from the rig (the contract of rig.blocks.AnalogBlock); the bench's
#: other truth series (coil current, stage velocity, spot positions, flags) are not stored.
RIG_TRUTH = ("stage_accel_mps2", "theta_rad", "mirror_x_m", "mirror_rot_rad", "source_v")
#: bench block length [s] (at most; a record if shorter): the paper's 100 s records come as one
#: block each. Blocks of any length give the same samples (tests/rig/bench/test_fused.py);
#: longer ones spread the per-block work (digitising, slicing, queueing) over more samples.
BLOCK_S = 100.0


def rig_bench(scene: Scene, seed: int, *, lifted: bool = True, block_s: float = BLOCK_S,
              **bench_kw) -> Bench:
    """The emulated rig of ``scene`` (:class:`rig.bench.BenchSimulation`) as a bench;
    ``bench_kw`` (e.g. ``method="lawson4"``) go to the simulation. ``lifted`` (default True):
    a :class:`DecimatingBench` by the rig's fused chain (:mod:`rig.bench.fused`: the linear
    model lifted, the nonlinear one fused after its per-sample bench); False: the per-sample
    blocks (a plain :class:`Bench`). ``block_s``: its block length [s] (default
    :data:`BLOCK_S`; the same samples whatever it is). ``functools.partial`` of this is an
    ``acquire(bench=...)``."""
    return (_FusedRigBench if lifted else _RigBench)(scene, seed, block_s=block_s, **bench_kw)


class _RigBench:
    """:class:`rig.bench.BenchSimulation` behind the :class:`Bench` interface.

    ``expected_response`` is the exact discrete-time response of the simulated samples
    (``sampled=True``: DAC hold and folding included) for every (nf,) response of the bench, plus
    the continuous pendulum alone (``*_continuous``, from ``sampled=False``).
    """

    units = rb.BenchResponse.UNITS
    long_names = rb.BenchResponse.LONG_NAMES
    truth_keys = RIG_TRUTH
    saturation_keys = {"a": "a_overrange", "x": "psd_off_detector", "y": "psd_off_detector"}

    def __init__(self, scene: Scene, seed: int, *, block_s: float = BLOCK_S, **bench_kw):
        self._scene = scene
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

    def blocks(self) -> Iterator[AnalogBlock]:
        return self._sim.blocks(self._block_s, self._duration_s)

    def calibrations(self) -> dict[str, Calibration]:
        return dict(self._sim.calibrations())

    def expected_response(self, freqs_hz) -> dict:
        exact = rb.expected_response(self._scene, freqs_hz, sampled=True)
        cont = rb.expected_response(self._scene, freqs_hz, sampled=False)
        out = {k: v for k, v in _as_dict(exact).items() if k in self.units}
        out["h_t_pendulum_continuous"] = cont.h_t_pendulum
        out["theta_2_pendulum_continuous"] = cont.theta_2_pendulum
        return out

    def model_info(self) -> ModelInfo:
        return self._sim.model_info()


class _FusedRigBench(_RigBench):
    """:class:`_RigBench` as a :class:`DecimatingBench`: the rig's fused chain
    (:meth:`rig.bench.BenchSimulation.decimated_blocks`), either model."""

    def decimated_blocks(self, aa: AntiAliasFilter) -> Iterator[DecimatedBlock]:
        """The run through the anti-alias filter ``aa`` and kept every ``aa.decimation``
        samples by the fused chain (the filter's sections handed to rig as plain arrays)."""
        q = self._sim.model.decimation
        if aa.decimation != q:
            raise ConfigError(f"the anti-alias filter decimates by {aa.decimation} but the "
                              f"bench's acquisition by {q}")
        sos = np.zeros((0, 6)) if aa.kind == "none" else aa.sos
        return self._sim.decimated_blocks(self._block_s, self._duration_s, sos)

    def model_info(self) -> ModelInfo:
        return rb.fused_model_info(self._sim.model, super().model_info())


def _as_dict(obj) -> dict:
    if isinstance(obj, dict):
        return dict(obj)
    import dataclasses

    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}
