"""Records: how a run is cut into records, and the plain data types of the acquisition stream.

One continuous run
------------------
The bench starts once at t = 0 and is never restarted: after ``settle_s`` (which lets the
pendulum's and the anti-alias filter's transients die out) ``records`` records of ``record_s`` each
are taken back to back. Output sample ``j`` (at ``rate_hz``) is at ``t = j / rate_hz`` from the
start of the run; record ``r`` holds samples ``settle + r N .. settle + (r+1) N - 1`` (``N``
samples per record), so the last sample of record ``r`` and the first of record ``r + 1`` are consecutive
samples of one signal, and every state (pendulum, sensors, filter, random generators) carries over.

Channels and ground truth
-------------------------
The channels are sensor volts that went through the anti-alias filter, then the ADC. The ground
truth (stage acceleration, angles, mirror translation and rotation, source voltage) is the bench's
state *sampled* at the same instants ``t = j / rate_hz``, with no filter, no sensor and no ADC.
Consequences for comparing the two:

- in time, a channel lags its truth by the filter's group delay (27.6 ms at low frequency for the
  default 100 Hz design) plus the sensor's own dynamics, and its gain differs by the filter's
  ripple (<= 0.01 dB below 0.4 rate) and roll-off (above 0.4 rate): compare a channel with the
  sensor chain *and* :meth:`daq.antialias.AntiAliasFilter.response` applied to the truth, or
  compare in frequency with the stored model response of the whole chain;
- the truth is not band-limited before sampling: whatever it holds above ``rate_hz / 2`` aliases in
  it (the channels are protected by the filter);
- ratios of channels (H_t = x / a, Theta_2 = y / a) do not see the filter, which is the same on all
  channels: they compare directly with the truth's ratios and with the analytic model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from daq.antialias import AntiAliasFilter
from daq.channels import Channel
from rig.acquisition_settings import AcquisitionSettings, whole_samples
from rig.model_info import ModelInfo
from rig.scene import Scene

STATUSES = ("acquiring", "complete", "interrupted", "failed")


@dataclass(frozen=True)
class RecordPlan:
    """How the run is sampled and cut into records (validated; see the module docstring).

    Attributes
    ----------
    rate_hz : sample rate of every channel [Hz].
    simulation_rate_hz : rate of the analog simulation [Hz], ``decimation * rate_hz``.
    records : number of records (>= 1).
    samples : samples per record (>= 1).
    settle_samples : samples dropped before the first record (>= 0).
    """

    rate_hz: float
    simulation_rate_hz: float
    records: int
    samples: int
    settle_samples: int

    @classmethod
    def from_acquisition(cls, acquisition: AcquisitionSettings) -> "RecordPlan":
        """From ``Scene.acquisition`` (validated when the scene was loaded)."""
        rate = acquisition.rate_hz
        return cls(rate_hz=float(rate), simulation_rate_hz=float(acquisition.simulation_rate_hz),
                   records=acquisition.records,
                   samples=whole_samples("acquisition.record_s", acquisition.record_s, rate,
                                         minimum=1),
                   settle_samples=whole_samples("acquisition.settle_s", acquisition.settle_s,
                                                rate, minimum=0))

    @property
    def decimation(self) -> int:
        return int(round(self.simulation_rate_hz / self.rate_hz))

    @property
    def record_s(self) -> float:
        return self.samples / self.rate_hz

    @property
    def settle_s(self) -> float:
        return self.settle_samples / self.rate_hz

    @property
    def total_samples(self) -> int:
        """Output samples from t = 0 to the end of the last record."""
        return self.settle_samples + self.records * self.samples

    @property
    def simulation_samples(self) -> int:
        """Samples the bench must deliver at the simulation rate."""
        return self.total_samples * self.decimation

    @property
    def duration_s(self) -> float:
        """Simulated time, settling included [s]."""
        return self.total_samples / self.rate_hz

    def record_start_s(self, record: int) -> float:
        """Time of the first sample of ``record`` from the start of the run [s]."""
        return (self.settle_samples + record * self.samples) / self.rate_hz

    def times_s(self) -> np.ndarray:
        """Sample times within a record [s], shape (samples,)."""
        return np.arange(self.samples) / self.rate_hz

    def frequencies_hz(self) -> np.ndarray:
        """The record's FFT grid ``k / record_s``, k = 0 .. samples // 2 [Hz] (0 .. rate/2)."""
        return np.arange(self.samples // 2 + 1) * (self.rate_hz / self.samples)

    def describe(self) -> dict:
        return {"rate_hz": self.rate_hz, "simulation_rate_hz": self.simulation_rate_hz,
                "decimation": self.decimation, "records": self.records,
                "samples_per_record": self.samples, "record_s": self.record_s,
                "settle_samples": self.settle_samples, "settle_s": self.settle_s}


# -- ground truth ----------------------------------------------------------------------------

#: What the bench's truth keys are (SPEC section 5); unknown keys get their unit from the suffix.
TRUTH_NAMES = {
    "stage_accel_mps2": "stage acceleration x0'' (true, unfiltered)",
    "theta_rad": "pendulum angles theta_j from the downward vertical",
    "mirror_x_m": "mirror translation relative to the stage along +x",
    "mirror_rot_rad": "mirror rotation (theta of the mirror's body)",
    "source_v": "analyzer source voltage (DAC output, held)",
}
_SUFFIX_UNITS = (("_mps2", "m/s^2"), ("_rad_s", "rad/s"), ("_mps", "m/s"), ("_rad", "rad"),
                 ("_m", "m"), ("_v", "V"), ("_a", "A"), ("_n", "N"), ("_s", "s"))


@dataclass(frozen=True)
class TruthField:
    """One ground-truth series: ``(samples,) + shape`` per block; ``dims`` names the extra axes."""

    name: str
    unit: str
    long_name: str
    shape: tuple = ()
    dims: tuple = ()

    @classmethod
    def from_array(cls, name: str, a: np.ndarray) -> "TruthField":
        unit = next((u for s, u in _SUFFIX_UNITS if name.endswith(s)), "")
        shape = tuple(int(n) for n in np.shape(a)[1:])
        dims = tuple("body" if (name.startswith("theta") and i == 0) else f"{name}_dim{i}"
                     for i in range(len(shape)))
        return cls(name, unit, TRUTH_NAMES.get(name, name), shape, dims)


# -- the stream ------------------------------------------------------------------------------

@dataclass(frozen=True)
class ModelResponse:
    """Exact responses of the whole chain on a frequency grid.

    ``values[name]`` is complex, shape (frequencies,); ``units[name]`` and ``long_names[name]`` say
    what it is, e.g. ``values["H_t"]`` [m per m/s^2].
    """

    freqs_hz: np.ndarray
    values: dict
    units: dict = field(default_factory=dict)
    long_names: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Header:
    """What is known before the first sample: sent to every sink first."""

    scene: Scene
    seed: int
    plan: RecordPlan
    channels: tuple
    antialias: AntiAliasFilter
    truth: tuple
    model_info: ModelInfo
    response: ModelResponse
    software_version: str
    start_time: str

    @property
    def names(self) -> tuple:
        return tuple(c.name for c in self.channels)

    def channel(self, name: str) -> Channel:
        for c in self.channels:
            if c.name == name:
                return c
        raise KeyError(name)

    def noise_rms(self, *, quantisations: int = 1) -> dict[str, float]:
        """Predicted rms of the noise of each channel a, x, y, in engineering units: its
        sensor's white noise through the anti-alias filter plus ``quantisations``
        quantisations (one ADC's: 1; a difference of two quantised channels: 2)."""
        import math

        sc, aa = self.scene, self.antialias
        f = np.linspace(0.0, aa.fs_hz / 2, 200_001)
        gain2 = float(np.trapezoid(np.abs(aa.response(f)) ** 2, f))  # [Hz]
        density_v = {"a": sc.accelerometer.sensitivity_vpmps2 * sc.accelerometer.noise_mps2_rthz,
                     "x": sc.lever.gain_vpm * sc.lever.noise_m_rthz,
                     "y": sc.lever.gain_vpm * sc.lever.noise_m_rthz}
        out = {}
        for c in (c for c in self.names if c in density_v):
            ch = self.channel(c)
            var_v = abs(density_v[c]) ** 2 * gain2 + quantisations * ch.adc.lsb_v ** 2 / 12
            out[c] = math.sqrt(var_v) / abs(ch.volts_per_unit)
        return out


@dataclass(frozen=True, eq=False)
class Block:
    """Consecutive samples of one record as they are digitised (for live views).

    ``codes[name]`` and ``clipped[name]`` are (samples,); ``truth[name]`` is (samples,) + shape.
    ``saturated[name]`` (samples,) is True where the channel's sensor was beyond its range at
    some simulation instant of the sample's decimation interval (absent: never).
    ``start`` is the index within record ``record`` of the first sample.
    """

    record: int
    start: int
    t0_s: float
    codes: dict
    clipped: dict
    truth: dict
    saturated: dict = field(default_factory=dict)

    @property
    def samples(self) -> int:
        return len(next(iter(self.codes.values())))


@dataclass(frozen=True, eq=False)
class Record:
    """One complete record: ``codes[name]``, ``clipped[name]``, ``saturated[name]`` (samples,),
    ``truth[name]``."""

    index: int
    t0_s: float
    codes: dict
    clipped: dict
    truth: dict
    saturated: dict = field(default_factory=dict)

    def clip_counts(self) -> dict:
        """Clipped samples per channel in this record."""
        return {k: int(np.count_nonzero(v)) for k, v in self.clipped.items()}

    def saturation_counts(self) -> dict:
        """Samples per channel whose sensor saturated (see :class:`Block`) in this record."""
        return {k: int(np.count_nonzero(self.saturated.get(k, ()))) for k in self.codes}


@dataclass(frozen=True, eq=False)
class Footer:
    """How the run ended: sent to every sink last.

    ``status`` is one of "complete", "interrupted", "failed"; ``clip_counts`` is
    (records_complete, channels) in the header's channel order.
    """

    status: str
    records_complete: int
    clip_counts: np.ndarray
    message: str = ""
    wall_s: float = 0.0


class RecordBuffer:
    """Assembles the blocks of one record at a time into a :class:`Record`."""

    def __init__(self, header: Header):
        self._header = header
        self._index = None
        self._filled = 0

    def _new(self, index: int):
        h, n = self._header, self._header.plan.samples
        self._index, self._filled = index, 0
        self._codes = {c.name: np.empty(n, c.adc.dtype) for c in h.channels}
        self._clipped = {c.name: np.empty(n, bool) for c in h.channels}
        self._saturated = {c.name: np.zeros(n, bool) for c in h.channels}
        self._truth = {t.name: np.empty((n,) + t.shape) for t in h.truth}

    def add(self, block: Block) -> Record | None:
        """Add a block (in order); return the record it completes, if any."""
        if block.start == 0:
            self._new(block.record)
        if block.record != self._index or block.start != self._filled:
            raise ValueError(f"block of record {block.record} at sample {block.start} is out of "
                             f"order (expected record {self._index} at {self._filled})")
        sl = slice(block.start, block.start + block.samples)
        for k, v in block.codes.items():
            self._codes[k][sl] = v
            self._clipped[k][sl] = block.clipped[k]
            if k in block.saturated:
                self._saturated[k][sl] = block.saturated[k]
        for k, v in block.truth.items():
            self._truth[k][sl] = v
        self._filled = sl.stop
        if self._filled < self._header.plan.samples:
            return None
        return Record(index=self._index, t0_s=self._header.plan.record_start_s(self._index),
                      codes=self._codes, clipped=self._clipped, truth=self._truth,
                      saturated=self._saturated)


@dataclass(frozen=True, eq=False)
class Recording:
    """A run's records in memory (from :class:`daq.acquisition.MemorySink` or
    :func:`daq.hdf5.read_run`).

    Attributes
    ----------
    header : the run's header.
    codes, clipped : per channel, (records, samples).
    truth : per truth field, (records, samples) + shape (empty if not recorded).
    status : "complete", "interrupted", "failed" or "acquiring" (writer stopped or still running).
    saturated : per channel, (records, samples): the sensor beyond its range within the sample's
        decimation interval (see :class:`Block`; a channel absent here never saturated).
    """

    header: Header
    codes: dict
    clipped: dict
    truth: dict
    status: str
    saturated: dict = field(default_factory=dict)

    @property
    def records(self) -> int:
        """Number of complete records held."""
        return len(next(iter(self.codes.values())))

    @property
    def complete(self) -> bool:
        return self.status == "complete"

    def volts(self, name: str) -> np.ndarray:
        """Channel ``name`` in volts, (records, samples) [V]."""
        return self.header.channel(name).adc.volts(self.codes[name])

    def values(self, name: str) -> np.ndarray:
        """Channel ``name`` in its engineering unit (calibration and its sign undone)."""
        return self.volts(name) / self.header.channel(name).volts_per_unit

    def to_xarray(self, units: str = "eu"):
        """The channels as an ``xarray.Dataset`` in ``units`` ("eu": m/s^2, m, rad, the arrays
        the analyzer transforms; "volts"; "codes"), units on every variable
        (:func:`daq.eu.to_xarray`)."""
        from daq.eu import to_xarray

        return to_xarray(self, units=units)

    def clip_counts(self) -> np.ndarray:
        """Clipped samples, (records, channels)."""
        return np.array([[np.count_nonzero(self.clipped[c][r]) for c in self.header.names]
                         for r in range(self.records)], dtype=np.int64).reshape(
            self.records, len(self.header.names))

    def saturation_counts(self) -> np.ndarray:
        """Samples whose sensor saturated, (records, channels)."""
        return np.array([[np.count_nonzero(self.saturated[c][r]) if c in self.saturated else 0
                          for c in self.header.names] for r in range(self.records)],
                        dtype=np.int64).reshape(self.records, len(self.header.names))

    def times_s(self) -> np.ndarray:
        """Sample times within a record [s]."""
        return self.header.plan.times_s()

    def record_start_s(self) -> np.ndarray:
        """Start of each record from the start of the run [s]."""
        return np.array([self.header.plan.record_start_s(r) for r in range(self.records)])
