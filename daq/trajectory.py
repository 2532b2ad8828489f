"""Trajectory files written by ``daq simulate``: CSV or HDF5, chosen by the file's extension.

CSV: ``#``-prefixed header lines (scene, method, settings, error estimate and how it was obtained),
then the columns ``t, theta_1..theta_n, omega_1..omega_n, energy`` (units on the header line:
s, rad, rad/s, J); values are written with ``repr`` so they read back exactly.

HDF5 (``.h5``/``.hdf5``): an NXentry ``trajectory`` with datasets ``t`` [s] (dimension scale),
``body`` (scale), ``theta`` (t, body) [rad], ``omega`` (t, body) [rad/s], ``energy`` (t,) [J] and,
when estimated, ``theta_error_estimate`` (t, body) [rad]; the method, its settings, the error
estimate's description and the resolved scene are attributes. ``xarray.open_dataset(path,
group="trajectory", engine="h5netcdf")`` opens it. The root has ``@file_format`` (:data:`FORMAT`)
and ``@file_format_version``; HDF5 1.10 format bounds (readable by HDF5 1.10 to 2.0); every
array carries a fletcher32 checksum.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import h5py
import numpy as np

from rig.output_files import atomic_output, software_version
from rig.errors import ConfigError
from rig.scene import Scene
from rig.simulate import Trajectory

HDF5_SUFFIXES = (".h5", ".hdf5")
FORMAT = "pendulum-daq trajectory"
#: 1.1: root attributes file_format and file_format_version, HDF5 1.10 format bounds, a
#: fletcher32 checksum on every array (1.0 files have no file_format attribute).
FORMAT_VERSION = "1.1"
CSV_SUFFIXES = (".csv",)


def trajectory_format(path: Path) -> str:
    """``"csv"`` or ``"hdf5"`` from the extension; ConfigError for anything else."""
    suffix = Path(path).suffix.lower()
    if suffix in CSV_SUFFIXES:
        return "csv"
    if suffix in HDF5_SUFFIXES:
        return "hdf5"
    raise ConfigError(f"trajectory file {str(path)!r}: unknown extension {suffix!r}; expected .csv, .h5 "
                      "or .hdf5")


def _metadata(traj: Trajectory, scene: Scene) -> dict:
    return {
        "software_version": software_version(),
        "scene": scene.name,
        "scene_source": scene.origin,
        "method": traj.method,
        "settings": traj.settings,
        "n_steps": traj.n_steps,
        "n_rejected": traj.n_rejected,
        "n_fev": traj.n_fev,
        "wall_time_s": traj.wall_time_s,
        "max_error_estimate_rad": traj.max_error_rad,
        "error_method": traj.error_method,
        "warnings": list(traj.warnings),
    }


def write_trajectory(path: Path, traj: Trajectory, scene: Scene, *, force: bool) -> None:
    """Write ``traj`` (of ``scene``) to ``path`` as CSV or HDF5 (atomically; no overwrite
    without ``force``)."""
    fmt = trajectory_format(path)
    meta = _metadata(traj, scene)
    with atomic_output(path, force=force) as tmp:
        if fmt == "csv":
            _write_csv(tmp, traj, meta)
        else:
            _write_hdf5(tmp, traj, meta, scene)


def _write_csv(path: Path, traj: Trajectory, meta: dict) -> None:
    n = traj.theta_rad.shape[1]
    with open(path, "w", newline="") as fh:
        for key, value in meta.items():
            text = json.dumps(value) if isinstance(value, (dict, list)) else str(value)
            fh.write(f"# {key}: {text}\n")
        fh.write("# units: t [s], theta [rad], omega [rad/s], energy [J]\n")
        w = csv.writer(fh)
        w.writerow(["t"] + [f"theta_{j + 1}" for j in range(n)]
                   + [f"omega_{j + 1}" for j in range(n)] + ["energy"])
        rows = np.column_stack([traj.t_s, traj.theta_rad, traj.omega_rad_s, traj.energy_j])
        for row in rows:
            w.writerow([repr(float(v)) for v in row])


def _write_hdf5(path: Path, traj: Trajectory, meta: dict, scene: Scene) -> None:
    from daq.hdf5 import LIBVER

    with h5py.File(path, "w", libver=LIBVER) as f:
        f.attrs["NX_class"] = "NXroot"
        f.attrs["file_format"] = FORMAT
        f.attrs["file_format_version"] = FORMAT_VERSION
        f.attrs["default"] = "trajectory"
        g = f.create_group("trajectory")
        g.attrs["NX_class"] = "NXdata"
        g.attrs["signal"] = "theta"
        g.attrs["axes"] = ["t", "body"]
        for key, value in meta.items():
            g.attrs[key] = json.dumps(value) if isinstance(value, (dict, list)) else value
        g.attrs["scene_settings_json"] = json.dumps(scene.settings)
        t = g.create_dataset("t", data=traj.t_s, fletcher32=True)
        t.attrs.update(units="s", long_name="time")
        t.make_scale("t")
        body = g.create_dataset("body", data=np.arange(1, traj.theta_rad.shape[1] + 1))
        body.attrs["long_name"] = "body number (1 = top)"
        body.make_scale("body")

        def put(name, data, units, long_name, dims):
            d = g.create_dataset(name, data=data, fletcher32=True)
            d.attrs.update(units=units, long_name=long_name)
            for i, scale in enumerate(dims):
                d.dims[i].attach_scale(scale)

        put("theta", traj.theta_rad, "rad", "angle from the downward vertical", (t, body))
        put("omega", traj.omega_rad_s, "rad/s", "angular velocity", (t, body))
        put("energy", traj.energy_j, "J", "mechanical energy in the base frame", (t,))
        if traj.error_estimate_rad is not None:
            put("theta_error_estimate", traj.error_estimate_rad, "rad",
                "estimated absolute error of theta", (t, body))
