"""The paper's reading of rotation isolation ``|Theta_2 / Theta_1|`` above f1 (claim (29)).

:func:`rotation_reading` averages the measured ratio over a band above f1 (weights from the
Bendat-Piersol errors, the window's line correlation in the covariance), compares it with the
exact model over the same lines, and extrapolates the measurement to its high-frequency limit
with the model's shape (:class:`RotationReading`, dB).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from processing.compare import correlation_matrix, line_correlation
from processing.frf import MeasuredResponse
from processing.modal_model import FitError
from processing.spectra import SpectralSettings
from rig.readonly import readonly

__all__ = ["RotationReading", "rotation_reading"]


@dataclass(frozen=True, eq=False)
class RotationReading:
    """The paper's claim (29): ``|Theta_2 / Theta_1|`` above f1, measured and modelled.

    Attributes
    ----------
    freqs_hz : (n,) lines of the band [Hz].
    ratio : (n,) measured ``Theta_2 / Theta_1`` (complex) on those lines.
    ratio_sigma_rel : (n,) its relative standard deviation (``sqrt(eps_1^2 + eps_2^2)``).
    model_ratio : (n,) the exact model's ratio, or None.
    band_hz : (f_lo, f_hi).
    mean_db, mean_std_db : mean over the lines of ``20 log10 |ratio|`` and its standard
        deviation [dB] (line correlation included when settings are given).
    model_mean_db : the same mean of the model's ratio [dB] (NaN without model).
    limit_db : extrapolated high-frequency limit ``20 log10 |L|`` from the measured ratio with the
        model's shape (``ratio(f) = L * model_ratio(f) / model_limit``) [dB]; limit_std_db its
        standard deviation (NaN without a model and its limit).
    exact_limit_db : the exact limit ``nu^2 (1 - sigma^2) / (1 - beta^2 / sigma^2)`` [dB] (NaN if
        not given); alpha_db : ``20 log10 alpha`` (claim (29)) [dB] (NaN if not given).
    """

    freqs_hz: np.ndarray
    ratio: np.ndarray
    ratio_sigma_rel: np.ndarray
    model_ratio: np.ndarray | None
    band_hz: tuple
    mean_db: float
    mean_std_db: float
    model_mean_db: float
    limit_db: float
    limit_std_db: float
    exact_limit_db: float
    alpha_db: float


def rotation_reading(theta2: MeasuredResponse, theta1, *, band_hz: tuple[float, float],
                     theta1_scale: float = 1.0, model_ratio=None, exact_limit: float | None = None,
                     alpha: float | None = None,
                     settings: SpectralSettings | None = None) -> RotationReading:
    """Measured ``|Theta_2 / Theta_1|`` in a band above f1, next to the exact model and alpha.

    Parameters
    ----------
    theta2 : MeasuredResponse of the rotation channel (rad per input unit).
    theta1 : MeasuredResponse of a channel proportional to Theta_1 (e.g. the mirror translation
        ``x = l theta_1`` with ``theta1_scale = l``), measured with the same input; or a complex
        array of Theta_1 from the model on ``theta2.freqs_hz`` (then only Theta_2's error enters).
    band_hz : (f_lo, f_hi) [Hz]: above f1 and, to approach the limit, above Theta_2's
        anti-resonance.
    theta1_scale : ``theta1 = channel / theta1_scale`` (e.g. the lever l [m/rad]).
    model_ratio : complex array of the model's ``Theta_2 / Theta_1`` on ``theta2.freqs_hz``,
        or a callable ``freqs_hz -> ratio``.
    exact_limit : the model's high-frequency limit (``rig.ishizaki.rotation_isolation(d).ratio``).
    alpha : ``r2 / r1`` (claim (29)).
    settings : for the line correlation in the band mean's uncertainty.
    """
    lo, hi = (float(v) for v in band_hz)
    f_all = np.asarray(theta2.freqs_hz, dtype=float)
    if isinstance(theta1, MeasuredResponse):
        if theta1.freqs_hz.shape != f_all.shape or not np.allclose(theta1.freqs_hz, f_all):
            raise FitError("theta1 and theta2 must be on the same lines")
        t1 = np.asarray(theta1.h) / theta1_scale
        e1 = np.asarray(theta1.relative_error)
    else:
        t1 = np.asarray(theta1, dtype=complex) / theta1_scale
        if t1.shape != f_all.shape:
            raise FitError(f"theta1 has shape {t1.shape}: expected {f_all.shape}")
        e1 = np.zeros(f_all.shape)
    e2 = np.asarray(theta2.relative_error)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_all = np.asarray(theta2.h) / t1
    sel = (f_all >= lo) & (f_all <= hi) & np.isfinite(ratio_all) & np.isfinite(e1) \
        & np.isfinite(e2)
    if sel.sum() < 2:
        raise FitError(f"fewer than 2 usable lines in band_hz = {band_hz}")
    f = f_all[sel]
    ratio = ratio_all[sel]
    srel = np.sqrt(e1[sel] ** 2 + e2[sel] ** 2)
    if model_ratio is not None:
        mr = np.asarray(model_ratio(f_all) if callable(model_ratio) else model_ratio,
                        dtype=complex)[sel]
    else:
        mr = None
    # Unweighted mean of ln|ratio| over the lines: weights from the measured coherence would
    # correlate with the values (a line whose output happens to read high also reads a higher
    # coherence) and bias the mean up (0.35 dB at 6-10 Hz in the ishizaki2009 test). Its
    # variance 1^T C 1 / n^2 uses srel and, with settings, the window's line correlation.
    y = np.log(np.abs(ratio))
    cmat = np.diag(srel**2)
    if settings is not None:
        lines = np.round(f / settings.resolution_hz).astype(int)
        cmat = correlation_matrix(lines, line_correlation(settings)) * np.outer(srel, srel)
    n = f.size
    std = math.sqrt(float(cmat.sum())) / n
    db = 20.0 / math.log(10.0)
    mean = float(np.mean(y)) * db
    model_mean = float(np.mean(np.log(np.abs(mr)))) * db if mr is not None else math.nan
    if mr is not None and exact_limit is not None:
        lim = float(np.mean(y - np.log(np.abs(mr / exact_limit)))) * db
        lim_std = std * db
    else:
        lim = lim_std = math.nan
    return RotationReading(
        freqs_hz=readonly(f), ratio=readonly(ratio), ratio_sigma_rel=readonly(srel),
        model_ratio=None if mr is None else readonly(mr), band_hz=(lo, hi), mean_db=mean,
        mean_std_db=std * db, model_mean_db=model_mean, limit_db=lim,
        limit_std_db=lim_std,
        exact_limit_db=20 * math.log10(abs(exact_limit)) if exact_limit else math.nan,
        alpha_db=20 * math.log10(alpha) if alpha else math.nan)
