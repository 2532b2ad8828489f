"""A run's responses as an output-only (OMA) data set: what pyOMA2's ``SingleSetup`` takes.

:func:`write_oma_file` writes a NumPy ``.npz`` holding only the responses, the mirror's
translation ``x`` [m] and rotation ``y`` [rad] in engineering units (the analyzer's own arrays,
``Recording.values``), every finished record joined in time order (the records of a run are
contiguous: each starts where the previous ended). The stage's acceleration and the drive are
left out: the bench is shaken by the source's broadband noise, which an OMA method treats as an
unmeasured input. Beside the data it stores the truth an OMA method should recover, the linear
bench's modes (:func:`rig.bench.modes.bench_modes`)::

    data (samples, 2) float64     x [m], y [rad]          fs ()  sample rate [Hz]
    channels, units (2,)          "x", "y"; "m", "rad"
    exact_f_hz, exact_zeta (modes,)     natural frequency [Hz], damping ratio
    exact_shapes (modes, 2) complex     at (x, y), the larger component 1
    scene_json, seed                    what made the run

``SingleSetup(z["data"], float(z["fs"]))`` then runs FDD, SSI or pLSCF on it unchanged.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rig.output_files import atomic_output
from rig.errors import ConfigError

__all__ = ["OMA_CHANNELS", "output_only_data", "write_oma_file"]

OMA_CHANNELS = ("x", "y")


def output_only_data(recording) -> tuple[np.ndarray, float]:
    """The responses ``(samples, 2)`` (x [m], y [rad]) of every finished record, joined, and
    the sample rate [Hz]."""
    h = recording.header
    missing = [c for c in OMA_CHANNELS if c not in h.names]
    if missing:
        raise ConfigError(f"the run has no channel {missing[0]!r}: an output-only data set "
                          f"needs {', '.join(OMA_CHANNELS)}")
    if recording.records < 1:
        raise ConfigError("the run has no finished record: nothing to export")
    data = np.column_stack([recording.values(c).reshape(-1) for c in OMA_CHANNELS])
    return data, float(h.plan.rate_hz)


def write_oma_file(recording, path: str | Path, *, force: bool = False) -> Path:
    """Write the output-only data set of ``recording`` (module docstring) to ``path`` (.npz)."""
    from rig.bench.modes import bench_modes

    path = Path(path)
    if path.suffix != ".npz":
        raise ConfigError(f"output {str(path)!r} is invalid: an output-only data set is a "
                          "NumPy .npz file")
    data, fs = output_only_data(recording)
    h = recording.header
    modes = bench_modes(h.scene)
    units = [h.channel(c).unit for c in OMA_CHANNELS]
    with atomic_output(path, force=force, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, data=data, fs=np.float64(fs), channels=np.array(OMA_CHANNELS),
                     units=np.array(units), exact_f_hz=modes.f_hz, exact_zeta=modes.zeta,
                     exact_shapes=modes.shapes,
                     scene_json=np.array(json.dumps(h.scene.settings, sort_keys=True)),
                     seed=np.int64(h.seed))
    return path
