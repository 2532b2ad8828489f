"""A run as a system-identification benchmark: input, outputs, sampling time, train and test, and
the floor no model can go below.

:func:`write_sysid_file` writes a NumPy ``.npz`` in the layout system-identification loaders use
(``nonlinear_benchmarks``' ``Input_output_data``: ``u``, ``y``, ``sampling_time``, a train and a
test part)::

    u (samples,)                the drive [V]: the source's DAC output at the sample instants
    y (samples, 3)              a [m/s^2], x [m], y [rad]: the measured channels in engineering units
    sampling_time ()            [s];  channels, units (3,)
    u_train, y_train, u_test, y_test   the first records and the last ``test_fraction`` of them
                                (whole records: a record never straddles the two)
    y_oracle (samples, 3)       the emulator's own output for the same run without sensor noise:
                                the same source, bench and quantiser, only the sensors' white noise
                                off; the best simulation any model of u -> y can give
    noise_floor_rms (3,)        the predicted rms of y - y_oracle: each sensor's white noise
                                through the anti-alias filter, ``N^2 int_0^{fs/2} |H(f)|^2 df``, plus
                                two independent quantisations, ``2 lsb^2 / 12``, in engineering units
    scene_json, seed

``y_test - y_oracle_test`` is then the known noise floor: the sanity case a measured benchmark
cannot give. The drive comes from the run's ground truth (``acquisition.truth``, on by default).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rig.output_files import atomic_output
from rig.errors import ConfigError

__all__ = ["write_sysid_file", "noise_floor_rms", "oracle_recording"]

_NOISE_KEYS = ("accelerometer.noise_mps2_rthz", "psd.noise_m_rthz")


def oracle_recording(recording):
    """The same run (scene, seed, records) acquired again with the sensors' noise off."""
    from daq.acquisition import acquire
    from daq.sinks import MemorySink
    from rig.scene import scene_from_settings

    settings = json.loads(json.dumps(recording.header.scene.settings))
    for key in _NOISE_KEYS:
        section, name = key.split(".")
        settings[section][name] = 0.0
    settings["acquisition"]["records"] = recording.records
    mem = MemorySink()
    acquire(scene_from_settings(settings), seed=recording.header.seed, sinks=[mem])
    return mem.recording


def noise_floor_rms(recording) -> dict[str, float]:
    """Predicted rms of (measured - oracle) per channel, in engineering units (module docstring;
    :meth:`daq.records.Header.noise_rms` with two quantisations)."""
    return recording.header.noise_rms(quantisations=2)


def write_sysid_file(recording, path: str | Path, *, test_fraction: float = 0.2,
                     force: bool = False) -> Path:
    """Write the benchmark file of ``recording`` (module docstring)."""
    path = Path(path)
    if path.suffix != ".npz":
        raise ConfigError(f"output {str(path)!r} is invalid: a system-identification file is a "
                          "NumPy .npz file")
    if not (0.0 < test_fraction < 1.0):
        raise ConfigError(f"test_fraction = {test_fraction!r} is invalid: expected 0 < "
                          "test_fraction < 1")
    if "source_v" not in recording.truth:
        raise ConfigError("the run has no ground truth, so no drive: acquire it with "
                          "acquisition.truth = true (the default)")
    n = recording.records
    n_test = int(round(test_fraction * n))
    if n < 2 or not 1 <= n_test <= n - 1:
        raise ConfigError(f"the run has {n} finished record(s): train and test need whole "
                          f"records each (test_fraction {test_fraction:g} of {n})")
    h = recording.header
    names = h.names
    y = np.stack([recording.values(c).reshape(-1) for c in names], axis=1)
    oracle = oracle_recording(recording)
    y_oracle = np.stack([oracle.values(c).reshape(-1) for c in names], axis=1)
    u = np.asarray(recording.truth["source_v"], float)[:n].reshape(-1)
    cut = (n - n_test) * h.plan.samples
    floor = noise_floor_rms(recording)
    with atomic_output(path, force=force, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, u=u, y=y, sampling_time=np.float64(1.0 / h.plan.rate_hz),
                     channels=np.array(names), units=np.array([h.channel(c).unit for c in names]),
                     u_train=u[:cut], y_train=y[:cut], u_test=u[cut:], y_test=y[cut:],
                     y_oracle=y_oracle, noise_floor_rms=np.array([floor[c] for c in names]),
                     scene_json=np.array(json.dumps(h.scene.settings, sort_keys=True)),
                     seed=np.int64(h.seed))
    return path
