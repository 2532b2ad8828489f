"""Measured frequency response against the exact model: random error, leakage bias, statistics.

A measured H1 differs from the exact response ``H`` of the system for two reasons (SPEC section 6):

* **leakage bias**, deterministic: for a white input the expected estimate is
  ``E[H1](f_k) = sum_tau g[tau] r_w(|tau|) exp(-2j pi f_k tau / fs)``, the discrete-time impulse
  response ``g`` tapered by the window's normalised autocorrelation ``r_w`` (zero beyond
  ``nperseg`` lags; :mod:`processing.leakage`). ``bias = E[H1] - H``. It matters where ``H``
  changes on the scale of a line: at the 2.48 Hz mode of the ``ishizaki2009`` preset (Q ~ 529,
  half-power bandwidth ``f/Q`` ~ 4.7 mHz) a 100 s record's 10 mHz lines cannot resolve the peak;
* **random error**: ``measured - E[H1]``, predicted by Bendat & Piersol from the measured coherence
  (:attr:`processing.frf.MeasuredResponse.relative_error`, ``eps``), as standard deviation of the
  relative error along (gain) and across (phase) the response.

:func:`compare` takes the measured response, the exact model on the same lines and (optionally)
``E[H1]``, and reports residuals normalised by ``eps``, per band, plus the bias and the random
part at each resonance peak.

Statistics of normalised residuals
----------------------------------
With ``n_d`` averages and the band from the *measured* coherence, a normalised gain or phase
residual of an unbiased H1 is Student-t distributed: ``t_nu sqrt(n_d / (n_d - 1))`` with
``nu = 2 (n_d - 1)`` degrees of freedom (conditional on the input, the error of H1 is Gaussian
with variance ``G_nn / (n_d G_xx)``; the residual power estimate behind the coherence is
``chi^2_nu`` and independent of it). :func:`expected_fraction_within` gives the fraction of lines
within ``k`` sigma (0.9460 for k = 2, n_d = 30, against 0.9545 for a normal law). Lines are
correlated through the window: the complex errors of lines ``j`` apart have correlation
``|rho_j|^2``, ``rho_j`` the normalised transform of ``w^2`` (Hann: 4/9, 1/36), so the binomial
standard error of a fraction over ``N`` lines is inflated by ``sqrt(1 + 2 sum_j c_j)`` with
``c_j`` the indicator correlations (Hann: 1.089; :func:`fraction_standard_error`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from processing.frf import MeasuredResponse
from processing.spectra import ProcessingError, SpectralSettings
from rig.readonly import readonly

__all__ = [
    "ModelError", "line_correlation", "correlation_matrix", "expected_fraction_within",
    "fraction_standard_error", "BandStats", "PeakBias", "Comparison", "compare",
]

class ModelError(ProcessingError, ValueError):
    """A model, or a model array, that does not fit the measurement (shape, frequencies, NaN)."""



# -- statistics of normalised residuals ------------------------------------------------------

def line_correlation(settings: SpectralSettings, *, tol: float = 1e-6) -> np.ndarray:
    """Correlation ``|rho_j|^2`` of the complex H1 errors of lines ``j`` apart, ``j = 0, 1, ...``
    while above ``tol`` (white input and noise): ``rho_j = sum w^2 exp(-2j pi j n / N) / sum w^2``.
    Hann: ``[1, 4/9, 1/36]``; uniform: ``[1]``."""
    w2 = settings.window_array ** 2
    rho = np.abs(np.fft.rfft(w2)) / w2.sum()
    c = rho**2
    big = np.nonzero(c > tol)[0]
    return c[: big[-1] + 1].copy() if big.size else np.ones(1)


def correlation_matrix(lines: np.ndarray, corr: np.ndarray) -> np.ndarray:
    """The correlation matrix ``R[i, j] = corr[|lines[i] - lines[j]|]`` (0 beyond the last lag)
    of the errors at the line indices ``lines``, ``corr`` from :func:`line_correlation`."""
    lag = np.abs(lines[:, None] - lines[None, :])
    return np.where(lag < corr.size, corr[np.minimum(lag, corr.size - 1)], 0.0)


def expected_fraction_within(k: float, n_effective: float) -> float:
    """Expected fraction of normalised gain (or phase) residuals within ``+-k`` for an unbiased H1
    with its band from the measured coherence: ``P(|t_nu| < k sqrt((n_d - 1)/n_d))``,
    ``nu = 2 (n_d - 1)`` (module notes); the normal value ``erf(k / sqrt 2)`` for large ``n_d``."""
    nd = float(n_effective)
    if nd <= 1.0:
        return float("nan")
    nu = 2.0 * (nd - 1.0)
    x = k * math.sqrt((nd - 1.0) / nd)
    return float(1.0 - _betainc(0.5 * nu, 0.5, nu / (nu + x * x)))


def _betainc(a: float, b: float, x: float) -> float:
    """The regularised incomplete beta function ``I_x(a, b)`` (``P(|t_nu| > t) = I_x(nu/2, 1/2)``
    with ``x = nu / (nu + t^2)``), by its continued fraction (modified Lentz; relative error
    ~1e-15, tests/processing/test_compare.py checks it against scipy.stats.t)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
                     + b * math.log1p(-x))
    if x > (a + 1.0) / (a + b + 2.0):
        return 1.0 - front * _betacf(b, a, 1.0 - x) / b
    return front * _betacf(a, b, x) / a


def _betacf(a: float, b: float, x: float) -> float:
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 1000):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    return h


def fraction_standard_error(p: float, n_lines: int, settings: SpectralSettings | None = None,
                            k: float = 2.0) -> float:
    """Standard error of a fraction ``p`` of ``n_lines`` lines within ``k`` sigma.

    Binomial ``sqrt(p (1 - p) / N)``, inflated for the window's line correlation: indicators
    ``1{|z| < k}`` of Gaussians with correlation ``c`` have covariance ``sum_m a_m^2 c^m m!``
    over even ``m`` (Hermite expansion, ``a_2 = -k phi(k)``); ``c = |rho_j|^2`` per lag
    (:func:`line_correlation`). Without ``settings`` the lines are taken as independent.
    """
    if n_lines <= 0:
        return float("nan")
    var1 = p * (1.0 - p)
    infl = 1.0
    if settings is not None and var1 > 0:
        phi = math.exp(-0.5 * k * k) / math.sqrt(2 * math.pi)
        # Hermite coefficients of the even indicator: a_m = E[1{|z|<k} He_m(z)] / m!
        he = [-2 * k * phi, -2 * (k**3 - 3 * k) * phi, None]  # m = 2, 4
        he[2] = -2 * (k**5 - 10 * k**3 + 15 * k) * phi  # m = 6
        for c in line_correlation(settings)[1:]:
            cov = sum((h / math.factorial(m)) ** 2 * math.factorial(m) * c**m
                      for h, m in zip(he, (2, 4, 6)))
            infl += 2.0 * cov / var1
    return math.sqrt(var1 * infl / n_lines)


# -- the comparison --------------------------------------------------------------------------

_DB = 20.0 / math.log(10.0)  # dB per neper


def _projected(h: np.ndarray, ref: np.ndarray, sigma_abs: np.ndarray) -> tuple:
    """In-phase and quadrature components of ``h - ref`` relative to ``ref``'s phase, in units of
    ``sigma_abs``."""
    d = (h - ref) * np.exp(-1j * np.angle(ref)) / sigma_abs
    return d.real, d.imag


@dataclass(frozen=True)
class BandStats:
    """Residual statistics over one band of lines.

    A normalised residual ``z`` is the in-phase (gain, ``z_gain``) or quadrature (phase,
    ``z_phase``) component of ``measured - reference``, relative to the reference's phase, in
    units of the Bendat-Piersol standard deviation ``eps |measured|``. To first order in ``eps``
    these are the gain residual in units of ``sigma_dB`` and the phase residual in units of
    ``sigma_deg``; ``|z_gain| <= k`` is exactly "the reference's gain lies inside the measured
    ``k``-sigma gain band" (:meth:`MeasuredResponse.gain_band_db`) when ``z`` is small. Both are
    Student-t distributed at any coherence (module notes). ``*_total``: reference = exact model;
    ``*_random``: reference = ``E[H1]`` (NaN without it).

    Attributes
    ----------
    name : "away", "near f Hz" (a resonance) or "notch f Hz" (an anti-resonance).
    fmin_hz, fmax_hz : extent of the band's lines [Hz]; n_lines : lines used.
    k : the sigma multiple of the fractions.
    expected_fraction : :func:`expected_fraction_within` (k, n_d); fraction_se : its standard
        error over ``n_lines`` (:func:`fraction_standard_error`).
    rms_gain_total, max_gain_total, frac_gain_total : rms and max of ``|z_gain|`` and the
        fraction of lines with ``|z_gain| <= k``; ``*_phase_*`` the same for ``z_phase``.
    rms_gain_random ... frac_phase_random : the same against ``E[H1]``.
    max_bias_db, max_bias_deg : largest ``|20 log10|E[H1]/H||`` [dB] and ``|angle(E[H1]/H)|``
        [deg] in the band (signed values of those lines).
    max_bias_sigma : largest ``|E[H1] - H| / (eps |measured|)``: the bias in units of the random
        error's standard deviation per component.
    median_sigma_db : median 1-sigma gain error [dB]; median_coherence : median gamma^2.
    """

    name: str
    fmin_hz: float
    fmax_hz: float
    n_lines: int
    k: float
    expected_fraction: float
    fraction_se: float
    rms_gain_total: float
    max_gain_total: float
    frac_gain_total: float
    rms_phase_total: float
    max_phase_total: float
    frac_phase_total: float
    rms_gain_random: float
    max_gain_random: float
    frac_gain_random: float
    rms_phase_random: float
    max_phase_random: float
    frac_phase_random: float
    max_bias_db: float
    max_bias_deg: float
    max_bias_sigma: float
    median_sigma_db: float
    median_coherence: float


@dataclass(frozen=True)
class PeakBias:
    """Leakage bias against random error at one resonance.

    Attributes
    ----------
    f_hz, q : the model's mode [Hz], [-].
    half_power_bw_hz : ``f / Q`` [Hz]; lines_per_bw : that over the line spacing.
    leakage_limited : ``lines_per_bw < 8`` (the 35670A manual's rule, SPEC section 6).
    line_hz : the line nearest ``f_hz`` [Hz].
    model_db, expected_db, measured_db : gain at that line [dB] of the exact model, ``E[H1]``
        (NaN if not given) and the measurement.
    bias_db, bias_deg : ``E[H1] / H`` at that line [dB], [deg].
    random_db, random_deg : ``measured / E[H1]`` at that line [dB], [deg].
    sigma_db, sigma_deg : predicted 1-sigma random error there (measured coherence).
    bias_sigma : ``|E[H1] - H| / (eps |measured|)`` at that line.
    random_z_gain, random_z_phase : the random part's normalised components (``BandStats``).
    coherence : measured gamma^2 at that line.
    true_peak_db : the model's maximum gain near ``f_hz`` (on a fine grid when the model is a
        callable, else the largest of the 5 lines around it) [dB].
    measured_peak_db, expected_peak_db : largest measured / expected gain of those 5 lines [dB].
    peak_deficit_db : ``expected_peak_db - true_peak_db``: how low the peak reads on average.
    """

    f_hz: float
    q: float
    half_power_bw_hz: float
    lines_per_bw: float
    leakage_limited: bool
    line_hz: float
    model_db: float
    expected_db: float
    measured_db: float
    bias_db: float
    bias_deg: float
    random_db: float
    random_deg: float
    sigma_db: float
    sigma_deg: float
    bias_sigma: float
    random_z_gain: float
    random_z_phase: float
    coherence: float
    true_peak_db: float
    measured_peak_db: float
    expected_peak_db: float
    peak_deficit_db: float


@dataclass(frozen=True, eq=False)
class Comparison:
    """A measured frequency response next to the exact model and its expected estimate.

    Attributes
    ----------
    measured : MeasuredResponse, restricted to the compared lines.
    model : complex (nf,) exact response on ``measured.freqs_hz``.
    expected : complex (nf,) ``E[H1]`` on the same lines, or None.
    k : sigma multiple of the fractions.
    bands : BandStats: "away" first, then one per resonance and anti-resonance.
    peaks : PeakBias per resonance inside the compared lines.
    masks : dict band name -> (nf,) bool, the lines of each band.
    resolution_hz : line spacing [Hz].
    settings : the analyzer settings, if given.
    """

    measured: MeasuredResponse
    model: np.ndarray
    expected: np.ndarray | None
    k: float
    bands: tuple
    peaks: tuple
    masks: Mapping
    resolution_hz: float
    settings: SpectralSettings | None = None

    @property
    def freqs_hz(self) -> np.ndarray:
        return self.measured.freqs_hz

    @property
    def n_effective(self) -> float:
        return self.measured.n_effective

    @property
    def sigma_rel(self) -> np.ndarray:
        """Bendat-Piersol relative error ``eps`` per line (1-sigma of ``|H|`` / ``|H|`` and the
        phase's std [rad])."""
        return self.measured.relative_error

    @property
    def sigma_abs(self) -> np.ndarray:
        """``eps |measured|``: standard deviation of each component of the complex error."""
        return self.sigma_rel * np.abs(self.measured.h)

    @property
    def sigma_db(self) -> np.ndarray:
        """1-sigma gain error [dB], ``20/ln(10) eps``."""
        return _DB * self.sigma_rel

    @property
    def sigma_deg(self) -> np.ndarray:
        """1-sigma phase error [deg], ``degrees(eps)``."""
        return np.degrees(self.sigma_rel)

    @property
    def z_total(self) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (gain, phase) residual against the model (see :class:`BandStats`)."""
        return _projected(self.measured.h, self.model, self.sigma_abs)

    @property
    def z_random(self) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (gain, phase) residual against ``E[H1]`` (NaN without it)."""
        if self.expected is None:
            nan = np.full(self.model.shape, np.nan)
            return nan, nan
        return _projected(self.measured.h, self.expected, self.sigma_abs)

    def _ratio(self, a, b, kind):
        if a is None or b is None:
            return np.full(self.model.shape, np.nan)
        r = a / b
        return _DB * np.log(np.abs(r)) if kind == "db" else np.degrees(np.angle(r))

    @property
    def bias_db(self) -> np.ndarray:
        """``20 log10 |E[H1] / model|`` [dB] (NaN without E[H1])."""
        return self._ratio(self.expected, self.model, "db")

    @property
    def bias_deg(self) -> np.ndarray:
        """``angle(E[H1] / model)`` [deg] (NaN without E[H1])."""
        return self._ratio(self.expected, self.model, "deg")

    @property
    def bias_sigma(self) -> np.ndarray:
        """``|E[H1] - model| / (eps |measured|)`` (NaN without E[H1])."""
        if self.expected is None:
            return np.full(self.model.shape, np.nan)
        return np.abs(self.expected - self.model) / self.sigma_abs

    @property
    def random_db(self) -> np.ndarray:
        """``20 log10 |measured / E[H1]|`` [dB] (NaN without E[H1])."""
        return self._ratio(self.measured.h, self.expected, "db")

    @property
    def random_deg(self) -> np.ndarray:
        """``angle(measured / E[H1])`` [deg] (NaN without E[H1])."""
        return self._ratio(self.measured.h, self.expected, "deg")

    def band(self, name: str) -> BandStats:
        """The :class:`BandStats` called ``name`` (KeyError if absent)."""
        for b in self.bands:
            if b.name == name:
                return b
        raise KeyError(f"no band named {name!r}: have {[b.name for b in self.bands]}")


def _trio(z: np.ndarray, k: float) -> tuple:
    z = np.abs(z)
    if not z.size:
        return (math.nan,) * 3
    return float(np.sqrt(np.mean(z * z))), float(z.max()), float(np.mean(z <= k))


def _stats(name: str, mask: np.ndarray, cmp: Comparison) -> BandStats:
    zg, zp = cmp.z_total
    ok = mask & np.isfinite(zg) & np.isfinite(zp)
    n = int(ok.sum())
    k = cmp.k
    gt, pt = _trio(zg[ok], k), _trio(zp[ok], k)
    if cmp.expected is not None:
        rg, rp = cmp.z_random
        gr, pr = _trio(rg[ok], k), _trio(rp[ok], k)
        bdb, bdeg, bs = cmp.bias_db[ok], cmp.bias_deg[ok], cmp.bias_sigma[ok]
        if n:
            max_bias_db = float(bdb[np.argmax(np.abs(bdb))])
            max_bias_deg = float(bdeg[np.argmax(np.abs(bdeg))])
            max_bias_sigma = float(bs.max())
        else:
            max_bias_db = max_bias_deg = max_bias_sigma = math.nan
    else:
        gr = pr = (math.nan,) * 3
        max_bias_db = max_bias_deg = max_bias_sigma = math.nan
    p = expected_fraction_within(k, cmp.n_effective)
    f = cmp.freqs_hz[ok]
    return BandStats(
        name=name, fmin_hz=float(f.min()) if n else math.nan,
        fmax_hz=float(f.max()) if n else math.nan, n_lines=n, k=k, expected_fraction=p,
        fraction_se=fraction_standard_error(p, n, cmp.settings, k),
        rms_gain_total=gt[0], max_gain_total=gt[1], frac_gain_total=gt[2],
        rms_phase_total=pt[0], max_phase_total=pt[1], frac_phase_total=pt[2],
        rms_gain_random=gr[0], max_gain_random=gr[1], frac_gain_random=gr[2],
        rms_phase_random=pr[0], max_phase_random=pr[1], frac_phase_random=pr[2],
        max_bias_db=max_bias_db, max_bias_deg=max_bias_deg, max_bias_sigma=max_bias_sigma,
        median_sigma_db=float(np.median(cmp.sigma_db[ok])) if n else math.nan,
        median_coherence=float(np.median(cmp.measured.coherence[ok])) if n else math.nan)


def _db(x) -> float:
    with np.errstate(divide="ignore"):
        return float(_DB * np.log(np.abs(x)))


def compare(measured: MeasuredResponse, model, *, expected=None,
            resonances: Sequence[tuple[float, float]] = (),
            antiresonances_hz: Sequence[float] = (), settings: SpectralSettings | None = None,
            fmin_hz: float = 0.1, fmax_hz: float = 10.0, k: float = 2.0,
            near_lines: float = 20.0, near_bandwidths: float = 10.0) -> Comparison:
    """Compare a measured response with the exact model, separating leakage bias and random error.

    Parameters
    ----------
    measured : MeasuredResponse
        An H1 estimate (its coherence and ``n_effective`` give the Bendat-Piersol error).
    model : complex array (nf,) on ``measured.freqs_hz``, or a callable ``freqs_hz -> complex``
        (then also evaluated on a fine grid for each true peak height). For data sampled from a
        held input use the discrete model (:meth:`DiscreteModel.frequency_response`).
    expected : complex array (nf,), optional
        ``E[H1]`` on the same lines (:meth:`ImpulseResponse.expected_h1`). Without it the bias and
        random parts are NaN and only the total residual is reported.
    resonances : sequence of (f_hz, Q)
        The model's modes (e.g. ``zip(*chain.modes())``). Each has a "near" band of half-width
        ``max(near_lines * df, near_bandwidths * f / Q)``. Leakage bias falls off slowly away
        from a peak narrower than a line: relatively ``m2 / d^2`` at ``d`` lines, ``m2`` the
        second moment of the window's power kernel (1/3 line^2 for Hann: 0.03 dB at 10 lines,
        0.007 dB at 20), which matters where the coherence is very high (see
        ``BandStats.max_bias_sigma``); the default of 20 lines keeps it below 0.2 sigma at
        gamma^2 = 0.999 (eps = 0.004 with 30 averages).
    antiresonances_hz : sequence of float
        Sharp anti-resonances (notches are filled in by leakage too); each has a "notch" band of
        half-width ``near_lines * df``.
    settings : SpectralSettings, optional
        For the line correlation in the fractions' standard error (lines independent without).
    fmin_hz, fmax_hz : compared band [Hz] (default 0.1 - 10 Hz, the paper's plots).
    k : sigma multiple for the fractions (default 2).
    near_lines, near_bandwidths : band half-widths, see above.

    Returns
    -------
    Comparison

    Raises
    ------
    ModelError
        If ``model`` or ``expected`` do not match the measured lines, or are NaN or 0 in the band.
    """
    f_all = np.asarray(measured.freqs_hz)
    model_fn = model if callable(model) else None
    model_all = np.asarray(model_fn(f_all) if model_fn else model, dtype=complex)
    for name, arr in (("model", model_all), ("expected", expected)):
        if arr is not None and np.shape(arr) != f_all.shape:
            raise ModelError(f"{name} has shape {np.shape(arr)}: expected {f_all.shape}, one value "
                             "per measured line")
    sel = (f_all >= fmin_hz) & (f_all <= fmax_hz) & np.isfinite(measured.h) \
        & np.isfinite(measured.coherence)
    if not np.any(sel):
        raise ModelError(f"no finite measured lines in {fmin_hz} <= f <= {fmax_hz} Hz")
    idx = np.nonzero(sel)[0]
    meas = dataclasses.replace(measured, freqs_hz=f_all[idx], h=readonly(measured.h[idx]),
                               coherence=readonly(measured.coherence[idx]))
    mod = model_all[idx]
    exp_ = None if expected is None else np.asarray(expected, dtype=complex)[idx]
    for name, arr in (("model", mod), ("expected", exp_)):
        if arr is not None and not np.all(np.isfinite(arr) & (arr != 0)):
            raise ModelError(f"{name} has non-finite or zero values in the compared band")
    f = meas.freqs_hz
    df = float(np.median(np.diff(f_all))) if f_all.size > 1 else math.nan
    res = [(float(fr), float(q)) for fr, q in resonances]
    masks = _band_masks(f, df, res, antiresonances_hz, near_lines, near_bandwidths)
    cmp = Comparison(meas, readonly(mod), None if exp_ is None else readonly(exp_), float(k),
                     (), (), masks, df, settings)
    bands = tuple(_stats(name, m, cmp) for name, m in masks.items())
    peaks = [p for fr, q in res
             if (p := _peak_bias(fr, q, cmp, model_fn)) is not None]
    return Comparison(meas, cmp.model, cmp.expected, float(k), bands, tuple(peaks),
                      MappingProxyType(masks), df, settings)


def _band_masks(f, df: float, res, antiresonances_hz, near_lines: float,
                near_bandwidths: float) -> dict:
    """The compared bands as read-only masks over the lines ``f``: "away" first, then "near"
    each resonance and "notch" at each anti-resonance (see :func:`compare`)."""
    masks = {}
    for fr, q in res:
        half = max(near_lines * df, near_bandwidths * fr / q)
        masks[f"near {fr:.4g} Hz"] = np.abs(f - fr) <= half
    for fz in antiresonances_hz:
        masks[f"notch {float(fz):.4g} Hz"] = np.abs(f - float(fz)) <= near_lines * df
    away = np.ones(f.size, bool)
    for m in masks.values():
        away &= ~m
    masks = {"away": away, **masks}
    for m in masks.values():
        m.setflags(write=False)
    return masks


def _peak_bias(fr: float, q: float, cmp: Comparison, model_fn) -> PeakBias | None:
    """The :class:`PeakBias` at the line nearest the resonance ``(fr, q)``, or None if it lies
    outside the compared lines; the true peak from ``model_fn`` on a fine grid if given."""
    meas, mod, exp_, df = cmp.measured, cmp.model, cmp.expected, cmp.resolution_hz
    f = meas.freqs_hz
    eps = meas.relative_error
    sig_abs = cmp.sigma_abs
    j = int(np.argmin(np.abs(f - fr)))
    if abs(f[j] - fr) > df:
        return None  # the resonance lies outside the compared lines
    win = slice(max(j - 2, 0), j + 3)
    if model_fn is not None:
        fine = np.linspace(fr - 3 * fr / q, fr + 3 * fr / q, 2001)
        true_peak = _db(np.max(np.abs(np.asarray(model_fn(fine)))))
    else:
        true_peak = _db(np.max(np.abs(mod[win])))
    if exp_ is not None:
        e = exp_[j]
        zg, zp = _projected(meas.h[j], e, sig_abs[j])
        exp_vals = dict(expected_db=_db(e), bias_db=_db(e / mod[j]),
                        bias_deg=float(np.degrees(np.angle(e / mod[j]))),
                        random_db=_db(meas.h[j] / e),
                        random_deg=float(np.degrees(np.angle(meas.h[j] / e))),
                        bias_sigma=float(abs(e - mod[j]) / sig_abs[j]),
                        random_z_gain=float(zg), random_z_phase=float(zp),
                        expected_peak_db=_db(np.max(np.abs(exp_[win]))))
    else:
        exp_vals = dict.fromkeys(("expected_db", "bias_db", "bias_deg", "random_db",
                                  "random_deg", "bias_sigma", "random_z_gain",
                                  "random_z_phase", "expected_peak_db"), math.nan)
    return PeakBias(
        f_hz=fr, q=q, half_power_bw_hz=fr / q, lines_per_bw=fr / q / df,
        leakage_limited=bool(fr / q / df < 8.0), line_hz=float(f[j]),
        model_db=_db(mod[j]), measured_db=_db(meas.h[j]),
        sigma_db=float(_DB * eps[j]), sigma_deg=float(np.degrees(eps[j])),
        coherence=float(meas.coherence[j]), true_peak_db=true_peak,
        measured_peak_db=_db(np.max(np.abs(meas.h[win]))),
        peak_deficit_db=exp_vals["expected_peak_db"] - true_peak, **exp_vals)
