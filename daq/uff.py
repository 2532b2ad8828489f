"""The run's records as Universal File Format (UFF) 58 time responses (``daq export --uff``).

Every finished record of every channel, in engineering units, one data set each (function type
1, time response), on the nodes and directions of :data:`rig.uff.CHANNEL_DOFS` (node 1 the stage,
node 2 the mirror). The ID lines say what each set is (quantity, unit, scene, seed, record).
``processing.uff.write_frf_uff`` writes the analyzer's H_t and Theta_2 with their coherence in
the same format.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.output_files import check_writable
from rig.uff import CHANNEL_DOFS, TIME_RESPONSE, uff58, write_uff
from rig.errors import ConfigError

__all__ = ["CHANNEL_DOFS", "time_datasets", "write_time_uff"]


def time_datasets(recording, *, source: str = "") -> list[dict]:
    """UFF 58 time responses of every finished record of every channel, in engineering units
    (``Recording.values``: the numbers the analyzer transforms); load case = record number
    (1-based), abscissa the time within the record [s]."""
    h = recording.header
    plan = h.plan
    t = np.arange(plan.samples) / plan.rate_hz
    for name in h.names:
        if name not in CHANNEL_DOFS:
            raise ConfigError(f"channel {name!r} has no UFF mapping (mapped: "
                              f"{', '.join(CHANNEL_DOFS)})")
    values = {name: recording.values(name) for name in h.names}
    out = []
    for r in range(recording.records):
        start = (plan.settle_samples + r * plan.samples) / plan.rate_hz
        for name in h.names:
            ch = h.channel(name)
            out.append(uff58(
                func_type=TIME_RESPONSE, response=CHANNEL_DOFS[name], reference=None, x=t,
                data=values[name][r], abscissa="time", load_case=r + 1, ids=(
                    f"{name}: {ch.quantity} [{ch.unit}]",
                    f"scene {h.scene.name}, seed {h.seed}, {source or 'run'}",
                    f"record {r + 1} of {recording.records}, starts {start:.9g} s into the run",
                    f"{plan.rate_hz:g} Hz, {plan.samples} samples, status {recording.status}",
                    f"pendulum-daq {h.software_version}, started {h.start_time}")))
    return out


def write_time_uff(recording, path: str | Path, *, source: str = "",
                   force: bool = False) -> Path:
    """Write :func:`time_datasets` of ``recording`` to the UFF file ``path``."""
    check_writable(Path(path), force=force)
    return write_uff(time_datasets(recording, source=source), path, force=force)
