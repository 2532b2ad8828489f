"""The best linear approximation (BLA) from a multisine run, with its noise and distortion variances.

The robust method of Pintelon and Schoukens (System Identification, 2nd ed., 2012, sec. 3.4;
Schoukens, Pintelon, Rolain, Mastering System Identification, 2012, ch. 3): the run's source is
a random-phase multisine (``source.type = "multisine"``) of period ``T`` with R realisations of
P periods each (:mod:`rig.devices.multisine`). The records are cut into whole periods (counted
from t = 0, when the source starts: ``acquisition.settle_s`` and ``record_s`` must be whole
periods), the first ``transient_periods`` of every realisation are dropped, and at the excited
lines ``k``::

    G[r, p](k)   = Y[r, p](k) / U[r, p](k)           U: stage acceleration a [m/s^2]; Y: x [m]
                                                     or y [rad] (the analyzer's H_t, Theta_2)
    G_r          = mean_p G[r, p]                    sigma2_n,r = var_p G[r, p] / P'
    G_BLA        = mean_r G_r
    sigma2_total = var_r G_r / R                     (noise + stochastic nonlinear distortion)
    sigma2_noise = mean_r sigma2_n,r / R             (noise only)
    sigma2_dist  = R (sigma2_total - sigma2_noise)   (the distortion of one realisation, >= 0)

(variances of complex quantities: E|.|^2, sample variances with ``ddof = 1``). Beside it: the
exact linear FRF at the lines (:func:`rig.bench.response.expected_response`, the whole sampled
chain, as the analyzer's model), and at the lines the multisine leaves empty, the output's
periodic (non-noise) power: at even lines it comes from even nonlinearities (the optical lever's
second-order geometry), at the odd lines a random-odd grid leaves out from odd ones (the
pendulum's large-angle terms), each with the noise's own contribution removed
(``mean_r (|mean_p Y|^2 - var_p Y / P')``, the noise power of one realisation's average,
``mean_r var_p Y / P'``, given as the floor).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError

__all__ = ["BestLinearApproximation", "best_linear_approximation", "transient_periods_for",
           "predicted_even_power",
           "OUTPUTS", "TRANSIENT_DECAY"]

#: The two FRFs: output channel -> name.
OUTPUTS = {"x": "H_t", "y": "Theta_2"}


@dataclass(frozen=True)
class BestLinearApproximation:
    """The BLA of one run (module docstring). Per output channel ``c`` in ("x", "y"):
    ``g[c]``, ``exact[c]`` (lines,) complex [c's unit per m/s^2]; ``var_total[c]``,
    ``var_noise[c]``, ``var_distortion[c]`` (lines,) [(unit per m/s^2)^2]; ``even_power[c]``,
    ``odd_power[c]``: the periodic output power at the empty even / odd lines [unit^2] (mean
    over those lines, noise removed; NaN where the grid has none); ``noise_power_floor[c]``:
    the noise's own power per line after the average [unit^2]; ``excited_power[c]``: mean
    output power at the excited lines [unit^2]; ``predicted_even_power[c]``: the even-line power
    the optical lever's second-order geometry makes of the exact linear motion (the even
    distortion computed exactly, to second order: :func:`predicted_even_power`)."""

    freqs_hz: np.ndarray
    lines: np.ndarray
    realisations: int
    periods: int
    g: dict
    exact: dict
    var_total: dict
    var_noise: dict
    var_distortion: dict
    even_power: dict
    odd_power: dict
    noise_power_floor: dict
    excited_power: dict
    predicted_even_power: dict

    def within_sigma(self, c: str, k: float = 2.0) -> np.ndarray:
        """Lines where ``|G_BLA - exact| <= k sigma_total`` (boolean, (lines,))."""
        return np.abs(self.g[c] - self.exact[c]) <= k * np.sqrt(self.var_total[c])


def _periods(recording, source, transient: int):
    """Spectra (R, P', n_freq) of a, x, y from the whole periods of the records."""
    plan = recording.header.plan
    n = source.period_s * plan.rate_hz
    if abs(n - round(n)) > 1e-9 * n:
        raise ConfigError(f"source.period_s = {source.period_s:g} s is not a whole number of "
                          f"samples at {plan.rate_hz:g} Hz: the periods cannot be cut")
    n = int(round(n))
    if plan.samples % n or plan.settle_samples % n:
        raise ConfigError(f"acquisition.record_s and settle_s must be whole multiples of the "
                          f"multisine's period {source.period_s:g} s (they are "
                          f"{plan.samples / plan.rate_hz:g} s and "
                          f"{plan.settle_samples / plan.rate_hz:g} s)")
    per = plan.samples // n
    first = plan.settle_samples // n
    q = first + np.arange(recording.records * per)  # period index from t = 0
    r, p = q // source.multisine_periods, q % source.multisine_periods
    keep = p >= transient
    realisations = np.unique(r[keep])
    counts = {int(x): int(np.sum(r[keep] == x)) for x in realisations}
    full = [x for x in realisations if counts[x] == source.multisine_periods - transient]
    if len(full) < 2 or source.multisine_periods - transient < 2:
        raise ConfigError(f"the run has {len(full)} whole realisation(s) of "
                          f"{source.multisine_periods - transient} kept period(s): the BLA's "
                          "variances need at least 2 realisations of at least 2 periods after "
                          "the transient (more records, or more source.multisine_periods)")
    spectra = {"realisations": np.array(full)}
    for c in ("a", "x", "y"):
        v = recording.values(c).reshape(-1, n)  # (periods, n)
        sel = np.concatenate([np.flatnonzero(keep & (r == x)) for x in full])
        spectra[c] = np.fft.rfft(v[sel], axis=1).reshape(len(full), -1, n // 2 + 1)
    return spectra, n, len(full)


#: The transient left when a realisation's kept periods start, relative to its start.
TRANSIENT_DECAY = 1e-3


def transient_periods_for(scene) -> int:
    """Periods to drop at the start of each realisation: enough for the slowest mode of the
    bench (:func:`rig.bench.modes.bench_modes`, time constant ``1 / (zeta 2 pi f)``) to decay
    to :data:`TRANSIENT_DECAY` of its start, ``ceil(ln(1 / 1e-3) tau / T)``, at least 1."""
    import math

    from rig.bench.modes import bench_modes

    m = bench_modes(scene)
    tau = float(np.max(1.0 / (m.zeta * 2 * np.pi * m.f_hz))) if m.f_hz.size else 0.0
    return max(1, math.ceil(math.log(1 / TRANSIENT_DECAY) * tau / scene.source.period_s))


def best_linear_approximation(recording, *, transient_periods: int | None = None
                              ) -> BestLinearApproximation:
    """The BLA of a multisine run (module docstring); ``transient_periods`` dropped at the
    start of every realisation (default :func:`transient_periods_for` the run's scene)."""
    from rig.bench.response import expected_response
    from rig.devices import multisine as ms

    scene = recording.header.scene
    src = scene.source
    if src.type != "multisine":
        raise ConfigError(f"source.type = {src.type!r}: the best linear approximation needs a "
                          "multisine run (source.type = \"multisine\")")
    if transient_periods is None:
        transient_periods = transient_periods_for(scene)
    spectra, n, n_real = _periods(recording, src, transient_periods)
    rate = recording.header.plan.rate_hz
    # the grid at the acquisition rate: same lines as at the DAC rate (same period)
    key = _grid_key(recording)
    lines = ms.excited_lines(src.multisine_grid, src.period_samples, src.fs_hz, src.fmin_hz,
                             src.fmax_hz, key)
    lines = lines[lines < n // 2]
    freqs = lines * rate / n
    exact = expected_response(scene, freqs, sampled=True)
    band = np.arange(max(1, lines.min()), lines.max() + 1)
    empty = np.setdiff1d(band, lines)
    even, odd = empty[empty % 2 == 0], empty[empty % 2 == 1]
    out = {k: {} for k in ("g", "exact", "vt", "vn", "vd", "even", "odd", "floor", "exc")}
    u = spectra["a"][:, :, lines]
    pp = u.shape[1]
    predicted = predicted_even_power(recording, spectra["realisations"], n, even, key)
    for c, name in OUTPUTS.items():
        y = spectra[c]
        g_rp = y[:, :, lines] / u
        g_r = g_rp.mean(axis=1)
        vn_r = _cvar(g_rp, axis=1) / pp
        g = g_r.mean(axis=0)
        vt = _cvar(g_r, axis=0) / n_real
        vn = vn_r.mean(axis=0) / n_real
        out["g"][c], out["vt"][c], out["vn"][c] = g, vt, vn
        out["vd"][c] = np.maximum(n_real * (vt - vn), 0.0)
        out["exact"][c] = getattr(exact, name.lower())
        scale = 2.0 / n ** 2  # |rfft|^2 -> the line's power (one-sided, amplitude^2 / 2)
        # per realisation: the periodic part is the mean over its periods, whose noise power is
        # the periods' variance / P'; the periodic power, noise removed, averaged over r
        y_mean = y.mean(axis=1)
        y_var = _cvar(y, axis=1) / pp
        periodic = scale * np.mean(np.abs(y_mean) ** 2 - y_var, axis=0)
        floor = scale * np.mean(y_var, axis=0)
        out["even"][c] = float(np.mean(periodic[even])) if even.size else float("nan")
        out["odd"][c] = float(np.mean(periodic[odd])) if odd.size else float("nan")
        out["floor"][c] = float(np.mean(floor[empty])) if empty.size else float("nan")
        out["exc"][c] = float(np.mean(periodic[lines]))
    return BestLinearApproximation(
        freqs_hz=freqs, lines=lines, realisations=n_real, periods=pp, g=out["g"],
        exact=out["exact"], var_total=out["vt"], var_noise=out["vn"], var_distortion=out["vd"],
        even_power=out["even"], odd_power=out["odd"], noise_power_floor=out["floor"],
        excited_power=out["exc"], predicted_even_power=predicted)


def predicted_even_power(recording, realisations, n: int, even: np.ndarray, key: int) -> dict:
    """The mean power at the ``even`` lines [unit^2] of the lever's second-order terms
    (:func:`processing.coherence_model.lever_quadratic_coefficients`: ``x = dx - c_x theta^2``,
    ``y = theta - c_y dx theta``) of the exact linear motion under the run's multisine, through
    the anti-alias filter: the mirror's translation ``dx`` and angle ``theta`` at the DAC
    instants from each realisation's DAC samples (the exact discrete-time response,
    ``expected_response(sampled=True)``), taken at the sample instants, the products'
    spectra at the even lines averaged over the realisations."""
    from processing.coherence_model import lever_quadratic_coefficients
    from rig.bench.response import expected_response
    from rig.devices import multisine as ms

    h = recording.header
    src = h.scene.source
    if even.size == 0:
        return {c: float("nan") for c in OUTPUTS}
    big_n = src.period_samples
    q = big_n // n
    lines = ms.excited_lines(src.multisine_grid, big_n, src.fs_hz, src.fmin_hz, src.fmax_hz,
                             key)
    r = expected_response(h.scene, lines * src.fs_hz / big_n, sampled=True)
    coef = lever_quadratic_coefficients(h.scene.lever)
    aa2 = np.abs(h.antialias.response(even * h.plan.rate_hz / n)) ** 2
    scale = 2.0 / n ** 2
    power = {"x": 0.0, "y": 0.0}
    for real in realisations:
        v = ms.period(src.multisine_grid, big_n, src.fs_hz, src.fmin_hz, src.fmax_hz,
                      src.level_vrms, key, int(real), src.crest_iterations)
        vl = np.fft.rfft(v)[lines]
        motion = {}
        for name, hresp in (("dx", r.mirror_x), ("theta", r.mirror_rot)):
            spec = np.zeros(big_n // 2 + 1, complex)
            spec[lines] = hresp * vl
            motion[name] = np.fft.irfft(spec, big_n)[::q]  # at the sample instants
        terms = {"x": -coef["x"] * motion["theta"] ** 2,
                 "y": -coef["y"] * motion["dx"] * motion["theta"]}
        for c, t in terms.items():
            power[c] += float(np.mean(scale * np.abs(np.fft.rfft(t)[even]) ** 2 * aa2))
    return {c: p / len(realisations) for c, p in power.items()}


def _cvar(z: np.ndarray, axis: int) -> np.ndarray:
    """Sample variance E|z - mean|^2 of complex values (ddof = 1)."""
    m = z.mean(axis=axis, keepdims=True)
    return np.sum(np.abs(z - m) ** 2, axis=axis) / (z.shape[axis] - 1)


def _grid_key(recording) -> int:
    """The multisine's key, as the source drew it from the run's seed (the random-odd grid
    depends on it)."""
    from rig.bench.run import source_seed
    from rig.devices.source import start_source

    return int(start_source(recording.header.scene.source,
                            source_seed(recording.header.seed)).history[0])
