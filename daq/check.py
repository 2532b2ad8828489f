"""Checking a file the project wrote: is it whole, and which of its records verify?

:func:`check_file` is the one check behind ``daq check``, ``daq inspect`` and ``daq analyze`` (and
any reader of many run files): it never raises for a bad file -- a bad file is a result, a
:class:`FileCheck` -- and it never hangs on one:

- the HDF5 superblock is read by hand first: a file shorter than the end-of-file address its
  superblock records is *truncated* (no HDF5 reader opens it), named as such without calling
  HDF5; only a file still marked "open for writing" (a live or killed writer) is opened as a
  SWMR reader, never after another open failed, and with
  :data:`daq.repair.SWMR_READ_ATTEMPTS` metadata read attempts (HDF5's default SWMR reader
  retries unreadable metadata with doubling sleeps for days; :func:`daq.repair.open_hdf5`);
- every object and attribute is read; every chunk's fletcher32 checksum is verified by reading
  it (a record of a run-file channel is one chunk), so a corrupt record is named with its index;
- a run file is checked against its own plan: format version, status, ``records_complete``
  against ``records_planned`` and the rows of every per-record dataset, the record plan of the
  stored scene against the datasets' shapes, the channels' calibrations (scale factor = LSB,
  volts per unit x units per volt = 1) and the scene rebuilt from its stored settings.

A file is ``ok`` when nothing in it is damaged or inconsistent; a run cut short by Ctrl-C, a
signal or a killed writer is ``ok`` (its status says so and :attr:`FileCheck.notes` explain) as
long as every record it counts verifies.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from daq import run_layout as layout
from daq.channels import Channel
from daq.hdf5 import READABLE_FORMAT_VERSIONS
from daq.records import STATUSES
from daq.repair import UnreadableFile, first_line, open_hdf5
from rig.output_files import not_a_file
from rig.errors import ConfigError

__all__ = ["FileCheck", "MissingFile", "check_file", "check_ok_or_raise"]

#: Statuses of a file that is not whole (besides a run's own: complete, interrupted, failed,
#: acquiring).
BAD_STATUSES = ("not hdf5", "truncated", "corrupt", "unreadable", "invalid")
_KINDS = {"pendulum-daq run": "run", "pendulum-daq spectra": "spectra",
          "pendulum-daq trajectory": "trajectory", "pendulum-daq dataset": "dataset",
          "pendulum-daq sine": "sine"}


class MissingFile(ConfigError, FileNotFoundError):
    """The path to check does not exist (or is not a file)."""


@dataclass(frozen=True)
class FileCheck:
    """What :func:`check_file` found.

    Attributes
    ----------
    path : the file checked.
    kind : "run", "spectra", "trajectory", "dataset" (the project's files, from the root's
        ``file_format``), "hdf5" (another HDF5 file) or "unknown" (not HDF5).
    ok : True if nothing is damaged or inconsistent (an incomplete run can be ok).
    status : a run's own status ("complete", "interrupted", "failed", "acquiring": writer
        killed or still running), "complete" for other whole files, or one of
        :data:`BAD_STATUSES` ("truncated", "corrupt": a checksum failed, "unreadable": HDF5
        cannot open it, "invalid": structure or plan inconsistent, "not hdf5").
    records_valid : records that verify (run files; None for other kinds).
    records_planned : records the run planned (run files; None for other kinds).
    format_version : the file's ``file_format_version`` (None if unknown).
    problems : one sentence per problem found (empty if ``ok``).
    notes : remarks that do not make the file bad (incomplete run, writer mark set ...).
    bad_records : indices (0-based) of counted records that fail to verify.
    """

    path: str
    kind: str
    ok: bool
    status: str
    records_valid: int | None
    records_planned: int | None
    format_version: str | None
    problems: tuple[str, ...]
    notes: tuple[str, ...] = ()
    bad_records: tuple[int, ...] = ()
    records_complete: int | None = None

    @property
    def valid_records(self) -> tuple[int, ...]:
        """Indices of the counted records that verify (run files)."""
        if self.records_complete is None:
            return ()
        bad = set(self.bad_records)
        return tuple(k for k in range(self.records_complete) if k not in bad)

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("problems", "notes", "bad_records"):
            d[k] = list(d[k])
        return d

    def line(self) -> str:
        """One line: ``PATH: OK|BAD kind status, records ..., version; first problem`` (or
        note), then how many more there are (all in :meth:`to_dict`)."""
        head = f"{self.path}: {'OK' if self.ok else 'BAD'} {self.kind}, {self.status}"
        if self.records_planned is not None:
            head += f", {self.records_valid} of {self.records_planned} records verify"
        if self.format_version is not None:
            head += f", format {self.format_version}"
        extra = self.problems or self.notes
        if extra:
            n, what = len(extra) - 1, "problem" if self.problems else "note"
            more = f" (and {n} more {what}{'s' if n > 1 else ''})" if n else ""
            head += f"; {extra[0]}{more}"
        return head


def check_file(path: str | Path) -> FileCheck:
    """Check ``path`` (see the module docstring). Never raises for a bad file; raises
    :class:`MissingFile` if ``path`` does not exist or is not a file."""
    path = Path(path)
    why = not_a_file(path)
    if why is not None:
        raise MissingFile(f"{str(path)!r} {why}; expected a run, spectra or trajectory file")
    c = _Checker(path)
    try:
        c.run()
    except Exception as exc:  # noqa: BLE001 - whatever breaks on a bad file is a finding
        if "checksum" in str(exc):
            c.problem("corrupt", f"its metadata fails a checksum ({first_line(exc)})")
        else:
            what = (f"no {exc.args[0]!r}" if isinstance(exc, KeyError) and exc.args
                    else first_line(exc))
            c.problem("invalid", f"unexpected structure ({what})")
    return c.result()


class _Checker:
    def __init__(self, path: Path):
        self.path = path
        self.kind = "unknown"
        self.status = None
        self.run_status = None
        self.version = None
        self.problems: list[str] = []
        self.notes: list[str] = []
        self.bad: set[int] = set()
        self.n = None
        self.planned = None
        self._severity = None

    def problem(self, status: str, text: str) -> None:
        order = BAD_STATUSES
        if self._severity is None or order.index(status) < order.index(self._severity):
            self._severity = status
        self.problems.append(text)

    def result(self) -> FileCheck:
        ok = not self.problems
        status = self._severity if not ok else (self.run_status or "complete")
        valid = None
        if self.kind == "run":
            valid = max(0, (self.n or 0) - len(self.bad))
        return FileCheck(path=str(self.path), kind=self.kind, ok=ok, status=status,
                         records_valid=valid,
                         records_planned=self.planned if self.kind == "run" else None,
                         format_version=self.version, problems=tuple(self.problems),
                         notes=tuple(self.notes), bad_records=tuple(sorted(self.bad)),
                         records_complete=self.n if self.kind == "run" else None)

    # -- opening ------------------------------------------------------------------------------
    def run(self) -> None:
        try:
            f, marked = open_hdf5(self.path)
        except UnreadableFile as exc:
            if exc.status != "not hdf5":
                self.kind = "hdf5"
            self.problem(exc.status, ("truncated: " if exc.status == "truncated" else "")
                         + exc.reason)
            return
        with f:
            fmt = _text(f.attrs.get("file_format", ""))
            self.kind = _KINDS.get(fmt, "hdf5")
            if "file_format_version" in f.attrs:
                self.version = _text(f.attrs["file_format_version"])
            if self.kind == "hdf5" and "trajectory" in f:  # trajectory files before 1.1
                self.kind = "trajectory"
            skip = set()
            if self.kind == "run":
                skip = self._run(f)
            elif self.kind == "sine":
                self._sine(f)
            self._everything(f, skip)
            if marked:
                self.notes.append("still marked open for writing (writer running or killed): "
                                  "read as SWMR; a repair clears the mark once the writer is gone")

    # -- every object -------------------------------------------------------------------------
    def _everything(self, f, skip: set) -> None:
        """Read every attribute and every dataset not verified per record already."""
        import h5py

        names = []

        def visit(name, obj):
            names.append(name)
            try:
                for k in obj.attrs:
                    obj.attrs[k]
            except (OSError, TypeError, ValueError) as exc:
                self.problem("corrupt", f"{name}: an attribute cannot be read "
                                        f"({first_line(exc)})")
            if isinstance(obj, h5py.Dataset) and name not in skip:
                try:
                    obj[()]
                except (OSError, TypeError, ValueError) as exc:
                    what = ("fails its checksum" if "filter" in str(exc) else "cannot be read")
                    self.problem("corrupt", f"{name} {what} ({first_line(exc)})")

        try:
            for k in f.attrs:
                f.attrs[k]
            f.visititems(visit)
        except (OSError, RuntimeError, KeyError) as exc:
            self.problem("corrupt", f"its object tree cannot be walked ({first_line(exc)})")

    # -- run files ----------------------------------------------------------------------------
    def _run(self, f) -> set:
        """The run-file checks; returns the per-record datasets it verified itself."""

        if self.version not in READABLE_FORMAT_VERSIONS:
            self.problem("invalid", f"format version {self.version!r} is not one this reader "
                                    f"knows ({', '.join(READABLE_FORMAT_VERSIONS)})")
        need = (layout.STATUS, layout.RECORDS_COMPLETE, layout.RECORDS_PLANNED, layout.DATA,
                layout.member(layout.DATA, layout.RECORD), layout.member(layout.DATA, layout.TIME),
                layout.member(layout.CLIPPING, layout.COUNT), layout.ACQUISITION,
                layout.ANTIALIAS, layout.SCENE_SETTINGS,
                layout.member(layout.MODEL, layout.FREQUENCY))
        missing = [k for k in need if k not in f]
        if missing:
            self.problem("invalid", f"not a whole run file: missing {', '.join(missing)}")
            return set()
        e = f[layout.ENTRY]
        status = _text(f[layout.STATUS][()]).strip("\x00 ")
        n, planned = int(f[layout.RECORDS_COMPLETE][()]), int(f[layout.RECORDS_PLANNED][()])
        self.n, self.planned = n, planned
        if status not in STATUSES:
            self.problem("invalid", f"status {status!r} is not one of {', '.join(STATUSES)}")
        self.run_status = status
        if not 0 <= n <= planned:
            self.problem("invalid", f"records_complete = {n} outside 0..{planned} "
                                    "(records_planned)")
        if status == "complete" and n != planned:
            self.problem("invalid", f"status complete but {n} of {planned} records written")
        if status != "complete":
            msg = _text(f[layout.MESSAGE][()]).strip("\x00 ") if layout.MESSAGE in f else ""
            self.notes.append(f"incomplete ({status}): {n} of {planned} records"
                              + (f" ({msg})" if msg else ""))

        data = f[layout.DATA]
        names = [_text(data.attrs["signal"])] + [_text(s) for s in
                                                  data.attrs.get("auxiliary_signals", [])]
        for c in names:
            if c not in data:
                self.problem("invalid", f"channel {c!r} named by {layout.DATA}@signal is "
                                        "missing")
        samples = int(data[layout.TIME].shape[0])
        self._plan(f, planned, samples)
        self._calibrations(data, names)

        # per-record datasets: every dataset whose first axis grows with the records
        grow = []

        def visit(name, obj):
            import h5py

            if isinstance(obj, h5py.Dataset) and obj.maxshape and obj.maxshape[0] is None:
                grow.append((layout.member(layout.ENTRY, name), obj))

        e.visititems(visit)
        unfinished = None  # a dataset with rows beyond records_complete, if any
        for name, ds in grow:
            rows = ds.shape[0]
            if rows < n:
                self.problem("truncated", f"{name} holds {rows} rows but records_complete = {n}")
                self.bad.update(range(rows, n))
            elif rows > n and status == "complete":
                self.problem("invalid", f"{name} holds {rows} rows but records_complete = {n}")
            elif rows > n and unfinished is None:
                # a writer killed mid-record, or one whose stop could not trim the record it
                # was writing (a full disk): rows readers never read
                unfinished = name
            if (ds.ndim >= 2 and name.rsplit("/", 1)[-1] != layout.COUNT
                    and ds.shape[1] != samples):
                self.problem("invalid", f"{name} has {ds.shape[1]} samples per record, "
                                        f"{layout.member(layout.DATA, layout.TIME)} {samples}")
            self._verify_rows(name, ds, min(rows, n))
        if unfinished is not None and status != "acquiring":
            self.notes.append(f"rows of an unfinished record beyond records_complete = {n} (e.g. "
                              f"{unfinished}): ignored by readers")
        if not grow:
            self.problem("invalid", "no per-record datasets")
        return {name for name, _ in grow}

    def _sine(self, f) -> None:
        """The sine run file's checks (:mod:`daq.sine_file`): its version, status and
        ``points_complete`` against the rows of every per-point dataset (the checksums are
        verified when :meth:`_everything` reads every dataset)."""
        import h5py

        from daq.sine_file import FORMAT_VERSION as SINE_VERSION

        if self.version != SINE_VERSION:
            self.problem("invalid", f"format version {self.version!r} is not one this reader "
                                    f"knows ({SINE_VERSION})")
        need = ("entry/status", "entry/points_complete", "entry/sweep", "entry/sweep/point",
                "entry/scene/settings_json", "entry/model")
        missing = [k for k in need if k not in f]
        if missing:
            self.problem("invalid", f"not a whole sine run file: missing {', '.join(missing)}")
            return
        e = f["entry"]
        status = _text(e["status"][()]).strip("\x00 ")
        n = int(e["points_complete"][()])
        self.run_status = status if status in STATUSES else None
        if status not in STATUSES:
            self.problem("invalid", f"status {status!r} is not one of {', '.join(STATUSES)}")
        elif status != "complete":
            self.notes.append(f"incomplete ({status}): {n} points")
        self.notes.append(f"{n} points")
        for name in ("sweep", "records"):
            if name not in e:
                continue
            for key, ds in e[name].items():
                if (isinstance(ds, h5py.Dataset) and ds.maxshape and ds.maxshape[0] is None
                        and key != "sample" and not key.startswith("codes_")
                        and ds.shape[0] < n):
                    self.problem("truncated", f"entry/{name}/{key} holds {ds.shape[0]} rows "
                                              f"but points_complete = {n}")

    def _verify_rows(self, name: str, ds, n: int) -> None:
        """Read rows 0..n-1 of ``ds`` (all at once, then row by row if that fails), which
        verifies each chunk's fletcher32 checksum."""
        if n == 0:
            return
        if ds.fletcher32 is False and self.version not in (None, "1.0"):
            self.problem("invalid", f"{name} has no fletcher32 checksum")
        try:
            ds[:n]
            return
        except OSError:
            pass
        bad = []
        for k in range(n):
            try:
                ds[k]
            except OSError:
                bad.append(k)
        self.bad.update(bad)
        if bad:
            self.problem("corrupt", f"{name}: record{'s' if len(bad) > 1 else ''} "
                                    f"{_ranges(bad)} fail{'' if len(bad) > 1 else 's'} "
                                    "the checksum (corrupt data)")

    def _plan(self, f, planned: int, samples: int) -> None:
        from daq.records import RecordPlan
        from rig.errors import RigError
        from rig.scene import scene_from_settings

        try:
            settings = json.loads(_text(f[layout.SCENE_SETTINGS][()]))
        except ValueError as exc:
            self.problem("invalid", f"{layout.SCENE_SETTINGS} is not JSON ({exc})")
            return
        try:
            scene = scene_from_settings(settings,
                                        origin=_text(f[layout.SCENE].attrs.get("source", "")))
            plan = RecordPlan.from_acquisition(scene.acquisition)
        except (RigError, KeyError, TypeError, ValueError) as exc:
            self.problem("invalid", f"the stored scene does not rebuild: {first_line(exc)}")
            return
        if plan.records != planned:
            self.problem("invalid", f"the stored scene plans {plan.records} records, "
                                    f"records_planned = {planned}")
        if plan.samples != samples:
            self.problem("invalid", f"the stored scene plans {plan.samples} samples per record, "
                                    f"the file has {samples}")

    def _calibrations(self, data, names) -> None:
        for c in names:
            if c not in data:
                continue
            a = data[c].attrs
            try:
                ch = Channel.from_attrs(c, a)
            except Exception as exc:  # noqa: BLE001 - any failure is an inconsistent file
                self.problem("invalid", f"channel {c}: calibration does not rebuild "
                                        f"({first_line(exc)})")
                continue
            lsb = float(a.get("scale_factor", np.nan))
            vpu, upv = float(a.get("volts_per_unit", np.nan)), float(a.get("units_per_volt",
                                                                             np.nan))
            if not np.isclose(lsb, ch.adc.lsb_v, rtol=1e-12, atol=0):
                self.problem("invalid", f"channel {c}: scale_factor {lsb!r} != lsb_v "
                                        f"{ch.adc.lsb_v!r}")
            if not np.isclose(vpu * upv, 1.0, rtol=1e-9, atol=0):
                self.problem("invalid", f"channel {c}: volts_per_unit {vpu!r} x units_per_volt "
                                        f"{upv!r} != 1")


def _ranges(ks) -> str:
    out, start, prev = [], None, None
    for k in sorted(ks):
        if start is None:
            start = prev = k
        elif k == prev + 1:
            prev = k
        else:
            out.append(f"{start}" if start == prev else f"{start}-{prev}")
            start = prev = k
    out.append(f"{start}" if start == prev else f"{start}-{prev}")
    return ", ".join(out)


def _text(v) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.shape == ():
        return _text(v[()])
    return str(v)


def check_ok_or_raise(path: str | Path) -> FileCheck:
    """:func:`check_file`, raising :class:`rig.errors.ConfigError` with its line if the file is
    not ok (for commands that need a whole file)."""
    fc = check_file(path)
    if not fc.ok:
        raise ConfigError(fc.line())
    return fc

