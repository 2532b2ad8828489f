"""The analyzer's source: a DAC at the simulation rate whose value is held between samples.

The Agilent 35670A drives the voice-coil amplifier from its source output (SPEC sections 1, 6, 8).
Here the source is a sequence of DAC samples ``v[k]`` at ``t_k = k / fs`` (``fs`` =
``acquisition.simulation_rate_hz``, 1 kHz by default), each held on ``[t_k, t_{k+1})`` (a
zero-order hold) and smoothed by an analog reconstruction filter, a Butterworth low-pass
(``source.reconstruction_hz`` = 100 Hz, order 4 by default) that removes the DAC's images.
Everything downstream is continuous (:mod:`rig.bench`); the filter is common to the stage and the
pendulum, so it does not change the ratios x/a and y/a (why it is needed: docs/devices.md).

Signal types (``source.type``), level ``L = source.level_vrms``:

``random``
    Gaussian noise band-limited to ``[fmin_hz, fmax_hz]`` (default the analysis span), flat in the
    band, expected rms ``L``.
``burst-random``
    the same noise, switched to the output only during the first ``burst_fraction`` of every
    ``period_s`` (hard edges at sample instants, 0 V otherwise); ``L`` is the rms *while on*.
``periodic-chirp``
    a linear sweep from ``fmin_hz`` to ``fmax_hz`` over ``period_s`` (a whole number of samples),
    restarted at phase 0 every period, amplitude ``sqrt(2) L``.
``pink``
    Gaussian noise with one-sided PSD proportional to ``1 / max(f, f_shelf)`` in the band, rms
    ``L``; ``f_shelf = fmin_hz`` if it is > 0, else ``fmax_hz / 1000``.
``sine``
    ``sqrt(2) L sin(2 pi frequency_hz t_k)``, phase 0 at t = 0.
``multisine``
    a random-phase multisine of period ``period_s`` on the harmonics in ``[fmin_hz, fmax_hz]``
    (``multisine_grid``: full, odd or random-odd), rms ``L``, new phases every
    ``multisine_periods`` periods (:mod:`rig.devices.multisine`).

The noise types filter seeded white Gaussian samples by a linear-phase FIR ``h`` with
``sum h^2 = 1`` (``FILTER_SPAN_S`` = 128 s of taps), run by overlap-save: blocks of any size
reproduce a one-shot run bit for bit, the noise is stationary from t = 0, and the deterministic
types draw nothing. The one-sided PSD of the DAC samples is ``2 L^2 |H(f)|^2 / fs``
(:meth:`Source.design_psd`). The filter's design, its band edges and the frame arithmetic:
docs/devices.md.

Public API: :class:`Source`, :class:`SourceState`, :func:`start_source`, :func:`generate`,
:data:`SOURCE_TYPES`, :func:`fill_standard_normal`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from rig.validation import number as _number
from rig.devices import multisine as _ms
from rig.errors import ConfigError
from rig.jit import njit
from rig.params import param
from rig.readonly import readonly

SOURCE_TYPES = ("random", "burst-random", "periodic-chirp", "pink", "sine", "multisine")
NOISE_TYPES = ("random", "burst-random", "pink")
FILTER_SPAN_S = 128.0  # minimum duration of the noise-shaping FIR [s]
KAISER_BETA = 8.6
FRAME_FACTOR = 4  # FFT length of one overlap-save frame = FRAME_FACTOR * n_taps
#: frames made per refill of the buffer: 2, a pair in one complex FFT (:func:`_frame_pair`);
#: 1, one real FFT each (:func:`_frame_real`, the path before, kept for the benchmark)
FRAMES_PER_FFT = 2
_DESIGN_OVERSAMPLE = 8
_REL = 1e-9


def _whole_samples(where: str, duration_s: float, fs_hz: float) -> int:
    r = duration_s * fs_hz
    k = int(round(r))
    if k < 1 or abs(r - k) > _REL * max(1.0, r):
        raise ConfigError(f"{where} = {duration_s!r} s is invalid: expected a whole number (>= 1) "
                          f"of samples at the simulation rate {fs_hz!r} Hz (a multiple of "
                          f"{1 / fs_hz!r} s)")
    return k


def butterworth_poles(order: int) -> np.ndarray:
    """Poles of the unit-corner analog Butterworth low-pass of ``order`` (gain 1, no zeros): the
    left half of the unit circle, ``-exp(i pi m / (2 order))``, m = -order+1, -order+3, ...,
    order-1 (the numbers of ``scipy.signal.buttap``, which is not imported here: importing
    scipy.signal costs ~1 s, half of a whole ``daq acquire``)."""
    m = np.arange(-order + 1, order, 2)
    return -np.exp(1j * np.pi * m / (2 * order))


def butterworth_state_space(order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Controller-canonical realisation (a, b, c) of the unit-corner Butterworth low-pass,
    ``r' = a r + b v``, output ``c . r`` (the matrices of ``scipy.signal.zpk2ss(*buttap(order))``,
    tests/rig/devices/test_source.py)."""
    den = np.poly(butterworth_poles(order)).real
    a = np.zeros((order, order))
    a[0] = -den[1:]
    a[1:, :-1] = np.eye(order - 1)
    b = np.zeros(order)
    b[0] = 1.0
    c = np.zeros(order)
    c[-1] = 1.0
    return a, b, c


@dataclass(frozen=True)
class Source:
    """The analyzer's source as a DAC (parameters frozen and validated; see the module docstring).

    The fields but ``fs_hz`` are the keys of the scene's ``[source]`` section (unit, default and
    range in each field's doc, :func:`rig.params.param`); ``fs_hz`` is the DAC (simulation) rate
    [Hz], > 0 (``acquisition.simulation_rate_hz``), which bounds the frequencies (``fmax_hz <=
    fs/2``, ``frequency_hz`` and ``reconstruction_hz < fs/2``) and makes ``period_s`` a whole
    number of samples.
    """

    type: str = param("random", "source signal (random: band-limited Gaussian noise)",
                      choices=SOURCE_TYPES)
    level_vrms: float = param(0.1, "rms source voltage [V] (burst random: while on)")
    fmin_hz: float = param(0.0, "lower band edge of random/pink/chirp [Hz], 0 <= fmin < fmax")
    fmax_hz: float = param(12.5, "upper band edge (the analysis span) [Hz], <= fs/2")
    frequency_hz: float = param(2.0, "frequency of the fixed sine [Hz], 0 < f < fs/2")
    period_s: float = param(100.0, "period of chirp and burst random [s], whole samples")
    burst_fraction: float = param(0.5, "on-fraction of each burst-random period, (0, 1]")
    fs_hz: float = 1000.0
    reconstruction_hz: float = param(100.0, "corner of the source output's smoothing filter "
                                     "(Butterworth) [Hz]; 0: off, the raw DAC staircase")
    reconstruction_order: int = param(4, "order of that filter, 1..8")
    multisine_grid: str = param("full", "harmonics a multisine excites: full, odd, random-odd",
                                choices=_ms.GRIDS)
    multisine_periods: int = param(2, "periods of a multisine realisation before new phases, "
                                   ">= 1")
    crest_iterations: int = param(0, "rounds of crest-factor reduction of a multisine, >= 0")

    def __post_init__(self):
        set_ = object.__setattr__
        if self.type not in SOURCE_TYPES:
            raise ConfigError(f"source.type = {self.type!r} is invalid: expected one of "
                              f"{', '.join(SOURCE_TYPES)}")
        fs = _number("acquisition.simulation_rate_hz", self.fs_hz, lo=0.0, lo_open=True,
                     valid="a finite rate > 0 Hz")
        set_(self, "fs_hz", fs)
        nyq = fs / 2
        set_(self, "level_vrms", _number("source.level_vrms", self.level_vrms, lo=0.0,
                                         valid="a finite rms voltage >= 0 V"))
        set_(self, "fmax_hz", _number("source.fmax_hz", self.fmax_hz, lo=0.0, hi=nyq,
                                      lo_open=True,
                                      valid=f"0 < fmax_hz <= {nyq:g} Hz (half the simulation "
                                            "rate)"))
        set_(self, "fmin_hz", _number("source.fmin_hz", self.fmin_hz, lo=0.0, hi=self.fmax_hz,
                                      hi_open=True,
                                      valid=f"0 <= fmin_hz < fmax_hz = {self.fmax_hz:g} Hz"))
        set_(self, "frequency_hz", _number("source.frequency_hz", self.frequency_hz, lo=0.0,
                                           hi=nyq, lo_open=True, hi_open=True,
                                           valid=f"0 < frequency_hz < {nyq:g} Hz (half the "
                                                 "simulation rate)"))
        set_(self, "period_s", _number("source.period_s", self.period_s, lo=0.0, lo_open=True,
                                       valid="a finite period > 0 s"))
        _whole_samples("source.period_s", self.period_s, fs)
        set_(self, "burst_fraction", _number("source.burst_fraction", self.burst_fraction,
                                             lo=0.0, hi=1.0, lo_open=True,
                                             valid="0 < burst_fraction <= 1"))
        set_(self, "reconstruction_hz", _number(
            "source.reconstruction_hz", self.reconstruction_hz, lo=0.0, hi=nyq, hi_open=True,
            valid=f"0 (off) or 0 < reconstruction_hz < {nyq:g} Hz (half the simulation rate)"))
        order = self.reconstruction_order
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= 8:
            raise ConfigError(f"source.reconstruction_order = {order!r} is invalid: expected an "
                              "integer 1..8")
        for name, lo in (("multisine_periods", 1), ("crest_iterations", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ConfigError(f"source.{name} = {v!r} is invalid: expected an integer "
                                  f">= {lo}")
        if self.multisine_grid not in _ms.GRIDS:
            raise ConfigError(f"source.multisine_grid = {self.multisine_grid!r} is invalid: "
                              f"expected one of {', '.join(_ms.GRIDS)}")
        if self.type == "multisine":  # a grid with no line in the band is refused here
            _ms.excited_lines(self.multisine_grid, self.period_samples, fs, self.fmin_hz,
                              self.fmax_hz, 0)
        if self.type == "burst-random" and self.burst_samples < 1:
            raise ConfigError(f"source.burst_fraction = {self.burst_fraction!r} is invalid: "
                              f"the burst would be shorter than one sample of the period "
                              f"{self.period_s!r} s")

    # -- the analog output stage ------------------------------------------------------------
    def reconstruction_state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Continuous state space (a, b, c) of the reconstruction filter, ``r' = a r + b v``,
        output ``c . r`` [V] (Butterworth, unit DC gain, no feedthrough), or None when off."""
        if self.reconstruction_hz == 0:
            return None
        # the unit-corner prototype (O(1) coefficients) with time scaled by the corner:
        # H(s / wc) has the realisation (wc a, wc b, c)
        a, b, c = butterworth_state_space(self.reconstruction_order)
        wc = 2 * np.pi * self.reconstruction_hz
        return wc * a, wc * b, c

    def reconstruction_response(self, freqs_hz) -> np.ndarray:
        """Complex response of the reconstruction filter at ``freqs_hz`` [Hz] (1 when off)."""
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        if self.reconstruction_hz == 0:
            return np.ones(f.shape, complex)
        s = 1j * f / self.reconstruction_hz  # s / wc
        p = butterworth_poles(self.reconstruction_order)
        return 1.0 / np.prod(s[..., None] - p, axis=-1)

    # -- derived constants ----------------------------------------------------------------
    @property
    def period_samples(self) -> int:
        """Samples per chirp/burst period."""
        return int(round(self.period_s * self.fs_hz))

    @property
    def burst_samples(self) -> int:
        """Samples switched on at the start of each burst period."""
        return int(round(self.burst_fraction * self.period_samples))

    @property
    def shelf_hz(self) -> float:
        """Lower corner of the pink spectrum [Hz] (fmin_hz if > 0, else fmax_hz / 1000)."""
        return self.fmin_hz if self.fmin_hz > 0 else self.fmax_hz / 1000.0

    @property
    def n_taps(self) -> int:
        """Length of the noise-shaping FIR (a power of two spanning >= FILTER_SPAN_S)."""
        return 1 << int(math.ceil(math.log2(FILTER_SPAN_S * self.fs_hz)))

    @property
    def frame_len(self) -> int:
        """FFT length of one overlap-save frame."""
        return FRAME_FACTOR * self.n_taps

    def design_amplitude(self, freqs_hz) -> np.ndarray:
        """Ideal (unnormalised) amplitude response of the noise shaping at ``freqs_hz`` [Hz]."""
        return _amplitude(self.type == "pink", self.fmin_hz, self.fmax_hz, self.shelf_hz,
                          np.asarray(freqs_hz, float))

    @property
    def taps(self) -> np.ndarray:
        """The normalised FIR (``sum taps^2 = 1``), shape (n_taps,), read-only (noise types)."""
        return noise_fir(self.type == "pink", self.fmin_hz, self.fmax_hz, self.shelf_hz,
                         self.fs_hz)[0]

    @property
    def _taps_spectrum(self) -> np.ndarray:
        """rfft of the taps over one frame (the path of one real FFT a frame, made when first
        asked for)."""
        return noise_fir_rfft(self.type == "pink", self.fmin_hz, self.fmax_hz, self.shelf_hz,
                              self.fs_hz)

    @property
    def _taps_spectrum_full(self) -> np.ndarray:
        """The complex FFT of the taps over one frame (both halves)."""
        return noise_fir(self.type == "pink", self.fmin_hz, self.fmax_hz, self.shelf_hz,
                         self.fs_hz)[1]

    def design_psd(self, freqs_hz) -> np.ndarray:
        """Design one-sided PSD of the DAC samples [V^2/Hz] for the noise types (random, pink;
        for burst random the PSD while on), without the window's smoothing of the edges."""
        f = np.asarray(freqs_hz, float)
        if self.type not in NOISE_TYPES:
            raise ConfigError(f"design_psd is defined for noise sources ({', '.join(NOISE_TYPES)}),"
                              f" not for source.type = {self.type!r}")
        return self.level_vrms**2 * self.design_amplitude(f) ** 2 / self.design_power

    @property
    def design_power(self) -> float:
        """Integral of the ideal |amplitude|^2 over [0, fs/2] [Hz] (the PSD's normalisation)."""
        lo, hi = self.fmin_hz, self.fmax_hz
        if self.type != "pink":
            return hi - lo
        sh = self.shelf_hz  # 1/max(f, shelf): flat below the shelf, 1/f above
        return max(sh - lo, 0.0) / sh + math.log(hi / max(lo, sh))

    def describe(self) -> dict:
        """Plain-data description (what to record beside a run)."""
        d = {"type": self.type, "level_vrms": self.level_vrms, "fs_hz": self.fs_hz,
             "hold": "zoh"}
        if self.type in NOISE_TYPES or self.type == "periodic-chirp":
            d.update(fmin_hz=self.fmin_hz, fmax_hz=self.fmax_hz)
        if self.type in NOISE_TYPES:
            d.update(fir_taps=self.n_taps, kaiser_beta=KAISER_BETA)
        if self.type == "pink":
            d.update(shelf_hz=self.shelf_hz)
        if self.type in ("periodic-chirp", "burst-random"):
            d.update(period_s=self.period_s)
        if self.type == "burst-random":
            d.update(burst_fraction=self.burst_fraction)
        if self.type == "sine":
            d.update(frequency_hz=self.frequency_hz)
        if self.type == "multisine":
            d.update(fmin_hz=self.fmin_hz, fmax_hz=self.fmax_hz, period_s=self.period_s,
                     multisine_grid=self.multisine_grid,
                     multisine_periods=self.multisine_periods,
                     crest_iterations=self.crest_iterations)
        return d


def _amplitude(pink: bool, fmin_hz: float, fmax_hz: float, shelf_hz: float,
               f: np.ndarray, cell_hz: float = 0.0) -> np.ndarray:
    """Ideal amplitude at ``f``; with ``cell_hz`` > 0 the band indicator is averaged over a cell
    of that width around each point (so a design grid places the edges between its points)."""
    f = np.abs(f)
    if cell_hz > 0:
        inband = (np.clip((f + cell_hz / 2 - fmin_hz) / cell_hz, 0.0, 1.0)
                  * np.clip((fmax_hz - (f - cell_hz / 2)) / cell_hz, 0.0, 1.0))
        if fmin_hz == 0:
            inband = np.clip((fmax_hz - (f - cell_hz / 2)) / cell_hz, 0.0, 1.0)
    else:
        inband = ((f >= fmin_hz) & (f <= fmax_hz)).astype(float)
    amp = 1.0 / np.sqrt(np.maximum(f, shelf_hz)) if pink else np.ones_like(f)
    return inband * amp


@lru_cache(maxsize=8)
def noise_fir(pink: bool, fmin_hz: float, fmax_hz: float, shelf_hz: float, fs_hz: float):
    """(taps, the complex FFT of the taps over one frame) of the noise-shaping FIR (module
    docstring); cached by its parameters, both read-only."""
    n = 1 << int(math.ceil(math.log2(FILTER_SPAN_S * fs_hz)))
    big = _DESIGN_OVERSAMPLE * n
    grid = np.fft.rfftfreq(big, 1.0 / fs_hz)
    ideal = np.fft.irfft(_amplitude(pink, fmin_hz, fmax_hz, shelf_hz, grid, fs_hz / big),
                         n=big)  # zero phase, circular
    h = np.roll(ideal, n // 2)[:n] * np.kaiser(n, KAISER_BETA)
    h /= math.sqrt(float(np.sum(h * h)))
    full = _fft().fft(h, n=FRAME_FACTOR * n)
    for a in (h, full):
        a.setflags(write=False)
    return h, full


@lru_cache(maxsize=8)
def noise_fir_rfft(pink: bool, fmin_hz: float, fmax_hz: float, shelf_hz: float,
                   fs_hz: float) -> np.ndarray:
    """rfft over one frame of :func:`noise_fir`'s taps for these parameters, read-only (cached)."""
    taps = noise_fir(pink, fmin_hz, fmax_hz, shelf_hz, fs_hz)[0]
    spec = np.fft.rfft(taps, n=FRAME_FACTOR * taps.size)
    spec.setflags(write=False)
    return spec


def _fft():
    """scipy.fft, imported when first used (its complex transforms were the faster of the two
    libraries' when timed)."""
    import scipy.fft

    return scipy.fft


@dataclass(frozen=True, eq=False)
class SourceState:
    """What the source carries from block to block.

    Attributes
    ----------
    index : samples emitted so far (the next sample is at ``t = index / fs``).
    rng_state : the generator's ``bit_generator.state`` (a dict; copied, never shared).
    history : (n_taps - 1,) last white samples fed to the FIR (noise types); (1,) the phases'
        key (multisine); else ``None``.
    buffer : the last filtered frames (read-only; noise types), of which ``buffer[offset:]`` is
        not emitted yet.
    offset : first sample of ``buffer`` not yet emitted.
    """

    index: int
    rng_state: dict
    history: np.ndarray | None
    buffer: np.ndarray
    offset: int = 0


def standard_normals(rng: np.random.Generator, n: int) -> np.ndarray:
    """``rng.standard_normal(n)``: the same values from the same stream, leaving ``rng`` in the
    same state, drawn in compiled code (numba's Generator runs numpy's ziggurat on the same bit
    generator, faster than numpy's own loop: docs/benchmarks/history.md)."""
    out = np.empty(int(n))
    fill_standard_normal(rng, out)
    return out


@njit(cache=True, nogil=True)
def fill_standard_normal(rng, out):
    """``out`` filled with ``rng``'s standard normals in order (compiled: the same values and
    generator state as ``rng.standard_normal(out.size)``)."""
    for i in range(out.shape[0]):
        out[i] = rng.standard_normal()


def _generator(state: dict) -> np.random.Generator:
    bg = getattr(np.random, state["bit_generator"])(0)  # fixed seed, overwritten at once
    bg.state = state
    return np.random.Generator(bg)


def _copy_state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state  # a fresh dict of ints (a snapshot), not shared


def start_source(source: Source, seed) -> SourceState:
    """The state at t = 0. ``seed``: an int, a :class:`numpy.random.SeedSequence` or a
    :class:`numpy.random.Generator` (whose current state is copied, not consumed)."""
    if isinstance(seed, np.random.Generator):
        rng = _generator(_copy_state(seed))
    else:
        rng = np.random.Generator(np.random.PCG64(seed))
    history = None
    if source.type in NOISE_TYPES:
        history = standard_normals(rng, source.n_taps - 1)  # primes the FIR: stationary from t = 0
    elif source.type == "multisine":  # the key of its phases and grid (rig.devices.multisine)
        history = np.array([rng.integers(0, 2 ** 63 - 1)], dtype=np.int64)
    return SourceState(index=0, rng_state=_copy_state(rng), history=readonly(history),
                       buffer=readonly(np.empty(0)), offset=0)


def _noise(source: Source, state: SourceState, n: int) -> tuple[np.ndarray, SourceState]:
    """n samples of the shaped unit-rms noise (before the level), from whole frames."""
    buffer, offset, history = state.buffer, state.offset, state.history
    rng = None
    parts = []
    need = n
    n_taps, frame = source.n_taps, source.frame_len
    while True:
        take = min(need, buffer.size - offset)
        if take > 0:
            parts.append(buffer[offset:offset + take])
            offset += take
            need -= take
        if need == 0:
            break
        if rng is None:
            rng = _generator(state.rng_state)
        fresh = standard_normals(rng, FRAMES_PER_FFT * (frame - n_taps + 1))
        if FRAMES_PER_FFT == 2:
            y, history = _frame_pair(history, fresh, source._taps_spectrum_full)
        else:
            y, history = _frame_real(history, fresh, source._taps_spectrum)
        buffer, history = readonly(y), readonly(history)
        offset = 0
    if len(parts) == 1:
        out = parts[0].copy()
    else:
        out = np.concatenate(parts) if parts else np.empty(0)
    rng_state = state.rng_state if rng is None else _copy_state(rng)
    return out, SourceState(index=state.index, rng_state=rng_state, history=history,
                            buffer=buffer, offset=offset)


def _frame_real(history: np.ndarray, fresh: np.ndarray, spectrum: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """One overlap-save frame by a real FFT: the filtered ``fresh`` samples (the frame's
    outputs) and the history after them; ``spectrum`` the taps' rfft over the frame, whose
    length is ``history.size + fresh.size``."""
    x = np.concatenate([history, fresh])
    y = np.fft.irfft(np.fft.rfft(x) * spectrum, n=x.size)
    return y[history.size:], x[fresh.size:].copy()


def _frame_pair(history: np.ndarray, fresh: np.ndarray, spectrum: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Two consecutive overlap-save frames by one complex FFT: the filtered ``fresh`` samples
    (both frames' outputs, in order) and the history after them. ``fresh`` holds both frames'
    new samples (an even count); ``spectrum`` is the taps' complex FFT over one frame (length
    ``history.size + fresh.size / 2``). The first frame's input is the real part, the second's
    the imaginary part; the taps are real, so the inverse transform holds the first frame's
    outputs in its real part and the second's in its imaginary part (each as its own real
    transform would give it, up to round-off)."""
    keep, step = history.size, fresh.size // 2
    frame = keep + step
    z = np.empty(frame, dtype=complex)
    z.real[:keep] = history
    z.real[keep:] = fresh[:step]
    z.imag[:keep] = z.real[step:]  # the second frame starts where the first ends
    z.imag[keep:] = fresh[step:]
    history = z.imag[step:].copy()
    fft = _fft()
    y = fft.fft(z, overwrite_x=True)
    y *= spectrum
    y = fft.ifft(y, overwrite_x=True)
    out = np.empty(2 * step)
    out[:step] = y.real[keep:]
    out[step:] = y.imag[keep:]
    return out, history


def generate(source: Source, state: SourceState, n: int) -> tuple[np.ndarray, SourceState]:
    """The next ``n`` DAC samples [V] and the state after them.

    Samples ``k = state.index .. state.index + n - 1`` at ``t_k = k / fs``; each is held until the
    next. Any split of a run into blocks gives the same samples as one call.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ConfigError(f"n = {n!r} is invalid: expected an integer number of samples >= 0")
    n = int(n)
    k = state.index + np.arange(n, dtype=np.int64)
    lvl = source.level_vrms
    if source.type in NOISE_TYPES:
        v, new = _noise(source, state, n)
        v = lvl * v
        if source.type == "burst-random":
            v = np.where(k % source.period_samples < source.burst_samples, v, 0.0)
    elif source.type == "multisine":
        v = _ms.samples(source.multisine_grid, source.period_samples, source.fs_hz,
                        source.fmin_hz, source.fmax_hz, lvl, int(state.history[0]),
                        source.multisine_periods, source.crest_iterations, k)
        new = state
    elif source.type == "sine":
        cycles = np.mod(k * (source.frequency_hz / source.fs_hz), 1.0)
        v = math.sqrt(2.0) * lvl * np.sin(2 * np.pi * cycles)
        new = state
    else:  # periodic chirp
        t = (k % source.period_samples) / source.fs_hz
        f0, f1, p = source.fmin_hz, source.fmax_hz, source.period_s
        cycles = np.mod(f0 * t + 0.5 * (f1 - f0) / p * t * t, 1.0)
        v = math.sqrt(2.0) * lvl * np.sin(2 * np.pi * cycles)
        new = state
    new = SourceState(index=state.index + n, rng_state=new.rng_state, history=new.history,
                      buffer=new.buffer, offset=new.offset)
    return v, new
