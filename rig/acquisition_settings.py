"""The scene's ``[acquisition]`` section: how the bench is sampled, filtered, digitised and cut into
records, and which pendulum model is simulated (frozen, validated at load).

The rates, the record count and the durations are checked here, when the scene is loaded
(:func:`decimation_factor`, :func:`whole_samples`); the anti-alias design and the ADC check their
own numbers (:mod:`daq.antialias`, :mod:`daq.adc`) when the acquisition is planned, before any
work. ``daq`` turns these settings into its record plan (:class:`daq.records.RecordPlan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rig.errors import ConfigError
from rig.params import param

_REL = 1e-9


def decimation_factor(fs_hz: float, rate_hz: float, *, fs_name: str = "simulation_rate_hz",
                      rate_name: str = "rate_hz") -> int:
    """``fs_hz / rate_hz`` as an integer >= 2, or :class:`ConfigError` naming both values."""
    for name, v in ((rate_name, rate_hz), (fs_name, fs_hz)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ConfigError(f"{name} = {v!r} is invalid: expected a finite rate > 0 Hz")
    if rate_hz > fs_hz:
        raise ConfigError(f"{rate_name} = {rate_hz:g} Hz is invalid: it is above {fs_name} = "
                          f"{fs_hz:g} Hz; expected {fs_name} / q for an integer q >= 2")
    r = fs_hz / rate_hz
    q = int(round(r)) if math.isfinite(r) else 0
    if not math.isfinite(r) or abs(r - q) > 1e-9 * r:
        raise ConfigError(f"{rate_name} = {rate_hz:g} Hz is invalid: {fs_name} = {fs_hz:g} Hz is "
                          f"not an integer multiple of it (ratio {r:.6g}); expected {fs_name} / q "
                          "for an integer q >= 2")
    if q < 2:
        raise ConfigError(f"{rate_name} = {rate_hz:g} Hz is invalid: it equals {fs_name}; the "
                          "anti-alias filter runs at the simulation rate and needs room above "
                          f"Nyquist: expected {fs_name} / q for an integer q >= 2")
    return q


def whole_samples(name: str, seconds, rate_hz: float, *, minimum: int) -> int:
    """``seconds * rate_hz`` as a whole number of samples >= ``minimum`` (to 1e-9 relative), or
    :class:`ConfigError` naming ``name``, the value and the sample period."""
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(
            seconds):
        raise ConfigError(f"{name} = {seconds!r} is invalid: expected a duration in seconds")
    r = seconds * rate_hz
    n = int(round(r)) if math.isfinite(r) else 0
    if not math.isfinite(r) or abs(r - n) > _REL * max(1.0, abs(r)) or n < minimum:
        what = "at least one sample" if minimum else ">= 0"
        raise ConfigError(f"{name} = {seconds!r} s is invalid: expected a whole number of samples "
                          f"at rate_hz = {rate_hz:g} Hz ({what}; a multiple of {1 / rate_hz:g} s), "
                          f"got {r:.6g} samples")
    return n


@dataclass(frozen=True)
class AcquisitionSettings:
    """``[acquisition]``: every field is a scene key (unit, default and range in its doc,
    :func:`rig.params.param`). Validated on construction: positive rates with
    ``simulation_rate_hz = q rate_hz`` for an integer q >= 2, ``records >= 1``, ``record_s`` and
    ``settle_s`` whole numbers of samples at ``rate_hz`` (at least one, and >= 0), ``error_budget
    > 0``."""

    rate_hz: float = param(100.0, "sample rate of every channel [Hz]")
    simulation_rate_hz: float = param(1000.0, "rate of the analog simulation and source DAC "
                                      "[Hz]; an integer multiple q >= 2 of rate_hz")
    records: int = param(30, "number of records (>= 1), taken back to back")
    record_s: float = param(100.0, "duration of one record [s]; a whole number of samples")
    settle_s: float = param(300.0, "settling time before the first record [s]; a whole "
                            "number of samples")
    adc_bits: int = param(16, "ADC resolution [bits], 2..32")
    antialias: str = param("elliptic", "anti-alias low-pass before decimation ('none' "
                           "decimates unfiltered, to show aliasing)", choices=("elliptic", "none"))
    antialias_passband: float = param(0.4, "anti-alias passband edge as a fraction of "
                                      "rate_hz (< 0.5); the stopband starts at rate_hz / 2")
    antialias_ripple_db: float = param(0.01, "anti-alias passband ripple [dB]")
    antialias_attenuation_db: float | None = param(None, "anti-alias attenuation at and above "
                                                   "rate_hz / 2 [dB]; default 20 log10(2^(adc_bits"
                                                   "+1))", type="float")
    range_a_v: float = param(1.0, "ADC full scale of channel a, +-[V]")
    range_x_v: float = param(10.0, "ADC full scale of channel x, +-[V]")
    range_y_v: float = param(10.0, "ADC full scale of channel y, +-[V]")
    model: str = param("auto", "pendulum model simulated: 'auto' picks the cheapest that "
                       "meets error_budget (exact linear where the predicted linearisation error "
                       "is inside it, else nonlinear); 'linear' or 'nonlinear' force one "
                       "(rig.bench)", choices=("auto", "linear", "nonlinear"))
    error_budget: float = param(1e-2, "allowed relative RMS error of the simulated angles "
                                "over the records (max over the bodies), > 0; decides model = "
                                "'auto' and is checked for a forced model (the paper's default "
                                "drive: the linear model is predicted 0.5 % off, rig.bench)")
    truth: bool = param(True, "store the ground truth beside the channels")

    def __post_init__(self):
        decimation_factor(self.simulation_rate_hz, self.rate_hz,
                          fs_name="acquisition.simulation_rate_hz", rate_name="acquisition.rate_hz")
        if isinstance(self.records, bool) or not isinstance(self.records, int) or self.records < 1:
            raise ConfigError(f"acquisition.records = {self.records!r} is invalid: expected an "
                              "integer >= 1")
        whole_samples("acquisition.record_s", self.record_s, self.rate_hz, minimum=1)
        whole_samples("acquisition.settle_s", self.settle_s, self.rate_hz, minimum=0)
        e = self.error_budget
        if isinstance(e, bool) or not isinstance(e, (int, float)) or not (math.isfinite(e)
                                                                         and e > 0):
            raise ConfigError(f"acquisition.error_budget = {e!r} is invalid: expected a relative "
                              "RMS error > 0 (e.g. 1e-3)")

    @property
    def decimation(self) -> int:
        """q = simulation_rate_hz / rate_hz (an integer >= 2)."""
        return int(round(self.simulation_rate_hz / self.rate_hz))
