"""The sweep as one dataset: an HDF5 manifest of external links and virtual datasets, and a CSV.

:func:`write_manifest` writes ``manifest.h5`` laid out as netCDF-4 would be, so
``xarray.open_dataset("DIR/manifest.h5", engine="h5netcdf")`` gives the whole sweep::

    /                       @file_format = "pendulum-daq dataset" @file_format_version @sweep_*
                            @runs @complete @failed @missing @not_stacked (variables whose
                            shapes differ between runs) @coordinates note
      run (run,)            int64 dimension scale: the run index
      seed, status, error, file, sha256, model (run,)   coordinates: the run's seed, "complete" |
                            "failed" | "missing", its error message, file name, sha256 and the
                            model that ran
      <section.key> (run,)  coordinates: every varied parameter (e.g. source.level_vrms)
      record, time, frequency, model_frequency, body   dimension scales, from the run files
      a, x, y (run, record, time)   virtual: the runs' ADC codes (CF packing attributes, so
                            xarray decodes volts, when every run shares them)
      truth_<name> (run, record, time[, body])   virtual: the ground truth (if kept)
      H_t_real, ..., coherence_x, ... (run, frequency)   virtual: the kept analysis outputs
      model_h_t_real, ... (run, model_frequency)   virtual: the exact model on the record grid
      <fit>_mode<j>_f_hz, ... (run,)   the modal fits (copied: small), NaN where not made
      runs/run_000042       external link to that run file's /entry (complete runs only)

Virtual datasets and links name the run files relative to the manifest (``runs/...``), so the
directory can be moved. A run that is not complete maps nothing: its rows read as the fill value
(NaN for floats, 0 for ADC codes), and ``status`` says which rows hold data.
:func:`write_table` writes ``manifest.csv``: one row per run with its parameters, status, error,
seed, file and sha256.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import h5py
import numpy as np

from daq import run_layout as layout
from rig.output_files import atomic_output

__all__ = ["write_manifest", "write_table", "MANIFEST", "TABLE", "FORMAT", "FORMAT_VERSION"]

MANIFEST, TABLE = "manifest.h5", "manifest.csv"
FORMAT, FORMAT_VERSION = "pendulum-daq dataset", "1.0"
_STR = h5py.string_dtype()
_SKIP_ATTRS = ("DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME", "_Netcdf4Dimid")
#: Where the manifest's dimension scales take their attributes from, in the first run file.
_SCALE_SOURCES = {"record": layout.member(layout.DATA, layout.RECORD),
                  "time": layout.member(layout.DATA, layout.TIME),
                  "frequency": layout.member(layout.ANALYSIS, layout.FREQUENCY),
                  "model_frequency": layout.member(layout.MODEL, layout.FREQUENCY),
                  "body": layout.member(layout.TRUTH, layout.BODY)}


def _rows(specs, results: dict) -> list[dict]:
    """One row per planned run; ``results`` ({index: JobResult}) has those that finished."""
    rows = []
    for s in specs:
        r = results.get(s.index)
        if r is None:
            rows.append({"run": s.index, "status": "missing", "error": "", "seed": s.seed,
                         "file": "", "sha256": "", "model": "", **s.params})
            continue
        rows.append({"run": s.index, "status": r.status, "error": r.error, "seed": s.seed,
                     "file": r.file if r.status == "complete" else "", "sha256": r.sha256,
                     "model": r.model, **s.params})
    return rows


def write_table(path: Path, specs, results: dict, parameter_keys) -> Path:
    """The CSV of every run (module docstring), written under a temporary name and renamed."""
    cols = ["run", "status", "error", "seed", "file", "sha256", "model", *parameter_keys]
    with atomic_output(path, force=True, durable=True) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=cols)
            w.writeheader()
            for row in _rows(specs, results):
                w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return path


def _attrs(ds) -> dict:
    return {k: v for k, v in ds.attrs.items() if k not in _SKIP_ATTRS}


def _same_attrs(a: dict, b: dict) -> bool:
    if a.keys() != b.keys():
        return False
    return all(np.array_equal(np.asarray(a[k]), np.asarray(b[k])) for k in a)


def _survey(out_dir: Path, complete: list[tuple[int, str]]):
    """One pass over the complete run files: per stacked variable its path, dims, shape, dtype
    and attributes (None if the runs disagree), the axes, and every run's modal scalars."""
    variables: dict[str, dict] = {}
    axes: dict[str, np.ndarray] = {}
    bad_axes: set[str] = set()
    modal: dict[str, dict[int, float]] = {}
    modal_units: dict[str, str] = {}
    not_stacked: set[str] = set()
    seen = 0

    def add(name, path, ds, dims):
        shape, dtype, attrs = ds.shape, ds.dtype, _attrs(ds)
        v = variables.get(name)
        if v is None:
            if seen == 0:
                variables[name] = {"path": path, "dims": dims, "shape": shape, "dtype": dtype,
                                   "attrs": attrs, "count": 1}
            else:
                not_stacked.add(name)  # absent from an earlier run
            return
        if v["shape"] != shape or v["dtype"] != dtype:
            not_stacked.add(name)
            return
        if v["attrs"] is not None and not _same_attrs(v["attrs"], attrs):
            v["attrs"] = None
        v["count"] += 1

    def axis(name, values):
        if name not in axes:
            axes[name] = np.asarray(values)
        elif not np.array_equal(axes[name], values):
            bad_axes.add(name)

    for index, fname in complete:
        with h5py.File(out_dir / "runs" / fname, "r") as f:
            d = f[layout.DATA]
            axis("record", d[layout.RECORD][()])
            axis("time", d[layout.TIME][()])
            for c in ("a", "x", "y"):
                add(c, layout.member(layout.DATA, c), d[c], ("run", "record", "time"))
            if layout.TRUTH in f:
                t = f[layout.TRUTH]
                if layout.BODY in t:
                    axis("body", t[layout.BODY][()])
                for k in t:
                    if t[k].ndim >= 2 and k != layout.RECORD_START:
                        dims = ("run", "record", "time") + (("body",) if t[k].ndim == 3 else ())
                        add(f"truth_{k}", layout.member(layout.TRUTH, k), t[k], dims)
            m = f[layout.MODEL]
            axis("model_frequency", m[layout.FREQUENCY][()])
            for k in ("h_t_real", "h_t_imag", "theta_2_real", "theta_2_imag"):
                if k in m:
                    add(f"model_{k}", layout.member(layout.MODEL, k), m[k],
                        ("run", "model_frequency"))
            if layout.ANALYSIS not in f:  # a raw-only sweep (keep.analysis = false)
                seen += 1
                continue
            g = f[layout.ANALYSIS]
            axis("frequency", g[layout.FREQUENCY][()])
            for k in g:
                if isinstance(g[k], h5py.Dataset) and k != layout.FREQUENCY and g[k].ndim == 1:
                    add(k, layout.member(layout.ANALYSIS, k), g[k], ("run", "frequency"))
            if layout.MODAL in g:
                for k, ds in g[layout.MODAL].items():
                    modal.setdefault(k, {})[index] = float(ds[()])
                    modal_units[k] = str(ds.attrs.get("units", ""))
        seen += 1
    for name, v in variables.items():
        if v["count"] != seen or any(d in bad_axes for d in v["dims"]):
            not_stacked.add(name)
    stacked = {k: v for k, v in variables.items() if k not in not_stacked}
    return stacked, axes, modal, modal_units, sorted(not_stacked)


def write_manifest(out_dir: str | Path, sweep, specs, results: dict) -> Path:
    """Write ``out_dir/manifest.h5`` (module docstring) from the plan ``specs`` and the runs'
    ``results`` ({index: result of :func:`processing.dataset.task.run_task`}); under a temporary
    name, renamed when complete."""
    out_dir = Path(out_dir)
    n = len(specs)
    rows = _rows(specs, results)
    complete = [(r["run"], r["file"]) for r in rows if r["status"] == "complete"]
    stacked, axes, modal, modal_units, not_stacked = _survey(out_dir, complete)
    path = out_dir / MANIFEST
    keys = list(sweep.parameter_keys)
    with atomic_output(path, force=True, durable=True) as tmp:
        with h5py.File(tmp, "w", libver=("v110", "v110")) as f:
            counts = {s: sum(r["status"] == s for r in rows) for s in ("complete", "failed",
                                                                          "missing")}
            for k, v in {"file_format": FORMAT, "file_format_version": FORMAT_VERSION,
                         "title": f"sweep {sweep.name}: {n} runs ({counts['complete']} complete, "
                                  f"{counts['failed']} failed, {counts['missing']} missing)",
                         "sweep_name": sweep.name, "sweep_description": sweep.description,
                         "sweep_seed": np.int64(sweep.seed), "sweep_json": json.dumps(
                             sweep.describe(), sort_keys=True),
                         "runs": np.int64(n), "complete": np.int64(counts["complete"]),
                         "failed": np.int64(counts["failed"]), "missing": np.int64(counts["missing"]),
                         "not_stacked": json.dumps(not_stacked),
                         "note": "rows of runs that are not complete read as the fill value (NaN, or "
                                 "0 for ADC codes): select status == 'complete'"}.items():
                f.attrs[k] = v
            run = f.create_dataset("run", data=np.arange(n, dtype=np.int64), track_times=False)
            run.make_scale("run")
            run.attrs["long_name"] = "run index"
            run.attrs["units"] = "1"
            coords = ["seed", "status", "error", "file", "sha256", "model", *keys]
            for k in ("seed",):
                _coord(f, k, np.array([r[k] for r in rows], dtype=np.int64), run,
                       "run seed: SeedSequence(sweep_seed, spawn_key=(run,))", "1")
            for k, what in (("status", "complete | failed | missing"), ("error", "why it failed"),
                            ("file", "run file, relative to the manifest's runs/"),
                            ("sha256", "sha256 of the run file"), ("model", "model that ran")):
                _coord(f, k, np.array([str(r[k]) for r in rows], dtype=object), run, what, "")
            for k in keys:
                vals = [r.get(k) for r in rows]
                arr = (np.array(vals, dtype=float)
                       if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)
                       else np.array([json.dumps(v) if not isinstance(v, str) else v
                                      for v in vals], dtype=object))
                _coord(f, k, arr, run, f"varied parameter {k} (scene key)", unit_of(k))
            scales = {"run": run}
            for name, vals in axes.items():
                s = f.create_dataset(name, data=vals, track_times=False)
                s.make_scale(name)
                scales[name] = s
            if complete:
                with h5py.File(out_dir / "runs" / complete[0][1], "r") as first:
                    for name in ("record", "time", "frequency", "model_frequency", "body"):
                        if name in scales:
                            src = _SCALE_SOURCES[name]
                            if src in first:
                                for k, v in _attrs(first[src]).items():
                                    scales[name].attrs[k] = v
            coord_attr = " ".join(coords)
            by_index = dict(complete)
            for name, v in stacked.items():
                shape = (n,) + tuple(v["shape"])
                virtual = h5py.VirtualLayout(shape=shape, dtype=v["dtype"])
                for index, fname in by_index.items():
                    virtual[index] = h5py.VirtualSource(f"runs/{fname}", v["path"],
                                                        shape=v["shape"])
                fill = np.nan if np.issubdtype(v["dtype"], np.floating) else 0
                ds = f.create_virtual_dataset(name, virtual, fillvalue=fill)
                for i, dim in enumerate(v["dims"]):
                    ds.dims[i].attach_scale(scales[dim])
                for k, val in (v["attrs"] or {}).items():
                    ds.attrs[k] = val
                if v["attrs"] is None:
                    ds.attrs["note"] = "the runs' attributes differ (e.g. ADC scaling): see each run"
                ds.attrs["coordinates"] = coord_attr
            for name in sorted(modal):
                vals = np.array([modal[name].get(i, np.nan) for i in range(n)], dtype=float)
                ds = f.create_dataset(name, data=vals, track_times=False)
                ds.dims[0].attach_scale(run)
                ds.attrs["units"] = modal_units.get(name, "")
                ds.attrs["long_name"] = f"modal fit: {name} (NaN: not made)"
                ds.attrs["coordinates"] = coord_attr
            links = f.create_group("runs")
            links.attrs["note"] = "external links to each complete run file's /entry"
            for index, fname in complete:
                links[Path(fname).stem] = h5py.ExternalLink(f"runs/{fname}", "/" + layout.ENTRY)
    return path


def _coord(f, name, data, run, long_name, units):
    if data.dtype == object:
        ds = f.create_dataset(name, data=data, dtype=_STR, track_times=False)
    else:
        ds = f.create_dataset(name, data=data, track_times=False)
    ds.dims[0].attach_scale(run)
    ds.attrs["long_name"] = long_name
    if units:
        ds.attrs["units"] = units


def unit_of(key: str) -> str:
    """The SI unit a scene key's suffix names (``q1``: 1)."""
    name = key.split(".")[-1]
    for suffix, unit in (("_vrms", "V"), ("_hz", "Hz"), ("_kg", "kg"), ("_m", "m"),
                         ("_s", "s"), ("_nms", "N m s/rad"), ("_npm", "N/m"), ("_nspm", "N s/m"),
                         ("_npa", "N/A"), ("_ohm", "ohm"), ("_h", "H"), ("_vpv", "V/V"),
                         ("_vpmps2", "V/(m/s^2)"), ("_mps2_rthz", "m/s^2/sqrt(Hz)"),
                         ("_mps2", "m/s^2"), ("_m_rthz", "m/sqrt(Hz)"), ("_vpm", "V/m"),
                         ("_deg", "deg"), ("_rad", "rad"), ("_db", "dB"), ("_v", "V"),
                         ("_kgm2", "kg m^2"), ("_kgpm", "kg/m")):
        if name.endswith(suffix):
            return unit
    return "1"
