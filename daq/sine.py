"""The stepped-sine acquisition: the bench point by point through the anti-alias filter and the
ADC, as every run is acquired.

:class:`SineAcquisition` builds, for a scene, the acquisition's anti-alias filter and channels
(:func:`daq.acquisition.antialias_for`, :func:`daq.channels.channels_for`), the bench model
chosen by the error budget for the sweep's worst point (:func:`rig.bench.sine.sine_model`), the
bench run point by point (:class:`rig.bench.sine.SineBench`: the fused chain of every run) and
the exact linear chain of the whole thing (:class:`rig.bench.sine.SineChain`); :meth:`point`
runs one :class:`rig.devices.stepped_sine.SinePoint` and digitises it: a :class:`PointRecord`
of ADC codes, their volts, and the clipped and saturated sample counts of each channel.

Public API: :class:`SineAcquisition`, :class:`PointRecord`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from daq.acquisition import antialias_for, check_seed
from daq.channels import channels_for
from daq.records import RecordPlan
from rig.scene import Scene


@dataclass(frozen=True, eq=False)
class PointRecord:
    """One point as digitised.

    Attributes
    ----------
    point : the :class:`rig.devices.stepped_sine.SinePoint` run.
    t0_s : its start from the start of the sweep [s] (simulated time).
    phase_cycles : the source's phase at its first sample [cycles].
    codes : name -> (samples,) ADC codes of the whole point (settle and window).
    volts : (3, samples) those codes in volts (a, x, y).
    clipped, saturated : name -> samples the ADC clipped / the sensor was beyond its range.
    """

    point: object
    t0_s: float
    phase_cycles: float
    codes: dict
    volts: np.ndarray
    clipped: dict
    saturated: dict


class SineAcquisition:
    """A stepped-sine run of ``scene`` (module docstring).

    Parameters
    ----------
    scene : the scene (its source's type and frequency are not used: the points drive it).
    seed : seeds the sensors' noise (0 <= seed < 2**63).
    worst_hz, level_vrms, duration_s, fmax_hz : the model choice's worst point (the frequency
        of the largest pendulum response per volt, the highest level, the longest point [s])
        and the highest drive frequency (:func:`rig.bench.sine.sine_model`).
    """

    def __init__(self, scene: Scene, seed: int, *, worst_hz: float, level_vrms: float,
                 duration_s: float, fmax_hz: float):
        from rig.bench.response import calibrations
        from rig.bench.sine import SineBench, sine_chain, sine_model

        self.seed = check_seed(seed)
        acq = scene.acquisition
        plan = RecordPlan.from_acquisition(acq)
        self.scene = scene
        self.antialias = antialias_for(acq, plan)
        self.channels = channels_for(scene.settings["acquisition"], calibrations(scene))
        sos = (np.array([[1.0, 0, 0, 1.0, 0, 0]]) if self.antialias.kind == "none"
               else np.asarray(self.antialias.sos))
        self.model, self.selection = sine_model(scene, worst_hz, level_vrms, duration_s,
                                                fmax_hz)
        self.bench = SineBench(self.model, self.seed, sos)
        self.chain = sine_chain(self.model, sos)
        self.rate_hz = float(plan.rate_hz)
        self._t_s = 0.0

    @property
    def model_info(self) -> dict:
        """What runs and why (JSON-ready): model, method, the selection's reason and numbers."""
        info = {"model": self.model.model, "method": self.model.method
                if self.model.model == "nonlinear" else "lifted exact linear step",
                "requested_model": self.scene.acquisition.model,
                "error_budget": self.scene.acquisition.error_budget}
        sel = self.selection or {}
        for k in ("reason", "predicted_linear_error", "predicted_linear_error_upper", "chosen"):
            if k in sel:
                v = sel[k]
                info[k] = float(v) if isinstance(v, (float, np.floating)) else v
        return info

    def point(self, point) -> PointRecord:
        """Run and digitise ``point`` (:class:`PointRecord`)."""
        block, phase0 = self.bench.run(point)
        codes, clip, volts, sat = self.digitize(block)
        rec = PointRecord(point=point, t0_s=self._t_s, phase_cycles=phase0, codes=codes,
                          volts=volts, clipped={k: int(np.count_nonzero(v))
                                                for k, v in clip.items()},
                          saturated={k: int(np.count_nonzero(v)) for k, v in sat.items()})
        self._t_s += point.samples / self.rate_hz
        return rec

    def samples(self, v: np.ndarray):
        """Run the DAC samples ``v`` [V] (a whole number of output intervals, any source:
        the swept one's, :mod:`rig.devices.swept_sine`) and digitise them: ``(codes, clipped,
        volts, saturated)``, codes and per-sample clipped / saturated flags by channel name,
        volts (3, samples) of a, x, y."""
        return self.digitize(self.bench.run_samples(v))

    def digitize(self, block):
        """A :class:`rig.blocks.DecimatedBlock` through the ADCs: ``(codes, clipped, volts,
        saturated)`` as :meth:`samples`."""
        codes, clipped, volts = {}, {}, []
        for c in self.channels:
            adc = c.adc
            code, clip = adc.digitize(np.asarray(block.volts[c.name]))
            codes[c.name], clipped[c.name] = code, np.asarray(clip, bool)
            volts.append(adc.volts(code))
        saturated = {k: np.asarray(v, bool) for k, v in block.saturated.items()}
        return codes, clipped, np.stack(volts), saturated

    def extend(self, record: PointRecord, times: int) -> PointRecord:
        """Continue ``record``'s point (which must be the last one run) so that its window is
        ``times`` its length: the same frequency and level, the phase continuing, the window
        ``times`` as many samples and cycles (still whole cycles). Returns the whole point."""
        import dataclasses

        p = record.point
        extra = dataclasses.replace(p, settle_samples=0,
                                    integrate_samples=(times - 1) * p.integrate_samples,
                                    cycles=(times - 1) * p.cycles)
        more = self.point(extra)
        whole = dataclasses.replace(p, integrate_samples=times * p.integrate_samples,
                                    cycles=times * p.cycles)
        return PointRecord(
            point=whole, t0_s=record.t0_s, phase_cycles=record.phase_cycles,
            codes={k: np.concatenate([v, more.codes[k]]) for k, v in record.codes.items()},
            volts=np.concatenate([record.volts, more.volts], axis=1),
            clipped={k: v + more.clipped[k] for k, v in record.clipped.items()},
            saturated={k: v + more.saturated.get(k, 0) for k, v in record.saturated.items()})
