"""Anti-alias filter and decimation: the simulation rate -> the sample rate of every channel.

A real DAQ puts an analog low-pass in front of each ADC and samples on one clock. Here the bench
is simulated at ``fs_hz`` (``acquisition.simulation_rate_hz``), an integer multiple ``q >= 2`` of
the sample rate ``rate_hz``; every channel goes through the *same* digital low-pass running at
``fs_hz`` (standing in for the analog filter) and then every ``q``-th filtered sample is kept.

Design (``kind="elliptic"``, the default)
-----------------------------------------
An elliptic (Cauer) low-pass in second-order sections (:func:`scipy.signal.ellip`, ``fs=fs_hz``):

- passband edge ``f_p = passband * rate_hz`` (default 0.4 rate: 40 Hz at 100 Hz), peak-to-peak
  ripple ``ripple_db`` (default 0.01 dB; the gain stays within [-ripple_db, 0] dB below f_p);
- stopband edge ``f_s = rate_hz / 2`` (the Nyquist frequency of the decimated signal), attenuation
  ``attenuation_db`` (default ``20 log10(2^(bits+1))``, 102.35 dB for a 16-bit ADC) at and above
  f_s, up to ``fs_hz / 2``: a full-scale alias stays below the ADC's rounding threshold;
- order from :func:`scipy.signal.ellipord` (12 for 1000 Hz -> 100 Hz).

The design is memoised on disk (:func:`design_cache_dir`) and the filter runs in compiled code
with ``scipy.signal.sosfilt``'s arithmetic (the same samples, bit for bit), so that a run does not
import scipy.signal. An analysis should use 0..f_p. ``kind="none"`` decimates without filtering
(to show what aliasing does).

Exact response
--------------
Sample ``j`` of the decimated output is the filtered signal at simulation index ``j q`` (time
``j / rate_hz``; no added delay). For ``f < rate_hz / 2`` a sine ``exp(2 pi i f t)`` comes out,
in steady state, times ``H(f) = prod_k (b0k + b1k z^-1 + b2k z^-2) / (1 + a1k z^-1 + a2k z^-2)``,
``z = exp(2 pi i f / fs_hz)`` (:meth:`AntiAliasFilter.response`, exact for the simulated samples;
the rows of ``sos`` are ``[b0k, b1k, b2k, 1, a1k, a2k]``). The filter is not linear-phase
(:meth:`AntiAliasFilter.group_delay_s`); the same filter on every channel cancels in any ratio of
channels (H_t = x/a, Theta_2 = y/a). Aliasing and the delay in numbers: docs/antialias.md.

State
-----
The filter starts at rest (zero state) with the bench at t = 0; the settling time before the first
record absorbs its transient. :class:`FilterState` (the ``sosfilt`` ``zi`` of every channel and the
decimation phase) is passed in and handed back by :meth:`AntiAliasFilter.step`, so filtering a run
in blocks of any sizes gives the same samples, bit for bit, as filtering it in one piece.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rig.acquisition_settings import decimation_factor
from rig.errors import ConfigError
from rig.output_files import atomic_output
from rig.sosfilt import sosfilt_inplace

KINDS = ("elliptic", "none")


def default_attenuation_db(bits: int) -> float:
    """Stopband attenuation that makes a full-scale alias at most LSB/4 [dB]:
    ``20 log10(2^(bits+1))``."""
    return 20.0 * math.log10(2.0 ** (bits + 1))


@dataclass(frozen=True)
class FilterState:
    """What carries over between blocks.

    Attributes
    ----------
    zi : (sections, channels, 2) ``sosfilt`` state (empty for ``kind="none"``).
    phase : index, within the next block, of its first sample to keep (0 <= phase < q).
    """

    zi: np.ndarray
    phase: int


@dataclass(frozen=True, eq=False)
class AntiAliasFilter:
    """One anti-alias low-pass + decimator, shared by every channel (see the module docstring).

    Build it with :meth:`design`. Attributes are in Hz and dB; ``sos`` is (sections, 6), read-only.
    """

    fs_hz: float
    rate_hz: float
    kind: str
    passband_hz: float
    stopband_hz: float
    ripple_db: float
    attenuation_db: float
    order: int
    sos: np.ndarray = field(repr=False)

    @classmethod
    def design(cls, fs_hz: float, rate_hz: float, *, bits: int = 16, kind: str = "elliptic",
               passband: float = 0.4, ripple_db: float = 0.01,
               attenuation_db: float | None = None) -> "AntiAliasFilter":
        """Design the filter for ``fs_hz -> rate_hz``.

        Parameters
        ----------
        fs_hz : simulation rate [Hz], an integer multiple q >= 2 of ``rate_hz``.
        rate_hz : sample rate after decimation [Hz].
        bits : ADC resolution; sets the default ``attenuation_db`` = 20 log10(2^(bits+1)).
        kind : "elliptic" or "none" (decimation only).
        passband : passband edge as a fraction of ``rate_hz``, 0 < passband < 0.5.
        ripple_db : passband ripple [dB], > 0.
        attenuation_db : minimum attenuation at and above ``rate_hz / 2`` [dB], > 0.
        """
        decimation_factor(fs_hz, rate_hz)
        if kind not in KINDS:
            raise ConfigError(f"antialias = {kind!r} is invalid: expected one of "
                              f"{', '.join(KINDS)}")
        if not (isinstance(passband, (int, float)) and 0 < passband < 0.5):
            raise ConfigError(f"antialias_passband = {passband!r} is invalid: expected a fraction "
                              "of rate_hz with 0 < passband < 0.5")
        if not (isinstance(ripple_db, (int, float)) and 0 < ripple_db <= 3):
            raise ConfigError(f"antialias_ripple_db = {ripple_db!r} is invalid: expected "
                              "0 < ripple <= 3 dB")
        if attenuation_db is None:
            attenuation_db = default_attenuation_db(bits)
        if not (isinstance(attenuation_db, (int, float)) and 20 <= attenuation_db <= 200):
            raise ConfigError(f"antialias_attenuation_db = {attenuation_db!r} is invalid: expected "
                              "20 .. 200 dB")
        fp, fst = passband * rate_hz, rate_hz / 2
        if kind == "none":
            order, sos = 0, np.array([[1.0, 0, 0, 1.0, 0, 0]])
        else:
            order, sos = _elliptic_design(float(fs_hz), float(fp), float(fst), float(ripple_db),
                                          float(attenuation_db))
        sos = np.ascontiguousarray(sos, dtype=float)
        sos.setflags(write=False)
        return cls(fs_hz=float(fs_hz), rate_hz=float(rate_hz), kind=kind, passband_hz=float(fp),
                   stopband_hz=float(fst), ripple_db=float(ripple_db),
                   attenuation_db=float(attenuation_db), order=int(order), sos=sos)

    # -- derived -------------------------------------------------------------------------------
    @property
    def decimation(self) -> int:
        """q = fs_hz / rate_hz."""
        return int(round(self.fs_hz / self.rate_hz))

    def response(self, freqs_hz) -> np.ndarray:
        """Exact complex response H(f) at ``freqs_hz`` [Hz] (any shape; module docstring)."""
        f = np.asarray(freqs_hz, dtype=float)
        zinv = np.exp(-2j * np.pi * f / self.fs_hz)
        h = np.ones(f.shape, dtype=complex)
        for b0, b1, b2, a0, a1, a2 in self.sos:
            h *= (b0 + zinv * (b1 + zinv * b2)) / (a0 + zinv * (a1 + zinv * a2))
        return h

    def group_delay_s(self, freqs_hz) -> np.ndarray:
        """Group delay -d(phase)/d(omega) at ``freqs_hz`` [s] (per section, summed)."""
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        tau = np.zeros(f.shape)
        from scipy import signal

        for sec in self.sos:
            _, gd = signal.group_delay((sec[:3], sec[3:]), w=f, fs=self.fs_hz)
            tau += gd
        return tau / self.fs_hz

    def describe(self) -> dict:
        """The design as plain data (for file attributes and summaries)."""
        return {"kind": self.kind, "fs_hz": self.fs_hz, "rate_hz": self.rate_hz,
                "decimation": self.decimation, "order": self.order,
                "passband_hz": self.passband_hz, "stopband_hz": self.stopband_hz,
                "ripple_db": self.ripple_db, "attenuation_db": self.attenuation_db}

    # -- stepping ------------------------------------------------------------------------------
    def initial_state(self, channels: int) -> FilterState:
        """At rest: zero filter state, the first sample of the run is kept."""
        zi = np.zeros((0 if self.kind == "none" else len(self.sos), channels, 2))
        return FilterState(zi=zi, phase=0)

    def kept(self, state: FilterState, samples: int) -> slice:
        """Which of the next ``samples`` input samples the decimation keeps."""
        return slice(state.phase, samples, self.decimation)

    def step(self, state: FilterState, x: np.ndarray) -> tuple[np.ndarray, FilterState]:
        """Filter and decimate one block.

        Parameters
        ----------
        state : from :meth:`initial_state` or the previous call.
        x : (channels, samples) volts at ``fs_hz``.

        Returns
        -------
        y : (channels, kept) filtered volts at ``rate_hz``,
            ``kept = len(range(phase, samples, q))``.
        state : the state after this block.
        """
        x = np.asarray(x, dtype=float)
        n = x.shape[-1]
        sl = self.kept(state, n)
        if self.kind == "none":
            y, zi = x, state.zi
        else:
            y = np.array(x, dtype=float, order="C", ndmin=2)
            zi = np.array(state.zi, dtype=float, order="C")
            sosfilt_inplace(self.sos, y.reshape(-1, n), zi.reshape(len(self.sos), -1, 2))
            y = y.reshape(x.shape)
        return (np.ascontiguousarray(y[..., sl]),
                FilterState(zi=zi, phase=(state.phase - n) % self.decimation))


# -- the design cache -------------------------------------------------------------------------------

def design_cache_dir() -> Path:
    """Where designed filters are kept: ``$PENDULUM_DAQ_CACHE``, else
    ``$XDG_CACHE_HOME/pendulum-daq``, else ``~/.cache/pendulum-daq``."""
    env = os.environ.get("PENDULUM_DAQ_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "pendulum-daq"


def _elliptic_design(fs_hz: float, fp_hz: float, fst_hz: float, ripple_db: float,
                     attenuation_db: float) -> tuple[int, np.ndarray]:
    """``scipy.signal.ellipord`` + ``ellip(..., output="sos")``, memoised on disk.

    Importing scipy.signal costs about 1 s (scipy 1.17 rewrites ~800 docstrings at import), half
    of the 2 s a whole ``daq acquire`` may take; the design is a pure function of its arguments
    and of scipy's version, so it is computed once and read back from a JSON file (floats written
    with ``repr``, which round-trips exactly) in :func:`design_cache_dir`. A missing, unreadable or
    foreign cache entry is recomputed; a cache that cannot be written is skipped silently.
    """
    import scipy  # the package alone is cheap; its version is part of the key

    key = {"design": "ellipord+ellip sos lowpass", "fs_hz": repr(fs_hz), "fp_hz": repr(fp_hz),
           "fst_hz": repr(fst_hz), "ripple_db": repr(ripple_db),
           "attenuation_db": repr(attenuation_db), "scipy": scipy.__version__}
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]
    path = design_cache_dir() / f"antialias-{digest}.json"
    try:
        entry = json.loads(path.read_text())
        if entry["key"] == key:
            sos = np.array(entry["sos"], dtype=float)
            if sos.ndim == 2 and sos.shape[1] == 6 and np.isfinite(sos).all():
                return int(entry["order"]), sos
    except (OSError, ValueError, KeyError, TypeError):
        pass
    from scipy import signal  # imported when used: scipy.signal costs ~1 s to import

    order, wn = signal.ellipord(fp_hz, fst_hz, ripple_db, attenuation_db, fs=fs_hz)
    sos = signal.ellip(order, ripple_db, attenuation_db, wn, btype="low", output="sos", fs=fs_hz)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(path, force=True) as tmp:
            tmp.write_text(json.dumps({"key": key, "order": int(order), "sos": sos.tolist()}))
    except (OSError, ConfigError):  # a cache that cannot be written is only a slower next run
        pass
    return int(order), np.asarray(sos, dtype=float)

