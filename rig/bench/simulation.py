"""The stateful wrapper of a bench run: :class:`BenchSimulation`.

:func:`rig.bench.model.build_model` + :func:`rig.bench.run.start` + repeated
:func:`rig.bench.run.advance`, with the source's blocks made ahead in a thread, the channel
calibrations and the model information (:func:`rig.bench.estimates.model_info`) of the run.
"""

from __future__ import annotations

import math
from typing import Iterator

import numpy as np

from rig.blocks import AnalogBlock, Calibration, DecimatedBlock
from rig.errors import ConfigError
from rig.threads import Prefetch
from rig.sosfilt import lift_sections
from rig.scene import Scene
from rig.devices.source import generate, start_source
from rig.bench.estimates import model_info_of
from rig.model_info import ModelInfo
from rig.bench.fused import advance_decimated, advance_decimated_nonlinear, lift, start_decimated
from rig.bench.model import build_model
from rig.bench.response import calibrations
from rig.bench.run import spawn_streams, advance, start

_REL = 1e-9


class _Replay:
    """Items taken from a :class:`rig.threads.Prefetch` ahead of time, then the rest of it;
    ``close()`` closes it."""

    def __init__(self, taken: list, rest: Prefetch):
        self._taken, self._rest = list(taken), rest

    def __iter__(self):
        return self

    def __next__(self):
        if self._taken:
            return self._taken.pop(0)
        return next(self._rest)

    def close(self) -> None:
        self._taken = []
        self._rest.close()


def _block_sizes(fs: float, decimation: int, block_s, duration_s) -> list[int]:
    """Samples per block for :meth:`BenchSimulation.blocks` (one block if ``duration_s`` is
    None), or :class:`ConfigError` naming the bad value."""
    r = block_s * fs if isinstance(block_s, (int, float)) and not isinstance(block_s, bool) \
        else float("nan")
    n = int(round(r)) if math.isfinite(r) else 0
    if n < 1 or abs(r - n) > _REL * max(1.0, r) or n % decimation:
        raise ConfigError(f"block_s = {block_s!r} s is invalid: expected a whole number (>= 1)"
                          f" of ADC samples at acquisition.rate_hz = {fs / decimation:g} Hz")
    if duration_s is None:
        return [n]
    total = duration_s * fs if isinstance(duration_s, (int, float)) else float("nan")
    if not (math.isfinite(total) and total >= 1 and abs(total - round(total)) <= _REL * total):
        raise ConfigError(f"duration_s = {duration_s!r} s is invalid: expected a whole number "
                          f"(>= 1) of samples at {fs:g} Hz")
    left = int(round(total))
    sizes = []
    while left > 0:
        sizes.append(min(n, left))
        left -= sizes[-1]
    return sizes


def _source_blocks(source, state, sizes):
    """``generate(source, ., k)`` for each k of ``sizes`` in turn, from ``state``."""
    for k in sizes:
        v, state = generate(source, state, k)
        yield v, state


class BenchSimulation:
    """A running bench: :func:`build_model` + :func:`start` + repeated :func:`advance`.

    Parameters
    ----------
    scene : the scene (its ``source``, ``stage``, ``accelerometer``, ``psd`` and ``acquisition``
        sections).
    seed : int or SeedSequence for every random stream of the run.
    method, oversample, substeps, every, rtol, atol : nonlinear-model settings
        (:func:`build_model`).

    ahead : ``(block_s, duration_s)`` of the first :meth:`blocks` call to come: its source is
        made from now on in another thread (the source does not depend on the model; numpy's
        FFTs release the GIL), while the model is chosen and the compiled kernels load. A later
        call with other arguments, or after other steps, makes its own.

    With ``acquisition.model = "auto"`` the model is chosen at construction (:func:`select_model`).
    ``next_block(n)`` returns the next n samples, ``blocks(block_s, duration_s)`` yields blocks of
    ``block_s`` seconds; both continue where the previous call stopped. ``state`` is the current
    :class:`BenchState` (assignable, e.g. to rewind).
    """

    #: source samples made ahead at most (2^22: 32 MB of float64, the paper's whole 3330 s at
    #: 1 kHz; in whole blocks, at least 2)
    AHEAD_SAMPLES = 1 << 22

    def __init__(self, scene: Scene, seed=0, *, method: str | None = None, oversample: int = 8,
                 substeps: int = 1, every: int | None = None, rtol: float = 1e-10,
                 atol: float = 1e-12, ahead: tuple[float, float] | None = None):
        root, children = spawn_streams(seed)
        self.seed = root  # seed=None draws OS entropy once; root.entropy is then the record
        self._ahead = None
        if ahead is not None:
            acq, source = scene.acquisition, scene.source
            sizes = _block_sizes(acq.simulation_rate_hz, acq.decimation, *ahead)
            made = Prefetch(_source_blocks(source, start_source(source, children[0]), sizes),
                            max(2, self.AHEAD_SAMPLES // max(sizes)))
            self._ahead = (tuple(ahead), sizes, made)
        self.model = build_model(scene, method=method, oversample=oversample, substeps=substeps,
                                 every=every, rtol=rtol, atol=atol)
        self.state = start(self.model, root)
        self._info = None

    @property
    def fs_hz(self) -> float:
        """Simulation rate [Hz]."""
        return self.model.fs_hz

    @property
    def time_s(self) -> float:
        """Time of the next sample [s]."""
        return self.state.index / self.model.fs_hz

    def next_block(self, n_samples: int) -> AnalogBlock:
        """The next ``n_samples`` samples as an :class:`AnalogBlock`."""
        block, self.state = advance(self.model, self.state, n_samples)
        return block

    def blocks(self, block_s: float, duration_s: float | None = None) -> Iterator[AnalogBlock]:
        """Blocks of ``block_s`` seconds (a whole number of samples, and of ADC samples), for
        ``duration_s`` seconds (a whole number of blocks' worth; the last block may be shorter)
        or for ever (None)."""
        fs = self.model.fs_hz
        if duration_s is None:
            n = _block_sizes(fs, self.model.decimation, block_s, None)[0]
            while True:
                yield self.next_block(n)
        sizes, made = self._sources(block_s, duration_s)
        try:
            for k, src in zip(sizes, made):
                block, self.state = advance(self.model, self.state, k, src)
                yield block
        finally:
            made.close()

    def decimated_blocks(self, block_s: float, duration_s: float, sos
                         ) -> Iterator[DecimatedBlock]:
        """Like :meth:`blocks`, but through the anti-alias sections ``sos`` (rows ``[b0, b1,
        b2, 1, a1, a2]``, (0, 6) for none) and kept at every ``decimation``-th sample, by the
        fused chain (:mod:`rig.bench.fused`): the linear model lifted, the nonlinear one stepped
        per sample and fused after the bench, the filter lifted in both (each equal to
        :meth:`blocks` filtered and decimated up to round-off). Starts at a kept instant."""
        q = self.model.decimation
        if self.state.index % q:
            raise ConfigError(f"decimated_blocks must start at a kept instant (sample "
                              f"{self.state.index} is not a multiple of {q})")
        chain = start_decimated(sos)
        sections = lift_sections(sos, q)
        if self.model.model == "linear":
            lifted = lift(self.model, q)

            def step(k, src, chain):
                return advance_decimated(self.model, lifted, self.state, chain, k, sections, src)
        else:
            def step(k, src, chain):
                return advance_decimated_nonlinear(self.model, self.state, chain, k, sections,
                                                   src)
        sizes, made = self._sources(block_s, duration_s)
        try:
            for k, src in zip(sizes, made):
                block, self.state, chain = step(k, src, chain)
                yield block
        finally:
            made.close()

    def _sources(self, block_s, duration_s):
        """The block sizes and the source's blocks for them, made ahead in a thread (those made
        since construction if ``ahead`` matches and nothing ran yet)."""
        sizes = _block_sizes(self.model.fs_hz, self.model.decimation, block_s, duration_s)
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead[0] == (block_s, duration_s) and self.state.index == 0:
            return sizes, ahead[2]
        if ahead is not None:
            ahead[2].close()
        # the source does not depend on the bench: its blocks are made ahead in a thread
        return sizes, Prefetch(_source_blocks(self.model.source, self.state.source, sizes), 2)

    def run(self, duration_s: float) -> AnalogBlock:
        """The next ``duration_s`` seconds as one block."""
        r = duration_s * self.model.fs_hz
        n = int(round(r))
        if n < 1 or abs(r - n) > _REL * max(1.0, r):
            raise ConfigError(f"duration_s = {duration_s!r} s is invalid: expected a whole number "
                              f"(>= 1) of samples at {self.model.fs_hz:g} Hz")
        return self.next_block(n)

    def calibrations(self) -> dict[str, Calibration]:
        """Per-channel calibrations (:func:`calibrations`)."""
        return calibrations(self.model.scene)

    def model_info(self, *, probe_s: float = 20.0) -> ModelInfo:
        """What runs, why, and how accurate it is (computed once, cached).

        Fields (:class:`rig.model_info.ModelInfo`): ``model`` ("linear" or "nonlinear": what
        runs), ``requested_model`` (``acquisition.model``), ``error_budget``, ``reason`` (a
        sentence: the choice and the numbers behind it), ``budget_met`` (the estimated error of
        the model that runs is within the budget), ``selection`` (:func:`select_model`, with the predictor's ``how``),
        ``method`` (how it is integrated; etdab also ``remainder_every_steps``: the steps
        between its remainder's evaluations), ``error_estimate`` (``max_abs_theta_rad`` first,
        ``relative_rms_theta``: the total relative RMS angle error, and its parts),
        ``error_method``, ``linearity`` (rms angles and the frequency-shift rule of thumb),
        ``states``, ``seed``, ``probe_s``, ``fs_hz``, ``hold``, ``reaction``,
        ``estimate_wall_time_s``. The error of the nonlinear model's integrator and the linear
        model's round-off are measured on a ``probe_s`` run of the scene's drive from rest.
        """
        if self._info is None or self._info.probe_s != probe_s:
            n = max(1, int(round(probe_s * self.model.fs_hz)))
            self._info = model_info_of(self.model, probe_s=probe_s, seed=self.seed,
                                       probe_v=self._first_samples(n))
        return self._info

    def _first_samples(self, n: int):
        """The run's first ``n`` source samples from the blocks made ahead (the probe of
        :meth:`model_info` drives the bench with the same stream from rest: no need to make
        them twice), or None if there are none or too few. The blocks taken are handed to the
        run as before."""
        if self._ahead is None or self.state.index != 0:
            return None
        args, sizes, made = self._ahead
        got, have = [], 0
        try:
            while have < n and len(got) < len(sizes):
                got.append(next(made))
                have += got[-1][0].size
        finally:
            self._ahead = (args, sizes, _Replay(got, made))
        return np.concatenate([g[0] for g in got])[:n] if have >= n else None
