"""The linearisation error of the exact linear bench, predicted, and the model choice.

Models (``acquisition.model``, ``acquisition.error_budget``): ``linear`` (the exact linear bench:
its error is the linearisation, a model error), ``nonlinear`` (:mod:`rig.bench.model`), and
``auto`` (default): the cheapest model that meets ``acquisition.error_budget`` (the allowed
relative RMS error of the simulated angles over the records, max over the bodies; default
1e-2). :func:`select_model` takes ``linear`` if even the upper estimate of
:func:`predict_linearisation_error` is inside the budget, ``nonlinear`` otherwise; the choice,
the prediction, the reason and how it was predicted are stored in the run file
(:meth:`rig.bench.BenchSimulation.model_info`); a forced model records the same prediction and
whether the budget is met. A lightly damped mode turns a tiny amplitude-dependent frequency shift
into a large time-domain difference, so the linear model's error grows as the drive level squared
and with the run length up to a few amplitude time constants ``tau = Q / (pi f)``
(docs/bench_model.md: where the choice flips for the paper's run).

The predictor: first-order perturbation
---------------------------------------
``z_nl = z_lin + d + O(theta^2 d)`` with ``d' = A d + f(z_lin(t))``, ``f`` the nonlinear
remainder of the accelerations (:mod:`rig.solvers.coupled`): the linearisation error to first
order is the linear bench's response to the remainder evaluated along the *linear* trajectory. It is
computed for the scene's own source type, level, initial state and run length on a surrogate
drive: the scene's source regenerated at a reduced rate (>= 8 times the highest source or
pendulum frequency; its own random stream, so the choice is a property of the scene, not of the
run's seed), the coil + stage + pendulum (no reconstruction filter) discretised exactly with a
first-order hold of the voltage and of ``f``. The relative RMS error of every angle over the
recorded span is estimated from 8 values: for a run of >= 16 ``tau`` one realisation cut into 8
batches (pooled ratio; uncertainty from the batches' jackknife x :data:`SPREAD_CALIBRATION`; for
a run longer than 24 tau a probe of 5 tau settling + 24 tau of records, stationary and
conservative if the run settles less), for a shorter run 8 independent realisations of it (their
mean and standard deviation). Spread of the actual run's value: that scaled to the run's length;
decision on ``upper = estimate + t sqrt(spread^2 + uncertainty^2)`` (t = 2.36, Student's 97.5 %
quantile for 7 degrees of freedom). The first order must hold all along: if the predicted error
anywhere in the run (settling included) exceeds :data:`FIRST_ORDER_LIMIT` of the largest angle
(e.g. a pendulum released far from rest) the prediction is flagged ``first_order_valid = False``
and ``auto`` takes the nonlinear model. Clear cases stop early (every realisation so far over
10 x the budget, or two under a tenth of it). Cost: one compiled step per reduced sample of the
probe (its accuracy and cost: docs/bench_model.md).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from rig.chain import Chain
from rig.jit import njit
from rig.errors import ConfigError, DivergenceError
from rig.solvers.coupled import arg_groups, coupled_params, kernel_scratch, remainder_fast_at
from rig.linear import discretise
from rig.scene import Scene
from rig.scene_memo import per_scene
from rig.devices.source import generate, start_source

PREDICTOR_ENTROPY = 20090005  # the predictor's own random stream (the choice is the scene's)
PREDICTOR_BATCHES = 8
SPREAD_CALIBRATION = 1.5  # jackknife std of 8 batches -> measured run-to-run scatter (see how)
FIRST_ORDER_LIMIT = 0.1  # largest |d theta| / largest |theta| for the first order to hold
_T975 = {1: 12.71, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
         9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131}


def _predictor_rate(scene: Scene, fs: float) -> float:
    """The predictor's reduced rate: the lowest fs / k >= 8 x (the highest source or pendulum
    frequency) at which the scene's source is valid (whole-sample periods)."""
    src = scene.source
    f_src = src.frequency_hz if src.type == "sine" else src.fmax_hz
    f_modes = scene.chain.modes()[0]
    f_top = max(float(f_src), float(np.max(f_modes)) if f_modes.size else 0.0)
    k_max = max(1, int(fs // (8.0 * f_top))) if f_top > 0 else 1
    for k in range(k_max, 0, -1):
        try:
            dataclasses.replace(src, reconstruction_hz=0.0, fs_hz=fs / k)
        except ConfigError:
            continue
        return fs / k
    return fs


def _amplitude_time_constant_s(chain: Chain) -> float:
    """The longest modal amplitude time constant tau = Q / (pi f) [s] (inf if undamped)."""
    f, q = chain.modes()
    if f.size == 0:
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(np.isfinite(q), q / (np.pi * f), np.inf)
    return float(np.max(tau))


def predict_linearisation_error(scene: Scene, *, decide_at: float | None = None) -> dict:
    """Predicted error of the exact linear model against the nonlinear bench (module docstring,
    "The predictor"): relative RMS of ``theta_lin - theta_nl`` over the recorded span per body.

    Returns a dict (JSON-ready): ``relative_rms_theta`` (n,) the estimate (pooled over the
    batches); ``spread_relative_rms_theta`` (n,) the standard deviation of a single run's value
    about it (the run's own drive is another realisation); ``uncertainty_relative_rms_theta``
    (n,) the standard deviation of the estimate itself; ``upper_relative_rms_theta`` (n,) =
    estimate + t sqrt(spread^2 + uncertainty^2) (t the 97.5 % Student-t quantile for the
    batches' degrees of freedom, 2.36 for 8 batches); ``max`` / ``upper`` (the largest over the
    bodies); ``max_abs_theta_rad`` (largest |theta_lin - theta_nl| seen); ``theta_rms_rad`` (n,)
    of the linear bench; ``rate_hz``, ``realisations``, ``batches``, ``tau_s``,
    ``probe_settle_s``, ``probe_recorded_s`` (per realisation), ``simulated_s``, ``how``.

    ``first_order_valid``: the largest |d_theta| anywhere in the run (settling included) stays
    below ``FIRST_ORDER_LIMIT`` (0.1) of the largest |theta|; otherwise the prediction is only
    an order of magnitude. ``decide_at``: a budget; stop after the realisations done so far
    once every one of them is over 10 x ``decide_at`` (one suffices), under ``decide_at`` / 10
    (two needed) or the first order fails: the decision is then not in doubt (e.g. a pendulum
    released far from rest, or a tiny drive on an expensive chain); the statistics come from
    those realisations (``stopped_early``: "under" or "over", else "").
    """
    acq = scene.acquisition
    n = scene.chain.n
    fr = _predictor_rate(scene, acq.simulation_rate_hz)
    settle, t_rec = float(acq.settle_s), float(acq.records * acq.record_s)
    tau = _amplitude_time_constant_s(scene.chain)
    k_runs, batches, settle_p, rec_p = _probe_plan(tau, settle, t_rec)
    n_tot = max(1, int(round((settle_p + rec_p) * fr)))
    k_rec = min(int(round(settle_p * fr)), n_tot - 1)
    sums, peaks, stopped_early = _realisations(scene, fr, k_runs, batches, n_tot, k_rec,
                                               decide_at)
    k_runs = sums.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = float(np.nan_to_num(np.max(peaks[:, 1, :]) / np.max(peaks[:, 0, :])))
    t2 = sums[:, :, 0, :].reshape(-1, n)
    d2 = sums[:, :, 1, :].reshape(-1, n)
    nb = t2.shape[0]
    pooled, spread, unc = _batch_statistics(t2, d2, k_runs, rec_p / t_rec)
    t975 = _T975.get(nb - 1, 2.0)  # Student-t: the spread is itself estimated from nb values
    upper = pooled + t975 * np.sqrt(spread**2 + unc**2)
    n_rec = n_tot + 1 - k_rec
    how = (f"first-order perturbation: the linear bench (coil, stage, pendulum"
           f"{' with its reaction' if scene.stage.reaction else ''}) and its first-order "
           "linearisation error d' = A d + f(z_lin) (f: nonlinear minus linear accelerations "
           f"along the linear trajectory), both discretised exactly at {fr:g} Hz (first-order "
           "hold) and driven by the scene's source regenerated at that rate (own random stream); "
           f"{k_runs} run(s) of {settle_p:g} s settle + {rec_p:g} s recorded from the scene's "
           f"initial state (the run: {settle:g} s + {t_rec:g} s; longest amplitude time constant "
           f"tau = {tau:.3g} s), each recorded span in {batches} batch(es); " + _STATISTICS_HOW +
           f"uncertainty^2), t = {t975:.3g} the two-sided 95 % Student-t quantile for "
           f"{nb - 1} degrees of freedom. Exact to first order: the neglected term is O(e^2) "
           "relative")
    return {
        "relative_rms_theta": pooled.tolist(),
        "spread_relative_rms_theta": spread.tolist(),
        "uncertainty_relative_rms_theta": unc.tolist(),
        "upper_relative_rms_theta": upper.tolist(),
        "max": float(np.max(pooled)),
        "upper": float(np.max(upper)),
        "max_abs_theta_rad": float(np.max(sums[:, :, 2, :])),
        "theta_rms_rad": np.sqrt(t2.sum(0) / (k_runs * n_rec)).tolist(),
        "rate_hz": fr,
        "realisations": k_runs,
        "batches": batches,
        "tau_s": tau,
        "probe_settle_s": settle_p,
        "probe_recorded_s": rec_p,
        "simulated_s": k_runs * n_tot / fr,
        "stopped_early": stopped_early,
        "first_order_valid": ratio <= FIRST_ORDER_LIMIT,
        "peak_error_over_peak_theta": ratio,
        "how": how + (f"; stopped after {k_runs} run(s), the decision at {decide_at:g} being "
                      "clear" if stopped_early else ""),
    }


#: how the predictor's statistics are made (the middle of its ``how``)
_STATISTICS_HOW = (
    "one run: estimate = pooled RMS ratio, its uncertainty = the delete-one-batch jackknife "
    f"standard deviation times {SPREAD_CALIBRATION:g} (the jackknife of 8 batches underestimates "
    "the scatter by 20-35 %, measured over 30 predictor streams), spread of the actual run = that "
    "times sqrt(probe records / run records); several runs: estimate = their mean, spread = "
    "their standard deviation, uncertainty = spread / sqrt(runs); upper = estimate + t "
    "sqrt(spread^2 + ")


def _probe_plan(tau: float, settle: float, t_rec: float) -> tuple[int, int, float, float]:
    """``(runs, batches, settle_s, recorded_s)`` of the predictor's probe for a run of
    ``settle`` + ``t_rec`` seconds whose slowest amplitude time constant is ``tau`` [s]."""
    nb_all = PREDICTOR_BATCHES
    if math.isfinite(tau) and t_rec >= 2 * nb_all * tau:
        # a long run: one realisation cut into 8 batches of >= 2 tau; longer than 24 tau, its
        # records are stationary after 5 tau and a probe of 5 tau + 24 tau estimates them
        # (conservatively: a shorter settle only lowers the error)
        if t_rec > 3 * nb_all * tau:
            return 1, nb_all, 5 * tau, 3 * nb_all * tau
        return 1, nb_all, settle, t_rec
    return nb_all, 1, settle, t_rec  # a short run: 8 independent realisations of it


def _realisations(scene: Scene, fr: float, k_runs: int, batches: int, n_tot: int, k_rec: int,
                  decide_at: float | None):
    """Run the first-order kernel over ``k_runs`` realisations of the scene's source at ``fr``
    [Hz]: ``(sums (runs, batches, 3, n), peaks (runs, 2, n), stopped_early)``, fewer runs if
    ``decide_at`` decides early (see :func:`predict_linearisation_error`)."""
    chain, stage, n = scene.chain, scene.stage, scene.chain.n
    src = dataclasses.replace(scene.source, reconstruction_hz=0.0, fs_hz=fr)
    ss = stage.state_space(chain)
    a = ss.a
    nz = a.shape[0]
    phi, g0, g1 = discretise(a, ss.b, 1.0 / fr, "linear")
    prm = coupled_params(chain, stage, a)
    nf = prm.rows.size
    bf = np.zeros((nz, nf))
    bf[prm.rows, np.arange(nf)] = 1.0
    _, gf0, gf1 = discretise(a, bf, 1.0 / fr, "linear")
    sums = np.zeros((k_runs, batches, 3, n))
    z0 = np.zeros(nz)
    z0[3:3 + n] = scene.theta0_rad
    z0[3 + n:3 + 2 * n] = scene.omega0_rad_s
    g0c, g1c = np.ascontiguousarray(g0[:, 0]), np.ascontiguousarray(g1[:, 0])
    gf0, gf1 = np.ascontiguousarray(gf0), np.ascontiguousarray(gf1)
    peaks = np.zeros((k_runs, 2, n))
    for r, child in enumerate(np.random.SeedSequence(PREDICTOR_ENTROPY).spawn(k_runs)):
        v, _ = generate(src, start_source(src, child), n_tot + 1)
        z, d = z0.copy(), np.zeros(nz)
        first_order_kernel(prm.args(), phi, g0c, g1c, gf0, gf1, v, z, d, k_rec,
                           batches, sums[r], peaks[r])
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(d))):
            raise DivergenceError("the linearisation-error predictor diverged (is the linear "
                                  "bench unstable?)", 0.0, z)
        if decide_at is not None and k_runs > 1 and r + 1 < k_runs:
            with np.errstate(divide="ignore", invalid="ignore"):
                e_r = np.nan_to_num(np.sqrt(sums[:r + 1, 0, 1, :] / sums[:r + 1, 0, 0, :]))
            e_r = e_r.max(axis=1)  # (runs so far,): the worst body of each
            invalid = np.max(peaks[:r + 1, 1]) > FIRST_ORDER_LIMIT * np.max(peaks[:r + 1, 0])
            under = r >= 1 and np.all(e_r < decide_at / 10)
            if invalid or np.all(e_r > 10 * decide_at) or under:
                return sums[:r + 1], peaks[:r + 1], "under" if under else "over"
    return sums, peaks, ""


def _batch_statistics(t2: np.ndarray, d2: np.ndarray, k_runs: int,
                      probe_over_run: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(estimate, spread, uncertainty)`` per body from the batches' sums of theta^2 ``t2``
    and d_theta^2 ``d2`` (batches, n): one run: pooled ratio and the delete-one-batch
    jackknife; several: their mean and scatter."""
    nb = t2.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        if k_runs == 1:  # pooled ratio; delete-one-batch jackknife for its uncertainty
            pooled = np.where(t2.sum(0) > 0, np.sqrt(d2.sum(0) / t2.sum(0)), 0.0)
            loo_t = t2.sum(0) - t2
            e_loo = np.where(loo_t > 0, np.sqrt((d2.sum(0) - d2) / loo_t), 0.0)
            unc = SPREAD_CALIBRATION * np.sqrt(
                (nb - 1) / nb * np.sum((e_loo - e_loo.mean(0)) ** 2, axis=0))
            spread = unc * math.sqrt(probe_over_run)  # the variance shrinks as 1 / length
        else:  # the runs' own values: their mean, their scatter
            e_k = np.where(t2 > 0, np.sqrt(d2 / t2), 0.0)
            pooled = e_k.mean(0)
            spread = e_k.std(0, ddof=1) if nb > 1 else pooled.copy()
            unc = spread / math.sqrt(nb)
    return pooled, spread, unc


@per_scene()
def select_model(scene: Scene) -> dict:
    """The model for ``acquisition.model`` and ``acquisition.error_budget``, and why.

    ``auto``: ``linear`` if the upper predicted linearisation error
    (:func:`predict_linearisation_error`) is within the budget, else ``nonlinear``; a forced
    model is kept and the same prediction says whether the linear model meets the budget.
    Returns a dict (JSON-ready): ``requested``, ``chosen``, ``error_budget``,
    ``linear_meets_budget``, ``predicted_linear_error`` (the max over bodies), its ``upper``,
    ``reason`` (a sentence), ``prediction`` (the predictor's dict, with ``how``).
    Memoised per scene (:mod:`rig.scene_memo`): it depends on the scene alone.
    """
    requested = scene.acquisition.model
    budget = scene.acquisition.error_budget
    tic = time.perf_counter()
    pred = predict_linearisation_error(scene, decide_at=budget)
    e, up = pred["max"], pred["upper"]
    # (a prediction stopped early as clearly under the budget is under it, whatever the
    # Student-t factor of two runs makes of their scatter)
    ok = (up <= budget or pred["stopped_early"] == "under") and pred["first_order_valid"]
    th = ", ".join(f"{x:.2g}" for x in pred["theta_rms_rad"])
    told = (f"the predicted linearisation error (relative RMS of the angles over the records) "
            f"is {e:.2g} (upper {up:.2g}) at {th} rad rms")
    if not pred["first_order_valid"]:
        told += (f", and that is only an order of magnitude: the first-order error reaches "
                 f"{pred['peak_error_over_peak_theta']:.2g} of the largest angle during the run")
    if requested == "auto":
        chosen = "linear" if ok else "nonlinear"
        if ok:
            reason = (f"auto: {told}, within the error budget {budget:g}: the exact linear model "
                      "(round-off only) is the cheapest that meets it")
        else:
            reason = (f"auto: {told}, over the error budget {budget:g}: the linear model is not "
                      "enough, the nonlinear model runs")
    else:
        chosen = requested
        if requested == "linear":
            reason = (f"forced by acquisition.model = 'linear'; {told}, "
                      + (f"within the error budget {budget:g}" if ok else
                         f"OVER the error budget {budget:g} ('auto' would run the nonlinear "
                         "model)"))
        else:
            reason = (f"forced by acquisition.model = 'nonlinear'; {told}, "
                      + (f"so the linear model would have met the budget {budget:g} ('auto' "
                         "would run it)" if ok else f"over the budget {budget:g}"))
    return {"requested": requested, "chosen": chosen, "error_budget": budget,
            "linear_meets_budget": bool(ok), "predicted_linear_error": e,
            "predicted_linear_error_upper": up, "reason": reason, "prediction": pred,
            "predict_wall_time_s": time.perf_counter() - tic}


# ================================================================================================
# first-order linearisation error (the predictor)
# ================================================================================================

@njit(cache=True, nogil=True, error_model="numpy")
def first_order_kernel(prm, phi, g0, g1, gf0, gf1, v, z, d, k_rec, n_batches, sums, peaks):
    """Linear bench z and its first-order linearisation error d over len(v) - 1 intervals.

    z_{k+1} = Phi z_k + G0 v_k + G1 (v_{k+1} - v_k);  d_{k+1} = Phi d_k + GF0 f_k + GF1 (f_{k+1}
    - f_k) with f_k = f(z_k) in ``rows`` (first-order hold of both inputs). From sample ``k_rec``
    on, the samples are split into ``n_batches`` equal consecutive batches and
    ``sums[b, 0, j] += theta_j^2``, ``sums[b, 1, j] += d_theta_j^2``,
    ``sums[b, 2, j] = max |d_theta_j|``; over every sample ``peaks[0, j] = max |theta_j|``,
    ``peaks[1, j] = max |d_theta_j|`` (is the first order valid all along?). ``z``, ``d``
    (in/out) end at the last sample.

    For n = 2, f is :func:`remainder2_fast`'s (polynomial sines, one division: the dense
    equations rounded differently, a few ulp), as etdab's; the state products run row beside
    row (each row's sum over the columns in order, as a loop per row would form it)."""
    n, two, nz, nf, work, alpha = kernel_scratch(prm, z)
    dense, bodies, stage = arg_groups(prm)
    th0, q_idx, wc, a_rows = prm.th0, prm.q_idx, prm.wc, prm.a_rows
    f = np.empty(nf)
    fn = np.empty(nf)
    zt = np.empty(nz)
    dt = np.empty(nz)
    phi_t = np.ascontiguousarray(phi.T)  # rows side by side: row r's terms in column order
    gf0_t = np.ascontiguousarray(gf0.T)
    gf1_t = np.ascontiguousarray(gf1.T)
    a_cols = a_rows.shape[1]
    n_s = v.shape[0]
    n_rec = n_s - k_rec
    ax = remainder_fast_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, a_cols, z,
                           work, alpha, f)
    for kk in range(n_s):
        for j in range(n):
            if abs(z[th0 + j]) > peaks[0, j]:
                peaks[0, j] = abs(z[th0 + j])
            if abs(d[th0 + j]) > peaks[1, j]:
                peaks[1, j] = abs(d[th0 + j])
        if kk >= k_rec:
            b = ((kk - k_rec) * n_batches) // n_rec
            for j in range(n):
                t = z[th0 + j]
                e = d[th0 + j]
                sums[b, 0, j] += t * t
                sums[b, 1, j] += e * e
                if abs(e) > sums[b, 2, j]:
                    sums[b, 2, j] = abs(e)
        if kk + 1 == n_s:
            break
        v0 = v[kk]
        dv = v[kk + 1] - v0
        for r in range(nz):
            zt[r] = g0[r] * v0 + g1[r] * dv
        for col in range(nz):
            zc = z[col]
            for r in range(nz):
                zt[r] += phi_t[col, r] * zc
        for r in range(nz):
            z[r] = zt[r]
        ax = remainder_fast_at(two, dense, bodies, stage, th0, q_idx, wc, a_rows, a_cols, z,
                               work, alpha, fn)
        for r in range(nz):
            dt[r] = 0.0
        for col in range(nz):
            dc = d[col]
            for r in range(nz):
                dt[r] += phi_t[col, r] * dc
        for i in range(nf):
            fi = f[i]
            dfi = fn[i] - fi
            for r in range(nz):
                dt[r] += gf0_t[i, r] * fi + gf1_t[i, r] * dfi
        for r in range(nz):
            d[r] = dt[r]
        for i in range(nf):
            f[i] = fn[i]
