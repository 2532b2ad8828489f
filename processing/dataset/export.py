"""A finished sweep as flat shards that ML tools load without this project: Parquet or NumPy.

:func:`export_dataset` reads a dataset directory (``daq dataset SWEEP.toml --out DIR``: its
``manifest.h5`` and ``runs/``) and writes, under ``OUT/``::

    data/<split>-<k>-of-<n>.parquet | .npz   one row per window (or per record): the run, its
                                             seed and varied parameters, the split, the window's
                                             place, and a, x, y in engineering units (m/s^2, m,
                                             rad), optionally the ground truth and the drive
    README.md                                the dataset card (Hugging Face's format): features
                                             with units, how the data were made, the commands
                                             that regenerate it bit for bit
    export.json                              the settings of this export, as plain data

Windows never straddle records, and every window of a run is in the run's split: splits are by
run (or by the value of one parameter, ``split_by``), drawn from the sweep's seed, so the same
dataset and settings always give the same shards, byte for byte. Only complete runs are
exported. Shard names follow the pattern ``datasets.load_dataset("parquet", data_dir=OUT)``
infers splits from.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from processing.dataset.manifest import unit_of
from rig.errors import ConfigError
from rig.output_files import atomic_output

__all__ = ["ExportSettings", "ExportResult", "export_dataset", "parse_split", "assign_splits",
           "manifest_runs",
           "FORMATS"]

FORMATS = ("parquet", "npz")
#: The ground-truth channels an export can carry: truth name in the run file -> column, unit.
TRUTH_COLUMNS = {"stage_accel_mps2": ("truth_stage_accel", "m/s^2"),
                 "mirror_x_m": ("truth_mirror_x", "m"),
                 "mirror_rot_rad": ("truth_mirror_rot", "rad")}
DRIVE_COLUMN = ("drive", "V")  # the source's DAC output (entry/truth/source_v)
SHARD_ROWS_BYTES = 256 * 2 ** 20  # a shard holds at most about this many bytes of samples
_SPLIT_SALT = 0x5EED5  # the split's generator: SeedSequence(sweep seed, spawn_key=(salt,))


@dataclass(frozen=True)
class ExportSettings:
    """What :func:`export_dataset` writes.

    format: "parquet" or "npz"; window_s, hop_s: window length and step [s] (None: one row per
    record; hop defaults to the window); split: ((name, fraction), ...) summing to 1; split_by:
    a varied parameter (``section.key``) whose values, not runs, are drawn into splits;
    truth, drive: add the ground-truth columns and the drive.
    """

    format: str = "parquet"
    window_s: float | None = None
    hop_s: float | None = None
    split: tuple = (("train", 0.8), ("val", 0.1), ("test", 0.1))
    split_by: str | None = None
    truth: bool = False
    drive: bool = False

    def __post_init__(self):
        if self.format not in FORMATS:
            raise ConfigError(f"format = {self.format!r} is invalid: expected one of "
                              f"{', '.join(FORMATS)}")
        for name, v in (("window_s", self.window_s), ("hop_s", self.hop_s)):
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} = {v!r} is invalid: expected a positive number of "
                                  "seconds")
        if self.hop_s is not None and self.window_s is None:
            raise ConfigError("hop_s needs window_s: the hop is the step between windows")
        fractions = [f for _, f in self.split]
        names = [n for n, _ in self.split]
        if not self.split or len(set(names)) != len(names):
            raise ConfigError(f"split = {_split_text(self.split)} is invalid: expected distinct "
                              "names with fractions, e.g. train=0.8,val=0.1,test=0.1")
        if any(not (math.isfinite(f) and f >= 0) for f in fractions) or \
                abs(sum(fractions) - 1.0) > 1e-9:
            raise ConfigError(f"split = {_split_text(self.split)} is invalid: the fractions must "
                              f"be >= 0 and sum to 1 (they sum to {sum(fractions):g})")
        for n in names:
            if not n.replace("_", "").isalnum() or "-" in n:
                raise ConfigError(f"split name {n!r} is invalid: use letters, digits and _")

    def describe(self) -> dict:
        return {"format": self.format, "window_s": self.window_s, "hop_s": self.hop_s,
                "split": [[n, f] for n, f in self.split], "split_by": self.split_by,
                "truth": self.truth, "drive": self.drive}


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_dataset` wrote: the shard files per split, rows per split, the card."""

    out_dir: Path
    shards: dict
    rows: dict
    runs: dict
    card: Path


def _split_text(split) -> str:
    return ",".join(f"{n}={f:g}" for n, f in split)


def parse_split(text: str) -> tuple:
    """``"train=0.8,val=0.1,test=0.1"`` -> (("train", 0.8), ("val", 0.1), ("test", 0.1))."""
    out = []
    for part in text.split(","):
        name, eq, value = part.partition("=")
        try:
            out.append((name.strip(), float(value)))
        except ValueError:
            raise ConfigError(f"split {text!r} is invalid at {part!r}: expected name=fraction, "
                              "e.g. train=0.8,val=0.1,test=0.1") from None
        if not eq or not name.strip():
            raise ConfigError(f"split {text!r} is invalid at {part!r}: expected name=fraction")
    return tuple(out)


def assign_splits(keys, split, seed: int) -> dict:
    """Each distinct key (a run index, or a parameter's value) -> a split name.

    The keys, sorted, are shuffled by a generator drawn from the sweep's ``seed``; split ``j``
    gets the next ``round`` of ``fraction_j x count`` (largest remainders), so the counts are as
    close to the fractions as whole keys allow and the same keys always land in the same splits.
    """
    keys = sorted(set(keys), key=lambda k: (str(type(k)), k))
    n = len(keys)
    exact = [f * n for _, f in split]
    counts = [int(math.floor(e)) for e in exact]
    order = sorted(range(len(split)), key=lambda j: (-(exact[j] - counts[j]), j))
    for j in order[:n - sum(counts)]:
        counts[j] += 1
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_SPLIT_SALT,)))
    perm = rng.permutation(n)
    out, start = {}, 0
    for (name, _), c in zip(split, counts):
        for i in perm[start:start + c]:
            out[keys[i]] = name
        start += c
    return out


def manifest_runs(ds_dir: Path) -> tuple[list[dict], list[str], int]:
    """The complete runs of the dataset: [{run, seed, file, params}], parameter keys, seed."""
    path = ds_dir / "manifest.h5"
    if not path.is_file():
        raise ConfigError(f"{ds_dir} is not a dataset directory: {path.name} is missing (make "
                          "one with daq dataset SWEEP.toml --out DIR)")
    with h5py.File(path, "r") as f:
        sweep = json.loads(f.attrs["sweep_json"])
        keys = [p["key"] for p in sweep.get("grid", []) + sweep.get("random", [])]
        status = [s.decode() if isinstance(s, bytes) else str(s) for s in f["status"][()]]
        files = [s.decode() if isinstance(s, bytes) else str(s) for s in f["file"][()]]
        seeds = f["seed"][()]
        params = {k: f[k][()] for k in keys}
    rows = []
    for i, st in enumerate(status):
        if st != "complete":
            continue
        p = {}
        for k in keys:
            v = params[k][i]
            p[k] = v.decode() if isinstance(v, bytes) else (float(v) if np.ndim(v) == 0 and
                                                             not isinstance(v, str) else v)
        rows.append({"run": i, "seed": int(seeds[i]), "file": files[i], "params": p})
    if not rows:
        raise ConfigError(f"{ds_dir} has no complete run to export (see manifest.csv)")
    return rows, keys, int(sweep["seed"])


def _windows(n_samples: int, rate_hz: float, s: ExportSettings) -> np.ndarray:
    """Start sample of every window within a record."""
    if s.window_s is None:
        return np.array([0]), n_samples
    w = s.window_s * rate_hz
    h = (s.hop_s if s.hop_s is not None else s.window_s) * rate_hz
    for name, v, given in (("window_s", w, s.window_s), ("hop_s", h, s.hop_s or s.window_s)):
        if abs(v - round(v)) > 1e-9 * max(1.0, v) or round(v) < 1:
            raise ConfigError(f"{name} = {given!r} s is invalid: it must be a whole "
                              f"number of samples at {rate_hz:g} Hz (a multiple of "
                              f"{1 / rate_hz:g} s)")
    w, h = int(round(w)), int(round(h))
    if w > n_samples:
        raise ConfigError(f"window_s = {s.window_s!r} is invalid: longer than a record "
                          f"({n_samples / rate_hz:g} s); windows never straddle records")
    return np.arange(0, n_samples - w + 1, h), w


def _run_columns(path: Path, s: ExportSettings) -> tuple[dict, dict, float]:
    """A run file's (records, samples) arrays in engineering units (plus truth and drive when
    asked), their units, and the sample rate."""
    from daq.hdf5 import read_run

    rec = read_run(path)
    cols, units = {}, {}
    for c in rec.header.names:  # the analyzer's own arrays: code -> volts -> calibration undone
        cols[c], units[c] = rec.values(c), rec.header.channel(c).unit
    if s.truth or s.drive:
        t = rec.truth  # read_run's: every truth field, finished records only
        if not t:
            raise ConfigError(f"{path.name} has no ground truth: the sweep was made with "
                              "keep.truth = false; export without --truth/--drive")
        if s.truth:
            for name, (col, unit) in TRUTH_COLUMNS.items():
                cols[col], units[col] = np.asarray(t[name], dtype=float), unit
        if s.drive:
            cols[DRIVE_COLUMN[0]] = np.asarray(t["source_v"], dtype=float)
            units[DRIVE_COLUMN[0]] = DRIVE_COLUMN[1]
    return cols, units, float(rec.header.plan.rate_hz)


def export_dataset(ds_dir: str | Path, out_dir: str | Path, settings: ExportSettings, *,
                   command: str = "") -> ExportResult:
    """Export the dataset in ``ds_dir`` to ``out_dir`` (module docstring; ``out_dir`` must not
    exist or be empty). ``command``: how the dataset was made, for the card."""
    ds_dir, out_dir = Path(ds_dir), Path(out_dir)
    s = settings
    rows, keys, seed = manifest_runs(ds_dir)
    if s.split_by is not None and s.split_by not in keys:
        raise ConfigError(f"split_by = {s.split_by!r} is not a varied parameter of this dataset;"
                          f" valid: {', '.join(keys) or '(none: the sweep varies nothing)'}")
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ConfigError(f"{out_dir} exists and is not empty: choose a new directory")
    group = ({r["run"]: r["run"] for r in rows} if s.split_by is None
             else {r["run"]: r["params"][s.split_by] for r in rows})
    by_key = assign_splits(group.values(), s.split, seed)
    split_of = {run: by_key[k] for run, k in group.items()}
    tables: dict[str, list] = {name: [] for name, _ in s.split}
    units: dict = {}
    meta = None
    for r in rows:
        cols, units, rate = _run_columns(ds_dir / "runs" / r["file"], s)
        n_rec, n_samp = cols["a"].shape
        starts, w = _windows(n_samp, rate, s)
        meta = meta or {"rate_hz": rate, "window_samples": w}
        if (rate, w) != (meta["rate_hz"], meta["window_samples"]):
            raise ConfigError(f"run {r['run']} samples at {rate:g} Hz, another at "
                              f"{meta['rate_hz']:g} Hz: one export needs one rate")
        rec_idx = np.repeat(np.arange(n_rec), len(starts))
        st = np.tile(starts, n_rec)
        block = {"run": np.full(rec_idx.size, r["run"], np.int64),
                 "seed": np.full(rec_idx.size, r["seed"], np.int64),
                 "record": rec_idx.astype(np.int64), "start_s": st / rate}
        for k in keys:
            block[k] = np.full(rec_idx.size, r["params"][k],
                               dtype=float if isinstance(r["params"][k], float) else object)
        idx = st[:, None] + np.arange(w)[None, :]
        for c, arr in cols.items():
            block[c] = np.ascontiguousarray(arr[rec_idx[:, None], idx])
        tables[split_of[r["run"]]].append(block)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "data").mkdir(exist_ok=True)
    signal_cols = [c for c in units]
    shards, counts = {}, {}
    for name, blocks in tables.items():
        if not blocks:
            shards[name], counts[name] = [], 0
            continue
        merged = {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}
        n = merged["run"].size
        per_row = 8 * w * len(signal_cols)
        n_shards = max(1, math.ceil(n * per_row / SHARD_ROWS_BYTES))
        bounds = np.linspace(0, n, n_shards + 1).astype(int)
        files = []
        for k in range(n_shards):
            part = {c: v[bounds[k]:bounds[k + 1]] for c, v in merged.items()}
            part["split"] = np.full(part["run"].size, name, dtype=object)
            p = out_dir / "data" / f"{name}-{k:05d}-of-{n_shards:05d}.{s.format}"
            (_write_parquet if s.format == "parquet" else _write_npz)(p, part, units, keys)
            files.append(p)
        shards[name], counts[name] = files, n
    runs = {name: sorted({int(r) for b in tables[name] for r in b["run"][:1]})
            for name in tables}
    (out_dir / "export.json").write_text(json.dumps(
        {"settings": s.describe(), "dataset": str(ds_dir), "rows": counts, "runs": runs,
         "rate_hz": meta["rate_hz"], "window_samples": meta["window_samples"],
         "units": units, "parameters": keys}, indent=2, sort_keys=True) + "\n")
    card = out_dir / "README.md"
    card.write_text(_card(ds_dir, s, keys, units, counts, runs, meta, command))
    return ExportResult(out_dir, shards, counts, runs, card)


def _write_parquet(path: Path, part: dict, units: dict, keys: list) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    fields, arrays = [], []
    for c, v in part.items():
        md = {"unit": units[c]} if c in units else None
        if c in units:  # (rows, w) float64 -> fixed-size lists
            w = v.shape[1]
            arr = pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1)), w)
        elif v.dtype == object:
            arr = pa.array([str(x) for x in v], pa.string())
        else:
            arr = pa.array(v)
        if c == "start_s":
            md = {"unit": "s"}
        elif c in keys:
            md = {"unit": unit_of(c), "parameter": "varied scene parameter"}
        fields.append(pa.field(c, arr.type, metadata=md))
        arrays.append(arr)
    table = pa.Table.from_arrays(arrays, schema=pa.schema(fields))
    with atomic_output(path, force=True) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def _write_npz(path: Path, part: dict, units: dict, keys: list) -> None:
    arrays = {c: (v.astype(str) if v.dtype == object else v) for c, v in part.items()}
    arrays["units_json"] = np.array(json.dumps({**units, "start_s": "s",
                                                **{k: unit_of(k) for k in keys}}))
    with atomic_output(path, force=True, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def _card(ds_dir, s, keys, units, counts, runs, meta, command) -> str:
    lines = ["---", "configs:", "- config_name: default", "  data_files:"]
    for name, _ in s.split:
        if counts.get(name):
            lines += [f"  - split: {name}", f"    path: data/{name}-*.{s.format}"]
    lines += ["license: mit", "tags:", "- time-series", "- system-identification",
              "- physics-simulation", "---", "",
              "# A pendulum-daq dataset", "",
              "Runs of an emulated vibration-measurement rig (a double physical pendulum on a "
              "shaken stage, measured by an accelerometer and an optical lever), exported from "
              f"`{ds_dir}` by pendulum-daq. Every window comes from a run whose exact model and "
              "ground truth are known.", "",
              f"Sample rate {meta['rate_hz']:g} Hz; {meta['window_samples']} samples per row "
              f"({'one record' if s.window_s is None else f'windows of {s.window_s:g} s, hop '}"
              f"{'' if s.window_s is None else f'{(s.hop_s or s.window_s):g} s'}); windows "
              "never straddle records.", "",
              "## Features", "", "| column | unit | what |", "|---|---|---|",
              "| run | 1 | run index in the sweep |",
              "| seed | 1 | the run's seed: SeedSequence(sweep seed, spawn_key=(run,)) |",
              "| record | 1 | record index within the run |",
              "| start_s | s | first sample of the row within its record |",
              "| split | | the row's split (all rows of a run share it) |"]
    what = {"a": "stage acceleration (accelerometer, calibration undone)",
            "x": "mirror translation relative to the stage (optical lever)",
            "y": "mirror rotation (optical lever)",
            "truth_stage_accel": "true stage acceleration", "truth_mirror_x":
            "true mirror translation relative to the stage", "truth_mirror_rot":
            "true mirror rotation", "drive": "the source's drive voltage (DAC output)"}
    for c, u in units.items():
        lines.append(f"| {c} | {u} | {what.get(c, c)} (list of {meta['window_samples']} "
                     "float64) |")
    for k in keys:
        lines.append(f"| {k} | {unit_of(k)} | varied scene parameter |")
    split_rule = ("by run" if s.split_by is None
                  else f"by the value of `{s.split_by}` (runs sharing a value share a split)")
    lines += ["", "## Splits", "",
              f"Drawn {split_rule} from the sweep's seed: "
              + ", ".join(f"{n} {f:g} ({counts.get(n, 0)} rows, {len(runs.get(n, []))} runs)"
                          for n, f in s.split) + ".", "",
              "## Loading", "", "```python",
              "from datasets import load_dataset",
              "ds = load_dataset(\"parquet\", data_dir=\"THIS_DIRECTORY\")"
              if s.format == "parquet" else
              "import numpy as np; z = np.load(\"data/train-00000-of-00001.npz\")",
              "```", "", "## How it was made, and again", "",
              "```", command or f"daq dataset {Path(ds_dir) / 'sweep.toml'} --out DATASET",
              _export_command(ds_dir, s), "```", "",
              "The same sweep file and seed give the same run files, and the same export the "
              "same shards, byte for byte.", ""]
    return "\n".join(lines)


def _export_command(ds_dir, s: ExportSettings) -> str:
    parts = [f"daq dataset export {ds_dir} --out OUT --format {s.format}"]
    if s.window_s is not None:
        parts.append(f"--window-s {s.window_s:g}")
        if s.hop_s is not None:
            parts.append(f"--hop-s {s.hop_s:g}")
    parts.append(f"--split {_split_text(s.split)}")
    if s.split_by:
        parts.append(f"--split-by {s.split_by}")
    if s.truth:
        parts.append("--truth")
    if s.drive:
        parts.append("--drive")
    return " ".join(parts)
