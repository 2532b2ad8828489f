"""A Zarr v3 index of a dataset's run files: the chunks stay where they are, in the HDF5 files.

:func:`write_zarr_index` reads the chunk layout of every complete run file (VirtualiZarr's HDF5
parser: byte ranges, gzip, shuffle and fletcher32 mapped to Zarr codecs, so the checksums are
verified on every read) and commits it as virtual references to an Icechunk repository,
``DIR/index.icechunk``. Nothing is copied: the index is a few hundred kB for any dataset size.
:func:`open_zarr_index` (or ``xarray.open_zarr`` on the repository's session store) gives the
stacked dataset::

    a, x, y (run, record, time)                the ADC codes (decoded to volts by xarray through
                                               their scale_factor/add_offset, as the manifest)
    truth_<name> (run, record, time[, body])   the ground truth, when the sweep kept it
    model_<name> (run, model_frequency)        the exact model on the record's FFT grid
    <analysis variable> (run, frequency)       the 1-D analysis outputs, when the sweep kept them
    run; seed and the varied parameters (run)  coordinates

The references name the files by URL: ``file://<DIR>/runs/`` by default, or any prefix the files
are served from (``s3://bucket/ds/runs/`` after copying ``runs/`` there; the reader then
authorises that container with its credentials, README "Datasets").
"""

from __future__ import annotations

import contextlib
import json
import shutil
import warnings
from pathlib import Path

import numpy as np

from daq import run_layout as layout
from rig.errors import ConfigError

__all__ = ["write_zarr_index", "open_zarr_index", "INDEX", "default_chunks_url"]

INDEX = "index.icechunk"
#: The run file's groups in the index: (group, prefix of its variables, variables left out).
_GROUPS = ((layout.DATA, "", (layout.RECORD_START,)),
           (layout.TRUTH, "truth_", (layout.RECORD_START,)),
           (layout.MODEL, "model_", ()), (layout.ANALYSIS, "", ()))


@contextlib.contextmanager
def _quiet():
    """Zarr warns that numcodecs codecs (the HDF5 filters: shuffle, zlib, fletcher32) are not
    in the Zarr v3 specification: true, and the reason readers need numcodecs; not the user's
    concern on every read."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Numcodecs codecs are not in the Zarr version 3")
        yield


def _needs():
    try:
        import icechunk
        import virtualizarr  # noqa: F401
    except ImportError:
        raise ConfigError("the Zarr index needs VirtualiZarr and Icechunk: pip install "
                          "'pendulum-daq[zarr]'") from None
    # its local-storage warning (not safe for concurrent commits) is about writers other than
    # this one process; errors still show
    icechunk.set_logs_filter("error")


def default_chunks_url(ds_dir: str | Path) -> str:
    """``file://`` URL of the dataset's ``runs/`` directory, with the trailing slash."""
    return f"file://{(Path(ds_dir) / 'runs').resolve()}/"


def _complete_runs(ds_dir: Path) -> tuple[list[dict], list[str]]:
    from processing.dataset.export import manifest_runs

    rows, keys, _ = manifest_runs(ds_dir)
    return rows, keys


def _run_dataset(path: Path, registry):
    """One run file's groups as one virtual dataset (names prefixed per group)."""
    import h5py
    import xarray as xr
    from virtualizarr import open_virtual_dataset
    from virtualizarr.parsers import HDFParser

    url = f"file://{path.resolve()}"
    with h5py.File(path, "r") as f:
        present = [g for g in _GROUPS if g[0] in f]
    parts = []
    for group, prefix, drop in present:
        v = open_virtual_dataset(url, registry=registry, parser=HDFParser(group=group))
        v = v.drop_vars([d for d in drop if d in v.variables])
        if group == layout.MODEL:
            v = v.rename({layout.FREQUENCY: "model_frequency"})
        if prefix:
            v = v.rename({k: f"{prefix}{k}" for k in v.data_vars})
        parts.append(v)
    return xr.merge(parts, compat="override", join="override", combine_attrs="override")


def write_zarr_index(ds_dir: str | Path, *, chunks_url: str | None = None,
                     force: bool = False) -> Path:
    """Index the complete runs of the dataset in ``ds_dir`` (module docstring) into
    ``ds_dir/index.icechunk``; ``chunks_url``: where readers find the run files (default
    :func:`default_chunks_url`). An existing index is replaced only with ``force``."""
    _needs()
    import icechunk
    import xarray as xr
    from obstore.store import LocalStore
    from obspec_utils.registry import ObjectStoreRegistry

    ds_dir = Path(ds_dir)
    rows, keys = _complete_runs(ds_dir)
    out = ds_dir / INDEX
    if out.exists() and not force:
        raise ConfigError(f"{out} exists: it is replaced only when asked (force)")
    local = default_chunks_url(ds_dir)
    url = chunks_url or local
    if not url.endswith("/"):
        raise ConfigError(f"chunks URL {url!r} is invalid: it must end with '/' (the folder "
                          "the run files are in)")
    registry = ObjectStoreRegistry({"file://": LocalStore(prefix="/")})
    with _quiet():
        per_run = [_run_dataset(ds_dir / "runs" / r["file"], registry) for r in rows]
        stacked = xr.concat(per_run, dim="run", coords="minimal", compat="override",
                            join="override", combine_attrs="override")
    coords = {"run": ("run", np.array([r["run"] for r in rows], np.int64),
                      {"long_name": "run index", "units": "1"}),
              "seed": ("run", np.array([r["seed"] for r in rows], np.int64),
                       {"long_name": "run seed", "units": "1"})}
    for k in keys:
        vals = [r["params"][k] for r in rows]
        arr = (np.array(vals, float) if all(isinstance(v, float) for v in vals)
               else np.array([json.dumps(v) if not isinstance(v, str) else v for v in vals]))
        coords[k] = ("run", arr, {"long_name": f"varied parameter {k} (scene key)"})
    stacked = stacked.assign_coords(coords)
    stacked.attrs = {"title": f"pendulum-daq dataset {ds_dir.name}: {len(rows)} complete runs",
                     "source": "virtual references to the run files (VirtualiZarr, Icechunk)",
                     "chunks_url": url}
    if url != local:  # references name the files where readers will find them
        stacked = stacked.vz.rename_paths(lambda p: url + p[len(local):]
                                          if p.startswith(local) else p)
    tmp = ds_dir / f".{INDEX}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        repo = icechunk.Repository.create(icechunk.local_filesystem_storage(str(tmp)),
                                          _config(url, ds_dir))
        session = repo.writable_session("main")
        with _quiet():
            stacked.vz.to_icechunk(session.store)
        session.commit(f"index of {len(rows)} runs")
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _config(url: str, ds_dir: Path):
    """The repository's virtual chunk container for ``url`` (a local one for ``file://``; for
    another scheme the reader declares the container with its store and credentials)."""
    import icechunk

    config = icechunk.RepositoryConfig.default()
    if url.startswith("file://"):
        store = icechunk.local_filesystem_store(url[len("file://"):])
        config.set_virtual_chunk_container(icechunk.VirtualChunkContainer(url, store))
    return config


def open_zarr_index(ds_dir: str | Path, *, chunks_url: str | None = None, decode: bool = True):
    """The dataset's index as an ``xarray.Dataset`` (lazily; reads go to the run files at
    ``chunks_url``, the one the index was written with; default the dataset's ``runs/``).
    ``decode=False`` gives the ADC codes as stored. For run files on an object store, open the
    repository with Icechunk and the container's credentials and pass ``session.store`` to
    ``xarray.open_zarr`` (README)."""
    _needs()
    import icechunk
    import xarray as xr

    ds_dir = Path(ds_dir)
    path = ds_dir / INDEX
    if not path.is_dir():
        raise ConfigError(f"{ds_dir} has no Zarr index ({INDEX}): make it with daq dataset "
                          "index DIR")
    storage = icechunk.local_filesystem_storage(str(path))
    url = chunks_url or default_chunks_url(ds_dir)
    repo = icechunk.Repository.open(storage, _config(url, ds_dir),
                                    authorize_virtual_chunk_access={url: None})
    with _quiet():
        return xr.open_zarr(repo.readonly_session("main").store, consolidated=False,
                            mask_and_scale=decode)
