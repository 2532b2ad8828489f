"""What a bench simulated, as a typed value: :class:`ModelInfo`.

The run file stores it as JSON (:meth:`ModelInfo.to_dict`, the key order of the fields; a field
that is None is absent) and reads it back with :meth:`ModelInfo.from_dict`, which keeps keys it
does not know (another bench's, or a later version's) in ``extra``. The nested parts
(``selection``, ``per_sample``, ``linearity``, ``error_estimate``) stay JSON-ready dicts: their
keys depend on the model and method (:func:`rig.bench.estimates.model_info` lists them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

__all__ = ["ModelInfo"]


@dataclass(frozen=True)
class ModelInfo:
    """Which model ran, why, how, and its error estimate (JSON-ready values).

    Attributes
    ----------
    model : what ran ("linear", "nonlinear", or another bench's name).
    requested_model : ``acquisition.model`` ("auto", "linear", "nonlinear").
    error_budget : the budget on the relative RMS angle error.
    reason : one sentence: the choice and the numbers behind it.
    fs_hz : simulation rate [Hz].
    hold : how the source's DAC value is held.
    reaction : the stage feels the pendulum's reaction.
    states : names (with units) of the bench's state vector.
    seed : the seed as recorded (the root SeedSequence's entropy).
    probe_s : duration of the probe run the error estimate is measured on [s].
    selection : the model choice (:func:`rig.bench.selection.select_model`).
    per_sample : what runs at every DAC sample and why (``rate_hz``, ``what``, ``why``, ...).
    linearity : rms angles and the frequency-shift rule of thumb.
    method : how the model is integrated and stepped.
    remainder_every_steps : etdab only: steps between the remainder's evaluations.
    error_estimate : the estimated error (a dict of parts in [rad] or relative, or a number).
    error_method : how the estimate was made.
    budget_met : the estimate is within ``error_budget``.
    estimate_wall_time_s : wall time of the estimate [s] (not stored in run files).
    extra : any other keys, in their order (after the fields).
    """

    model: str | None = None
    requested_model: str | None = None
    error_budget: float | None = None
    reason: str | None = None
    fs_hz: float | None = None
    hold: str | None = None
    reaction: bool | None = None
    states: list | None = None
    seed: Any = None
    probe_s: float | None = None
    selection: dict | None = None
    per_sample: dict | None = None
    linearity: dict | None = None
    method: str | None = None
    remainder_every_steps: int | None = None
    error_estimate: dict | float | None = None
    error_method: str | None = None
    budget_met: bool | None = None
    estimate_wall_time_s: float | None = None
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The JSON-ready dict the run file stores: the fields that are not None, in order,
        then ``extra``."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if f.name != "extra" and getattr(self, f.name) is not None}
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, d: dict) -> ModelInfo:
        """The :class:`ModelInfo` of a stored dict (keys it does not name go to ``extra``)."""
        names = {f.name for f in dataclasses.fields(cls)} - {"extra"}
        return cls(**{k: v for k, v in d.items() if k in names},
                   extra={k: v for k, v in d.items() if k not in names})

