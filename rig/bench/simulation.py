"""The stateful wrapper of a bench run: :class:`BenchSimulation`.

:func:`rig.bench.model.build_model` + :func:`rig.bench.run.start` + repeated
:func:`rig.bench.run.advance`, with the source's blocks made ahead in a thread, the channel
calibrations and the model information (:func:`rig.bench.estimates.model_info`) of the run.
"""

from __future__ import annotations

from typing import Iterator

from rig.blocks import AnalogBlock, Calibration
from rig.errors import ConfigError
from rig._threads import Prefetch
from rig.scene import Scene
from rig.devices.source import start_source
from rig.bench.estimates import _model_info
from rig.bench.model import build_model
from rig.bench.response import _calibrations
from rig.bench.run import _REL, _block_sizes, _source_blocks, _spawn, advance, start


class BenchSimulation:
    """A running bench: :func:`build_model` + :func:`start` + repeated :func:`advance`.

    Parameters
    ----------
    scene : the scene (its ``source``, ``stage``, ``accelerometer``, ``psd`` and ``acquisition``
        sections).
    seed : int or SeedSequence for every random stream of the run.
    method, oversample, substeps, rtol, atol : nonlinear-model settings (:func:`build_model`).

    ahead : ``(block_s, duration_s)`` of the first :meth:`blocks` call to come: its source is
        made from now on in another thread (the source does not depend on the model; numpy's
        FFTs release the GIL), while the model is chosen and the compiled kernels load. A later
        call with other arguments, or after other steps, makes its own.

    With ``acquisition.model = "auto"`` the model is chosen at construction (:func:`select_model`).
    ``next_block(n)`` returns the next n samples, ``blocks(block_s, duration_s)`` yields blocks of
    ``block_s`` seconds; both continue where the previous call stopped. ``state`` is the current
    :class:`BenchState` (assignable, e.g. to rewind).
    """

    #: source blocks made ahead at most (10 s blocks at 1 kHz: 64 x 80 kB)
    AHEAD_BLOCKS = 64

    def __init__(self, scene: Scene, seed=0, *, method: str | None = None, oversample: int = 8,
                 substeps: int = 1, rtol: float = 1e-10, atol: float = 1e-12,
                 ahead: tuple[float, float] | None = None):
        root, children = _spawn(seed)
        self.seed = root  # seed=None draws OS entropy once; root.entropy is then the record
        self._ahead = None
        if ahead is not None:
            acq, source = scene.acquisition, scene.source
            sizes = _block_sizes(acq.simulation_rate_hz, acq.decimation, *ahead)
            made = Prefetch(_source_blocks(source, start_source(source, children[0]), sizes),
                            self.AHEAD_BLOCKS)
            self._ahead = (tuple(ahead), sizes, made)
        self.model = build_model(scene, method=method, oversample=oversample, substeps=substeps,
                                 rtol=rtol, atol=atol)
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
        sizes = _block_sizes(fs, self.model.decimation, block_s, duration_s)
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead[0] == (block_s, duration_s) and self.state.index == 0:
            made = ahead[2]
        else:
            if ahead is not None:
                ahead[2].close()
            # the source does not depend on the bench: its blocks are made ahead in a thread
            made = Prefetch(_source_blocks(self.model.source, self.state.source, sizes), 2)
        try:
            for k, src in zip(sizes, made):
                block, self.state = advance(self.model, self.state, k, src)
                yield block
        finally:
            made.close()

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
        return _calibrations(self.model)

    def model_info(self, *, probe_s: float = 20.0) -> dict:
        """What runs, why, and how accurate it is (computed once, cached; JSON-ready).

        Keys: ``model`` ("linear" or "nonlinear": what runs), ``requested_model``
        (``acquisition.model``), ``error_budget``, ``reason`` (a sentence: the choice and the
        numbers behind it), ``budget_met`` (the estimated error of the model that runs is within
        the budget), ``selection`` (:func:`select_model`, with the predictor's ``how``),
        ``method`` (how it is integrated), ``error_estimate`` (``max_abs_theta_rad`` first,
        ``relative_rms_theta``: the total relative RMS angle error, and its parts),
        ``error_method``, ``linearity`` (rms angles and the frequency-shift rule of thumb),
        ``states``, ``seed``, ``probe_s``, ``fs_hz``, ``hold``, ``reaction``,
        ``estimate_wall_time_s``. The error of the nonlinear model's integrator and the linear
        model's round-off are measured on a ``probe_s`` run of the scene's drive from rest.
        """
        if self._info is None or self._info["probe_s"] != probe_s:
            self._info = _model_info(self.model, probe_s=probe_s, seed=self.seed)
        return self._info
