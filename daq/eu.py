"""A run's channels as labelled arrays in engineering units (or volts, or ADC codes).

:func:`to_xarray` turns a :class:`daq.records.Recording` (``daq.hdf5.read_run(path)``) into an
``xarray.Dataset`` whose ``a``, ``x``, ``y`` are the stage acceleration [m/s^2], the mirror
translation relative to the stage [m] and the mirror rotation [rad]: ``Recording.values``, the
very arrays the analyzer transforms (each channel's ADC code to volts, then its signed calibration
undone). :func:`write_eu_file` writes that dataset as a netCDF-4/HDF5 file that xarray, netCDF
tools and plain h5py open.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.output_files import atomic_output, check_writable
from rig.errors import ConfigError, import_extra

UNITS = ("eu", "volts", "codes")


def channel_array(recording, name: str, units: str = "eu") -> tuple[np.ndarray, str]:
    """Channel ``name`` as (records, samples) in ``units`` ("eu": its engineering unit, "volts",
    "codes": the raw ADC integers) and that unit's symbol."""
    if units not in UNITS:
        raise ConfigError(f"units = {units!r} is invalid: expected one of {', '.join(UNITS)}")
    ch = recording.header.channel(name)
    if units == "eu":
        return recording.values(name), ch.unit
    if units == "volts":
        return recording.volts(name), "V"
    return np.asarray(recording.codes[name]), "1"


def to_xarray(recording, units: str = "eu"):
    """The run's channels as an ``xarray.Dataset`` (dims ``record``, ``time``).

    Variables: one per channel (``a``, ``x``, ``y``) in ``units`` ("eu", the default: m/s^2, m,
    rad; "volts"; "codes"), with ``units``, ``long_name``, ``quantity`` and the calibration
    (``volts_per_unit``, signed) as attributes; ``clipped_<c>`` and ``saturated_<c>`` (uint8, 1
    where the ADC clipped or the sensor saturated). Coordinates: ``record`` (index), ``time``
    within a record [s], ``record_start`` [s from the start of the run] and ``run_time``
    (record, time) [s]. Attributes: scene, seed, status, records complete/planned.
    Only finished records are held (an interrupted run gives the records it finished).
    """
    xr = import_extra("xarray", "xarray", "labelled arrays (xarray)")

    h = recording.header
    plan = h.plan
    n = recording.records
    time = np.arange(plan.samples) / plan.rate_hz
    start = (plan.settle_samples + np.arange(n) * plan.samples) / plan.rate_hz
    coords = {
        "record": ("record", np.arange(n), {"units": "1", "long_name": "record index"}),
        "time": ("time", time, {"units": "s", "long_name": "time within the record"}),
        "record_start": ("record", start, {"units": "s", "long_name":
                                           "first sample of the record from the start of the run"}),
        "run_time": (("record", "time"), start[:, None] + time[None, :],
                     {"units": "s", "long_name": "time from the start of the run"}),
    }
    data = {}
    for name in h.names:
        ch = h.channel(name)
        values, unit = channel_array(recording, name, units)
        what = {"eu": ch.quantity, "volts": f"{ch.quantity}, sensor output",
                "codes": f"{ch.quantity}, ADC codes"}[units]
        data[name] = (("record", "time"), values, {
            "units": unit, "long_name": f"{ch.long_name}: {what}", "quantity": ch.quantity,
            "engineering_unit": ch.unit, "volts_per_unit": float(ch.volts_per_unit),
            "range_v": float(ch.range_v), "bits": int(ch.bits)})
        data[f"clipped_{name}"] = (("record", "time"), np.asarray(recording.clipped[name], np.uint8),
                                   {"units": "1", "long_name": f"1 where the ADC of {name} clipped"})
        sat = recording.saturated.get(name)
        sat = np.zeros((n, plan.samples), np.uint8) if sat is None else np.asarray(sat, np.uint8)
        data[f"saturated_{name}"] = (("record", "time"), sat, {
            "units": "1", "long_name": f"1 where the sensor of {name} was beyond its range"})
    attrs = {"title": f"pendulum-daq run of scene {h.scene.name} in "
                      f"{'engineering units' if units == 'eu' else units}",
             "scene": h.scene.name, "seed": str(h.seed), "status": recording.status,
             "records_complete": n, "records_planned": plan.records, "channel_units": units,
             "rate_hz": plan.rate_hz, "software_version": h.software_version,
             "start_time": h.start_time}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def write_eu_file(recording, path: str | Path, *, units: str = "eu", force: bool = False) -> None:
    """Write :func:`to_xarray` of ``recording`` as a netCDF-4 (HDF5) file at ``path`` (``.nc``,
    ``.h5`` or ``.hdf5``; root group), never over an existing file without ``force``."""
    path = Path(path)
    if path.suffix not in (".nc", ".h5", ".hdf5"):
        raise ConfigError(f"output {str(path)!r} is invalid: expected a .nc, .h5 or .hdf5 file")
    check_writable(path, force=force)
    import_extra("h5netcdf", "xarray", "writing netCDF files")
    ds = to_xarray(recording, units=units)
    encoding = {v: {"zlib": True, "complevel": 4} for v in ds.data_vars}
    with atomic_output(path, force=force) as tmp:
        ds.to_netcdf(tmp, engine="h5netcdf", encoding=encoding, invalid_netcdf=False)
