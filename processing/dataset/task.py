"""One run of a sweep, as a task any worker can execute: acquire, analyse, keep, publish.

:func:`run_task` takes a :class:`Job` and returns a :class:`JobResult`, frozen dataclasses of
plain data (picklable, no open files), so the same function runs in a local process pool or on a
Dask worker. It writes the run under a temporary
name beside the final one (``.run_000042.h5.<host>.<pid>.<token>.partial.h5``), adds the analysis
outputs (:func:`processing.dataset.runfile.write_outputs`), flushes it to disk and publishes it
with a hard link, which fails if the final name exists: a finished file is never overwritten
unless the task says ``replace`` (the sweep was changed with ``--force``). A run that fails
(invalid scene, divergence, an analysis that cannot be made) leaves no file and returns its error;
only KeyboardInterrupt propagates (after the temporary file is removed).
"""

from __future__ import annotations

import os
import sys
import socket
import time
from dataclasses import dataclass, fields
from pathlib import Path

from rig.errors import ForceRequired
from rig.output_files import atomic_output

__all__ = ["Job", "JobResult", "run_task", "worker_init", "failure_text"]


@dataclass(frozen=True)
class Job:
    """One run of a sweep, as :func:`processing.dataset.runner.run_sweep` hands it to a worker.

    Attributes
    ----------
    index : the run's index in the plan.
    seed : the run's seed (a child of the sweep's).
    sweep_seed : the sweep's seed.
    params : the run's parameters (key -> value).
    overrides : the run's ``--set``-style overrides of the base scene.
    spec_hash : the hash of the run's specification (stored in the file, checked on resume).
    settings : the resolved scene settings (:func:`rig.scene.scene_from_settings`).
    scene_source : where the base scene came from.
    analysis : :class:`processing.analyzer.AnalyzerSettings` fields.
    keep : which outputs the run file keeps (``truth``, ``spectra``, ``analysis`` ...).
    runs_dir : the directory of the run files (absolute).
    file : the run file's name in ``runs_dir``.
    replace : a finished file of an earlier plan is there and is replaced (``--force``).
    """

    index: int
    seed: int
    sweep_seed: int
    params: dict
    overrides: tuple
    spec_hash: str
    settings: dict
    scene_source: str
    analysis: dict
    keep: dict
    runs_dir: str
    file: str
    replace: bool = False


@dataclass(frozen=True)
class JobResult:
    """What became of one run: ``status`` "complete" (the final ``file`` exists, valid, with
    that ``sha256``) or "failed" (``error`` says why, one line); ``model`` that ran; for a run
    a worker executed, ``wall_s`` and ``cpu_s`` (the worker's CPU time) [s] and its ``host``."""

    index: int
    status: str
    error: str = ""
    file: str = ""
    sha256: str = ""
    model: str = ""
    wall_s: float | None = None
    host: str | None = None
    cpu_s: float | None = None

    @classmethod
    def failed(cls, index: int, error: str) -> JobResult:
        """A run that failed before or outside its task."""
        return cls(index=index, status="failed", error=error)

    def to_dict(self) -> dict:
        """The journal's record (the fields that are not None)."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None}

    @classmethod
    def from_dict(cls, d: dict) -> JobResult:
        """The result of a journal record (keys it does not name are ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


_BUSY = False  # this worker is running a task (SIGINT interrupts it; an idle worker ignores it)


def _on_sigint(signum, frame):
    if _BUSY:
        raise KeyboardInterrupt


def _quiet_unraisable(*args) -> None:
    """A worker's errors in finalizers are not printed (h5py closing a file on a full disk
    prints a traceback per object, through both hooks): the task returns its own failure as
    one line, and a worker that dies is reported by the pool."""


def worker_init() -> None:
    """Initializer of local pool workers: die with the parent (Linux ``PR_SET_PDEATHSIG``), so
    that a killed sweep leaves no worker writing behind it; one BLAS thread; a Ctrl-C (or a
    SIGTERM or SIGHUP to the process group) interrupts the run in progress (its temporary file
    is removed) and is ignored by an idle worker (the parent shuts the pool down); errors in
    finalizers are not printed (:func:`_quiet_unraisable`)."""
    import signal

    for s in (signal.SIGINT, getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)):
        if s is not None:
            signal.signal(s, _on_sigint)
    sys.unraisablehook = sys.excepthook = _quiet_unraisable
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass


def run_task(job: Job) -> JobResult:
    """Run one job (made by :func:`processing.dataset.runner.run_sweep`) and return its result
    (:class:`JobResult`: "complete" means the final file exists, valid, with that sha256)."""
    global _BUSY
    from processing.dataset.runfile import check_run_file, sha256_file

    _BUSY = True
    t0, c0 = time.perf_counter(), time.process_time()
    final = Path(job.runs_dir) / job.file
    status, error, model, sha256 = "failed", "", "", ""
    try:
        try:  # a hard link publishes it: a finished file is never overwritten without replace
            with atomic_output(final, force=job.replace, suffix=".partial.h5",
                               reserve=False) as tmp:
                model = _run(job, tmp)
        except ForceRequired:
            # finished meanwhile by another worker of an earlier, killed sweep: keep that one
            # if it is this run, valid
            chk = check_run_file(final, spec_hash=job.spec_hash)
            if not chk.ok:
                raise RuntimeError(f"{final.name} exists and is not this run's valid file "
                                   f"({'; '.join(chk.problems)}); not overwritten") from None
        sha256 = sha256_file(final)
        status = "complete"
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # failures are data: the sweep records the error and goes on
        error = failure_text(exc)[:500]
    finally:
        _BUSY = False
    return JobResult(index=job.index, status=status, error=error, file=job.file, sha256=sha256,
                     model=model, wall_s=time.perf_counter() - t0, host=socket.gethostname(),
                     cpu_s=time.process_time() - c0)


def _run(job: Job, tmp: Path) -> str:
    """Acquire and analyse (unless the sweep keeps no analysis) into ``tmp``; returns the
    model that ran."""
    from daq.acquisition import acquire
    from daq.hdf5 import Hdf5Sink, read_run
    from processing.analyzer import AnalyzerSettings, analyze
    from processing.dataset.runfile import write_outputs
    from rig.scene import scene_from_settings

    scene = scene_from_settings(job.settings, origin=job.scene_source)
    summary = acquire(scene, seed=job.seed, sinks=[Hdf5Sink(tmp)])
    analysis = None
    if job.keep.get("analysis", True):
        settings = AnalyzerSettings(**{k: tuple(v) if isinstance(v, list) else v
                                       for k, v in job.analysis.items()})
        analysis = analyze(read_run(tmp), settings, source=job.file)
    write_outputs(tmp, analysis, job.keep, spec={
        "sweep_seed": job.sweep_seed, "run_index": job.index, "run_seed": job.seed,
        "spec_hash": job.spec_hash, "parameters": job.params,
        "overrides": list(job.overrides)})
    return str(summary.model_info.model or "")


def failure_text(exc: BaseException) -> str:
    """A failed run's error as a person reads it (no exception class names): the library's own
    message for its errors, the file and reason for a failed read or write, else the message
    marked as unexpected."""
    from processing.errors import ProcessingError
    from rig.errors import RigError

    msg = str(exc).splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, (RigError, ProcessingError)):
        return msg
    if isinstance(exc, OSError) and exc.filename:
        return f"{exc.filename}: {exc.strerror or msg}"
    if isinstance(exc, MemoryError):
        return f"out of memory{f' ({msg})' if msg else ''}"
    return f"unexpected failure: {msg or 'no message'}"
