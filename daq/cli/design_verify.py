"""``daq design --verify``: the designed scene run through the emulated experiment (the library's
:func:`daq.acquire` into memory, then :func:`processing.analyze`), its measured modes and rotation
suppression beside the designed ones. A composition of the three layers, so it lives with the CLI.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass

from rig.errors import ConfigError

__all__ = ["Verification", "verify_design"]


@dataclass(frozen=True)
class Verification:
    """Designed against measured, each measured value with its standard deviation.

    Attributes
    ----------
    modes : ((designed f [Hz], designed Q, measured f, f std, measured Q, Q std, fit label,
        the fit method's own bias [Hz]: its fit of the noiseless E[H1] minus the design), ...)
    band_hz : the band of the rotation reading [Hz].
    suppression_model_db, suppression_db, suppression_std_db : mean of -20 log10|theta2/theta1|
        over the band's lines, of the exact model and as measured (with its standard deviation).
    records, record_s, seed : the run. notes : the analysis' notes.
    """

    modes: tuple
    band_hz: tuple
    suppression_model_db: float
    suppression_db: float
    suppression_std_db: float
    records: int
    record_s: float
    seed: int
    notes: tuple

    def lines(self) -> list[str]:
        """The comparison as text lines."""
        out = [f"virtual measurement ({self.records} x {self.record_s:g} s, seed {self.seed}):"]
        for fd, qd, fm, fs, qm, qs, lab, bias in self.modes:
            out.append(f"  mode {fd:.5g} Hz (Q {qd:.4g}) designed; measured {fm:.5g} +- "
                       f"{fs:.2g} Hz (Q {qm:.4g} +- {qs:.2g}; {lab}, method bias "
                       f"{bias:+.2g} Hz)")
        out.append(f"  rotation suppression, mean over {self.band_hz[0]:.3g}-{self.band_hz[1]:.3g}"
                   f" Hz: designed {self.suppression_model_db:.2f} dB, measured "
                   f"{self.suppression_db:.2f} +- {self.suppression_std_db:.2f} dB")
        out += [f"  note: {n}" for n in self.notes[:3]]
        return out

    def markdown(self) -> str:
        rows = ["", "## Virtual measurement", "",
                f"{self.records} records of {self.record_s:g} s (seed {self.seed}), acquired and "
                "analysed like the paper's experiment.", "",
                "| quantity | designed | measured | std |", "|---|---|---|---|"]
        for fd, qd, fm, fs, qm, qs, lab, _ in self.modes:
            rows.append(f"| mode at {fd:.4g} Hz: frequency [Hz] ({lab}) | {fd:.5g} | {fm:.5g} | "
                        f"{fs:.2g} |")
            rows.append(f"| mode at {fd:.4g} Hz: Q | {qd:.4g} | {qm:.4g} | {qs:.2g} |")
        rows.append(f"| rotation suppression, mean over {self.band_hz[0]:.3g}-"
                    f"{self.band_hz[1]:.3g} Hz [dB] | {self.suppression_model_db:.2f} | "
                    f"{self.suppression_db:.2f} | {self.suppression_std_db:.2f} |")
        rows += ["", "The suppression is the mean over the band's lines of -20 log10|theta2/theta1|;"
                 " noise on a line raises |theta2/theta1| on average, so the measured mean "
                 "leans low by a fraction of its standard deviation."]
        rows += [f"- {n}" for n in self.notes]
        return "\n".join(rows) + "\n"


def _scene(scene_text: str, records: int | None, record_s: float | None, overrides=()):
    from rig.scene import load_scene, merge_scene_data, read_scene_data

    data = tomllib.loads(scene_text)
    base = data.pop("base")
    base_data, _ = read_scene_data(base)
    over = list(overrides)
    if records:
        over.append(f"acquisition.records={records}")
    if record_s:
        over.append(f"acquisition.record_s={record_s}")
    return load_scene(merge_scene_data(base_data, data), over)


def _band(d, rate_hz: float) -> tuple[float, float]:
    """The rotation reading's band: the first target band (else 1.5 f_upper .. 3.3 x that), from
    above the upper mode and the notch, to 0.4 of the sample rate at most."""
    f_hi = d.modes_hz[1]
    start = max(1.5 * f_hi, 1.2 * d.notch_hz if math.isfinite(d.notch_hz) else 0.0)
    top = 0.4 * rate_hz
    if d.targets.suppression:
        lo, hi = d.targets.suppression[0].band_hz
        band = (max(lo, start), min(hi, top))
    else:
        band = (start, min(3.3 * start, top))
    if band[1] <= 1.05 * band[0]:
        raise ConfigError(f"--verify: no band above the upper mode and the notch ({start:.3g} Hz)"
                          f" within the target band and below 0.4 x the sample rate "
                          f"({top:.3g} Hz) to read the rotation in")
    return band


def verify_design(d, scene_text: str, *, seed: int = 1, records: int | None = None,
                  record_s: float | None = None) -> Verification:
    """Acquire the designed scene (``scene_text``: :func:`rig.design.design_scene_toml`) and
    analyse it: fitted modes (leakage-aware fit of Theta_2) and the rotation reading over a band
    above f1 and above the notch (:func:`_band`), beside the design's exact values. The base's
    source span is raised, if need be, to drive that band (its default 12.5 Hz is the paper's
    analysis span); ``records``, ``record_s`` shorten the run."""
    import daq
    from processing.analyzer import AnalyzerSettings, analyze

    sc = _scene(scene_text, records, record_s)
    f_lo, f_hi = d.modes_hz
    band = _band(d, sc.acquisition.rate_hz)
    src = sc.source.fmax_hz
    raised = band[1] > 0.9 * src
    if raised:  # the analyzer's source must drive the band it reads
        src = min(1.15 * band[1], 0.45 * sc.acquisition.rate_hz)
        sc = _scene(scene_text, records, record_s, [f"source.fmax_hz={src!r}"])
    fmax = max(10.0, band[1])
    notch = d.notch_hz if math.isfinite(d.notch_hz) else 4 * f_hi
    settings = AnalyzerSettings(
        fmin_hz=min(0.1, 0.3 * f_lo), fmax_hz=fmax,
        theta2_fit_band_hz=(0.4 * f_lo, min(1.6 * f_hi, 0.9 * notch)),
        ht_fit_band_hz=(0.6 * f_hi, 1.6 * f_hi), rotation_band_hz=band)
    mem = daq.MemorySink()
    daq.acquire(sc, seed=seed, sinks=[mem])
    a = analyze(mem.recording, settings, source="daq design --verify")
    key = "Theta_2 leakage-aware" if "Theta_2 leakage-aware" in a.fits else "Theta_2 direct"
    fit, check = a.fits.get(key), a.fit_checks.get(key)
    modes = []
    for fd, qd in zip(d.modes_hz, d.modes_q):
        if fit is None:
            continue
        m = min(fit.modes, key=lambda x: abs(x.f_hz - fd))
        bias = (min(check.modes, key=lambda x: abs(x.f_hz - fd)).f_hz - fd
                if check is not None else 0.0)
        modes.append((fd, qd, m.f_hz, m.f_std_hz, m.q, m.q_std, f"{key} fit", bias))
    r = a.rotation
    if r is None:
        raise ConfigError("--verify: the analysis made no rotation reading: "
                          + "; ".join(a.notes))
    notes = list(a.notes)
    if raised:
        notes.insert(0, f"source span raised to {src:.4g} Hz to drive the band read")
    return Verification(modes=tuple(modes), band_hz=tuple(band),
                        suppression_model_db=-r.model_mean_db, suppression_db=-r.mean_db,
                        suppression_std_db=r.mean_std_db, records=sc.acquisition.records,
                        record_s=sc.acquisition.record_s, seed=seed, notes=tuple(notes))
