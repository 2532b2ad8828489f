"""The analyzer's reading of a run: one call from a recording to every number the paper shows.

:func:`analyze` turns a :class:`daq.records.Recording` (a run file read by
:func:`daq.hdf5.read_run`, complete or interrupted) into a frozen :class:`Analysis`:

1. **one shared set of segment FFTs** of the channels ``a, x, y`` in engineering units
   (:meth:`Recording.values`: calibration and sensor sign undone) with the 35670A-like
   :class:`AnalyzerSettings`; from it the auto spectra ``G_aa, G_xx, G_yy``, the cross spectra
   ``G_ax, G_ay``, ``H_t = G_ax / G_aa`` [m per m/s^2] and ``Theta_2 = G_ay / G_aa`` [rad per
   m/s^2] (H1), their coherences and Bendat-Piersol bands (:mod:`processing.frf`);
2. **the exact model at the FFT lines**: the whole sampled chain's ``h_t`` and ``theta_2``
   (:func:`rig.bench.expected_response` ``sampled=True``, which the run file stores on the record's
   FFT grid ``k / record_s``). With the default one-FFT-per-record settings the lines *are* that
   grid and the stored values are used as they are; otherwise (shorter time records, other spans)
   they are recomputed exactly at the lines -- never interpolated: the 2.48 Hz mode is 4.7 mHz
   wide, and interpolating it from a 10 mHz grid would misplace its peak by tens of dB. The model
   is the *whole chain*: the accelerometer's 0.05 Hz high-pass sits in the denominator of both
   ratios, so at 0.1 Hz the analyzer reads the pendulum +0.97 dB and -26.6 deg off (see
   :attr:`Analysis.highpass_at_fmin`);
3. **the expected estimate** ``E[H1]`` for this window and record length
   (:func:`expected_estimate`), which separates the leakage bias at the sharp resonances from the
   random error (:func:`processing.compare.compare`);
4. **modal fits** (:func:`processing.modal.fit_modes`), leakage-aware and analyzer-style direct,
   of Theta_2 (both modes, 0.83 and 2.48 Hz) and of H_t (the 2.48 Hz mode; the 0.83 Hz mode of
   the mirror translation is all but cancelled by its anti-resonance at 0.827 Hz), each next to
   the fit of the noiseless ``E[H1]`` with the same weights, which measures the method's own
   systematic error on this bench;
5. the paper's reading ``|Theta_2 / Theta_1|`` above f1 (:func:`processing.modal.rotation_reading`
   with :func:`rig.ishizaki.rotation_isolation`) and the Markdown report
   (:func:`processing.report.report_markdown` plus the run, the model and the fits' systematic
   error).

Window
------
The default is Hann, the 35670A's window for random noise. "Fourier transform each record"
(SPEC section 1) literally means the uniform window, which is a setting (``window="uniform"``).
Hann is the better choice here: for H1 the expected estimate is the response tapered by the
window's autocorrelation, which for Hann is flat to second order at lag 0 (so away from the
resonances the bias is second order in the record length) while the uniform window's triangle
biases every line to first order (relative error about the group delay over the record length);
and the uniform window's slowly falling side lobes carry power across many lines, which is not
coherent with the line's input: on the paper's run (seed 1) the median coherence over 0.1 - 10 Hz
falls from 0.999 to 0.52 for H_t and from 0.96 to 0.05 for Theta_2, and the error bands widen
accordingly. At the 2.48 Hz peak neither window resolves the mode (0.47 lines per half-power
bandwidth); ``E[H1]`` quantifies the bias for whichever is chosen.

The expected estimate on this bench
-----------------------------------
For a stationary input ``u`` and output ``x`` the averaged cross and auto spectra have the
expectations (any overlap and any power averaging; exact, no white-input assumption)::

    E[G_ux](f_k) ~ sum_tau R_ux[tau] r_w(|tau|) exp(-2j pi f_k tau / fs),   |tau| < nperseg

with ``R_ux[tau] = E[u[n] x[n + tau]]`` and ``r_w`` the window's normalised autocorrelation; so
``E[H1] = E[G_ux] / E[G_uu]`` (the ratio of expectations; the expected ratio differs by terms of
order ``1 / n_d`` inside the random error). :func:`expected_estimate` computes the correlations
as inverse FFTs of the bench's exact sampled cross spectra under its source::

    S_ax = S_v conj(A) X |F|^2,   S_aa = (S_v |A|^2 + N_a) |F|^2 + Q_a

``S_v`` the source's design PSD, ``A, X`` the channels in engineering units per source volt
(:func:`rig.bench.expected_response` ``sampled=True``), ``F`` the anti-alias filter, ``N_a``
the accelerometer's white noise and ``Q_a`` the ADC's quantisation noise of channel ``a``
(``lsb^2 / (6 rate)``). The sensor noise of x and y does not enter ``E[G_ux]``. Neglected:
aliasing of the decimation (the filter's stop band is ~100 dB down), the FIR's edge smoothing of the
source band (0.05 Hz at the 12.5 Hz edge, 250 lines from the 10 Hz display edge).
The white-input formula of :meth:`processing.compare.ImpulseResponse.expected_h1` does not hold
for this bench: with the stage's reaction (``stage.reaction = true``) the stage acceleration per
source volt has a notch exactly at each pendulum mode (the pendulum's dynamic mass is infinite
there): the input PSD at the 2.48 Hz line is 16 dB below its median over the band, so the
window weights the lines beside the peak more than the peak. On the paper's settings E[H1] of
H_t at the 2.48 Hz line is -11.8 dB, 15.4 dB below the exact 3.59 dB, where a white input would
give a bias of -8.35 dB (tests/test_report.py); the measurement agrees with the former. Time
aliasing of the correlations is below ``exp(-(n_fft - nperseg) / (fs tau))``, ``tau`` the
slowest decay time of the bench (about 40 s: :attr:`ExpectedEstimate.alias_bound`).

The leakage-aware modal fit (:func:`processing.modal.fit_modes` ``method="leakage"``) models
``E[H1]`` under this input: :attr:`ExpectedEstimate.input_spectrum` hands it the same coherent
input PSD, the accelerometer's and the ADC's noise and the accelerometer's high-pass as the input
sensor (:class:`processing.modal.InputSpectrum`). A white-input model would cost a systematic
error of -7 % in Q1 here (494 +- 20 against the exact 528.9 on the paper's run, chi^2/dof 1.6 -
2.2). :attr:`Analysis.fit_checks` measures what is left: the same fit of the noiseless ``E[H1]``
with the measured weights; its offset from the exact mode is the method's bias on this bench
(measured: < 3e-6 Hz and 0.03 in Q, below 0.02 of the fits' standard deviations), reported beside
the fitted value (never subtracted from it). The fits use the pendulum's own response: the
measured ratios times the accelerometer's exactly known high-pass (the model's ``h_t_pendulum /
h_t``), because the high-pass adds a pole at 0 Hz that the modal model (modes plus a polynomial
residual) cannot represent. Without an expected estimate (H2/Hv, vector averaging, a source that
is not noise) the leakage-aware fits fall back to a white input, and the notes say so.

Speed
-----
The paper's analysis (30 x 100 s, E[H1] on 131072-point correlation functions, eight modal fits)
computes in 0.2 - 0.3 s of CPU (1.5 s before): the bench's responses on the dense grids come from
the modal form of its exact ZOH step (:class:`_FastBench`, checked against
:func:`rig.bench.expected_response` on every run), the fits by variable projection, and BLAS runs
single-threaded (:mod:`rig._threads`: the products are thin, and OpenBLAS's spinning threads
had tripled the CPU time on a busy two-core machine). Nothing here imports scipy or matplotlib
(the Bode figure imports matplotlib when asked for). What ``daq analyze`` takes beyond that is
starting Python and importing numpy, click, h5py, scipy.linalg (the bench model's matrix
exponentials) and the run-file reader: about 0.6 s. Neither numba (:mod:`rig.jit`: kernels are
compiled or loaded on their first call, and the analysis calls none) nor scipy.signal (~1 s to
import; nothing imports it at run time) is imported; the whole command takes about 1 s
(BENCHMARKS.md).

Public API: :class:`AnalyzerSettings`, :class:`Analysis`, :class:`RunInfo`,
:class:`ModelAtLines`, :class:`ExpectedEstimate`, :func:`analyze`, :func:`model_at_lines`,
:func:`expected_estimate`, :func:`bode_figures`, :func:`write_csv`, :func:`write_bode_png`,
:func:`write_report`, :data:`CSV_COLUMNS`.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from processing.compare import compare, expected_h1_taps
from processing.frf import ESTIMATORS, FrequencyResponse, frequency_response
from processing.modal import (FitError, InputSpectrum, ModalFit, RotationReading, fit_modes,
                              rotation_reading)
from processing.report import report_markdown
from processing.spectra import (AVERAGING, WINDOWS, ChannelDataError, SettingsError,
                                SpectralSettings, _readonly, auto_spectrum, cross_spectrum,
                                segment_ffts)
from rig._io import atomic_output
from rig._threads import single_threaded_blas
from rig.errors import ConfigError

__all__ = ["AnalyzerSettings", "Analysis", "RunInfo", "ModelAtLines", "ExpectedEstimate",
           "analyze", "model_at_lines", "expected_estimate", "bode_figures", "write_csv",
           "write_bode_png", "write_report", "CSV_COLUMNS", "FIT_METHODS", "CHANNELS"]

#: The CSV columns (SPEC section 5): x in m per m/s^2, y in rad per m/s^2, gain in dB re 1 unit,
#: phase in degrees wrapped to (-180, 180], coherence gamma^2 in [0, 1].
CSV_COLUMNS = ("frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg", "x_coherence",
               "y_re", "y_im", "y_gain_db", "y_phase_deg", "y_coherence")
FIT_METHODS = ("leakage", "direct")
#: Input, translation and rotation channel of a run.
CHANNELS = ("a", "x", "y")
_LABEL_T, _LABEL_R = "H_t (x/a)", "Theta_2 (y/a)"
_DB = 20.0 / math.log(10.0)
_ALIAS_TARGET = 1e-12
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
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SettingsError(f"{name} = {value!r} is invalid: expected an integer >= {minimum}")
    return int(value)


def _finite(name: str, value, *, lo=None, hi=None, hi_open=False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(value, bool) or not math.isfinite(v) or (lo is not None and v < lo) or (
            hi is not None and (v >= hi if hi_open else v > hi)):
        rng = f"{lo if lo is not None else '-inf'} <= {name} {'<' if hi_open else '<='} " \
              f"{hi if hi is not None else 'inf'}"
        raise SettingsError(f"{name} = {value!r} is invalid: expected a finite number with {rng}")
    return v


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


class _FastBench:
    """The fields of :func:`rig.bench.expected_response` ``sampled=True`` at many frequencies.

    The exact sampled response is ``C (zeta I - Phi)^-1 Gamma`` (``Phi``, ``Gamma`` the bench's
    exact ZOH step, :attr:`rig.bench.BenchModel.phi`); with ``Phi = V diag(lambda) V^-1`` it is
    ``sum_r (C v_r)(w_r . Gamma) / (zeta - lambda_r)``: O(nz) per frequency and output instead of
    one ``(nz, nz)`` solve (the 12-state bench: ~15 times faster, and the model is built once).
    The outputs are combined as ``expected_response`` combines them. Its round-off differs from
    the solve's where the modal terms cancel: measured within 3e-9 relative of it over
    0 - 500 Hz (the largest near 0 Hz and at the anti-resonances). On construction it is checked
    against ``expected_response`` at frequencies spread over the band, the modes and the
    anti-resonances; beyond :attr:`CHECK_RTOL` it is not used (``verified`` False): the calls
    then go to ``expected_response`` itself. Used for the dense grids (``E[H1]``'s correlation
    functions, the fits' input spectrum, the fine grids of the peaks and plots); the model at
    the analyzer's lines stays ``expected_response``'s (or the run file's).
    """

    CHECK_RTOL = 1e-7

    def __init__(self, scene):
        from rig.bench import build_model, calibrations, expected_response

        self.scene = scene
        model = build_model(_linear_scene(scene))
        acc = model.accelerometer
        nz = model.n_states
        rows = [np.asarray(model.accel_row, float)]
        sensed = rows[0].copy()
        if acc.n_states:
            q = np.zeros(nz)
            q[model.slices["accel_highpass_q_mps"]] = 1.0
            sensed = sensed - acc.corner_rad_s * q
        rows.append(sensed)
        rows.extend(np.eye(nz)[model.slices["theta_rad"]])
        decay = -np.linalg.eigvals(model.a).real
        decay = decay[decay > 0]
        #: slowest decay time of the bench [s]
        self.tau_s = float(1.0 / decay.min()) if decay.size else 0.0
        lam, vec = np.linalg.eig(model.phi)
        w = np.linalg.solve(vec, np.asarray(model.gamma, complex))
        self.lam = lam
        self.residues = (np.vstack(rows) @ vec) * w  # (n_out, nz)
        self.fs = model.fs_hz
        cal = calibrations(scene)
        self.vpm = acc.volts_per_mps2
        self.cal = {k: cal[k].volts_per_unit for k in ("a", "x", "y")}
        self.weights = scene.mirror_weights()
        self.body = scene.mirror.body
        check = self._check_freqs(scene)
        ref = expected_response(scene, check, sampled=True)
        got = self._evaluate(check)
        worst = 0.0
        for k in (*_FIELDS, "theta"):
            a, b = np.asarray(got[k]), np.asarray(getattr(ref, k))
            scale = np.abs(b)
            worst = max(worst, float(np.max(np.abs(a - b) / scale)))
        self.check_error = worst
        self.verified = bool(worst <= self.CHECK_RTOL)

    def _check_freqs(self, scene) -> np.ndarray:
        chain = scene.chain
        fm = [float(v) for v in chain.modes()[0]]
        anti = [float(v) for v in chain.antiresonances_hz(scene.mirror_weights())]
        anti += [float(v) for v in chain.antiresonances_hz(np.eye(chain.n)[scene.mirror.body])]
        f = list(np.geomspace(0.05, 0.45 * self.fs, 12))
        for v in fm + anti:
            f += [v * (1 - 1e-3), v, v * (1 + 1e-3)]
        f = np.array(sorted(v for v in f if 0 < v < 0.5 * self.fs))
        return f

    def _evaluate(self, f: np.ndarray) -> dict:
        zf = np.exp(2j * np.pi * f / self.fs)
        g = 1.0 / (zf[:, None] - self.lam[None, :])  # (nf, nz)
        # (nf, n_out) by einsum's own loop: BLAS threads on this thin product cost ten times
        # its work on a busy two-core machine.
        y = np.einsum("fr,or->fo", g, self.residues)
        stage_accel, sensed, theta = y[:, 0], y[:, 1], y[:, 2:]
        a = self.vpm * sensed
        mirror_x = theta @ self.weights
        mirror_rot = theta[:, self.body]
        a_eng = a / self.cal["a"]
        with np.errstate(invalid="ignore", divide="ignore"):
            return {"a": a, "x": self.cal["x"] * mirror_x, "y": self.cal["y"] * mirror_rot,
                    "stage_accel": stage_accel, "theta": theta, "mirror_x": mirror_x,
                    "mirror_rot": mirror_rot, "h_t": mirror_x / a_eng,
                    "theta_2": mirror_rot / a_eng, "h_t_pendulum": mirror_x / stage_accel,
                    "theta_2_pendulum": mirror_rot / stage_accel}

    def __call__(self, f) -> dict:
        """The fields (and ``theta``, (nf, n)) at ``f`` [Hz], ``0 <= f < fs_sim / 2``."""
        f = np.atleast_1d(np.asarray(f, dtype=float))
        if not self.verified:
            return _bench_response(self.scene, f)
        if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f >= self.fs / 2):
            raise ConfigError(f"freqs_hz must lie in [0, {self.fs / 2:g}) Hz (half the "
                              "simulation rate)")
        return self._evaluate(f)


def model_at_lines(header, freqs_hz) -> ModelAtLines:
    """The exact whole-chain ``h_t``, ``theta_2`` (and the pendulum's) at ``freqs_hz``.

    Taken from the run's stored model (``header.response``) when every line lies on its grid (the
    default one-FFT-per-record settings); otherwise recomputed exactly with
    :func:`rig.bench.expected_response` ``sampled=True`` -- the same function that wrote the
    stored values -- never interpolated (module notes).
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
    return ModelAtLines(_readonly(f), *(_readonly(np.asarray(vals[k], complex))
                                        for k in _MODEL_KEYS), source)


# -- the expected estimate -------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class ExpectedEstimate:
    """``E[H1]`` of the bench at the analyzer's lines (module notes).

    Attributes
    ----------
    freqs_hz : (nf,) [Hz]; h_t, theta_2 : (nf,) complex, same units as the measured ratios.
    n_fft : FFT length of the correlation functions [samples].
    tau_s : slowest decay time of the bench [s].
    alias_bound : ``exp(-(n_fft - nperseg) / (fs tau))``: bound on the time aliasing (relative).
    input_psd : (nf,) the model's ``E[G_aa]`` at the lines [(m/s^2)^2/Hz] (window-averaged).
    input_notch_db : {mode f [Hz]: input PSD at the line nearest the mode relative to its median
        over the display band [dB]} -- how coloured the input is where it matters.
    input_spectrum : processing.modal.InputSpectrum, the same input (coherent PSD, noise PSD and
        the accelerometer's high-pass as the input sensor) at any frequency, for the
        leakage-aware fits of the pendulum's own response.
    """

    freqs_hz: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    n_fft: int
    tau_s: float
    alias_bound: float
    input_psd: np.ndarray
    input_notch_db: Mapping
    input_spectrum: InputSpectrum | None = None


def _linear_scene(scene):
    return scene.with_acquisition(model="linear")


def expected_estimate(header, settings: SpectralSettings, *, n_fft: int | None = None,
                      fmin_hz: float = 0.1, fmax_hz: float = 10.0) -> ExpectedEstimate:
    """Expected H1 of H_t and Theta_2 for the run's bench and source under ``settings``.

    Parameters
    ----------
    header : daq.records.Header of the run (scene, channels, anti-alias filter, plan).
    settings : the analyzer's settings (window, nperseg; power averaging).
    n_fft : FFT length of the correlation functions (default: a power of two >= 4 nperseg making
        the time aliasing of the slowest mode below 1e-12).
    fmin_hz, fmax_hz : band of :attr:`ExpectedEstimate.input_notch_db`.

    Raises
    ------
    SettingsError
        For a source that is not stationary noise (``source.type`` random or pink), vector
        averaging (whose expectation is not a ratio of averaged powers), or a rate mismatch.
    """
    return _expected_estimate(header, settings, _FastBench(header.scene), n_fft=n_fft,
                              fmin_hz=fmin_hz, fmax_hz=fmax_hz)


def _expected_estimate(header, settings: SpectralSettings, bench: _FastBench, *,
                       n_fft: int | None, fmin_hz: float, fmax_hz: float) -> ExpectedEstimate:
    scene = header.scene
    plan = header.plan
    fs = plan.rate_hz
    if abs(settings.fs - fs) > 1e-9 * fs:
        raise SettingsError(f"settings.fs = {settings.fs} Hz differs from the run's rate {fs} Hz")
    if settings.averaging == "vector":
        raise SettingsError("averaging = 'vector' averages complex spectra: E[H1] as a ratio of "
                            "averaged powers does not apply; expected rms or exponential")
    source = scene.source
    if source.type not in ("random", "pink"):
        raise SettingsError(f"source.type = {source.type!r}: E[H1] is modelled for stationary "
                            "noise sources (random, pink) only")
    acc = scene.accelerometer
    tau = bench.tau_s
    n = settings.nperseg
    if n_fft is None:
        need = max(4 * n, int(math.ceil(n + fs * tau * math.log(1.0 / _ALIAS_TARGET))))
        n_fft = 1 << (need - 1).bit_length()
    n_fft = int(n_fft)
    if n_fft < 2 * n:
        raise SettingsError(f"n_fft = {n_fft} is invalid: expected >= 2 nperseg = {2 * n}")
    ca = header.channel("a")
    vpu = {c: header.channel(c).volts_per_unit for c in CHANNELS}
    noise_a = (acc.sensitivity_vpmps2 * acc.noise_mps2_rthz / abs(vpu["a"])) ** 2
    quant_a = (ca.adc.lsb_v / vpu["a"]) ** 2 / (6.0 * fs)

    def channels(f):
        """(s_v, a, x, y in engineering units, |F|^2) at f (0 outside the source's band)."""
        s_v = source.design_psd(f)
        band = s_v > 0
        eng = {c: np.zeros(f.size, complex) for c in CHANNELS}
        r = bench(f[band])
        for c in CHANNELS:
            eng[c][band] = r[c] / vpu[c]
        return s_v, eng, np.abs(header.antialias.response(f)) ** 2

    f = np.arange(n_fft // 2 + 1) * (fs / n_fft)
    s_v, eng, f2 = channels(f)
    a_eng, x_eng, y_eng = (eng[c] for c in CHANNELS)
    s_aa = (s_v * np.abs(a_eng) ** 2 + noise_a) * f2 + quant_a
    s_ax = s_v * np.conj(a_eng) * x_eng * f2
    s_ay = s_v * np.conj(a_eng) * y_eng * f2

    def tapered(s):  # sum_tau R[tau] r_w(|tau|) exp(-2j pi f_k tau / fs), |tau| < nperseg
        rr = np.fft.irfft(s, n=n_fft)
        taps = np.concatenate([rr[-(n - 1):], rr[:n]]) if n > 1 else rr[:1]
        return expected_h1_taps(taps, settings, lag0=-(n - 1))

    g_aa = tapered(s_aa.astype(complex))
    with np.errstate(divide="ignore", invalid="ignore"):
        e_t = tapered(s_ax) / g_aa
        e_r = tapered(s_ay) / g_aa
    lines = settings.freqs_hz
    # The tapered sum of the one-sided PSD's correlation is (n_fft / 2) E[G] (irfft's 1/n_fft and
    # the two-sided density S/2): E[G_aa] in (m/s^2)^2/Hz, window-averaged.
    g_in = g_aa.real * 2.0 * fs / n_fft
    disp = (lines >= fmin_hz) & (lines <= fmax_hz)
    notch = {}
    if np.any(disp):
        med = float(np.median(g_in[disp]))
        for fm in scene.chain.modes()[0]:
            j = int(np.argmin(np.abs(lines - fm)))
            if disp[j]:
                notch[float(fm)] = float(10 * np.log10(g_in[j] / med))
    bound = math.exp(-(n_fft - n) / (fs * tau)) if tau > 0 else 0.0

    # The same input for the leakage-aware fits of the pendulum's own response (the measured
    # ratio times the accelerometer's high-pass K = a / stage acceleration).
    def psd(f):
        s_v, eng, f2 = channels(f)
        return s_v * np.abs(eng["a"]) ** 2 * f2

    def noise(f):
        return noise_a * np.abs(header.antialias.response(f)) ** 2 + quant_a

    def sensor(f):
        r = bench(f)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = r["h_t_pendulum"] / r["h_t"]
        return np.where(np.isfinite(k), k, 1.0)

    spectrum = InputSpectrum(psd, noise, sensor, decay_s=tau,
                             label="the bench's exact input spectrum")
    return ExpectedEstimate(_readonly(lines), _readonly(e_t), _readonly(e_r), n_fft, tau, bound,
                            _readonly(g_in), MappingProxyType(notch), spectrum)


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
    drawn or written (see :func:`bode_figures`, :func:`write_csv`, :func:`write_report`,
    :func:`processing.spectra_hdf5.write_spectra`).

    Attributes
    ----------
    settings : AnalyzerSettings; spectral : the SpectralSettings they gave for this run.
    run : RunInfo; scene : the run's resolved rig.scene.Scene.
    spectra : {"a", "x", "y": auto spectra G_aa, G_xx, G_yy; "ax", "ay": cross spectra G_ax,
        G_ay} (density scaling, engineering units), all lines.
    h_t, theta_2 : FrequencyResponse (x/a [m per m/s^2], y/a [rad per m/s^2]), all lines.
    model : ModelAtLines, the exact whole chain at every line.
    expected : ExpectedEstimate or None (why not: in ``notes``).
    comparisons : {"H_t (x/a)", "Theta_2 (y/a)": Comparison over the display band}.
    fits : {label: ModalFit}, labels "Theta_2 leakage-aware", "H_t direct", ...
    fit_checks : {label: ModalFit of the noiseless E[H1] with the same weights}.
    rotation : RotationReading or None.
    exact_modes : ((f_hz, Q), ...) of the pendulum.
    antiresonances_hz : {"x": (...), "y": (...)}.
    highpass_at_fmin : (dB, deg) of the whole chain against the pendulum alone at ``fmin_hz``.
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
    h_t: FrequencyResponse
    theta_2: FrequencyResponse
    model: ModelAtLines
    expected: ExpectedEstimate | None
    comparisons: Mapping
    fits: Mapping
    fit_checks: Mapping
    rotation: RotationReading | None
    exact_modes: tuple
    antiresonances_hz: Mapping
    highpass_at_fmin: tuple
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

    def report(self) -> str:
        """The Markdown report (module docstring, item 5)."""
        return _report(self)

    def summary(self) -> str:
        """A concise plain-text summary (what ``daq analyze`` prints)."""
        return _summary(self)


# -- analyze ---------------------------------------------------------------------------------

def _fit_with_check(frf: FrequencyResponse, expected, hp, band, modes, *, method, settings,
                    n_residual, input_spectrum=None) -> tuple[ModalFit, ModalFit | None]:
    """The fit of the pendulum's own response (``frf`` times the known high-pass ``hp``) and, if
    ``expected`` is given, the same fit of the noiseless expected estimate with the same
    weights. ``input_spectrum`` (leakage-aware fits): the bench's input."""
    own = FrequencyResponse(frf.freqs_hz, frf.h * hp, frf.coherence, frf.n_averages,
                            frf.n_effective, frf.estimator, frf.input, frf.output, frf.units)
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


def _analyze(recording, settings: AnalyzerSettings | None, source: str) -> Analysis:
    s = settings if settings is not None else AnalyzerSettings()
    h = recording.header
    plan = h.plan
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

    units = {c: h.channel(c).unit for c in CHANNELS}
    ffts = segment_ffts({c: recording.values(c) for c in CHANNELS}, spectral, units=units)
    spectra = {c: auto_spectrum(ffts, c) for c in CHANNELS}
    spectra.update(ax=cross_spectrum(ffts, "a", "x"), ay=cross_spectrum(ffts, "a", "y"))
    h_t = frequency_response(ffts, "a", "x", estimator=s.estimator)
    theta_2 = frequency_response(ffts, "a", "y", estimator=s.estimator)
    lines = spectral.freqs_hz

    model = model_at_lines(h, lines)
    scene = h.scene
    chain = scene.chain
    f_modes, q_modes = chain.modes()
    exact = tuple((float(fm), float(qm)) for fm, qm in zip(f_modes, q_modes))
    anti = {"x": tuple(float(v) for v in chain.antiresonances_hz(scene.mirror_weights())),
            "y": tuple(float(v) for v in chain.antiresonances_hz(np.eye(chain.n)[
                scene.mirror.body]))}
    bench = _FastBench(scene)
    if not bench.verified:
        notes.append(f"the fast evaluation of the bench's response differs from "
                     f"rig.bench.expected_response by {bench.check_error:.1e} (relative): the "
                     "slow one was used")
    r_min = bench(np.array([s.fmin_hz]))
    hp_min = r_min["h_t"][0] / r_min["h_t_pendulum"][0]
    highpass_at_fmin = (float(_DB * np.log(abs(hp_min))), float(np.degrees(np.angle(hp_min))))

    expected = None
    if s.estimator != "h1":
        notes.append(f"estimator {s.estimator.upper()}: E[H1] and the leakage bias model H1 and "
                     "are not computed")
    else:
        try:
            expected = _expected_estimate(h, spectral, bench, n_fft=None, fmin_hz=s.fmin_hz,
                                          fmax_hz=s.fmax_hz)
        except SettingsError as exc:
            notes.append(f"no expected estimate: {exc}")
    budget, dips = None, ()
    grid = expected  # the coherence does not depend on the estimator: its FFT length and notch
    if grid is None and s.estimator != "h1":
        try:
            grid = _expected_estimate(h, spectral, bench, n_fft=None, fmin_hz=s.fmin_hz,
                                      fmax_hz=s.fmax_hz)
        except SettingsError:
            grid = None
    if grid is not None:
        from processing.coherence_model import coherence_budget, named_dips

        budget = coherence_budget(h, spectral, bench, n_fft=grid.n_fft,
                                  n_averages=h_t.n_effective)
        dips = tuple(named_dips(budget, {"x": h_t.coherence, "y": theta_2.coherence},
                                modes_hz=[fm for fm, _ in exact], antiresonances_hz=anti,
                                input_notch_db=grid.input_notch_db, fmin_hz=s.fmin_hz,
                                fmax_hz=s.fmax_hz))

    def model_fn(name):
        stored = getattr(model, name)

        def fn(f):
            f = np.asarray(f, float)
            if f.shape == lines.shape and np.array_equal(f, lines):
                return stored
            return bench(f)[name]
        return fn

    cmp_kw = dict(resonances=exact, settings=spectral, fmin_hz=s.fmin_hz, fmax_hz=s.fmax_hz,
                  k=s.k)
    comparisons = {
        _LABEL_T: compare(h_t, model_fn("h_t"), antiresonances_hz=anti["x"],
                          expected=None if expected is None else expected.h_t, **cmp_kw),
        _LABEL_R: compare(theta_2, model_fn("theta_2"), antiresonances_hz=anti["y"],
                          expected=None if expected is None else expected.theta_2, **cmp_kw),
    }

    fits, checks = {}, {}
    hp = model.highpass
    names = {"leakage": "leakage-aware", "direct": "direct"}
    if h_t.n_effective <= 2.0:
        notes.append(f"n_eff = {h_t.n_effective:.3g} averages: too few for coherence-weighted "
                     "modal fits (their covariance needs n_eff > 2); not fitted")
    spectrum = None if expected is None else expected.input_spectrum
    if "leakage" in s.fit_methods and spectrum is None and h_t.n_effective > 2.0:
        notes.append("leakage-aware fits assume a white input (no expected estimate, hence no "
                     "input spectrum): their Q is biased where the input is notched")
    for label, frf, e, band in (
            ("Theta_2", theta_2, None if expected is None else expected.theta_2,
             s.theta2_fit_band_hz),
            ("H_t", h_t, None if expected is None else expected.h_t, s.ht_fit_band_hz)):
        modes = [fm for fm, _ in exact if band[0] < fm < band[1]]
        if h_t.n_effective <= 2.0:
            continue
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

    rotation = None
    try:
        rotation = _rotation(scene, h_t, theta_2, model, spectral, s.rotation_band_hz)
    except (ConfigError, FitError) as exc:
        notes.append(f"no rotation-isolation reading: {exc}")

    run = RunInfo(source=str(source), scene=scene.name, seed=int(h.seed),
                  status=str(recording.status), records=int(n_rec),
                  records_planned=int(plan.records), record_s=float(plan.record_s),
                  rate_hz=float(plan.rate_hz), clipped=MappingProxyType(clipped))
    return Analysis(settings=s, spectral=spectral, run=run, scene=scene,
                    spectra=MappingProxyType(spectra),
                    h_t=h_t, theta_2=theta_2, model=model, expected=expected,
                    comparisons=MappingProxyType(comparisons), fits=MappingProxyType(fits),
                    fit_checks=MappingProxyType(checks), rotation=rotation, exact_modes=exact,
                    antiresonances_hz=MappingProxyType(anti), highpass_at_fmin=highpass_at_fmin,
                    notes=tuple(notes), coherence_budget=budget, coherence_dips=dips)


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


# -- text ------------------------------------------------------------------------------------

def _pct(x) -> str:
    return f"{100 * x:.1f} %"


def _settings_line(a: Analysis) -> str:
    sp = a.spectral
    return (f"{sp.window} window, {sp.nperseg}-sample FFT ({sp.nperseg / sp.fs:g} s, "
            f"{sp.resolution_hz * 1e3:.4g} mHz lines), overlap {sp.overlap_fraction:.0%}, "
            f"{sp.averaging} averaging, {a.settings.estimator.upper()}: "
            f"{a.h_t.n_averages} averages (n_eff {a.h_t.n_effective:.3g})")


def _run_line(a: Analysis) -> str:
    r = a.run
    state = "complete" if r.complete else f"INCOMPLETE, status {r.status}"
    return (f"{r.source}: {r.scene}, seed {r.seed}, {r.records} of {r.records_planned} records "
            f"x {r.record_s:g} s at {r.rate_hz:g} Hz ({state})")


def _model_line(a: Analysis) -> str:
    db, deg = a.highpass_at_fmin
    where = ("from the run file (its grid is the FFT lines: exact, not interpolated)"
             if a.model.source == "file" else
             "recomputed exactly at the FFT lines (rig.bench.expected_response, sampled)")
    return (f"model: the whole sampled chain, accelerometer high-pass included ({db:+.2f} dB, "
            f"{deg:+.1f} deg against the pendulum alone at {a.settings.fmin_hz:g} Hz), {where}")


def _fmt_mode(md, check, exact) -> str:
    txt = f"{md.f_hz:.5f} ± {md.f_std_hz:.1e} Hz, Q {md.q:.4g} ± {md.q_std:.2g}"
    if not md.reliable:
        txt += " (leakage-limited: Q biased low)"
    if check is not None and exact is not None:
        cm = min(check.modes, key=lambda m: abs(m.f_hz - exact[0]))
        txt += (f"; method offset on this bench {1e3 * (cm.f_hz - exact[0]):+.3f} mHz, "
                f"Q {cm.q - exact[1]:+.2f}")
    return txt


def _summary(a: Analysis) -> str:
    out = [f"analysed {_run_line(a)}", f"analyzer: {_settings_line(a)}", _model_line(a)]
    if a.expected is not None:
        out.append(f"E[H1]: from the bench's exact correlations under its source (n_fft "
                   f"{a.expected.n_fft}, aliasing < {a.expected.alias_bound:.0e})")
    for n in a.notes:
        out.append(f"note: {n}")
    co = []
    for label, c in a.comparisons.items():
        g = c.measured.coherence
        j = int(np.nanargmin(g))
        co.append(f"{label.split()[0]} median {np.nanmedian(g):.4f}, min {g[j]:.3g} at "
                  f"{c.freqs_hz[j]:.4g} Hz")
    out.append(f"coherence {a.settings.fmin_hz:g}-{a.settings.fmax_hz:g} Hz: " + "; ".join(co))
    if a.coherence_dips:
        out.append("coherence dips predicted by the bench's model (expected gamma^2 with the "
                   "optical lever's second-order geometry, noise floors and leakage):")
        out += [f"  {d.text}" for d in a.coherence_dips]
    ok = []
    for label, c in a.comparisons.items():
        b = c.bands[0]
        ok.append(f"{label.split()[0]} {_pct(b.frac_gain_total)} / {_pct(b.frac_phase_total)} "
                  f"of {b.n_lines} lines")
        exp_txt = f"{_pct(b.expected_fraction)} ± {_pct(b.fraction_se)}"
    out.append(f"away from the peaks, gain / phase within {a.settings.k:g} sigma of the exact "
               f"model: {'; '.join(ok)} (expected {exp_txt})")
    out.append("peaks (line nearest each mode): exact | E[H1] | measured gain, bias = E[H1] vs "
               "exact")
    for label, c in a.comparisons.items():
        for p in c.peaks:
            bias = (f"bias {p.bias_db:+.2f} dB {p.bias_deg:+.1f} deg ({p.bias_sigma:.1f} sigma)"
                    if math.isfinite(p.bias_db) else "bias n/a")
            out.append(f"  {label.split()[0]:8s} {p.line_hz:.4g} Hz: {p.model_db:.2f} | "
                       f"{p.expected_db:.2f} | {p.measured_db:.2f} dB, {bias}, "
                       f"gamma^2 {p.coherence:.3f}")
    if a.fits:
        out.append("modes (fit ± 1 sigma; method offset = the same fit of the noiseless E[H1] "
                   "minus exact):")
    else:
        out.append("modes: not fitted (see the notes)")
    for i, (fe, qe) in enumerate(a.exact_modes):
        out.append(f"  mode {i + 1}: exact {fe:.5f} Hz, Q {qe:.1f}")
        for key, fit in a.fits.items():
            if not fit.modes:
                continue
            md = min(fit.modes, key=lambda m: abs(m.f_hz - fe))
            if abs(md.f_hz - fe) > 0.1 * fe:
                continue
            out.append(f"    {key:24s} {_fmt_mode(md, a.fit_checks.get(key), (fe, qe))}")
    rot = a.rotation
    if rot is not None:
        out.append(f"|Theta_2/Theta_1| {rot.band_hz[0]:g}-{rot.band_hz[1]:g} Hz: "
                   f"{rot.mean_db:.2f} ± {rot.mean_std_db:.2f} dB (model "
                   f"{rot.model_mean_db:.2f} dB); extrapolated limit {rot.limit_db:.2f} ± "
                   f"{rot.limit_std_db:.2f} dB (exact {rot.exact_limit_db:.2f} dB, alpha = r2/r1 "
                   f"{rot.alpha_db:.2f} dB)")
    return "\n".join(out)


def _report(a: Analysis) -> str:
    r = a.run
    body = report_markdown(dict(a.comparisons), fits=dict(a.fits), exact_modes=a.exact_modes,
                           settings=a.spectral, rotation=a.rotation,
                           title=f"Analysis of {Path(r.source).name}: {r.scene}, seed {r.seed}")
    title, _, rest = body.partition("\n")
    head = ["", "## Run", "", f"- {_run_line(a)}"]
    if any(r.clipped.values()):
        head.append("- clipped samples: " + ", ".join(f"{c} {v}" for c, v in r.clipped.items()))
    else:
        head.append("- no clipped samples")
    head += [f"- {n}" for n in a.notes]
    db, deg = a.highpass_at_fmin
    head += ["", "## Model", "",
             "H_t = W_ax/W_aa and Θ₂ = W_ay/W_aa are compared with the exact response of the "
             "*whole* sampled chain (rig.bench.expected_response, sampled=True): the "
             "accelerometer's high-pass is in the denominator of both, so at "
             f"{a.settings.fmin_hz:g} Hz the analyzer reads {db:+.2f} dB and {deg:+.1f}° off "
             "the pendulum alone; the anti-alias filter, common to all channels, cancels.",
             ""]
    if a.model.source == "file":
        head.append("- model values: the run file's, whose grid (k / record length) is the "
                    "analyzer's lines: exact, no interpolation.")
    else:
        head.append("- model values: recomputed exactly at the analyzer's lines (they are not on "
                    "the run file's grid; interpolating a 4.7 mHz wide mode would misplace its "
                    "peak).")
    e = a.expected
    if e is not None:
        notch = ", ".join(f"{v:+.1f} dB at {f:.4g} Hz" for f, v in e.input_notch_db.items())
        head.append(
            "- E[H1], the expected estimate for this window and record length, comes from the "
            "bench's exact auto and cross correlations under its source (input PSD, stage with "
            "the pendulum's reaction, accelerometer noise, ADC quantisation), tapered by the "
            f"window's autocorrelation (n_fft = {e.n_fft}, time aliasing < "
            f"{e.alias_bound:.0e}). The input is not white: relative to its median over the "
            f"display band the stage acceleration's PSD is {notch}, the notches the pendulum's "
            "reaction digs into the stage motion at its own modes. A white-input E[H1] would "
            "misstate the bias at the peaks.")
    head.append("")
    out = title + "\n" + "\n".join(head) + rest
    if a.coherence_budget is not None:
        out = _insert_before(out, "## Modal fit", _dips_section(a))
    if a.fit_checks:
        out = _insert_before(out, "## Leakage bias and random error at the peaks",
                             _checks_section(a))
    return out


def _dips_section(a: Analysis) -> str:
    """The report's "Coherence dips explained" section (processing.coherence_model)."""
    b = a.coherence_budget
    out = ["## Coherence dips explained", "",
           "The expected coherence comes from the bench's exact spectra tapered by the window "
           "(as E[H1]) with every mechanism that lowers it: the optical lever's second-order "
           f"geometry (calibrated x reads dx - {b.coefficients['x']:.4g} m/rad² θ², y reads "
           f"θ - {b.coefficients['y']:.4g} /m dx θ: products of Gaussian signals, uncorrelated "
           "with the input, at the sums and doubles of the frequencies in the motion), the "
           "accelerometer's and the PSD's noise floors, ADC quantisation and leakage, plus the "
           f"estimator's own bias (1 - γ²)²/n_d for n_d = {b.n_averages:g}. Each dip's causes "
           "are the shares of the lost coherence that each mechanism alone removes.", ""]
    if not a.coherence_dips:
        out.append(f"- no dip deeper than 1 - γ² = 0.05 is predicted over "
                   f"{a.settings.fmin_hz:g}-{a.settings.fmax_hz:g} Hz.")
    out += [f"- {d.text}" for d in a.coherence_dips]
    return "\n".join(out) + "\n"


def _insert_before(text: str, marker: str, section: str) -> str:
    i = text.find(marker)
    return text + "\n" + section if i < 0 else text[:i] + section + "\n" + text[i:]


def _input_text(a: Analysis) -> str:
    for fit in a.fits.values():
        if fit.method == "leakage":
            sp = fit.input_spectrum
            return "a white input" if sp is None else sp.label
    return "a white input"


def _checks_section(a: Analysis) -> str:
    lines = ["## Systematic error of the modal fits on this bench", "",
             "Each fit is repeated on the noiseless E[H1] with the same lines and weights; the "
             "difference from the exact mode is the method's own error on this bench (the "
             f"leakage-aware model takes {_input_text(a)}; the direct one ignores leakage). It "
             "is reported, not subtracted. The fits use the pendulum's own response: the "
             "measured ratio times the accelerometer's known high-pass, whose pole at 0 Hz the "
             "modal model cannot represent.", "",
             "| fit | exact f [Hz] | f of E[H1] fit − exact [mHz] | in σ of the fit | exact Q | "
             "Q of E[H1] fit − exact | in σ of the fit |",
             "|---|---|---|---|---|---|---|"]
    for key, check in a.fit_checks.items():
        fit = a.fits[key]
        for md in fit.modes:
            fe, qe = min(a.exact_modes, key=lambda m: abs(m[0] - md.f_hz))
            cm = min(check.modes, key=lambda m: abs(m.f_hz - fe))
            df, dq = cm.f_hz - fe, cm.q - qe
            zf = df / md.f_std_hz if md.f_std_hz > 0 else math.nan
            zq = dq / md.q_std if md.q_std > 0 else math.nan
            lines.append(f"| {key} | {fe:.6g} | {1e3 * df:+.4f} | {zf:+.3f} | {qe:.1f} | "
                         f"{dq:+.2f} | {zq:+.3f} |")
    lines.append("")
    return "\n".join(lines)


# -- pictures and files ----------------------------------------------------------------------

def _fine_grid(a: Analysis) -> np.ndarray:
    lo, hi = a.settings.fmin_hz, a.settings.fmax_hz
    parts = [np.geomspace(max(lo, 1e-3), hi, 1500)]
    for fm, q in a.exact_modes:
        half = min(8.0 * fm / q, 0.2 * fm) if math.isfinite(q) else 0.01 * fm
        parts.append(np.linspace(fm - half, fm + half, 401))
    f = np.unique(np.concatenate(parts))
    return f[(f >= max(lo, 1e-3)) & (f <= hi)]


def incomplete_note(a: Analysis) -> str:
    """"" for a complete run, else what the figures must say: "4 of 30 records (interrupted)"."""
    if a.run.complete:
        return ""
    return f"{a.run.records} of {a.run.records_planned} records ({a.run.status})"


def paper_figures(scene) -> bool:
    """Whether the paper's Figs. 9 and 10 show this kind of pendulum (an Ishizaki design)."""
    return scene.pendulum_kind == "ishizaki"


def bode_figures(a: Analysis, *, k: float | None = None, phase: str = "wrapped"):
    """The measured Bode diagrams (:func:`processing.plots.measured_bode_figure`): translation
    H_t (cf. the paper's Fig. 9 for an Ishizaki pendulum) and rotation Theta_2 (cf. Fig. 10),
    measured lines with their Bendat-Piersol band over the exact whole-chain model, stage 1
    dotted (body 1's centre of mass, resp. theta_1, per unit stage acceleration as the analyzer
    reads it), E[H1] dashed, and the coherence; titled from the scene, an incomplete run marked.
    ``phase``: "wrapped" or "unwrapped". Returns ``(fig_translation, fig_rotation)``; the caller
    closes them."""
    from processing.plots import Curve, measured_bode_figure

    scene = a.scene
    chain = scene.chain
    f = _fine_grid(a)
    r = _FastBench(scene)(f)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_eng = r["mirror_x"] / r["h_t"]  # sensed stage acceleration per source volt
        theta1 = r["theta"][:, 0] / a_eng
    g1 = theta1 * chain.point_weights(0, chain.com_m[0])[0]
    kk = a.settings.k if k is None else k
    paper = paper_figures(scene)
    figs = []
    lines = a.freqs_hz
    est = a.settings.estimator.upper()
    for frf, model, stage1, e, what, title, s1, unit in (
            (a.h_t, r["h_t"], g1, None if a.expected is None else a.expected.h_t, "H_t",
             "mirror translation H_t = W_ax/W_aa" + (" (cf. the paper's Fig. 9)" if paper else ""),
             "stage 1: translation of its centre of mass G1 (model)", "m/(m/s^2)"),
            (a.theta_2, r["theta_2"], theta1, None if a.expected is None else a.expected.theta_2,
             "Θ₂", "mirror rotation Θ₂ = W_ay/W_aa" + (" (cf. the paper's Fig. 10)" if paper
                                                       else ""),
             "stage 1: rotation θ₁ (model)", "rad/(m/s^2)")):
        figs.append(measured_bode_figure(
            frf, model=Curve(f"exact model of {what} (whole chain)", f, model),
            stage1=Curve(s1, f, stage1),
            expected=None if e is None else Curve(f"E[H1] of {what} (expected estimate)", lines,
                                                  e),
            k=kk, title=f"{a.run.scene}: {title}\nseed {a.run.seed}, {est}, "
                        f"{a.settings.window} window, {frf.n_averages} averages",
            unit=unit, fmin_hz=a.settings.fmin_hz, fmax_hz=a.settings.fmax_hz, what=what,
            phase=phase, incomplete=incomplete_note(a)))
    return tuple(figs)


def write_bode_png(a: Analysis, path, *, force: bool = False, dpi: int = 100,
                   phase: str = "wrapped") -> Path:
    """Both Bode diagrams side by side in one PNG (translation left, rotation right): the
    ``bode`` view of :func:`processing.views.write_views`."""
    from processing.views import write_views

    return write_views(a, path, "bode", phase=phase, force=force, dpi=dpi)[0]


def write_csv(a: Analysis, path, *, force: bool = False) -> Path:
    """The measured H_t (x) and Theta_2 (y) over the display band as CSV (:data:`CSV_COLUMNS`;
    x in m per m/s^2, y in rad per m/s^2, SPEC section 5); full float precision."""
    path = Path(path)
    m = a.display
    cols = [a.freqs_hz[m]]
    for frf in (a.h_t, a.theta_2):
        cols += [frf.h.real[m], frf.h.imag[m], frf.magnitude_db[m], frf.phase_deg[m],
                 frf.coherence[m]]
    with atomic_output(path, force=force) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(CSV_COLUMNS)
            for row in zip(*cols):
                w.writerow([repr(float(v)) for v in row])
    return path


def write_report(a: Analysis, path, *, force: bool = False) -> Path:
    """The Markdown report (:meth:`Analysis.report`)."""
    path = Path(path)
    text = a.report()
    with atomic_output(path, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path
