"""The run file: a self-describing HDF5 (NeXus-style) file written record by record.

Readable without this package: every group has an ``NX_class``; ``default`` attributes lead from
the root to the raw channels (``/entry/data``, an NXdata); every array has dimension scales with
``units`` and ``long_name``, so ``xarray.open_dataset(path, group="entry/data",
engine="h5netcdf")`` returns labelled arrays (also for ``entry/truth``, ``entry/clipping`` and
``entry/model``). The layout (groups, datasets, attributes and their units, format version
:data:`FORMAT_VERSION`) is drawn in docs/run-file.md; :func:`read_run` and :func:`run_info` are its
reader, :class:`Hdf5Sink` its writer.

Writing
-------
The file is created with the HDF5 1.10 format bounds (:data:`LIBVER`: SWMR, readable by HDF5
1.10, 1.14 and 2.0); every chunked dataset carries a fletcher32 checksum per chunk (a record of a
channel is one chunk), verified whenever it is read (:func:`daq.check.check_file`); after every dataset and attribute exists it switches
to SWMR mode, so a reader can follow it while it grows (``h5py.File(path, "r", swmr=True)``,
``refresh()`` the datasets). Each finished record is appended (datasets resized by one row) and
flushed, then ``records_complete`` is updated and flushed: a follower reads ``records_complete``
first, then refreshes the data, and finds at least that many complete rows. An interrupted run (KeyboardInterrupt, an
exception) closes the file with status "interrupted"/"failed" and every finished record. If the
process is killed, the file stays valid with every flushed record and status "acquiring", but
HDF5 marks it "open for writing": SWMR readers (and :func:`open_run`) read it as it is; others
need the mark cleared first (``h5clear -s FILE`` or :func:`daq.repair.clear_write_flags`, ``daq inspect
--repair``).

An existing file is never overwritten without ``force``; with ``force`` the new run is written
beside it (``<stem>.partial-XXXX<suffix>``) and replaces it only when complete; an incomplete
run stays in that partial file (deleted if it holds no record).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import h5py
import numpy as np

from daq import run_layout as layout
from daq.antialias import AntiAliasFilter
from daq.channels import Channel
from daq.records import (Footer, Header, ModelResponse, Record, RecordPlan, Recording, STATUSES,
                         TruthField)
from daq.repair import open_hdf5, write_flags, writer_alive
from daq.sinks import Sink
from rig.output_files import check_writable, not_a_file, umask_mode
from rig.errors import ConfigError
from rig.model_info import ModelInfo

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

FORMAT = "pendulum-daq run"
#: 1.1: HDF5 1.10 format bounds, fletcher32 on every chunked dataset, the anti-alias sections
#: as the dataset entry/instrument/antialias/sos (1.0: an attribute). 1.2: the model info's
#: text names the current modules (rig.solvers, rig.solvers.coupled, rig.bench.fused,
#: rig.describe); the layout is 1.1's. All three are read.
FORMAT_VERSION = "1.2"
READABLE_FORMAT_VERSIONS = ("1.0", "1.1", "1.2")
RUN_SUFFIXES = (".h5", ".hdf5", ".nxs")
#: HDF5 format bounds of every file the project writes: the oldest that has SWMR (superblock
#: v3, HDF5 1.10), so HDF5 1.10 and 1.14 read the files too ("latest" under HDF5 2.0 writes a
#: layout message 1.x cannot read).
LIBVER = ("v110", "v110")
_STATUS_LEN, _MESSAGE_LEN = 16, 512
_SOS_COEFFICIENTS = ("b0", "b1", "b2", "a0", "a1", "a2")
_STR = h5py.string_dtype()


def _fixed(text: str, n: int) -> np.bytes_:
    return np.bytes_(text.encode("utf-8")[:n])


def attr_value(value, *, list_dtype=None):
    """A value h5py and netCDF readers both understand: bools as 0/1, None as "", a list of
    strings as a string array, another list as an array (of ``list_dtype`` if given), a dict as
    JSON (numpy values as numbers, paths as text)."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, str) for v in value):
            return np.array(value, dtype=_STR)
        return np.asarray(value, dtype=list_dtype)
    if isinstance(value, dict):
        return json.dumps(value, default=_json_default)
    return value


_attr = attr_value


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return repr(o)


def _without_timings(d: dict) -> dict:
    """The model info without wall-clock timings (``*wall_time*`` keys): they differ between
    identical runs, and files of the same seed are identical apart from ``start_time``."""
    return {k: _without_timings(v) if isinstance(v, dict) else v for k, v in d.items()
            if "wall_time" not in k}


def _flat_scalars(d: dict, prefix: str = "") -> dict:
    """Scalar entries of a nested dict, keys joined by dots (``error_estimate.max_abs...``)."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat_scalars(v, f"{prefix}{k}."))
        elif isinstance(v, (str, int, float, bool, np.generic)) and not (
                isinstance(v, int) and not isinstance(v, bool) and not -2**63 <= v < 2**63):
            out[f"{prefix}{k}"] = v
    return out


def _set_attrs(obj, d: dict) -> None:
    for k, v in d.items():
        obj.attrs[k] = _attr(v)


def _group(parent, name: str, nx_class: str, /, **attrs):
    g = parent.create_group(name)
    g.attrs["NX_class"] = nx_class
    _set_attrs(g, attrs)
    return g


class Hdf5Sink(Sink):
    """Writes the stream into an HDF5 run file (see the module docstring).

    Parameters
    ----------
    path : the file to write.
    force : allow replacing an existing file (only once the new run is complete).
    compression_level : gzip level (with shuffle) of the channels and the clip and saturation
        flags; 1 (default): files slightly larger than at level 4 for less CPU writing them
        (BENCHMARKS.md has both figures).
    truth_compression_level : gzip level of the truth; 0 (default): none -- float64 samples of
        noise-driven signals shrink little for the CPU their compression costs.

    After :meth:`stop`, :attr:`path` is the file that holds the run (None if none was kept).
    """

    critical = True

    def __init__(self, path: str | Path, *, force: bool = False, compression_level: int = 1,
                 truth_compression_level: int = 0):
        self.target = Path(path)
        self.force = force
        self.level, self.truth_level = compression_level, truth_compression_level
        self.path: Path | None = None
        self._f = None
        self._tmp = None
        self._lock = None
        self._n = 0
        self._rows: dict = {}
        self._extents = None

    # -- stream ---------------------------------------------------------------------------
    def check(self) -> None:
        """Refuse an output that exists (without ``force``), is a directory or is in a missing
        or read-only directory (:func:`rig.output_files.check_writable`), or that is not named as a
        run file (:data:`RUN_SUFFIXES`)."""
        path = check_writable(self.target, force=self.force)
        if path.suffix.lower() not in RUN_SUFFIXES:
            raise ConfigError(f"run file {str(path)!r}: unknown extension {path.suffix!r}; "
                              f"a run file is HDF5: expected {', '.join(RUN_SUFFIXES)}")

    def start(self, header: Header) -> None:
        self.check()
        target = self.target
        # a sink may write another run (with force): the per-run state anew, the row shapes
        # keyed by HDF5 ids that the new file may reuse
        self._tmp, self._n, self._extents, self._rows = None, 0, None, {}
        if os.path.lexists(target):  # a file, or a link (dangling: replaced by the file)
            if target.exists():
                self._hold_target(target)
            fd, tmp = tempfile.mkstemp(prefix=f"{target.stem}.partial-", suffix=target.suffix,
                                       dir=target.parent)
            os.close(fd)
            os.chmod(tmp, umask_mode())
            self._tmp = Path(tmp)
            self._f = h5py.File(self._tmp, "w", libver=LIBVER)
        else:
            self._f = h5py.File(target, "x", libver=LIBVER)
        self.path = self._tmp or target
        self._header = header
        try:
            self._layout(header)
            self._f.swmr_mode = True
            self._f.flush()
        except BaseException:
            self._f.close()
            self._f = None
            self.path.unlink()
            self.path = None
            self._release_target()
            raise
        if fcntl is not None:  # tells clear_write_flags that the writer is alive
            self._lock = open(self.path, "rb")
            fcntl.flock(self._lock, fcntl.LOCK_SH)

    def _hold_target(self, target: Path) -> None:
        """Lock the file a ``force`` run replaces for the run's duration; refuse if another
        process holds it (a run writing it, or one replacing it)."""
        self._target_lock = None
        if fcntl is None:  # pragma: no cover - not POSIX
            return
        fh = open(target, "rb")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise ConfigError(f"output {str(target)!r} is held by another process (a run "
                              "writing or replacing it); wait for it to end or choose another "
                              "path") from None
        self._target_lock = fh

    def _release_target(self) -> None:
        fh = getattr(self, "_target_lock", None)
        if fh is not None:
            fh.close()
            self._target_lock = None

    def _flag_collection(self, f, group: str, n: int, count_name: str, what: str):
        """An NXcollection of per-sample uint8 flags per channel and their counts per record."""
        names = self._header.names
        g = _group(f, group, "NXcollection")
        grec, gtim = self._scales(g, n)
        chan = g.create_dataset("channel", data=np.array(names, dtype=_STR), track_times=False)
        chan.make_scale("channel")
        chan.attrs["long_name"] = "channel name"
        count = g.create_dataset(layout.COUNT, shape=(0, len(names)),
                                 maxshape=(None, len(names)), dtype=np.int64,
                                 chunks=(64, len(names)), fletcher32=True, track_times=False)
        count.dims[0].attach_scale(grec)
        count.dims[1].attach_scale(chan)
        _set_attrs(count, {"long_name": count_name, "units": "1"})
        self._grow.append(count)
        flags = {c: self._series(g, c, (n,), np.uint8, grec, gtim, self.level,
                                 long_name=f"1 where channel {c} {what}", units="1")
                 for c in names}
        return count, flags

    def record(self, record: Record) -> None:
        k = record.index
        if k != self._n:
            raise ValueError(f"record {k} arrives out of order (expected {self._n})")
        self._extend(k + 1)
        put = self._put_row
        for rec in self._record_scales:
            put(rec, k, k)
        put(self._rec_start, k, record.t0_s)
        names = self._header.names
        saturated = {c: record.saturated.get(c, np.zeros(len(record.codes[c]), bool))
                     for c in names}
        for name in names:
            put(self._codes[name], k, record.codes[name])
            put(self._flags[name], k, record.clipped[name])
            put(self._sat_flags[name], k, saturated[name])
        put(self._count, k, [np.count_nonzero(record.clipped[c]) for c in names])
        put(self._sat_count, k, [np.count_nonzero(saturated[c]) for c in names])
        for name, ds in self._truth.items():
            put(ds, k, record.truth[name])
        self._f.flush()  # the record (data and metadata) first ...
        self._n = k + 1
        self._records_complete[()] = self._n  # ... then the count a reader trusts
        self._f.flush()

    def _extend(self, rows: int) -> None:
        """Every growing dataset to ``rows`` rows, through HDF5's own call (cheaper than h5py's
        ``resize``: benchmarks/run_file_sink.py --replay); the same file."""
        if self._extents is None:  # each growing dataset's id and row shape, once
            self._extents = [(ds.id, ds.shape[1:]) for ds in self._grow]
        for dsid, tail in self._extents:
            dsid.set_extent((rows,) + tail)

    def _put_row(self, ds, k: int, value) -> None:
        """``ds[k] = value`` for a dataset growing along axis 0, through HDF5's own write with
        the row's shape and type known from the layout (h5py's general selection skipped: about
        half the sink's cost); the same values, the same bytes. TypeError for a row of another
        shape."""
        got = self._rows.get(ds.id.id)
        if got is None:
            shape = (1,) + ds.shape[1:]
            got = self._rows[ds.id.id] = (ds.dtype, shape, h5py.h5s.create_simple(shape))
        dtype, shape, mem = got
        arr = np.asarray(value, dtype=dtype)
        if arr.shape != shape[1:]:
            raise TypeError(f"{ds.name}: row {k} has the shape {arr.shape}; expected {shape[1:]}")
        row = np.ascontiguousarray(arr.reshape(shape))
        space = ds.id.get_space()
        space.select_hyperslab((k,) + (0,) * (len(shape) - 1), shape)
        ds.id.write(mem, space, row)

    def stop(self, footer: Footer) -> None:
        if self._f is None:
            return
        try:
            for ds in self._grow:  # a record cut short by an exception: drop its rows
                if ds.shape[0] != self._n:
                    ds.resize(self._n, axis=0)
            self._status[()] = _fixed(footer.status, _STATUS_LEN)
            self._message[()] = _fixed(footer.message, _MESSAGE_LEN)
            self._f.flush()
        finally:
            self._f.close()
            self._f = None
            if self._lock is not None:
                self._lock.close()
                self._lock = None
        if self._tmp is not None:
            try:
                if footer.status == "complete":
                    os.replace(self._tmp, self.target)
                    self.path = self.target
                elif self._n == 0:
                    self._tmp.unlink()
                    self.path = None
            finally:
                self._release_target()

    # -- layout ---------------------------------------------------------------------------
    def _layout(self, h: Header) -> None:
        f, plan = self._f, h.plan
        n = plan.samples
        f.attrs["NX_class"] = "NXroot"
        f.attrs["default"] = layout.ENTRY
        _set_attrs(f, {"creator": f"pendulum-daq {h.software_version}", "file_format": FORMAT,
                       "file_format_version": FORMAT_VERSION,
                       "HDF5_Version": h5py.version.hdf5_version,
                       "h5py_version": h5py.version.version})
        _group(f, layout.ENTRY, "NXentry", default=layout.name_of(layout.DATA),
               title=f"{h.scene.name}: {plan.records} records x {plan.record_s:g} s at "
                     f"{plan.rate_hz:g} Hz, seed {h.seed}",
               start_time=h.start_time, seed=np.int64(h.seed), software="pendulum-daq",
               software_version=h.software_version, file_format_version=FORMAT_VERSION,
               scene_name=h.scene.name,
               status_note="status and records_complete are updated as the run "
                           "proceeds; any status but 'complete' means incomplete")
        self._status = f.create_dataset(layout.STATUS, data=_fixed("acquiring", _STATUS_LEN),
                                        dtype=f"S{_STATUS_LEN}", track_times=False)
        self._status.attrs["long_name"] = "run status: " + " | ".join(STATUSES)
        self._records_complete = f.create_dataset(layout.RECORDS_COMPLETE, data=np.int64(0),
                                                  track_times=False)
        self._records_complete.attrs["long_name"] = "records fully written"
        f.create_dataset(layout.RECORDS_PLANNED, data=np.int64(plan.records),
                         track_times=False).attrs["long_name"] = "records requested"
        self._message = f.create_dataset(layout.MESSAGE, data=_fixed("", _MESSAGE_LEN),
                                         dtype=f"S{_MESSAGE_LEN}", track_times=False)
        self._message.attrs["long_name"] = "why the run stopped early"
        self._grow, self._record_scales = [], []

        # raw channels
        data = _group(f, layout.DATA, "NXdata", signal=h.names[0],
                      auxiliary_signals=list(h.names[1:]), axes=["record", "time"],
                      record_indices=0, time_indices=1)
        rec, tim = self._scales(data, n)
        self._rec_start = self._series(data, layout.RECORD_START, (), np.float64, rec, tim,
                                       None, units="s",
                                       long_name="time of the record's first sample from the "
                                                 "start of the run (settling included)")
        self._codes = {}
        for c in h.channels:
            d = c.describe()
            adc = c.adc
            attrs = {"long_name": c.long_name, "units": "V",
                     "scale_factor": adc.lsb_v, "add_offset": adc.offset_v,
                     "quantity": c.quantity, "engineering_unit": c.unit,
                     "volts_per_unit": c.volts_per_unit, "units_per_volt": c.units_per_volt,
                     "calibration": f"{c.quantity} [{c.unit}] = (code * {adc.lsb_v!r} + "
                                    f"{adc.offset_v!r}) / {c.volts_per_unit!r}",
                     **{k: v for k, v in d.items() if k not in ("long_name", "unit", "name")}}
            self._codes[c.name] = self._series(data, c.name, (n,), adc.dtype, rec, tim,
                                               self.level, **attrs)
        # per-sample flags: ADC clipping and sensor saturation
        self._count, self._flags = self._flag_collection(
            f, layout.CLIPPING, n, "clipped samples per record and channel", "clipped")
        self._sat_count, self._sat_flags = self._flag_collection(
            f, layout.SATURATION, n, "samples per record and channel whose sensor saturated",
            "saw its sensor beyond its range since the previous sample")

        # truth
        self._truth = {}
        if h.truth:
            signal = "mirror_x_m" if any(t.name == "mirror_x_m" for t in h.truth) \
                else h.truth[0].name
            tg = _group(f, layout.TRUTH, "NXdata", signal=signal, axes=["record", "time"],
                        record_indices=0, time_indices=1,
                        note="sampled at the channels' instants without anti-alias filter, "
                             "sensor or ADC")
            trec, ttim = self._scales(tg, n)
            extra = {}
            for t in h.truth:
                for dim, size in zip(t.dims, t.shape):
                    if dim not in extra:
                        s = tg.create_dataset(dim, data=np.arange(1, size + 1, dtype=np.int64),
                                              track_times=False)
                        s.make_scale(dim)
                        s.attrs["long_name"] = "body (1-based)" if dim == "body" else dim
                        extra[dim] = s
                self._truth[t.name] = self._series(
                    tg, t.name, (n,) + t.shape, np.float64, trec, ttim, self.truth_level,
                    extra=[extra[d] for d in t.dims], units=t.unit, long_name=t.long_name)

        # model response
        info = _without_timings(h.model_info.to_dict())
        m = _group(f, layout.MODEL, "NXcollection",
                   model_info_json=json.dumps(info, default=_json_default),
                   **_flat_scalars(info))
        fr = m.create_dataset(layout.FREQUENCY, data=h.response.freqs_hz, track_times=False)
        fr.make_scale(layout.FREQUENCY)
        _set_attrs(fr, {"units": "Hz", "long_name": "frequency (the record's FFT grid)"})
        for name, v in h.response.values.items():
            for part, arr in (("real", v.real), ("imag", v.imag)):
                ds = m.create_dataset(f"{name}_{part}", data=arr, track_times=False)
                ds.dims[0].attach_scale(fr)
                _set_attrs(ds, {"units": h.response.units.get(name, ""),
                                "long_name": f"{part} part of "
                                             f"{h.response.long_names.get(name, name)}"})

        # instrument
        _group(f, layout.INSTRUMENT, "NXinstrument")
        aa = _group(f, layout.ANTIALIAS, "NXcollection", **h.antialias.describe())
        sos_v = np.asarray(h.antialias.sos, dtype=np.float64)
        sec = aa.create_dataset("section", data=np.arange(1, sos_v.shape[0] + 1, dtype=np.int64),
                                track_times=False)
        sec.make_scale("section")
        sec.attrs["long_name"] = "second-order section (1-based, applied in order)"
        coef = aa.create_dataset("coefficient", data=np.array(_SOS_COEFFICIENTS, dtype=_STR),
                                 track_times=False)
        coef.make_scale("coefficient")
        coef.attrs["long_name"] = "coefficient of a section"
        sos = aa.create_dataset("sos", data=sos_v, track_times=False)
        sos.dims[0].attach_scale(sec)
        sos.dims[1].attach_scale(coef)
        _set_attrs(sos, {"units": "1", "long_name": "second-order sections of the anti-alias "
                                                    "filter at fs_hz"})
        aa.attrs["description"] = ("digital elliptic low-pass in second-order sections at the "
                                   "simulation rate, then decimation; H(f) = prod_k (b0 + b1 z^-1 "
                                   "+ b2 z^-2) / (1 + a1 z^-1 + a2 z^-2), z = exp(2 pi i f / fs)")
        _group(f, layout.ACQUISITION, "NXcollection", **plan.describe())

        _group(f, layout.SCENE, "NXcollection", name=h.scene.name, source=h.scene.origin,
               description=h.scene.description)
        js = f.create_dataset(layout.SCENE_SETTINGS,
                              data=json.dumps(h.scene.settings, sort_keys=True), dtype=_STR,
                              track_times=False)
        js.attrs["long_name"] = "resolved scene settings (rig.scene.scene_from_settings)"

    def _scales(self, g, n: int):
        rec = g.create_dataset(layout.RECORD, shape=(0,), maxshape=(None,), dtype=np.int64,
                               chunks=(256,), fletcher32=True, track_times=False)
        rec.make_scale(layout.RECORD)
        _set_attrs(rec, {"long_name": "record index", "units": "1"})
        tim = g.create_dataset(layout.TIME, data=self._header.plan.times_s(), track_times=False)
        tim.make_scale(layout.TIME)
        _set_attrs(tim, {"long_name": "time within the record", "units": "s"})
        self._grow.append(rec)
        self._record_scales.append(rec)
        return rec, tim

    def _series(self, g, name, row_shape, dtype, rec, tim, level, /, extra=(), **attrs):
        shape = tuple(row_shape)
        kw = dict(compression="gzip", compression_opts=level, shuffle=True) if level else {}
        ds = g.create_dataset(name, shape=(0,) + shape, maxshape=(None,) + shape, dtype=dtype,
                              chunks=(1,) + shape if shape else (256,), fletcher32=True,
                              track_times=False, **kw)
        ds.dims[0].attach_scale(rec)
        if shape:
            ds.dims[1].attach_scale(tim)
        for i, s in enumerate(extra):
            ds.dims[2 + i].attach_scale(s)
        _set_attrs(ds, attrs)
        self._grow.append(ds)
        return ds


# -- reading ---------------------------------------------------------------------------------

def mark_interrupted(path: str | Path) -> int | None:
    """Mark a run file a killed writer left ("acquiring", no writer alive, its open-for-writing
    mark cleared: :func:`daq.repair.clear_write_flags`) as "interrupted", with a message saying
    so; its records are untouched. Returns the number of finished records it holds, or None if
    it was not such a file (another status). Raises ConfigError while a writer is alive."""
    path = Path(path)
    if writer_alive(path):
        raise ConfigError(f"{str(path)!r} is still being written (its writer holds a lock); "
                          "not marking it")
    with h5py.File(path, "r+") as f:
        if f.attrs.get("file_format") != FORMAT:
            return None
        status, n = run_status(f)
        if status != "acquiring":
            return None
        f[layout.STATUS][()] = _fixed("interrupted", _STATUS_LEN)
        f[layout.MESSAGE][()] = _fixed(
            f"the writer stopped without closing the file (killed) after {n} finished records; "
            "marked interrupted on repair, its records kept", _MESSAGE_LEN)
    return n


@contextlib.contextmanager
def open_run(path: str | Path):
    """Open a run file read-only; a file still marked open for writing (a live or killed writer)
    is opened as a SWMR reader. A truncated or unreadable file is a ConfigError at once
    (:func:`daq.repair.open_hdf5`: never a retry in SWMR mode, which can wait for minutes)."""
    path = Path(path)
    why = not_a_file(path)
    if why is not None:
        raise ConfigError(f"run file {str(path)!r} {why}")
    f, _ = open_hdf5(path)
    try:
        if f.attrs.get("file_format") != FORMAT:
            raise ConfigError(f"{str(path)!r} is not a pendulum-daq run file (no "
                              f"file_format = {FORMAT!r} attribute)")
        yield f
    finally:
        f.close()


def attr_text(v) -> str:
    """An HDF5 attribute or scalar dataset value as text: bytes decoded as UTF-8 (bad bytes
    replaced), a 0-d array unwrapped, anything else through ``str``."""
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.shape == ():
        return attr_text(v[()])
    return str(v)


def run_status(f) -> tuple[str, int]:
    """(the run's status without its padding, its finished records) of the open run file ``f``
    (:data:`daq.run_layout.STATUS`, ``RECORDS_COMPLETE``): what a reader polling a growing
    file needs, without reading any data."""
    return attr_text(f[layout.STATUS][()]).strip("\x00 "), int(f[layout.RECORDS_COMPLETE][()])


def run_info(path: str | Path) -> dict:
    """What a run file holds, as plain data (no sample data is read; used by ``daq inspect``)."""
    path = Path(path)
    with open_run(path) as f:
        e = f[layout.ENTRY]
        status, n = run_status(f)
        data = f[layout.DATA]
        names = [data.attrs["signal"]] + [attr_text(s) for s in
                                          data.attrs.get("auxiliary_signals", [])]
        channels = []
        for c in names:
            a = dict(data[c].attrs)
            channels.append({k: (attr_text(v) if isinstance(v, (bytes, str)) else
                                 (v.item() if isinstance(v, np.generic) else v))
                             for k, v in a.items()
                             if k not in ("DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME")})
        counts = (f[layout.CLIPPING][layout.COUNT][:n] if layout.CLIPPING in f
                  else np.zeros((n, len(names)), int))
        sat = (f[layout.SATURATION][layout.COUNT][:n] if layout.SATURATION in f
               else np.zeros((n, len(names)), int))
        model = f[layout.MODEL]
        scene = f[layout.SCENE]
        info = {
            "path": str(path),
            "file_bytes": path.stat().st_size,
            "file_format": attr_text(f.attrs["file_format"]),
            "file_format_version": attr_text(f.attrs["file_format_version"]),
            "software_version": attr_text(e.attrs["software_version"]),
            "start_time": attr_text(e.attrs["start_time"]),
            "scene": attr_text(scene.attrs["name"]),
            "scene_source": attr_text(scene.attrs["source"]),
            "seed": int(e.attrs["seed"]),
            "status": status,
            "complete": status == "complete",
            "records_complete": n,
            "records_planned": int(f[layout.RECORDS_PLANNED][()]),
            "message": attr_text(f[layout.MESSAGE][()]).strip("\x00 "),
            "acquisition": {k: (v.item() if isinstance(v, np.generic) else v)
                            for k, v in f[layout.ACQUISITION].attrs.items()
                            if k != "NX_class"},
            "antialias": {k: (v.item() if isinstance(v, np.generic) else attr_text(v))
                          for k, v in f[layout.ANTIALIAS].attrs.items()
                          if k not in ("NX_class", "sos", "description")},
            "channels": channels,
            "clip_counts": {c: [int(x) for x in counts[:, i]] for i, c in enumerate(names)},
            "saturation_counts": {c: [int(x) for x in sat[:, i]] for i, c in enumerate(names)},
            "model_info": json.loads(attr_text(model.attrs["model_info_json"])),
            "truth": sorted(k for k, ds in f[layout.TRUTH].items() if ds.ndim >= 2)
            if layout.TRUTH in f else [],
            "responses": sorted(k[:-5] for k in model if k.endswith("_real")),
        }
        info["writer_flag_set"] = write_flags(path) not in (0, None)
    return info


def read_run(path: str | Path, records=None) -> Recording:
    """Read a run file back into a :class:`daq.records.Recording` (finished records only).

    ``records``: the indices of the finished records to read (default all), e.g.
    :attr:`daq.check.FileCheck.valid_records` to leave out records that fail their checksum.
    """
    from rig.scene import scene_from_settings

    with open_run(path) as f:
        e = f[layout.ENTRY]
        status, n = run_status(f)
        rows = slice(0, n)
        if records is not None:
            rows = np.unique(np.asarray(list(records), dtype=np.int64))
            if rows.size and not (0 <= rows[0] and rows[-1] < n):
                raise ConfigError(f"records {rows.tolist()} outside the {n} finished records "
                                  f"(0..{n - 1})")
            rows = rows if rows.size else slice(0, 0)
        settings = json.loads(attr_text(f[layout.SCENE_SETTINGS][()]))
        scene = scene_from_settings(settings, origin=attr_text(f[layout.SCENE].attrs["source"]))
        plan = RecordPlan.from_acquisition(scene.acquisition)
        data = f[layout.DATA]
        names = [attr_text(data.attrs["signal"])] + [attr_text(s) for s in
                                                     data.attrs["auxiliary_signals"]]
        channels = tuple(Channel.from_attrs(c, data[c].attrs) for c in names)
        ag = f[layout.ANTIALIAS]
        a = ag.attrs
        sos = np.array(ag["sos"][()] if "sos" in ag else a["sos"], dtype=float)  # 1.1 / 1.0
        sos.setflags(write=False)
        aa = AntiAliasFilter(fs_hz=float(a["fs_hz"]), rate_hz=float(a["rate_hz"]),
                             kind=attr_text(a["kind"]), passband_hz=float(a["passband_hz"]),
                             stopband_hz=float(a["stopband_hz"]), ripple_db=float(a["ripple_db"]),
                             attenuation_db=float(a["attenuation_db"]), order=int(a["order"]),
                             sos=sos)
        truth, truth_fields = {}, []
        if layout.TRUTH in f:
            tg = f[layout.TRUTH]
            for k in tg:
                ds = tg[k]
                if ds.ndim < 2 or k == layout.RECORD_START:
                    continue
                shape = ds.shape[2:]
                dims = tuple((list(ds.dims[2 + i].keys()) or [f"{k}_dim{i}"])[0]
                             for i in range(len(shape)))
                truth_fields.append(TruthField(k, attr_text(ds.attrs.get("units", "")),
                                               attr_text(ds.attrs.get("long_name", k)), shape,
                                               dims))
                truth[k] = ds[rows]
        m = f[layout.MODEL]
        values = {k[:-5]: m[k][()] + 1j * m[k[:-5] + "_imag"][()] for k in m
                  if k.endswith("_real")}
        response = ModelResponse(
            freqs_hz=m[layout.FREQUENCY][()], values=values,
            units={k: attr_text(m[k + "_real"].attrs.get("units", "")) for k in values},
            long_names={k: attr_text(m[k + "_real"].attrs.get("long_name", k))
                        [len("real part of "):] for k in values})
        header = Header(scene=scene, seed=int(e.attrs["seed"]), plan=plan, channels=channels,
                        antialias=aa, truth=tuple(truth_fields),
                        model_info=ModelInfo.from_dict(
                            json.loads(attr_text(m.attrs["model_info_json"]))),
                        response=response, software_version=attr_text(e.attrs["software_version"]),
                        start_time=attr_text(e.attrs["start_time"]))
        codes = {c: data[c][rows] for c in names}
        clipped = {c: f[layout.CLIPPING][c][rows].astype(bool) for c in names}
        saturated = ({c: f[layout.SATURATION][c][rows].astype(bool) for c in names}
                     if layout.SATURATION in f else {})
    return Recording(header=header, codes=codes, clipped=clipped, truth=truth, status=status,
                     saturated=saturated)
