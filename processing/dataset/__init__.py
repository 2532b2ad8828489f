"""Datasets: parameter sweeps of the emulated experiment, one HDF5 file per run, one manifest.

The sweep composes the acquisition (:mod:`daq`) and the analysis (:mod:`processing`) of every run,
so it lives in ``processing``, the layer that may use both (rig <- daq <- processing); the CLI's
``daq dataset`` only calls it.

- :func:`load_sweep` reads and validates a sweep file (:mod:`processing.dataset.sweep`);
- :func:`plan_runs` resolves every run, :func:`describe_plan` is the dry run;
- :func:`run_sweep` runs it into a directory on any ``concurrent.futures`` executor
  (:func:`local_pool` by default, :func:`dask_executor` for a Dask cluster), resumably;
- :func:`write_manifest` and :func:`write_table` index it (:mod:`processing.dataset.manifest`);
- :func:`check_run_file` says whether a run file is valid and complete;
- :func:`export_dataset` writes a finished dataset as Parquet/npz shards for ML tools
  (:mod:`processing.dataset.export`); :func:`write_zarr_index` indexes its run files as a Zarr v3
  store of virtual references (:mod:`processing.dataset.zarr_index`, the ``zarr`` extra).
"""

from processing.dataset.export import ExportSettings, export_dataset
from processing.dataset.engines import dask_executor, default_workers, local_pool, worker_limit
from processing.dataset.manifest import write_manifest, write_table
from processing.dataset.runfile import RunFileCheck, check_run_file
from processing.dataset.runner import (PlannedRun, SweepInterrupted, SweepProgress, SweepResult,
                                       SweepStopped, describe_plan, plan_runs, run_sweep)
from processing.dataset.sweep import RunSpec, Sweep, load_sweep, parse_sweep, run_seed

__all__ = ["Sweep", "RunSpec", "load_sweep", "parse_sweep", "run_seed", "PlannedRun",
           "SweepProgress", "SweepResult", "SweepInterrupted", "plan_runs", "describe_plan",
           "run_sweep", "local_pool", "dask_executor", "default_workers", "write_manifest",
           "write_table", "RunFileCheck", "check_run_file", "ExportSettings", "export_dataset",
           "write_zarr_index", "open_zarr_index", "worker_limit", "SweepStopped"]


def __getattr__(name):  # the Zarr index needs the optional extra: imported when first used
    if name in ("write_zarr_index", "open_zarr_index"):
        from processing.dataset import zarr_index

        return getattr(zarr_index, name)
    return _submodule(name)  # a public submodule is an attribute on first use


from rig.lazy_exports import submodule_getattr  # noqa: E402

_submodule = submodule_getattr("processing.dataset")
