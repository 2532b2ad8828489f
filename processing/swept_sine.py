"""The swept-sine measurement (``SineSettings(mode="swept")``): a continuous sweep through the
acquisition chain of every run, read by a tracking DFT at the source's instantaneous phase.

:func:`swept_plan` plans the sweep from the bench's exact linear chain:

- **path**: with ``sweep_s`` the plain log or linear chirp (``spacing``) of that duration
  (:func:`rig.devices.swept_sine.chirp_path`); otherwise the rule's path, moving at every
  frequency at the rule's rate from the chain's poles and the channels' zeros
  (:func:`rig.bench.swept.rule_rate`, ``sweep_tolerance``); a plan longer than ``max_sweep_s``
  is refused. A chirp faster than the rule anywhere is reported (:attr:`SweptPlan.warnings`,
  one line: where, how much faster, the bias to expect).
- **level**: ``level_vrms``, or with ``auto_level`` a profile holding the reference channel's
  exact steady amplitude at the target, capped (the level steps with the frequency).
- **lead-in and tail**: the source holds the first frequency for the settle (``settle_s``,
  ``settle_cycles`` or the stepped sine's settle rule from rest, :func:`rig.bench.sine.
  settle_samples`) plus half the first window, and the last frequency for half the last window.
- **points**: the grid of ``points`` frequencies (``spacing``, ``direction``); each is read when
  the sweep passes it, over ``K = max(integrate_cycles, ceil(integrate_s f))`` whole cycles of
  the source's phase centred on that instant.

:func:`run_swept` runs it in chunks of output samples (the DAC samples of the stair source,
:mod:`rig.devices.swept_sine`, through :meth:`daq.sine.SineAcquisition.samples`) and, beside the
bench, the chain's exact noiseless response to the same samples
(:class:`rig.bench.swept.ModalSweep`). Each point's window is fitted by
:func:`processing.sine.tracking_fit` (mean and harmonics 1..H of the instantaneous phase) on
the bench's volts and on the noiseless ones: the stated bias (``h_t_bias``, ``theta_2_bias``)
is the noiseless estimate minus the exact steady state at the point's frequency, exact for the
linear chain (sweep lag, window averaging and the lead-in's transient together). Per point,
``settle_s`` is the sweep time since the previous point's instant (the first: since the start),
``integrate_s`` its window, ``t0_s`` the window's start less ``settle_s`` (so that, as in the
stepped mode, ``t0_s + settle_s`` is the window's start), ``settle_bound`` the rule's
first-order relative bias at the path's actual rate, ``rate / (2 pi d^2)`` (the same for a, x, y).

Public API: :class:`SweptPlan`, :func:`swept_plan`, :func:`run_swept`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError

CHUNK = 1 << 15  # output samples per chunk


@dataclass(frozen=True, eq=False)
class SweptPlan:
    """A planned sweep: the path, the points' frequencies [Hz] in time order, their windows'
    cycles, the level profile (``level_f_hz`` increasing, ``level_v`` [V rms] there), the
    rule's relative first-order bias at each point, the settings and the warnings (one line
    each)."""

    path: object
    freqs_hz: np.ndarray
    cycles: np.ndarray
    level_f_hz: np.ndarray
    level_v: np.ndarray
    rule_bias: np.ndarray
    settings: object
    warnings: tuple

    @property
    def duration_s(self) -> float:
        return self.path.duration_s

    def level(self, f_hz) -> np.ndarray:
        """The source level [V rms] at ``f_hz`` (linear between the profile's frequencies)."""
        return np.interp(f_hz, self.level_f_hz, self.level_v)


def _frequency_grid(settings, singularities: np.ndarray) -> np.ndarray:
    """A grid fine enough for the rule's rate: log-spaced, plus points around every
    singularity in the band, spaced by fractions of its distance to the axis."""
    lo, hi = settings.fmin_hz, settings.fmax_hz
    parts = [np.geomspace(lo, hi, 4001)]
    u = np.sinh(np.linspace(-8.0, 8.0, 801))  # +-1500 half-widths, fine at the centre
    for s in singularities:
        if lo <= s.real <= hi:
            parts.append(s.real + max(abs(s.imag), 1e-9) * u)
    f = np.unique(np.concatenate(parts))
    return f[(f >= lo) & (f <= hi)]


def _window_s(settings, f_hz):
    return np.maximum(settings.integrate_cycles / np.asarray(f_hz, float),
                      settings.integrate_s)


def _level_profile(settings, chain, f: np.ndarray, level_vrms: float) -> np.ndarray:
    """The level [V rms] at ``f``: ``level_vrms``, or with ``auto_level = (channel, target,
    tol)`` the level that puts the channel's exact steady response at ``target`` (its unit),
    at most ``level_limit_vrms``."""
    if settings.auto_level is None:
        return np.full(f.shape, float(level_vrms))
    ch, target, _ = settings.auto_level
    i = ("a", "x", "y").index(ch)
    per_volt = np.array([abs(chain.steady_state(fi)[1][i]) for fi in f]) \
        * math.sqrt(2.0) / abs(chain.volts_per_unit[i])
    with np.errstate(divide="ignore"):
        return np.minimum(settings.level_limit_vrms, target / per_volt)


def swept_plan(settings, acq, level_vrms: float) -> SweptPlan:
    """Plan the sweep of ``settings`` on ``acq`` (a :class:`daq.sine.SineAcquisition`) at
    ``level_vrms``, or with ``auto_level`` at the level that holds the reference channel's exact
    steady amplitude at the target along the whole sweep, capped at ``level_limit_vrms`` (the
    instrument's SOUR:VOLT:AUTO, here from the model; module docstring). Raises ConfigError for a
    plan longer than ``max_sweep_s``."""
    from rig.bench.sine import settle_samples, step_error
    from rig.bench.swept import rule_rate, singularities_hz
    from rig.devices.stepped_sine import SinePoint
    from rig.devices.swept_sine import chirp_path, rate_path

    chain, rate = acq.chain, acq.rate_hz
    sing = singularities_hz(chain)
    fg = _frequency_grid(settings, sing)
    rule = rule_rate(fg, sing, settings.sweep_tolerance, _window_s(settings, fg))
    warnings = []
    if settings.sweep_s is None:
        path = rate_path(fg, rule, settings.direction)
    else:
        path = chirp_path(settings.fmin_hz, settings.fmax_hz, settings.sweep_s,
                          settings.spacing, settings.direction)
        over = path.rate(fg) / rule
        i = int(np.argmax(over))
        if over[i] > 1.0:
            warnings.append(
                f"the {settings.sweep_s:g} s sweep is {over[i]:.3g} x faster than the "
                f"quasi-steady rule at {fg[i]:.4g} Hz ({path.rate(fg[i:i + 1])[0]:.3g} Hz/s "
                f"against {rule[i]:.3g} Hz/s for a {settings.sweep_tolerance:g} relative "
                "bias): expect biases of about that many times the tolerance there (each "
                "point states its own)")
    lev_f = np.unique(np.concatenate([np.geomspace(settings.fmin_hz, settings.fmax_hz, 2001),
                                      fg[::4], [settings.fmax_hz]]))
    lev_v = _level_profile(settings, chain, lev_f, level_vrms)
    f_start, f_end = float(path.f_hz[0]), float(path.f_hz[-1])
    if settings.settle_s is not None:
        settle = settings.settle_s
    elif settings.settle_cycles is not None:
        settle = settings.settle_cycles / f_start
    else:
        p0 = SinePoint(f_start, float(np.interp(f_start, lev_f, lev_v)), 0, 2, 1)
        e0 = step_error(chain, np.zeros(chain.a.shape[0]), None, p0, 0.0)
        settle = settle_samples(chain, e0, p0, settings.settle_tolerance, 0,
                                int(round(settings.max_settle_s * rate))) / rate
    lead = settle + 0.5 * float(_window_s(settings, f_start)) + 2.0 / rate
    tail = 0.5 * float(_window_s(settings, f_end)) + 2.0 / rate
    import dataclasses

    path = dataclasses.replace(path, lead_s=float(lead), tail_s=float(tail))
    if path.duration_s > settings.max_sweep_s:
        raise ConfigError(f"the sweep would take {path.duration_s:.4g} s of bench time, more "
                          f"than max_sweep_s = {settings.max_sweep_s:g} s: narrow the band, "
                          "raise the sweep tolerance or max_sweep_s, or give the duration")
    f = settings.grid()
    cycles = np.maximum(settings.integrate_cycles,
                        np.ceil(settings.integrate_s * f - 1e-9)).astype(np.int64)
    d = np.min(np.abs(f[:, None] - sing[None, :]), axis=1)
    bias = path.rate(f) / (2 * np.pi * np.maximum(d, 1e-12) ** 2)
    return SweptPlan(path=path, freqs_hz=f, cycles=cycles, level_f_hz=lev_f, level_v=lev_v,
                     rule_bias=bias, settings=settings, warnings=tuple(warnings))


class _Buffer:
    """The chunks since the earliest window not yet analysed: phases, volts (bench and
    noiseless), codes, clipped and saturated flags, from output sample ``start``."""

    def __init__(self):
        self.start, self.parts = 0, []
        self.phi = np.zeros(0)
        self.volts = self.truth = np.zeros((3, 0))
        self.codes = None
        self.clip = self.sat = np.zeros((3, 0), bool)

    @property
    def end(self) -> int:
        return self.start + self.phi.size

    def append(self, phi, volts, truth, codes, clip, sat):
        self.phi = np.concatenate([self.phi, phi])
        self.volts = np.concatenate([self.volts, volts], axis=1)
        self.truth = np.concatenate([self.truth, truth], axis=1)
        self.codes = codes if self.codes is None else {
            k: np.concatenate([v, codes[k]]) for k, v in self.codes.items()}
        self.clip = np.concatenate([self.clip, clip], axis=1)
        self.sat = np.concatenate([self.sat, sat], axis=1)

    def trim(self, first: int):
        k = max(0, min(first, self.end) - self.start)
        if k:
            self.phi, self.volts, self.truth = self.phi[k:], self.volts[:, k:], \
                self.truth[:, k:]
            self.codes = {c: v[k:] for c, v in self.codes.items()}
            self.clip, self.sat = self.clip[:, k:], self.sat[:, k:]
            self.start += k


def run_swept(plan: SweptPlan, acq, accepted: list, sinks=(), progress=None) -> None:
    """Run ``plan`` on ``acq`` and append every point's :class:`processing.sine.
    SinePointResult` to ``accepted`` as its window completes, handing it to the sinks
    (module docstring)."""
    from daq.sine import PointRecord
    from processing.sine import point_result, point_row, tracking_fit
    from rig.bench.swept import ModalSweep
    from rig.devices.stepped_sine import SinePoint
    from rig.devices.swept_sine import stair_phases, swept_samples

    st, chain, rate = plan.settings, acq.chain, acq.rate_hz
    q, fs = chain.q, chain.fs_hz
    path = plan.path
    total = int(math.ceil(path.duration_s * rate))
    centre = np.clip(np.rint(path.time_at(plan.freqs_hz) * rate).astype(np.int64), 0,
                     total - 1)
    half = np.ceil(1.5 * 0.5 * plan.cycles / plan.freqs_hz * rate).astype(np.int64) + 2
    first = np.clip(centre - half, 0, total)
    last = np.clip(centre + half + 1, 0, total)
    pending_first = np.minimum.accumulate(first[::-1])[::-1]  # earliest start still needed
    truth = ModalSweep(chain)
    buf = _Buffer()
    phase, i, t_prev = 0.0, 0, 0.0
    lever = acq.scene.lever
    for n0 in range(0, total, CHUNK):
        n1 = min(n0 + CHUNK, total)
        f_out = path.frequency((np.arange(n0, n1) + 0.5) / rate)
        phi, phase = stair_phases(f_out, phase, q, fs)
        lev = plan.level(f_out)
        v = swept_samples(f_out, phi, q, fs, lev)
        codes, clip, volts, sat = acq.samples(v)
        buf.append(phi, volts, truth.run(f_out, phi, lev), codes,
                   np.stack([clip[c] for c in ("a", "x", "y")]),
                   np.stack([sat.get(c, np.zeros(n1 - n0, bool)) for c in ("a", "x", "y")]))
        while i < plan.freqs_hz.size and last[i] <= buf.end:
            a, b = first[i] - buf.start, last[i] - buf.start
            ph = buf.phi[a:b]
            phc = buf.phi[centre[i] - buf.start]
            k = int(plan.cycles[i])
            sel = np.flatnonzero((ph >= phc - k / 2) & (ph < phc + k / 2)) + a
            y, yt = buf.volts[:, sel], buf.truth[:, sel]
            coef, var = tracking_fit(y, buf.phi[sel], st.harmonics)
            noiseless, _ = tracking_fit(yt, buf.phi[sel], st.harmonics)
            fi = float(plan.freqs_hz[i])
            level = float(plan.level(fi))
            unit = -1j * math.sqrt(2.0) * level  # the sine's phasor
            t_c = centre[i] / rate
            res = point_result(
                coef, var, np.var(y, axis=1), sel.size,
                chain.steady_state(fi)[1] * unit, noiseless[:, 0], chain, lever,
                frequency_hz=fi, level_vrms=level, settle_s=t_c - t_prev,
                integrate_s=sel.size / rate, cycles=k,
                t0_s=(buf.start + sel[0]) / rate - (t_c - t_prev),
                clipped=buf.clip[:, sel].sum(axis=1), saturated=buf.sat[:, sel].sum(axis=1),
                settle_bound=np.full(3, plan.rule_bias[i]))
            t_prev = t_c
            accepted.append(res)
            rec = PointRecord(point=SinePoint(fi, level, 0, max(int(sel.size), 2), k),
                              t0_s=res.t0_s + res.settle_s,
                              phase_cycles=float(buf.phi[sel[0]]),
                              codes={c: w[sel] for c, w in buf.codes.items()}, volts=y,
                              clipped=dict(zip("axy", map(int, res.clipped))),
                              saturated=dict(zip("axy", map(int, res.saturated))))
            for s in sinks:
                s.point(point_row(res), rec)
            i += 1
            if progress is not None:
                progress(len(accepted), fi, buf.end / rate)
        buf.trim(int(pending_first[i]) if i < plan.freqs_hz.size else buf.end)
