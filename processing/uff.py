"""The analyzer's frequency responses as UFF 58 (``daq analyze --uff``).

Four data sets over the display band (the CSV's lines): H_t (function type 4, FRF: response the
mirror, +X translation [m], reference the stage, +X acceleration [m/s^2]), its coherence
(type 6, [1]), Theta_2 (FRF: mirror -Y rotation [rad] per stage acceleration) and its coherence.
Nodes, directions and precision as in :mod:`rig.uff`.
"""

from __future__ import annotations

from pathlib import Path

from rig.uff import CHANNEL_DOFS, COHERENCE, FRF, UNKNOWN, uff58, write_uff


def frf_datasets(a) -> list[dict]:
    """The UFF 58 sets of an :class:`processing.analyzer.Analysis` (module docstring)."""
    m = a.display
    f = a.freqs_hz[m]
    s = a.settings
    ref = CHANNEL_DOFS["a"]
    out = []
    for name, frf, out_ch, unit in (("H_t", a.h_t, "x", "m/(m/s^2)"),
                                    ("Theta_2", a.theta_2, "y", "rad/(m/s^2)")):
        rsp = CHANNEL_DOFS[out_ch]
        common = (f"scene {a.run.scene}, seed {a.run.seed}, {a.run.source}",
                  f"{frf.estimator.upper()}, {s.window} window, {s.averaging} averaging, "
                  f"{frf.n_averages} averages of {a.spectral.nperseg / a.spectral.fs:g} s",
                  f"run {a.run.status}, {a.run.records} of {a.run.records_planned} records")
        out.append(uff58(func_type=FRF, response=rsp, reference=ref, x=f, data=frf.h[m],
                         abscissa="frequency", ids=(
                             f"{name} = W_a{out_ch}/W_aa: {out_ch}/a [{unit}]", *common)))
        out.append(uff58(func_type=COHERENCE, response=rsp, reference=ref, x=f,
                         data=frf.coherence[m], abscissa="frequency",
                         ordinate_type=UNKNOWN, ordinate_unit="1",
                         ordinate_label="coherence", ids=(
                             f"coherence gamma^2 of {name} ({out_ch} with a) [1]", *common)))
    return out


def write_frf_uff(a, path, *, force: bool = False) -> Path:
    """Write :func:`frf_datasets` of ``a`` to the UFF file ``path`` (never over an existing
    file without ``force``)."""
    return write_uff(frf_datasets(a), path, force=force)
