"""A sweep's run file: the acquisition's run file plus the analysis outputs the sweep keeps.

:func:`write_outputs` adds to a finished run file (format of :mod:`daq.hdf5`)::

    entry/dataset/          NXcollection @sweep_seed @run_index @run_seed @spec_hash
                            @parameters_json (the varied parameters) @overrides_json
                            (@analysis = 0 in a raw-only sweep, which has no entry/analysis)
    entry/analysis/         NXcollection @settings_json @notes_json @n_averages @n_effective
                            @resolution_hz @window @nperseg
      frequency (frequency,) [Hz] dimension scale: the analyzer's lines 0 .. rate/2
      G_aa, G_xx, G_yy; G_ax_real/_imag, G_ay_real/_imag    (keep.spectra) one-sided PSDs
      H_t_real/_imag [m/(m/s^2)], Theta_2_real/_imag [rad/(m/s^2)], coherence_x, coherence_y,
      H_t_relative_error, Theta_2_relative_error          (keep.frf) H1 with its 1-sigma error
      model_H_t_*, model_Theta_2_*, expected_H_t_*, expected_Theta_2_*   (keep.expected) the
                            exact whole chain and E[H1] at the lines
      modal/                (keep.modal) one scalar per fitted quantity, e.g.
                            theta_2_leakage_mode1_f_hz, ..._f_std_hz, ..._q, ..._q_std,
                            ..._reduced_chi2 (NaN if the fit was not made, see @notes_json)

:func:`check_run_file` is the one place that decides whether a run file is valid and complete.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from daq import run_layout as layout
from processing.analysis_group import write_analysis_group

__all__ = ["write_outputs", "check_run_file", "RunFileCheck", "sha256_file", "modal_table",
           "FIT_LABELS"]

_STR = h5py.string_dtype()
#: Fit labels of processing.analyzer and their names in the file.
FIT_LABELS = {"Theta_2 leakage-aware": "theta_2_leakage", "Theta_2 direct": "theta_2_direct",
              "H_t leakage-aware": "h_t_leakage", "H_t direct": "h_t_direct"}


def sha256_file(path: str | Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def modal_table(analysis) -> dict:
    """{name: (value, units)} of every fitted mode (module docstring), NaN-free: only fits made."""
    out = {}
    for label, fit in analysis.fits.items():
        base = FIT_LABELS.get(label, label.lower().replace(" ", "_").replace("-", "_"))
        for j, md in enumerate(fit.modes, start=1):
            p = f"{base}_mode{j}"
            out[f"{p}_f_hz"] = (md.f_hz, "Hz")
            out[f"{p}_f_std_hz"] = (md.f_std_hz, "Hz")
            out[f"{p}_q"] = (md.q, "1")
            out[f"{p}_q_std"] = (md.q_std, "1")
        out[f"{base}_reduced_chi2"] = (fit.reduced_chi2, "1")
    return out


def write_outputs(path: str | Path, analysis, keep: dict, *, spec: dict) -> None:
    """Add the kept analysis outputs and the run's place in the sweep to the run file ``path``
    (module docstring). ``spec``: sweep_seed, run_index, run_seed, spec_hash, parameters,
    overrides. ``analysis`` is None for a raw-only sweep (``keep.analysis = false``): the file
    then gets ``entry/dataset`` (with ``@analysis = 0``) and no ``entry/analysis``."""
    a = analysis
    with h5py.File(path, "r+") as f:
        ds = f.create_group(layout.DATASET)
        ds.attrs["NX_class"] = "NXcollection"
        ds.attrs["sweep_seed"] = np.int64(spec["sweep_seed"])
        ds.attrs["run_index"] = np.int64(spec["run_index"])
        ds.attrs["run_seed"] = np.int64(spec["run_seed"])
        ds.attrs["seed_derivation"] = ("run_seed = SeedSequence(sweep_seed, spawn_key=(run_index,"
                                       ")).generate_state(1, uint64)[0] >> 1")
        ds.attrs["spec_hash"] = spec["spec_hash"]
        ds.attrs["parameters_json"] = json.dumps(spec["parameters"], sort_keys=True)
        ds.attrs["overrides_json"] = json.dumps(list(spec["overrides"]))
        if a is None:
            ds.attrs["analysis"] = np.int8(0)
            f.flush()
            os.fsync(f.id.get_vfd_handle())
            return

        g = f.create_group(layout.ANALYSIS)
        g.attrs["NX_class"] = "NXcollection"
        sp = a.spectral
        g.attrs["settings_json"] = json.dumps(a.settings.describe(), sort_keys=True)
        g.attrs["notes_json"] = json.dumps(list(a.notes))
        g.attrs["window"] = sp.window
        g.attrs["nperseg"] = np.int64(sp.nperseg)
        g.attrs["resolution_hz"] = float(sp.resolution_hz)
        g.attrs["n_averages"] = np.int64(a.h_t.n_averages)
        g.attrs["n_effective"] = float(a.h_t.n_effective)
        g.attrs["k_sigma"] = float(a.settings.k)
        write_analysis_group(g, a, keep, run_file=True)
        if keep.get("modal", True):
            m = g.create_group(layout.MODAL)
            m.attrs["NX_class"] = "NXcollection"
            # the stored text names the module before the analyzer was split: run files stay
            # byte-identical across the restructuring (it is a description, not a reference)
            m.attrs["note"] = ("fits of the pendulum's own response (processing.analysis); "
                               "absent: the fit was not made (see ../@notes_json)")
            for name, (value, unit) in modal_table(a).items():
                d = m.create_dataset(name, data=float(value), track_times=False)
                d.attrs["units"] = unit
        f.flush()
        os.fsync(f.id.get_vfd_handle())


@dataclass(frozen=True)
class RunFileCheck:
    """Whether a sweep's run file is valid and complete: ``ok``, ``status``, ``records_complete``
    and ``records_planned``, ``spec_hash`` (of the plan that wrote it), ``sha256`` (if computed)
    and ``problems`` (empty when ok)."""

    path: Path
    ok: bool
    status: str
    records_complete: int
    records_planned: int
    spec_hash: str
    sha256: str
    problems: tuple


def check_run_file(path: str | Path, *, sha256: str | None = None,
                   spec_hash: str | None = None) -> RunFileCheck:
    """Check ``path``: a whole run file (:func:`daq.check.check_file`: every record and chunk
    verifies), status complete with every planned record, the analysis outputs present, the
    plan's ``spec_hash`` (if given) and the file's sha256 against ``sha256`` (if given; computed
    either way when the rest is ok). Never raises for a bad file: ``problems`` say why."""
    from daq.check import check_file

    path = Path(path)
    if not path.is_file():
        return RunFileCheck(path, False, "missing", 0, 0, "", "", ("file does not exist",))
    fc = check_file(path)
    problems = list(fc.problems)
    n, planned = fc.records_valid or 0, fc.records_planned or 0
    if fc.kind != "run":
        problems.append(f"not a pendulum-daq run file ({fc.kind})")
    if fc.status != "complete":
        problems.append(f"status {fc.status!r}, expected 'complete'")
    if n != planned:
        problems.append(f"{n} of {planned} records verify")
    h = ""
    if not problems:
        try:
            with h5py.File(path, "r") as f:
                has_dataset = layout.DATASET in f
                raw_only = has_dataset and int(f[layout.DATASET].attrs.get("analysis", 1)) == 0
                if not has_dataset or (layout.ANALYSIS not in f and not raw_only):
                    problems.append(f"no analysis outputs ({layout.ANALYSIS}, {layout.DATASET})")
                else:
                    h = str(f[layout.DATASET].attrs["spec_hash"])
        except (OSError, KeyError) as exc:
            what = f"no {exc.args[0]!r} in it" if isinstance(exc, KeyError) else str(exc)
            problems.append(f"unreadable: {what}")
    if spec_hash is not None and h and h != spec_hash:
        problems.append("written by another sweep plan (spec_hash differs)")
    digest = ""
    if not problems:
        digest = sha256_file(path)
        if sha256 is not None and digest != sha256:
            problems.append(f"sha256 {digest[:12]}... differs from the manifest's "
                            f"{sha256[:12]}...")
    return RunFileCheck(path, not problems, fc.status, n, planned, h, digest, tuple(problems))
