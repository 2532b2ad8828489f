"""The analyzer's reading of a run: one call from a recording to every number the paper shows.

:func:`analyze` turns a :class:`daq.records.Recording` (a run file read by
:func:`daq.hdf5.read_run`, complete or interrupted) into a frozen :class:`Analysis`:

1. **one shared set of segment FFTs** of the channels ``a, x, y`` in engineering units
   (:meth:`Recording.values`: calibration and sensor sign undone) with the 35670A-like
   :class:`AnalyzerSettings`; from it the auto spectra ``G_aa, G_xx, G_yy``, the cross spectra
   ``G_ax, G_ay``, ``H_t = G_ax / G_aa`` [m per m/s^2] and ``Theta_2 = G_ay / G_aa`` [rad per
   m/s^2] (H1), their coherences and Bendat-Piersol bands (:mod:`processing.frf`);
2. **the exact model at the FFT lines** (:func:`model_at_lines`): the whole sampled chain's
   ``h_t`` and ``theta_2`` (:func:`rig.bench.expected_response` ``sampled=True``), taken from the
   run file when its grid holds every line, else recomputed exactly at the lines -- never
   interpolated (a mode narrower than a line would be misplaced). The accelerometer's high-pass
   sits in the denominator of both ratios (:attr:`Analysis.highpass_at_fmin`);
3. **the expected estimate** ``E[H1]`` for this window and record length
   (:func:`processing.leakage.expected_estimate`), which separates the leakage bias at the sharp
   resonances from the random error (:func:`processing.compare.compare`);
4. **modal fits** (:func:`processing.modal.fit_modes`), leakage-aware and direct, of Theta_2 and
   H_t in their fit bands, each next to the same fit of the noiseless ``E[H1]`` with the same
   weights (the method's own systematic error on this bench, reported, never subtracted). The
   fits use the pendulum's own response: the measured ratio times the accelerometer's exactly
   known high-pass, whose pole at 0 Hz the modal model cannot represent;
5. the paper's reading ``|Theta_2 / Theta_1|`` above f1
   (:func:`processing.rotation.rotation_reading`) and the text (:meth:`Analysis.report`,
   :meth:`Analysis.summary`: :mod:`processing.report`).

Nothing is drawn or written here (:mod:`processing.views`, :mod:`processing.writers`). The
default window is Hann (the 35670A's for random noise); ``window="uniform"`` is a setting. Cost:
the paper's analysis (30 x 100 s) computes in a fraction of a second; BLAS runs single-threaded
inside :func:`analyze` (thin products). No numba, scipy.signal or matplotlib is imported.
Measured figures of the paper's run: docs/analyzer-notes.md.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from processing.compare import compare
from processing.frf import ESTIMATORS, MeasuredResponse, frequency_response
from processing.leakage import CHANNELS, ExpectedEstimate, expected_estimate
from processing.modal import FitError, ModalFit, fit_modes
from processing.rotation import RotationReading, rotation_reading
from processing.report import analysis_report, analysis_summary
from processing.spectra import (AVERAGING, WINDOWS, ChannelDataError, SettingsError,
                                SpectralSettings, auto_spectrum, cross_spectrum,
                                segment_ffts)
from rig import validation
from rig.readonly import readonly
from rig.threads import single_threaded_blas
from rig.errors import ConfigError

if TYPE_CHECKING:  # rig.bench is imported on use: importing processing stays light
    from rig.bench import BenchResponse, SampledResponse

__all__ = ["AnalyzerSettings", "Analysis", "RunInfo", "ModelAtLines", "analyze",
           "band_limit_hz", "check_band", "model_at_lines", "incomplete_note", "paper_figures", "FIT_METHODS", "CHANNELS"]

FIT_METHODS = ("leakage", "direct")
_LABEL_T, _LABEL_R = "H_t (x/a)", "Theta_2 (y/a)"
_DB = 20.0 / math.log(10.0)
_CHUNK = 8192  # frequencies per expected_response call (bounds its (nf, nz, nz) work array)



def _band(name: str, value) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise SettingsError(f"{name} = {value!r} is invalid: expected (f_lo, f_hi) in Hz") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise SettingsError(f"{name} = {value!r} is invalid: expected 0 <= f_lo < f_hi [Hz]")
    return lo, hi


def _positive_int(name: str, value, minimum: int) -> int:
    return validation.integer(name, value, minimum=minimum, error=SettingsError)


def _finite(name: str, value, *, lo=None, hi=None, hi_open=False) -> float:
    return validation.number(name, value, lo=lo, hi=hi, hi_open=hi_open, error=SettingsError)


@dataclass(frozen=True)
class AnalyzerSettings:
    """How the run is analysed (immutable, validated on construction).

    The defaults are the paper's experiment on a 35670A: one FFT per record (the time record is
    the whole 100 s record: 10 mHz lines), RMS averaging of all records (30 averages), Hann window
    (the analyzer's default for random noise; see the module notes for why not uniform), H1, and
    the paper's display band 0.1 - 10 Hz.

    Parameters
    ----------
    window : {"uniform", "hann", "flattop", "force", "exponential"}, default "hann".
    averaging : {"rms", "vector", "exponential"}, default "rms". ("peak" hold is refused: it
        keeps auto powers only, so H_t, Theta_2 and coherence are undefined.)
    nperseg : int, optional
        Samples per FFT (the time record). Default (None, and no ``lines``): a record's length.
    lines, span_hz : int, float, optional
        35670A-style resolution instead of ``nperseg``: time record ``lines / span_hz`` [s],
        results up to ``span_hz`` (:meth:`SpectralSettings.from_lines`). Give both or neither.
    overlap : float, default 0.0
        Overlap of consecutive FFTs within a record, ``0 <= overlap < 1`` (irrelevant with one FFT
        per record).
    estimator : {"h1", "h2", "hv"}, default "h1". (``E[H1]`` and the comparison's bias model H1.)
    detrend : {"constant", "linear", None}, default "constant".
    exp_averages : int, default 10 (exponential averaging only).
    fmin_hz, fmax_hz : float, default 0.1, 10.0
        Display and comparison band [Hz] (CSV, plot, statistics).
    k : float, default 2.0
        Width of the error bands and of the "within k sigma" statistics [sigma].
    fit_methods : tuple, default ("leakage", "direct")
        Modal fits to make: leakage-aware and/or the analyzer's direct curve fit.
    theta2_fit_band_hz : (lo, hi), default (0.3, 6.0)
        Lines of Theta_2 fitted (the modes inside it are fitted: 0.83 and 2.48 Hz).
    ht_fit_band_hz : (lo, hi), default (1.5, 4.0)
        Lines of H_t fitted (the 2.48 Hz mode).
    n_residual : int, default 2
        Terms of the fits' residual polynomial.
    rotation_band_hz : (lo, hi), default (6.0, 10.0)
        Band of the |Theta_2 / Theta_1| reading: above f1 and above Theta_2's anti-resonance
        (4.66 Hz).

    Raises
    ------
    SettingsError
        (a ``ValueError``) naming the field, its value and what is valid.
    """

    window: str = "hann"
    averaging: str = "rms"
    nperseg: int | None = None
    lines: int | None = None
    span_hz: float | None = None
    overlap: float = 0.0
    estimator: str = "h1"
    detrend: str | None = "constant"
    exp_averages: int = 10
    fmin_hz: float = 0.1
    fmax_hz: float = 10.0
    k: float = 2.0
    fit_methods: tuple = FIT_METHODS
    theta2_fit_band_hz: tuple = (0.3, 6.0)
    ht_fit_band_hz: tuple = (1.5, 4.0)
    n_residual: int = 2
    rotation_band_hz: tuple = (6.0, 10.0)

    def __post_init__(self):
        set_ = object.__setattr__
        if self.window not in WINDOWS:
            raise SettingsError(f"window = {self.window!r} is invalid: expected one of "
                                f"{', '.join(WINDOWS)}")
        if self.averaging == "peak":
            raise SettingsError("averaging = 'peak' is invalid for this analysis: peak hold keeps "
                                "the maximum auto power per line, so H_t, Theta_2 and coherence "
                                "are undefined; expected one of rms, vector, exponential")
        if self.averaging not in AVERAGING:
            raise SettingsError(f"averaging = {self.averaging!r} is invalid: expected one of "
                                "rms, vector, exponential")
        est = str(self.estimator).lower()
        if est not in ESTIMATORS:
            raise SettingsError(f"estimator = {self.estimator!r} is invalid: expected one of "
                                f"{', '.join(ESTIMATORS)}")
        set_(self, "estimator", est)
        if (self.lines is None) != (self.span_hz is None):
            raise SettingsError(f"lines = {self.lines!r}, span_hz = {self.span_hz!r}: give both "
                                "(35670A-style resolution) or neither")
        if self.lines is not None:
            if self.nperseg is not None:
                raise SettingsError(f"nperseg = {self.nperseg!r} and lines = {self.lines!r} both "
                                    "given: give the time record as nperseg or as lines and "
                                    "span_hz, not both")
            set_(self, "lines", _positive_int("lines", self.lines, 1))
            set_(self, "span_hz", _finite("span_hz", self.span_hz, lo=0.0))
            if self.span_hz <= 0:
                raise SettingsError(f"span_hz = {self.span_hz!r} is invalid: expected > 0 Hz")
        if self.nperseg is not None:
            set_(self, "nperseg", _positive_int("nperseg", self.nperseg, 2))
        set_(self, "overlap", _finite("overlap", self.overlap, lo=0.0, hi=1.0, hi_open=True))
        set_(self, "exp_averages", _positive_int("exp_averages", self.exp_averages, 1))
        set_(self, "fmin_hz", _finite("fmin_hz", self.fmin_hz, lo=0.0))
        set_(self, "fmax_hz", _finite("fmax_hz", self.fmax_hz, lo=0.0))
        if not self.fmin_hz < self.fmax_hz:
            raise SettingsError(f"fmin_hz = {self.fmin_hz!r}, fmax_hz = {self.fmax_hz!r}: "
                                "expected fmin_hz < fmax_hz")
        set_(self, "k", _finite("k", self.k, lo=0.0))
        methods = tuple(self.fit_methods)
        bad = [m for m in methods if m not in FIT_METHODS]
        if bad or len(set(methods)) != len(methods):
            raise SettingsError(f"fit_methods = {self.fit_methods!r} is invalid: expected "
                                f"distinct entries of {FIT_METHODS}")
        set_(self, "fit_methods", methods)
        for name in ("theta2_fit_band_hz", "ht_fit_band_hz", "rotation_band_hz"):
            set_(self, name, _band(name, getattr(self, name)))
        set_(self, "n_residual", _positive_int("n_residual", self.n_residual, 0))
        # detrend and exp_averages are validated with the rest by SpectralSettings:
        SpectralSettings(fs=1.0, nperseg=2, detrend=self.detrend)

    def spectral(self, fs: float, record_samples: int) -> SpectralSettings:
        """The :class:`SpectralSettings` for records of ``record_samples`` at ``fs`` [Hz].

        Raises
        ------
        SettingsError
            If the time record is longer than a record (segments never straddle records), or
            ``lines``/``span_hz`` do not give a whole number of samples.
        """
        kw = dict(window=self.window, averaging=self.averaging, detrend=self.detrend,
                  exp_averages=self.exp_averages)
        if self.lines is not None:
            s = SpectralSettings.from_lines(fs, self.lines, self.span_hz, overlap=self.overlap,
                                            **kw)
            what = (f"lines = {self.lines}, span_hz = {self.span_hz:g} give a time record of "
                    f"{s.nperseg} samples ({s.nperseg / fs:g} s)")
        else:
            n = record_samples if self.nperseg is None else self.nperseg
            s = SpectralSettings(fs=fs, nperseg=n, overlap=self.overlap, **kw)
            what = f"nperseg = {n} ({n / fs:g} s)"
        if s.nperseg > record_samples:
            raise SettingsError(f"{what}, longer than a record ({record_samples} samples = "
                                f"{record_samples / fs:g} s): expected 2 <= nperseg <= "
                                f"{record_samples} (an FFT never straddles two records)")
        return s

    def describe(self) -> dict:
        """Plain data (None as "", tuples as lists) for file attributes and reports."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = "" if v is None else (list(v) if isinstance(v, tuple) else v)
        return out




# -- the model at the lines ------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class ModelAtLines:
    """The exact whole-chain responses at the analyzer's lines (complex, (nf,)).

    Attributes
    ----------
    freqs_hz : (nf,) [Hz].
    h_t : x / a [m per m/s^2]; theta_2 : y / a [rad per m/s^2] -- what the analyzer should read
        (accelerometer high-pass in the denominator; NaN at 0 Hz).
    h_t_pendulum, theta_2_pendulum : the pendulum alone (mirror motion / stage acceleration).
    source : "file" (the run file's stored values: its grid holds every line) or "recomputed"
        (:func:`rig.bench.expected_response` ``sampled=True`` at the lines).
    """

    freqs_hz: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    h_t_pendulum: np.ndarray
    theta_2_pendulum: np.ndarray
    source: str

    @property
    def highpass(self) -> np.ndarray:
        """The accelerometer's high-pass as the analyzer sees it, ``h_t_pendulum / h_t``
        (sensed over true stage acceleration; -> 1 well above its corner)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.h_t_pendulum / self.h_t


_MODEL_KEYS = ("h_t", "theta_2", "h_t_pendulum", "theta_2_pendulum")


def _line_indices(grid: np.ndarray, f: np.ndarray) -> np.ndarray | None:
    """Indices of ``f`` in ``grid`` if every line is a grid point (to 1e-9 of a line), else
    None."""
    if grid.size < 2:
        return None
    idx = np.searchsorted(grid, f)
    idx = np.clip(idx, 1, grid.size - 1)
    left = np.where(np.abs(grid[idx - 1] - f) <= np.abs(grid[idx] - f), idx - 1, idx)
    tol = 1e-9 * float(grid[1] - grid[0])
    return left if np.all(np.abs(grid[left] - f) <= tol) else None


_FIELDS = ("a", "x", "y", "stage_accel", "mirror_x", "mirror_rot", "h_t", "theta_2",
           "h_t_pendulum", "theta_2_pendulum")


def _bench_response(scene, f: np.ndarray):
    """:func:`rig.bench.expected_response` ``sampled=True`` in chunks (it solves an ``(nf, nz,
    nz)`` system at once); returns a dict of the fields used here (and ``theta``)."""
    from rig.bench import expected_response

    f = np.asarray(f, dtype=float)
    parts = {k: [] for k in (*_FIELDS, "theta")}
    for i in range(0, max(f.size, 1), _CHUNK):
        r = expected_response(scene, f[i:i + _CHUNK], sampled=True)
        for k in parts:
            parts[k].append(getattr(r, k))
    return {k: np.concatenate(v) for k, v in parts.items()}


def model_at_lines(header, freqs_hz) -> ModelAtLines:
    """The exact whole-chain ``h_t``, ``theta_2`` (and the pendulum's) at ``freqs_hz``.

    Taken from the run's stored model (``header.response``) when every line lies on its grid (the
    default one-FFT-per-record settings); otherwise recomputed exactly with
    :func:`rig.bench.expected_response` ``sampled=True`` -- the same function that wrote the
    stored values -- never interpolated (module docstring).
    """
    f = np.asarray(freqs_hz, dtype=float)
    resp = header.response
    stored = all(k in resp.values for k in _MODEL_KEYS)
    idx = _line_indices(np.asarray(resp.freqs_hz, float), f) if stored else None
    if idx is not None:
        vals = {k: np.asarray(resp.values[k])[idx] for k in _MODEL_KEYS}
        source = "file"
    else:
        r = _bench_response(header.scene, f)
        vals = {k: r[k] for k in _MODEL_KEYS}
        source = "recomputed"
    return ModelAtLines(readonly(f), *(readonly(np.asarray(vals[k], complex))
                                        for k in _MODEL_KEYS), source)


# -- the result ------------------------------------------------------------------------------

@dataclass(frozen=True)
class RunInfo:
    """What was analysed: ``source`` (a path or a label), scene, seed, status and records."""

    source: str
    scene: str
    seed: int
    status: str
    records: int
    records_planned: int
    record_s: float
    rate_hz: float
    clipped: Mapping

    @property
    def complete(self) -> bool:
        return self.status == "complete" and self.records == self.records_planned


@dataclass(frozen=True, eq=False)
class Analysis:
    """The analyzer's reading of one run (:func:`analyze`); everything is computed, nothing is
    drawn or written (see :func:`processing.views.bode_figures`, :mod:`processing.writers`).

    Attributes
    ----------
    settings : AnalyzerSettings; spectral : the SpectralSettings they gave for this run.
    run : RunInfo; scene : the run's resolved rig.scene.Scene.
    spectra : {"a", "x", "y": auto spectra G_aa, G_xx, G_yy; "ax", "ay": cross spectra G_ax,
        G_ay} (density scaling, engineering units), all lines.
    h_t, theta_2 : MeasuredResponse (x/a [m per m/s^2], y/a [rad per m/s^2]), all lines.
    model : ModelAtLines, the exact whole chain at every line.
    expected : ExpectedEstimate or None (why not: in ``notes``).
    comparisons : {"H_t (x/a)", "Theta_2 (y/a)": Comparison over the display band}.
    fits : {label: ModalFit}, labels "Theta_2 leakage-aware", "H_t direct", ...
    fit_checks : {label: ModalFit of the noiseless E[H1] with the same weights}.
    rotation : RotationReading or None.
    exact_modes : ((f_hz, Q), ...) of the pendulum.
    antiresonances_hz : {"x": (...), "y": (...)}.
    highpass_at_fmin : (dB, deg) of the whole chain against the pendulum alone at ``fmin_hz``;
        (NaN, NaN) for ``fmin_hz`` = 0, where the high-pass passes nothing and the ratio is
        undefined.
    bench : rig.bench.SampledResponse, the exact sampled response of the run's bench that this
        analysis evaluated (built once: E[H1], the coherence budget, the comparisons off the
        lines and the figures' model curves all use it).
    notes : tuple of str: what the reader must know (incomplete run, clipping, skipped parts).
    coherence_budget : processing.coherence_model.CoherenceBudget or None (with E[H1]): the
        expected coherence with the optical lever's second-order geometry, the noise floors and
        leakage, and without each.
    coherence_dips : tuple of processing.coherence_model.Dip: the predicted dips over the display
        band, named by mechanism, with the measured coherence there.
    """

    settings: AnalyzerSettings
    spectral: SpectralSettings
    run: RunInfo
    scene: object
    spectra: Mapping
    h_t: MeasuredResponse
    theta_2: MeasuredResponse
    model: ModelAtLines
    expected: ExpectedEstimate | None
    comparisons: Mapping
    fits: Mapping
    fit_checks: Mapping
    rotation: RotationReading | None
    exact_modes: tuple
    antiresonances_hz: Mapping
    highpass_at_fmin: tuple
    bench: SampledResponse
    notes: tuple
    coherence_budget: object = None
    coherence_dips: tuple = ()

    @property
    def freqs_hz(self) -> np.ndarray:
        return self.h_t.freqs_hz

    @property
    def display(self) -> np.ndarray:
        """(nf,) bool: the lines in ``fmin_hz <= f <= fmax_hz`` with finite estimates."""
        f = self.freqs_hz
        return (f >= self.settings.fmin_hz) & (f <= self.settings.fmax_hz) \
            & np.isfinite(self.h_t.h) & np.isfinite(self.theta_2.h)

    @functools.cached_property
    def model_curves(self) -> BenchResponse:
        """The exact whole-chain model over the display band on a grid that draws its modes and
        anti-resonances (:meth:`rig.bench.SampledResponse.resolved`, stage-1 curves included):
        what the figures show. Computed on first use, then kept."""
        return self.bench.resolved(self.settings.fmin_hz, self.settings.fmax_hz)

    def report(self) -> str:
        """The Markdown report (:func:`processing.report.analysis_report`)."""
        return analysis_report(self)

    def summary(self) -> str:
        """A concise plain-text summary (what ``daq analyze`` prints)."""
        return analysis_summary(self)


# -- analyze ---------------------------------------------------------------------------------

def _fit_with_check(frf: MeasuredResponse, expected, hp, band, modes, *, method, settings,
                    n_residual, input_spectrum=None) -> tuple[ModalFit, ModalFit | None]:
    """The fit of the pendulum's own response (``frf`` times the known high-pass ``hp``) and, if
    ``expected`` is given, the same fit of the noiseless expected estimate with the same
    weights. ``input_spectrum`` (leakage-aware fits): the bench's input."""
    own = dataclasses.replace(frf, h=frf.h * hp)
    kw = dict(initial=list(modes), settings=settings, method=method, n_residual=n_residual)
    if method == "leakage":
        kw["input_spectrum"] = input_spectrum
    fit = fit_modes(own, band, **kw)
    check = None
    if expected is not None:
        ideal = dataclasses.replace(own, h=expected * hp)
        # Started from the fit of the measurement (fewer iterations, the same minimum).
        kw["initial"] = [(md.f_hz, md.q) for md in fit.modes]
        check = fit_modes(ideal, band, **kw)
    return fit, check


def analyze(recording, settings: AnalyzerSettings | None = None, *,
            source: str = "recording") -> Analysis:
    """Analyse a run like the paper's analyzer, against the exact model (module docstring).

    Parameters
    ----------
    recording : daq.records.Recording
        A run (:func:`daq.hdf5.read_run`): its finished records are used, also of an incomplete
        run (noted in :attr:`Analysis.notes`).
    settings : AnalyzerSettings (default: the paper's experiment, see its docstring).
    source : a label for the run in the report (the file's path).

    Returns
    -------
    Analysis

    Raises
    ------
    SettingsError
        Settings that do not fit the run (e.g. a time record longer than a record).
    ChannelDataError
        A run without the channels a, x, y, or without any finished record.
    """
    with single_threaded_blas():  # thin products only: threads cost more than they do
        return _analyze(recording, settings, source)


def band_limit_hz(antialias_passband_hz: float, rate_hz: float) -> float:
    """The highest frequency [Hz] a run's analysis shows: its anti-alias filter's passband edge
    (``acquisition.antialias_passband`` x the rate: 40 Hz at 100 Hz). Above it the channels
    are attenuated on their way to the Nyquist frequency (rate / 2), and the auto spectrum of
    the input holds little but the window's leakage from below, so the expected estimate E[H1]
    and the comparisons have no meaning there (the 35670A likewise shows a span of rate / 2.56)."""
    return min(float(antialias_passband_hz), 0.5 * float(rate_hz))


def check_band(settings: AnalyzerSettings, antialias_passband_hz: float, rate_hz: float) -> None:
    """A SettingsError if ``settings.fmax_hz`` exceeds :func:`band_limit_hz` of a run sampled at
    ``rate_hz`` [Hz] behind an anti-alias filter whose passband ends at
    ``antialias_passband_hz``; the message names fmax_hz, the limit and why."""
    limit = band_limit_hz(antialias_passband_hz, rate_hz)
    if settings.fmax_hz > limit:
        raise SettingsError(f"fmax_hz = {settings.fmax_hz:g} Hz is above this run's band: its "
                            f"anti-alias filter's passband ends at {limit:g} Hz (the Nyquist "
                            f"frequency of its {rate_hz:g} Hz rate is {rate_hz / 2:g} Hz, and "
                            "above the passband the channels hold mostly leakage); expected "
                            f"fmax_hz <= {limit:g} Hz")


def _analyze(recording, settings: AnalyzerSettings | None, source: str) -> Analysis:
    from rig.bench.sampled import sampled_response

    s = settings if settings is not None else AnalyzerSettings()
    h = recording.header
    spectral = _checked_spectral(recording, s)
    notes, clipped = _run_notes(recording, s)
    spectra, h_t, theta_2 = _measured(recording, spectral, s)
    lines = spectral.freqs_hz
    model = model_at_lines(h, lines)
    scene = h.scene
    exact, anti = _exact_features(scene)
    bench = sampled_response(scene)  # the one evaluator of this analysis
    expected, budget, dips = _expected(h, spectral, s, bench, h_t, theta_2, exact, anti, notes)
    comparisons = _comparisons(h_t, theta_2, model, bench, lines, expected, exact, anti,
                               spectral, s)
    fits, checks = _fits(h_t, theta_2, model, expected, exact, spectral, s, notes)
    rotation = None
    try:
        rotation = _rotation(scene, h_t, theta_2, model, spectral, s.rotation_band_hz)
    except (ConfigError, FitError) as exc:
        notes.append(f"no rotation-isolation reading: {exc}")
    plan = h.plan
    run = RunInfo(source=str(source), scene=scene.name, seed=int(h.seed),
                  status=str(recording.status), records=int(recording.records),
                  records_planned=int(plan.records), record_s=float(plan.record_s),
                  rate_hz=float(plan.rate_hz), clipped=MappingProxyType(clipped))
    return Analysis(settings=s, spectral=spectral, run=run, scene=scene,
                    spectra=MappingProxyType(spectra),
                    h_t=h_t, theta_2=theta_2, model=model, expected=expected,
                    comparisons=MappingProxyType(comparisons), fits=MappingProxyType(fits),
                    fit_checks=MappingProxyType(checks), rotation=rotation, exact_modes=exact,
                    antiresonances_hz=MappingProxyType(anti),
                    highpass_at_fmin=_highpass_at(bench, s.fmin_hz), notes=tuple(notes),
                    coherence_budget=budget, coherence_dips=dips, bench=bench)


def _checked_spectral(recording, s: AnalyzerSettings) -> SpectralSettings:
    """The run's spectral settings, after the checks that the run can be analysed with ``s``
    (band, channels, at least one record, at least two averages)."""
    h = recording.header
    plan = h.plan
    check_band(s, h.antialias.passband_hz, plan.rate_hz)
    missing = [c for c in CHANNELS if c not in h.names]
    if missing:
        raise ChannelDataError(f"the run has channels {', '.join(h.names)}: expected a "
                               f"(input), x and y (outputs); missing {', '.join(missing)}")
    n_rec = recording.records
    if n_rec == 0:
        raise ChannelDataError(f"the run holds no finished record (status {recording.status}, "
                               f"0 of {plan.records} records): nothing to analyse")
    spectral = s.spectral(plan.rate_hz, plan.samples)
    per_record = 1 + (plan.samples - spectral.nperseg) // spectral.step
    if n_rec * per_record < 2:
        raise SettingsError(f"{n_rec} record x {per_record} FFT = 1 average: coherence and error "
                            "bands need at least 2; use a shorter time record (e.g. nperseg = "
                            f"{plan.samples // 2} with overlap 0.5)")
    return spectral


def _run_notes(recording, s: AnalyzerSettings) -> tuple[list, dict]:
    """The notes on the run itself (averaging, incomplete, clipped, saturated) and the clipped
    samples per channel."""
    h = recording.header
    plan = h.plan
    n_rec = recording.records
    notes = []
    if s.averaging == "vector":
        notes.append("vector averaging of an asynchronous random source averages the spectra "
                     "towards zero: the ratios are not H1 and the Bendat-Piersol bands do not "
                     "apply")
    if not recording.complete or n_rec < plan.records:
        notes.append(f"INCOMPLETE run (status {recording.status}): analysed the {n_rec} finished "
                     f"record{'s' if n_rec != 1 else ''} of {plan.records} planned")
    clips = recording.clip_counts().sum(axis=0) if n_rec else np.zeros(len(h.names), int)
    clipped = {c: int(v) for c, v in zip(h.names, clips)}
    if any(clipped.values()):
        notes.append("clipped samples (" + ", ".join(f"{c} {v}" for c, v in clipped.items() if v)
                     + "): the ratios are not those of a linear system there")
    sats = recording.saturation_counts().sum(axis=0) if n_rec else np.zeros(len(h.names), int)
    if sats.any():
        notes.append("samples whose sensor saturated (" + ", ".join(
            f"{c} {int(v)}" for c, v in zip(h.names, sats) if v) + "; the accelerometer over its "
            "range or the spot off the PSD): the ratios are not those of a linear system there")
    return notes, clipped


def _measured(recording, spectral: SpectralSettings, s: AnalyzerSettings):
    """``(spectra, h_t, theta_2)`` from one shared set of segment FFTs of ``a, x, y``."""
    h = recording.header
    units = {c: h.channel(c).unit for c in CHANNELS}
    ffts = segment_ffts({c: recording.values(c) for c in CHANNELS}, spectral, units=units)
    spectra = {c: auto_spectrum(ffts, c) for c in CHANNELS}
    spectra.update(ax=cross_spectrum(ffts, "a", "x"), ay=cross_spectrum(ffts, "a", "y"))
    h_t = frequency_response(ffts, "a", "x", estimator=s.estimator)
    theta_2 = frequency_response(ffts, "a", "y", estimator=s.estimator)
    return spectra, h_t, theta_2


def _exact_features(scene) -> tuple[tuple, dict]:
    """The pendulum's modes ``((f_hz, Q), ...)`` and the anti-resonances [Hz] of ``x``, ``y``."""
    chain = scene.chain
    f_modes, q_modes = chain.modes()
    exact = tuple((float(fm), float(qm)) for fm, qm in zip(f_modes, q_modes))
    anti = {"x": tuple(float(v) for v in chain.antiresonances_hz(scene.mirror_weights())),
            "y": tuple(float(v) for v in chain.antiresonances_hz(np.eye(chain.n)[
                scene.mirror.body]))}
    return exact, anti


def _highpass_at(bench: SampledResponse, fmin_hz: float) -> tuple[float, float]:
    """(dB, deg) of the whole chain against the pendulum alone at ``fmin_hz``; (NaN, NaN) at
    0 Hz, where the high-pass passes nothing and the ratio is 0/0."""
    if not fmin_hz > 0:
        return (math.nan, math.nan)
    r = bench(np.array([fmin_hz]))
    hp = r.h_t[0] / r.h_t_pendulum[0]
    return (float(_DB * np.log(abs(hp))), float(np.degrees(np.angle(hp))))


def _expected(h, spectral, s, bench, h_t, theta_2, exact, anti, notes):
    """``(expected, budget, dips)``: E[H1] (H1 only), the coherence budget and its named dips
    (any estimator: the coherence does not depend on it); what is skipped goes to ``notes``."""
    expected = None
    if s.estimator != "h1":
        notes.append(f"estimator {s.estimator.upper()}: E[H1] and the leakage bias model H1 and "
                     "are not computed")
    else:
        try:
            expected = expected_estimate(h, spectral, bench=bench, fmin_hz=s.fmin_hz,
                                         fmax_hz=s.fmax_hz)
        except SettingsError as exc:
            notes.append(f"no expected estimate: {exc}")
    grid = expected  # the coherence does not depend on the estimator: its FFT length and notch
    if grid is None and s.estimator != "h1":
        try:
            grid = expected_estimate(h, spectral, bench=bench, fmin_hz=s.fmin_hz,
                                     fmax_hz=s.fmax_hz)
        except SettingsError:
            grid = None
    if grid is None:
        return expected, None, ()
    from processing.coherence_model import coherence_budget, named_dips

    budget = coherence_budget(h, spectral, bench, n_fft=grid.n_fft, n_averages=h_t.n_effective)
    dips = tuple(named_dips(budget, {"x": h_t.coherence, "y": theta_2.coherence},
                            modes_hz=[fm for fm, _ in exact], antiresonances_hz=anti,
                            input_notch_db=grid.input_notch_db, fmin_hz=s.fmin_hz,
                            fmax_hz=s.fmax_hz))
    return expected, budget, dips


def _comparisons(h_t, theta_2, model, bench, lines, expected, exact, anti, spectral, s) -> dict:
    """The measured ratios against the model (at the lines: ``model``'s values, elsewhere
    ``bench``'s) over the display band (:func:`processing.compare.compare`)."""
    def model_fn(name):
        stored = getattr(model, name)

        def fn(f):
            f = np.asarray(f, float)
            if f.shape == lines.shape and np.array_equal(f, lines):
                return stored
            return getattr(bench(f), name)
        return fn

    kw = dict(resonances=exact, settings=spectral, fmin_hz=s.fmin_hz, fmax_hz=s.fmax_hz, k=s.k)
    return {
        _LABEL_T: compare(h_t, model_fn("h_t"), antiresonances_hz=anti["x"],
                          expected=None if expected is None else expected.h_t, **kw),
        _LABEL_R: compare(theta_2, model_fn("theta_2"), antiresonances_hz=anti["y"],
                          expected=None if expected is None else expected.theta_2, **kw),
    }


def _fits(h_t, theta_2, model, expected, exact, spectral, s, notes) -> tuple[dict, dict]:
    """The modal fits ``{label: ModalFit}`` of Theta_2 and H_t by each of ``s.fit_methods`` and
    the same fits of E[H1]; what is not fitted goes to ``notes``."""
    fits, checks = {}, {}
    names = {"leakage": "leakage-aware", "direct": "direct"}
    hp = model.highpass
    if h_t.n_effective <= 2.0:
        notes.append(f"n_eff = {h_t.n_effective:.3g} averages: too few for coherence-weighted "
                     "modal fits (their covariance needs n_eff > 2); not fitted")
        return fits, checks
    spectrum = None if expected is None else expected.input_spectrum
    if "leakage" in s.fit_methods and spectrum is None:
        notes.append("leakage-aware fits assume a white input (no expected estimate, hence no "
                     "input spectrum): their Q is biased where the input is notched")
    for label, frf, e, band in (
            ("Theta_2", theta_2, None if expected is None else expected.theta_2,
             s.theta2_fit_band_hz),
            ("H_t", h_t, None if expected is None else expected.h_t, s.ht_fit_band_hz)):
        modes = [fm for fm, _ in exact if band[0] < fm < band[1]]
        if not modes:
            notes.append(f"no mode of the model in {label}'s fit band {band[0]:g}-{band[1]:g} Hz: "
                         "not fitted")
            continue
        for method in s.fit_methods:
            key = f"{label} {names[method]}"
            try:
                fit, check = _fit_with_check(frf, e, hp, band, modes, method=method,
                                             settings=spectral, n_residual=s.n_residual,
                                             input_spectrum=spectrum)
            except FitError as exc:
                notes.append(f"{key} fit not made: {exc}")
                continue
            fits[key] = fit
            if check is not None:
                checks[key] = check
    return fits, checks


def _rotation(scene, h_t, theta_2, model, spectral, band) -> RotationReading:
    """|Theta_2 / Theta_1| with Theta_1 = x / l (mirror centre at O2, x = l theta_1)."""
    from rig.ishizaki import design_parameters, rotation_isolation

    chain = scene.chain
    w = scene.mirror_weights()
    if chain.n != 2 or w[1] != 0.0 or w[0] == 0.0:
        raise ConfigError("it needs the two-body pendulum with the mirror centre at O2 "
                          "(x = l theta_1)")
    ri = rotation_isolation(design_parameters(chain))
    lever = float(w[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = model.theta_2 / (model.h_t / lever)
    return rotation_reading(theta_2, h_t, band_hz=band, theta1_scale=lever, model_ratio=ratio,
                            exact_limit=ri.ratio, alpha=ri.alpha, settings=spectral)


# -- for the pictures ------------------------------------------------------------------------

def incomplete_note(a: Analysis) -> str:
    """"" for a complete run, else what the figures must say: "4 of 30 records (interrupted)"."""
    if a.run.complete:
        return ""
    return f"{a.run.records} of {a.run.records_planned} records ({a.run.status})"


def paper_figures(scene) -> bool:
    """Whether the paper's Figs. 9 and 10 show this kind of pendulum (an Ishizaki design)."""
    return scene.pendulum_kind == "ishizaki"
