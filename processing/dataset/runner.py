"""Run a sweep into a directory: plan, resume, execute on any executor, record, index.

The directory ``DIR`` of a sweep holds::

    sweep.toml      the sweep file as given          sweep.json   the plan a rerun compares
    runs/run_000000.h5 ...                           journal.jsonl  one line per finished run
    manifest.h5, manifest.csv   the dataset (processing.dataset.manifest)

:func:`run_sweep` is idempotent: a rerun of the same sweep skips every run whose file is valid and
complete (:func:`processing.dataset.runfile.check_run_file`: status, records, the plan's hash and
the sha256 the journal recorded), redoes the others and never overwrites a finished file. A
changed sweep file is refused unless ``force``, and the error says what changed; with ``force``
the runs whose specification changed are redone and their files replaced, and the run files the
new plan does not list are removed. Only the parent writes
the journal and the manifest; each task writes its own run file.

Failures are data: a parameter set the scene rejects is recorded as failed without running, a
run that fails in its task (divergence, an analysis that cannot be made) returns its error; a
worker that dies (killed, out of memory: :class:`~concurrent.futures.process.BrokenProcessPool`)
makes the runner rebuild the pool and resubmit the runs that were in flight, at most
``max_retries`` times each, then record them as failed. KeyboardInterrupt (Ctrl-C) stops the
sweep: the pool is shut down, finished runs stay, the manifest marks the rest "missing" and
:class:`SweepInterrupted` carries the result.
"""

from __future__ import annotations

import collections
import contextlib
import json
import os
import shutil
import socket
import time
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from daq.resources import run_file_bytes
from rig.output_files import atomic_output, process_alive
from rig.errors import ConfigError, ForceRequired

from processing.dataset.manifest import MANIFEST, TABLE, write_manifest, write_table
from processing.dataset.runfile import check_run_file
from processing.dataset.sweep import MAX_RUNS, RunSpec, Sweep  # noqa: F401 (docs)
from processing.dataset.task import Job, JobResult

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

__all__ = ["PlannedRun", "SweepProgress", "SweepResult", "SweepInterrupted", "SweepStopped",
           "plan_runs",
           "describe_plan", "run_sweep", "JOURNAL", "PLAN"]

JOURNAL, PLAN, RUNS = "journal.jsonl", "sweep.json", "runs"
#: Cost of a run of the linear model in a warm worker, for the dry run's estimate: seconds per
#: simulated second and per run (fitted to the paper's run: 2.4 s acquisition + 0.3 s analysis
#: for 3300 s simulated, BENCHMARKS.md "Datasets").
_S_PER_SIM_S, _S_PER_RUN = 6.3e-4, 0.6


@dataclass(frozen=True)
class PlannedRun:
    """A run of the plan: its spec, its resolved scene settings (None if the scene rejected the
    parameter set, ``error`` says why), simulated seconds and an estimate of its file size."""

    spec: RunSpec
    settings: dict | None
    scene_source: str
    error: str
    simulated_s: float
    bytes_estimate: int


@dataclass(frozen=True)
class SweepProgress:
    """Where a sweep is: runs ``done`` (complete, this session or skipped), ``failed``,
    ``skipped`` (already complete), ``total``; ``rate_per_min`` of runs finished this session and
    ``eta_s`` (None until a run has finished)."""

    total: int
    done: int
    failed: int
    skipped: int
    running: int
    elapsed_s: float
    rate_per_min: float
    eta_s: float | None


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` left in ``out_dir``: counts, the manifest files and every run's
    result ({index: :class:`processing.dataset.task.JobResult`}); ``removed``: the names
    of run files of an earlier plan that the new one does not list (removed with ``force``)."""

    out_dir: Path
    total: int
    complete: int
    failed: int
    missing: int
    skipped: int
    manifest: Path
    table: Path
    results: dict
    wall_s: float
    interrupted: bool = False
    removed: tuple = ()


class SweepInterrupted(KeyboardInterrupt):
    """The sweep was interrupted; ``result`` is the :class:`SweepResult` (manifest written),
    ``signum`` the signal that stopped it (that of :class:`daq.signals.Stopped`; 2, SIGINT, for
    a plain KeyboardInterrupt)."""

    def __init__(self, result: SweepResult, signum: int = 2):
        super().__init__(f"sweep interrupted: {result.complete} of {result.total} runs complete")
        self.result = result
        self.signum = signum


# -- planning --------------------------------------------------------------------------------

def plan_runs(sweep: Sweep, *, progress: Callable[[int, int], None] | None = None,
              every_s: float = 1.0) -> tuple[PlannedRun, ...]:
    """Resolve every run's scene (an invalid parameter set is recorded, not raised) and check the
    analysis settings against its records. ``progress(done, total)`` is called at most once per
    ``every_s`` seconds while that takes (at most :data:`MAX_RUNS` runs). What the runs share
    is checked once (:class:`rig.scene.ResolutionMemo`); each run's verdict and message are those
    of its scene loaded alone."""
    from processing.spectra import SettingsError
    from rig.scene import ResolutionMemo, load_scene, read_scene_data

    settings = sweep.analyzer_settings()
    base, origin = read_scene_data(sweep.scene)  # parsed once, copied per run
    memo = ResolutionMemo()  # what the runs share is checked once
    out = []
    specs = sweep.runs()
    shown = time.monotonic()
    for k, spec in enumerate(specs):
        if progress is not None and time.monotonic() - shown >= every_s:
            progress(k, len(specs))
            shown = time.monotonic()
        try:
            sc = load_scene({"settings": base, "origin": origin}, spec.overrides, memo=memo)
            acq = sc.acquisition
            samples = round(acq.record_s * acq.rate_hz)
            memo.step(("spectral", acq.rate_hz, samples),
                      lambda: settings.spectral(acq.rate_hz, samples),
                      errors=(ConfigError, SettingsError))
        except (ConfigError, SettingsError) as exc:
            out.append(PlannedRun(spec, None, "", str(exc).splitlines()[0], 0.0, 0))
            continue
        sim_s = acq.settle_s + acq.records * acq.record_s
        size = run_file_bytes(records=acq.records, samples=samples, channels=3,  # a, x, y
                              bodies=sc.chain.n, truth=acq.truth and sweep.keep["truth"])
        out.append(PlannedRun(spec, sc.settings, sc.origin, "", float(sim_s), size))
    return tuple(out)


def describe_plan(sweep: Sweep, planned, *, workers: int, head: int = 10) -> str:
    """What ``--dry-run`` prints: the count, the parameter table's head, time and disk."""
    ok = [p for p in planned if not p.error]
    keys = list(sweep.parameter_keys)
    lines = [f"sweep {sweep.name}: {len(planned)} runs ({len(ok)} valid, "
             f"{len(planned) - len(ok)} invalid parameter sets), seed {sweep.seed}, scene "
             f"{sweep.scene}"]
    cols = ["run", "seed", *keys, "status"]
    table = [cols]
    for p in planned[:head]:
        table.append([str(p.spec.index), str(p.spec.seed),
                      *(_fmt(p.spec.params[k]) for k in keys),
                      "ok" if not p.error else f"invalid: {p.error}"])
    widths = [max(len(r[i]) for r in table) for i in range(len(cols) - 1)]
    for r in table:
        lines.append("  " + "  ".join(c.rjust(w) for c, w in zip(r, widths)) + "  " + r[-1])
    if len(planned) > head:
        lines.append(f"  ... {len(planned) - head} more")
    each = [_S_PER_RUN + _S_PER_SIM_S * p.simulated_s for p in ok]
    disk = sum(p.bytes_estimate for p in ok)
    # the runs spread over the workers, never shorter than the longest run
    wall = max(max(each, default=0.0), sum(each) / max(1, workers))
    lines.append(f"estimated time: {_duration(wall)} on {workers} worker"
                 f"{'s' if workers != 1 else ''} for the linear model (runs whose drive needs "
                 "the nonlinear model take longer: BENCHMARKS.md)")
    lines.append(f"estimated disk: {disk / 1e6:.1f} MB (at most: run files before "
                 "compression)")
    return "\n".join(lines)


def _fmt(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def _duration(s: float) -> str:
    if s < 1:
        return "< 1 s"
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


# -- the directory ---------------------------------------------------------------------------

def _plan_doc(sweep: Sweep, planned) -> dict:
    return {"format": "pendulum-daq sweep plan", "version": 1, "sweep": sweep.describe(),
            "runs": len(planned), "spec_hashes": [p.spec.spec_hash for p in planned]}


def _changes(old: dict, new: dict) -> list[str]:
    out = []
    a, b = old.get("sweep", {}), new["sweep"]
    for k in sorted(set(a) | set(b)):
        if a.get(k) != b.get(k):
            out.append(f"{k}: {_short(a.get(k))} -> {_short(b.get(k))}")
    if old.get("runs") != new["runs"]:
        out.append(f"runs: {old.get('runs')} -> {new['runs']}")
    if not out and old.get("spec_hashes") != new["spec_hashes"]:
        out.append("the base scene's file changed")
    return out


def _short(v) -> str:
    s = json.dumps(v, sort_keys=True)
    return s if len(s) <= 80 else s[:77] + "..."


def _read_plan(path: Path) -> dict:
    """The plan a sweep directory was made with; a ConfigError saying what to do if it is
    damaged."""
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _damaged(path, f"not JSON: {str(exc).splitlines()[0]}", _PLAN_REMEDY) from None
    if not (isinstance(doc, dict) and isinstance(doc.get("sweep"), dict)):
        raise _damaged(path, "not a sweep's plan", _PLAN_REMEDY)
    return doc


_PLAN_REMEDY = ("it records which sweep made the directory; run the sweep into a new output "
                "directory, or remove this one and run it again")


def _prepare(out_dir: Path, sweep: Sweep, planned, force: bool) -> list[str]:
    doc = _plan_doc(sweep, planned)
    plan_path = out_dir / PLAN
    changes: list[str] = []
    if out_dir.exists():
        if not out_dir.is_dir():
            raise ConfigError(f"output directory {str(out_dir)!r} is a file; expected a "
                              "directory")
        if plan_path.exists():
            old = _read_plan(plan_path)
            changes = _changes(old, doc)
            if changes and not force:
                raise ForceRequired(f"{str(out_dir)!r} holds another version of this sweep; "
                                    f"changed: {'; '.join(changes)}; choose another output "
                                    "directory, or force",
                                    "apply the changes (runs whose specification changed are "
                                    "redone and their files replaced, run files it does not "
                                    "list removed)")
        elif any(p.name != ".lock" for p in out_dir.iterdir()):
            raise ConfigError(f"output directory {str(out_dir)!r} exists and is not a sweep "
                              f"directory (no {PLAN}); expected a new or empty directory, or a "
                              "sweep's")
    (out_dir / RUNS).mkdir(parents=True, exist_ok=True)
    _write_atomic(plan_path, json.dumps(doc, indent=1, sort_keys=True))
    if sweep.text:
        _write_atomic(out_dir / "sweep.toml", sweep.text)
    return changes


def _write_atomic(path: Path, text: str) -> None:
    with atomic_output(path, force=True, durable=True) as tmp:
        tmp.write_text(text)


@contextlib.contextmanager
def _locked(out_dir: Path):
    out_dir.mkdir(parents=True, exist_ok=True)
    fh = open(out_dir / ".lock", "a+")
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise ConfigError(f"{str(out_dir)!r} is in use by another running sweep; wait "
                                  "for it or choose another output directory") from None
        yield
    finally:
        fh.close()


def _damaged(path: Path, what: str, remedy: str) -> ConfigError:
    return ConfigError(f"{str(path)!r} is damaged ({what}): the sweep cannot be resumed from it; "
                       f"{remedy}")


def _read_journal(out_dir: Path) -> dict:
    """The journal's last record of each run; a line cut by a kill (the last) is skipped, any
    other damage refused with what to do (a ConfigError)."""
    out = {}
    path = out_dir / JOURNAL
    if not path.exists():
        return out
    remedy = (f"move it aside and run again (each run file in {RUNS}/ is then verified by its "
              "own checksums), or choose another output directory")
    try:
        lines = path.read_bytes().decode("utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise _damaged(path, f"byte {exc.start} is not text", remedy) from None
    for i, line in enumerate(lines, 1):
        try:
            r = json.loads(line)
        except json.JSONDecodeError:
            if i == len(lines):
                continue  # a line cut by a kill
            raise _damaged(path, f"line {i} is not JSON", remedy) from None
        if not (isinstance(r, dict) and isinstance(r.get("index"), int)):
            raise _damaged(path, f"line {i} is not a run's record", remedy)
        out[r["index"]] = r
    return out


def _remove_unlisted(runs_dir: Path, planned) -> list[str]:
    """Remove the run files (and set-aside damaged ones) of an earlier plan whose runs the new
    plan does not have (a sweep changed with ``force`` to fewer runs); returns their names."""
    names = {p.spec.name for p in planned}
    gone = []
    for f in sorted(runs_dir.glob("run_*.h5*")):
        base = f.name.split(".invalid-")[0]
        if base not in names and (f.name.endswith(".h5") or ".invalid-" in f.name):
            f.unlink()
            gone.append(f.name)
    return gone


def _clean_partials(runs_dir: Path) -> None:
    """Remove temporary files of this host's dead writers (``.run_*.<host>.<pid>.*.partial.h5``)."""
    host = socket.gethostname().replace(".", "-")
    for p in runs_dir.glob(".run_*.partial.h5"):
        parts = p.name.split(".")
        try:
            h, pid = parts[-5], int(parts[-4])
        except (IndexError, ValueError):
            continue
        if h == host and not process_alive(pid):
            p.unlink(missing_ok=True)


# -- running ---------------------------------------------------------------------------------

class SweepStopped(ConfigError):
    """The sweep stopped because its journal or manifest could not be written (a full disk);
    ``results`` holds every run's result so far ({index: JobResult})."""

    def __init__(self, message: str, results: dict):
        super().__init__(message)
        self.results = results


def _stopped(exc: OSError, out_dir: Path, total: int, results: dict, manifest) -> SweepStopped:
    """The error of a sweep stopped because its journal or manifest could not be written."""
    import errno

    full = (getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT)
            or "No space left on device" in str(exc))
    what = ("the disk is full" if full else
            f"{getattr(exc, 'filename', None) or out_dir}: {exc.strerror or exc}")
    done = sum(r.status == "complete" for r in results.values())
    index = "the manifest lists them" if manifest is not None else "no manifest was written"
    return SweepStopped(f"the sweep stopped after {done} of {total} runs complete because {what}"
                        f" ({index}); the finished run files are kept: free some space in "
                        f"{str(out_dir)!r} and run the same command again to finish",
                        dict(results))


def _job(sweep: Sweep, p: PlannedRun, runs_dir: Path, replace: bool) -> Job:
    s = p.spec
    return Job(index=s.index, seed=s.seed, sweep_seed=sweep.seed, params=s.params,
               overrides=tuple(s.overrides), spec_hash=s.spec_hash, settings=p.settings,
               scene_source=p.scene_source, analysis=dict(sweep.analysis), keep=dict(sweep.keep),
               runs_dir=str(runs_dir.resolve()), file=s.name, replace=replace)


def run_sweep(sweep: Sweep, out_dir: str | Path, *,
              executor: Executor | Callable[[], Executor] | None = None, workers: int | None = None,
              force: bool = False, max_retries: int = 2,
              progress: Callable[[SweepProgress], None] | None = None,
              planned=None) -> SweepResult:
    """Run (or finish) ``sweep`` into ``out_dir`` (module docstring).

    Parameters
    ----------
    executor : an Executor (e.g. ``distributed.Client(...).get_executor(pure=False)``), or a
        function making one (called again to rebuild a broken pool); default: a local spawn
        process pool of ``workers`` (:func:`processing.dataset.engines.local_pool`).
    workers : tasks in flight at once (default: the executor's workers, or the cores).
    force : apply a changed sweep file to an existing directory.
    max_retries : resubmissions of a run whose worker died before it is recorded as failed.
    progress : called with a :class:`SweepProgress` after every finished run.
    planned : the :func:`plan_runs` of ``sweep`` if already made.

    Raises
    ------
    ConfigError : before any run, for a directory that holds something else or another sweep.
    SweepInterrupted : on KeyboardInterrupt, after the manifest is written.
    """
    from processing.dataset.engines import default_workers

    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    planned = plan_runs(sweep) if planned is None else planned
    workers = workers or default_workers()
    factory, own = _executor_factory(executor, workers)
    with _locked(out_dir):
        changes = _prepare(out_dir, sweep, planned, force)
        runs_dir = out_dir / RUNS
        _clean_partials(runs_dir)
        removed = _remove_unlisted(runs_dir, planned) if changes else ()
        results, todo, skipped = _triage(sweep, planned, runs_dir, force,
                                         _read_journal(out_dir))
        total = len(planned)
        record = _Recorder(out_dir / JOURNAL, results, total, skipped, progress, t0)
        outcome = _Outcome()
        try:
            _execute(todo, record, factory, own, workers, max_retries, outcome)
        finally:
            _clean_partials(runs_dir)  # and those of workers that died
            try:
                manifest = write_manifest(out_dir, sweep, [p.spec for p in planned], results)
                table = write_table(out_dir / TABLE, [p.spec for p in planned], results,
                                    sweep.parameter_keys)
            except OSError as exc:
                if outcome.stopped_by is None and not outcome.interrupted:
                    outcome.stopped_by = exc
                manifest = table = None
        if outcome.stopped_by is not None:
            raise _stopped(outcome.stopped_by, out_dir, total, results, manifest)
        counts = collections.Counter(r.status for r in results.values())
        result = SweepResult(out_dir=out_dir, total=total, complete=counts["complete"],
                             failed=counts["failed"],
                             missing=total - counts["complete"] - counts["failed"],
                             skipped=skipped, manifest=manifest, table=table,
                             results=dict(results), wall_s=time.perf_counter() - t0,
                             interrupted=outcome.interrupted, removed=tuple(removed))
    if outcome.interrupted:
        raise SweepInterrupted(result, outcome.signum)
    return result


def _executor_factory(executor, workers: int) -> tuple[Callable[[], Executor], bool]:
    """A function making the executor of :func:`run_sweep`'s ``executor`` argument, and whether
    the sweep owns it (shuts it down, rebuilds it when broken)."""
    from processing.dataset.engines import local_pool

    if executor is None:
        return (lambda: local_pool(workers)), True
    if callable(executor) and not isinstance(executor, Executor):
        return executor, True
    return (lambda: executor), False


def _triage(sweep: Sweep, planned, runs_dir: Path, force: bool,
            journal: dict) -> tuple[dict, collections.deque, int]:
    """The results known before any run (failed plans, valid finished files: skipped) and the
    jobs to run; a damaged or unfinished file under a final name is moved aside, a finished file
    of an earlier plan replaced with ``force``. Returns ``(results, todo, skipped)``."""
    results: dict[int, JobResult] = {}
    todo = collections.deque()
    skipped = 0
    for p in planned:
        s = p.spec
        if p.error:
            results[s.index] = JobResult.failed(s.index, p.error)
            continue
        final = runs_dir / s.name
        replace = False
        if final.exists():
            j = journal.get(s.index)
            known = (j["sha256"] if j and j.get("status") == "complete"
                     and j.get("spec_hash") == s.spec_hash else None)
            chk = check_run_file(final, sha256=known, spec_hash=s.spec_hash)
            if chk.ok:
                results[s.index] = JobResult(index=s.index, status="complete", file=s.name,
                                             sha256=chk.sha256, model=(j or {}).get("model", ""))
                skipped += 1
                continue
            if chk.spec_hash and chk.spec_hash != s.spec_hash and force:
                replace = True  # a finished file of the old plan: --force replaces it
            else:  # damaged or unfinished under the final name: kept aside, redone
                k = 0
                while final.with_name(f"{s.name}.invalid-{k}").exists():
                    k += 1
                shutil.move(final, final.with_name(f"{s.name}.invalid-{k}"))
        todo.append(_job(sweep, p, runs_dir, replace))
    return results, todo, skipped


@dataclass
class _Outcome:
    """How :func:`_execute` ended: interrupted (and by which signal), or stopped by an error
    writing the journal."""

    interrupted: bool = False
    signum: int = 2
    stopped_by: OSError | None = None


class _Recorder:
    """Records a finished run: into ``results``, one journal line (flushed and synced), and the
    progress callback; ``inflight`` is the executor's futures of the runs in flight."""

    def __init__(self, path: Path, results: dict, total: int, skipped: int, progress, t0: float):
        self.path, self.results, self.total, self.skipped = path, results, total, skipped
        self.progress, self.t0 = progress, t0
        self.done = skipped
        self.failed = sum(r.status == "failed" for r in results.values())
        self.finished_now = 0
        self.inflight: dict = {}

    def __call__(self, res: JobResult, spec_hash: str) -> None:
        self.results[res.index] = res
        with open(self.path, "a") as fh:
            fh.write(json.dumps({**res.to_dict(), "spec_hash": spec_hash}) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        if res.status == "complete":
            self.done += 1
        else:
            self.failed += 1
        self.finished_now += 1
        if self.progress is not None:
            el = time.perf_counter() - self.t0
            rate = self.finished_now / el * 60 if el > 0 else 0.0
            left = self.total - self.done - self.failed
            self.progress(SweepProgress(total=self.total, done=self.done, failed=self.failed,
                                        skipped=self.skipped, running=len(self.inflight),
                                        elapsed_s=el, rate_per_min=rate,
                                        eta_s=left / rate * 60 if rate > 0 else None))


def _execute(todo: collections.deque, record: _Recorder, factory: Callable[[], Executor],
             own: bool, window: int, max_retries: int, outcome: _Outcome) -> None:
    """Run the jobs of ``todo``, at most ``window`` in flight (in flight = running: a dead
    worker charges only the runs it could hold), recording each result; a broken pool is
    rebuilt (if owned) and its runs resubmitted up to ``max_retries`` times. A journal that
    cannot be written or a KeyboardInterrupt ends it (``outcome`` says which)."""
    from processing.dataset.task import failure_text, run_task

    inflight = record.inflight
    ex = factory() if todo else None
    attempts = collections.Counter()
    try:
        while todo or inflight:
            while todo and len(inflight) < window:
                job = todo.popleft()
                inflight[ex.submit(run_task, job)] = job
            done, _ = wait(list(inflight), timeout=1.0, return_when=FIRST_COMPLETED)
            broken = []
            for fut in done:
                job = inflight.pop(fut)
                try:
                    res = fut.result()
                except BrokenProcessPool:
                    broken.append(job)
                    continue
                except KeyboardInterrupt:
                    raise
                except Exception as exc:  # e.g. Dask's KilledWorker after its retries
                    res = JobResult.failed(job.index, failure_text(exc)[:500])
                record(res, job.spec_hash)
            if broken:
                # the pool is dead: every run in flight went with it
                for fut in list(inflight):
                    broken.append(inflight.pop(fut))
                with contextlib.suppress(Exception):
                    ex.shutdown(wait=False, cancel_futures=True)
                ex = factory() if own else ex
                for job in sorted(broken, key=lambda j: j.index):
                    attempts[job.index] += 1
                    if attempts[job.index] > max_retries or not own:
                        record(JobResult.failed(
                            job.index, f"BrokenProcessPool: the worker running it died "
                                       f"{attempts[job.index]} times (killed or out of memory)"),
                               job.spec_hash)
                    else:
                        todo.appendleft(job)
    except OSError as exc:  # the journal cannot be written (a full disk): stop here
        outcome.stopped_by = exc
        todo.clear()
        for fut in list(inflight):
            fut.cancel()
    except KeyboardInterrupt as exc:
        outcome.interrupted, outcome.signum = True, getattr(exc, "signum", 2)
        _keep_finished(inflight, ex, record)
    finally:
        if ex is not None and own and not outcome.interrupted:
            ex.shutdown(wait=True)  # runs in flight end (and remove their temporary files)


def _keep_finished(inflight: dict, ex, record: _Recorder) -> None:
    """After a KeyboardInterrupt: cancel what has not started, shut the executor down, and
    record the runs that completed meanwhile."""
    for fut in list(inflight):
        fut.cancel()
    if ex is not None:
        with contextlib.suppress(BaseException):
            ex.shutdown(wait=True, cancel_futures=True)
    for fut, job in list(inflight.items()):
        if fut.done() and not fut.cancelled():
            with contextlib.suppress(BaseException):
                res = fut.result()
                if res.status == "complete":
                    record(res, job.spec_hash)
