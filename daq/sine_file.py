"""The sine run file (stepped or swept): one row per measured point, written point by point.

The conventions of the FFT run file (:mod:`daq.hdf5`): NeXus classes with ``default``
attributes, the HDF5 1.10 format bounds (:data:`daq.hdf5.LIBVER`), a fletcher32 checksum on
every chunked dataset, dimension scales with ``units`` and ``long_name`` (``xarray.open_dataset(
path, group="entry/sweep", engine="h5netcdf")`` reads the points), SWMR while it grows (a reader
follows it with ``h5py.File(path, "r", swmr=True)``), and written under a temporary name beside
the target, renamed to it when the sweep stops (an interrupted sweep keeps its finished points,
status "interrupted"). Layout (format :data:`FORMAT`, version :data:`FORMAT_VERSION`)::

    /                     NXroot @default=entry @file_format @file_format_version @creator
    entry/                NXentry @default=sweep @title @start_time @seed @scene_name
                          @mode (stepped | swept) @sweep_s (swept: the sweep's duration [s])
      status              S16: acquiring | complete | interrupted | failed
      points_complete     int64: points fully written (every per-point dataset has that many)
      sweep/              NXdata @signal=h_t_gain_db @axes=point
        point (point,), harmonic (harmonic,)   dimension scales
        <column> (point,) or (point, harmonic)  one per :data:`processing.sine.POINT_COLUMNS`
                          entry (complex values as _real/_imag pairs), @units @long_name
      records/            NXcollection (only when kept): codes_a, codes_x, codes_y (sample,)
                          int ADC codes of every point back to back, @scale_factor (V per code)
                          @volts_per_unit; first_sample, samples (point,): where each point is
      model/              NXcollection @model_info_json (which model ran and why)
      instrument/antialias NXcollection: sos (section, coefficient), @kind @order ...
      settings/           NXcollection @settings_json (the sweep's settings)
      scene/              NXcollection: settings_json (the resolved scene)

Public API: :class:`SineFileSink`, :func:`read_sine`, :func:`read_sine_records`,
:func:`is_sine_file`, :func:`sine_info`, :data:`FORMAT`.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import h5py
import numpy as np

from daq.acquisition import utc_now_iso
from daq.hdf5 import LIBVER, RUN_SUFFIXES, attr_value
from rig.output_files import check_writable, software_version, umask_mode
from rig.errors import ConfigError

FORMAT = "pendulum-daq sine"
FORMAT_VERSION = "1.0"
_STATUS_LEN = 16


def _json(value) -> str:
    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        return repr(o)

    return json.dumps(value, default=default)


class SineFileSink:
    """Writes a sweep (:func:`processing.sine_sweep.measure_sine`'s sinks protocol:
    ``start(info)``, ``point(row, record)``, ``stop(status)``) into a sine run file.

    Parameters
    ----------
    path : the file (.h5, .hdf5 or .nxs); never replaced without ``force``.
    force : replace an existing file (when the sweep stops).
    keep_records : also store every point's ADC codes (``entry/records``).
    """

    critical = True

    def __init__(self, path, *, force: bool = False, keep_records: bool = False):
        self.target = Path(path)
        self.force, self.keep = bool(force), bool(keep_records)
        self.path: Path | None = None
        self._f = None

    def check(self) -> None:
        """Refuse an unusable output before any work (:func:`rig.output_files.check_writable`)."""
        path = check_writable(self.target, force=self.force)
        if path.suffix.lower() not in RUN_SUFFIXES:
            raise ConfigError(f"--out {str(path)!r}: unknown extension {path.suffix!r}; "
                              f"a sine run file is HDF5: expected {', '.join(RUN_SUFFIXES)}")

    def start(self, info: dict) -> None:
        self.check()
        fd, tmp = tempfile.mkstemp(prefix=f".{self.target.stem}.partial-",
                                   suffix=self.target.suffix, dir=self.target.parent)
        os.close(fd)
        os.chmod(tmp, umask_mode())
        self.path = Path(tmp)
        self._f = h5py.File(self.path, "w", libver=LIBVER)
        self._n, self._samples = 0, 0
        try:
            self._layout(info)
            self._f.swmr_mode = True
            self._f.flush()
        except BaseException:
            self._f.close()
            self.path.unlink()
            raise

    def _layout(self, info: dict) -> None:
        f = self._f
        scene, columns, harmonics = info["scene"], info["columns"], int(info["harmonics"])
        for k, v in {"NX_class": "NXroot", "default": "entry", "file_format": FORMAT,
                     "file_format_version": FORMAT_VERSION,
                     "creator": f"pendulum-daq {software_version()}",
                     "HDF5_Version": h5py.version.hdf5_version}.items():
            f.attrs[k] = v
        e = f.create_group("entry")
        st = info["settings"]
        mode = str(info.get("mode", "stepped"))
        for k, v in {"NX_class": "NXentry", "default": "sweep",
                     "title": f"{scene.name}: {mode} sine {st['fmin_hz']:g}-{st['fmax_hz']:g} "
                              f"Hz, seed {info['seed']}", "mode": mode,
                     "start_time": utc_now_iso(), "seed": np.int64(info["seed"]),
                     "software_version": software_version(), "scene_name": scene.name,
                     "file_format_version": FORMAT_VERSION}.items():
            e.attrs[k] = v
        if "sweep_s" in info:
            e.attrs["sweep_s"] = float(info["sweep_s"])
        self._status = e.create_dataset("status", data=np.bytes_(b"acquiring"),
                                        dtype=f"S{_STATUS_LEN}")
        self._complete = e.create_dataset("points_complete", data=np.int64(0))
        g = e.create_group("sweep")
        g.attrs.update({"NX_class": "NXdata", "signal": "h_t_gain_db", "axes": "point"})
        point = g.create_dataset("point", shape=(0,), maxshape=(None,), dtype=np.int64,
                                 chunks=(64,), fletcher32=True)
        point.make_scale("point")
        point.attrs.update({"units": "1", "long_name": "point index, in the sweep's order"})
        harm = g.create_dataset("harmonic", data=np.arange(1, harmonics + 1, dtype=np.int64))
        harm.make_scale("harmonic")
        harm.attrs.update({"units": "1", "long_name": "harmonic number k (k f)"})
        self._grow = {"point": point}
        for name, (unit, long_name, per_harmonic) in columns.items():
            shape = (harmonics,) if per_harmonic else ()
            ds = g.create_dataset(name, shape=(0,) + shape, maxshape=(None,) + shape,
                                  dtype=np.float64, chunks=(64,) + shape, fletcher32=True)
            ds.dims[0].attach_scale(point)
            if per_harmonic:
                ds.dims[1].attach_scale(harm)
            ds.attrs.update({"units": unit, "long_name": long_name})
            self._grow[name] = ds
        if self.keep:
            r = e.create_group("records")
            r.attrs["NX_class"] = "NXcollection"
            sample = r.create_dataset("sample", shape=(0,), maxshape=(None,), dtype=np.int64,
                                      chunks=(4096,), fletcher32=True)
            sample.make_scale("sample")
            sample.attrs.update({"units": "1", "long_name": "output sample from the sweep's "
                                                            "start, at the output rate"})
            self._sample_scale = sample
            self._codes = {}
            for c in info["channels"]:
                ds = r.create_dataset(f"codes_{c.name}", shape=(0,), maxshape=(None,),
                                      dtype=c.adc.dtype, chunks=(4096,), fletcher32=True,
                                      compression="gzip", compression_opts=1, shuffle=True)
                ds.dims[0].attach_scale(sample)
                ds.attrs.update({"units": "1", "long_name": f"ADC codes of channel {c.name}",
                                 "scale_factor": c.adc.lsb_v, "add_offset": c.adc.offset_v,
                                 "volts_per_unit": c.volts_per_unit,
                                 "engineering_unit": c.unit})
                self._codes[c.name] = ds
            rp = r.create_dataset("point", shape=(0,), maxshape=(None,), dtype=np.int64,
                                  chunks=(64,), fletcher32=True)
            rp.make_scale("point")
            rp.attrs.update({"units": "1", "long_name": "point index, in the sweep's order"})
            self._grow["records/point"] = rp
            for name, what in (("first_sample", "first output sample of the point"),
                               ("samples", "output samples of the point")):
                ds = r.create_dataset(name, shape=(0,), maxshape=(None,), dtype=np.int64,
                                      chunks=(64,), fletcher32=True)
                ds.dims[0].attach_scale(rp)
                ds.attrs.update({"units": "1", "long_name": what})
                self._grow[f"records/{name}"] = ds
        m = e.create_group("model")
        m.attrs.update({"NX_class": "NXcollection", "model": info["model"]["model"],
                        "model_info_json": _json(info["model"])})
        inst = e.create_group("instrument")
        inst.attrs["NX_class"] = "NXinstrument"
        aa = inst.create_group("antialias")
        aa.attrs["NX_class"] = "NXcollection"
        for k, v in info["antialias"].describe().items():
            aa.attrs[k] = attr_value(v)
        sos_v = np.asarray(info["antialias"].sos, dtype=np.float64)
        sec = aa.create_dataset("section", data=np.arange(1, sos_v.shape[0] + 1, dtype=np.int64))
        sec.make_scale("section")
        sec.attrs["long_name"] = "second-order section (1-based, applied in order)"
        coef = aa.create_dataset("coefficient", data=np.array(
            ["b0", "b1", "b2", "a0", "a1", "a2"], dtype=h5py.string_dtype()))
        coef.make_scale("coefficient")
        coef.attrs["long_name"] = "coefficient of a section"
        sos = aa.create_dataset("sos", data=sos_v)
        sos.dims[0].attach_scale(sec)
        sos.dims[1].attach_scale(coef)
        sos.attrs.update({"units": "1", "long_name": "second-order sections of the anti-alias "
                                                     "filter at the simulation rate"})
        s = e.create_group("settings")
        s.attrs.update({"NX_class": "NXcollection", "settings_json": _json(st),
                        "worst_hz": info["worst_hz"]})
        sc = e.create_group("scene")
        sc.attrs.update({"NX_class": "NXcollection", "name": scene.name})
        sc.create_dataset("settings_json", data=_json(scene.settings),
                          dtype=h5py.string_dtype())

    def point(self, row: dict, record=None) -> None:
        """Append one point: ``row`` maps every column to its value (a number, or (harmonic,)
        values); ``record`` (a :class:`daq.sine.PointRecord`) gives the codes if kept."""
        k = self._n
        for name, ds in self._grow.items():
            if name.startswith("records/"):
                continue
            ds.resize(k + 1, axis=0)
            ds[k] = k if name == "point" else row[name]
        if self.keep and record is not None:
            m = next(iter(record.codes.values())).size
            s0 = self._samples
            for c, ds in self._codes.items():
                ds.resize(s0 + m, axis=0)
                ds[s0:] = record.codes[c]
            self._sample_scale.resize(s0 + m, axis=0)
            self._sample_scale[s0:] = np.arange(s0, s0 + m)
            for name, v in (("records/point", k), ("records/first_sample", s0),
                            ("records/samples", m)):
                ds = self._grow[name]
                ds.resize(k + 1, axis=0)
                ds[k] = v
            self._samples += m
        self._f.flush()
        self._n = k + 1
        self._complete[()] = np.int64(self._n)
        self._complete.flush()

    def stop(self, status: str) -> None:
        if self._f is None:
            return
        try:
            self._status[()] = np.bytes_(status.encode()[:_STATUS_LEN])
            self._f.flush()
        finally:
            self._f.close()
            self._f = None
        if self._n == 0:
            self.path.unlink()
            self.path = None
            return
        if self.target.exists() and not self.force:
            return  # appeared meanwhile: the sweep stays in its partial file
        os.replace(self.path, self.target)
        self.path = self.target


def read_sine(path) -> dict:
    """A sine run file's points as plain arrays: ``{"status", "points", "mode", "columns": {name:
    array}, "units": {name: unit}, "model_info", "settings", "scene_settings"}`` (the
    ``points_complete`` finished points only)."""
    from daq.repair import open_hdf5

    f, _ = open_hdf5(path)
    with f:
        if str(f.attrs.get("file_format", "")) != FORMAT:
            raise ConfigError(f"{str(path)!r} is not a sine run file (file_format "
                              f"{f.attrs.get('file_format', '')!r}, expected {FORMAT!r})")
        e = f["entry"]
        n = int(e["points_complete"][()])
        g = e["sweep"]
        cols = {k: g[k][:n] for k in g if k not in ("point", "harmonic")}
        units = {k: str(g[k].attrs.get("units", "")) for k in cols}
        return {"status": e["status"][()].decode().strip("\x00 "), "points": n,
                "mode": str(e.attrs.get("mode", "stepped")),
                "columns": cols, "units": units, "harmonic": g["harmonic"][()],
                "model_info": json.loads(e["model"].attrs["model_info_json"]),
                "settings": json.loads(e["settings"].attrs["settings_json"]),
                "scene_settings": json.loads(e["scene"]["settings_json"][()])}


def sine_info(path) -> dict:
    """What ``daq inspect`` shows of a sine run file (JSON-ready): format, scene, seed, mode,
    status, points, band, bench time, model and the settings (a file written before the mode
    was recorded is stepped)."""
    d = read_sine(path)
    from daq.repair import open_hdf5

    f, _ = open_hdf5(path)
    with f:
        e = f["entry"]
        head = {k: (v.item() if isinstance(v, np.generic) else str(v))
                for k, v in e.attrs.items() if k != "NX_class"}
        version = str(f.attrs.get("file_format_version", ""))
        kept = "records" in e
    c = d["columns"]
    f_hz = c.get("frequency", np.zeros(0))
    bench = float(np.sum(c.get("settle_s", 0)) + np.sum(c.get("integrate_s", 0)))
    if head.get("mode") == "swept":  # windows overlap: the sweep's own duration
        bench = float(head.get("sweep_s", bench))
    return {"path": str(path), "file_format": FORMAT, "file_format_version": version,
            "mode": "stepped", **head, "status": d["status"], "points": d["points"],
            "fmin_hz": float(f_hz.min()) if f_hz.size else None,
            "fmax_hz": float(f_hz.max()) if f_hz.size else None,
            "bench_s_accepted_points": bench, "records_kept": kept,
            "model": d["model_info"], "settings": d["settings"]}


def read_sine_records(path, *, tail=None) -> dict | None:
    """The kept ADC records of a sine run file's finished points, in volts, or None when the
    file keeps none: ``{"volts": {channel: [(samples,) array per point]}, "samples": (points,)
    whole samples of each point, "volts_per_unit": {channel: V per unit}, "units": {channel:
    engineering unit}}``. ``tail(k)`` is how many samples to read from the end of point k
    (default: all of it); volts are ``code * scale_factor + add_offset`` (the codes' own
    attributes)."""
    from daq.repair import open_hdf5

    f, _ = open_hdf5(path)
    with f:
        e = f["entry"]
        if "records" not in e:
            return None
        n = int(e["points_complete"][()])
        r = e["records"]
        n = min(n, r["first_sample"].shape[0], r["samples"].shape[0])
        first, samples = r["first_sample"][:n], r["samples"][:n]
        out = {"volts": {}, "samples": samples, "volts_per_unit": {}, "units": {}}
        for name in sorted(k for k in r if k.startswith("codes_")):
            ds, c = r[name], name[len("codes_"):]
            lsb, offset = float(ds.attrs["scale_factor"]), float(ds.attrs["add_offset"])
            parts = []
            for k in range(n):
                m = int(samples[k]) if tail is None else min(int(samples[k]), int(tail(k)))
                end = int(first[k] + samples[k])
                parts.append(ds[end - m:end].astype(np.float64) * lsb + offset)
            out["volts"][c] = parts
            out["volts_per_unit"][c] = float(ds.attrs["volts_per_unit"])
            out["units"][c] = str(ds.attrs.get("engineering_unit", ""))
        return out


def is_sine_file(path) -> bool:
    """True when ``path`` is an HDF5 file of this format (False for any other file, and for one
    that does not open: the run file's reader then says why)."""
    from daq.repair import open_hdf5

    try:
        f, _ = open_hdf5(path)
    except (ConfigError, OSError):
        return False
    with f:
        return str(f.attrs.get("file_format", "")) == FORMAT
