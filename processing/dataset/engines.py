"""Where a sweep's tasks run: any :class:`concurrent.futures.Executor`.

- :func:`local_pool`: the default, a :class:`~concurrent.futures.ProcessPoolExecutor` with the
  ``spawn`` start method (no fork after h5py or numba threads exist) whose long-lived workers keep
  their imports and compiled kernels from run to run; they die with the parent.
- :func:`dask_executor`: an existing Dask distributed cluster (``tcp://host:8786``) or a
  ``distributed.Client``, through ``Client.get_executor(pure=False)``, whose futures are
  ``concurrent.futures`` futures: the runner has one code path for both. Dask is the optional
  extra ``pendulum-daq[dask]``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from concurrent.futures import Executor, ProcessPoolExecutor

from rig.errors import ConfigError

__all__ = ["local_pool", "dask_executor", "default_workers", "worker_limit", "cluster_limit",
           "WORKER_BYTES", "DASK_MISSING"]

#: Seconds a Dask scheduler has to answer (connect and handshake) before it is given up.
CONNECT_TIMEOUT_S = 10.0
DASK_MISSING = ("--scheduler needs Dask distributed, the optional extra of pendulum-daq: "
                "pip install 'pendulum-daq[dask]' (or 'dask[distributed]')")


#: Memory a local worker takes once its imports and kernels are loaded [bytes] (an upper
#: figure: numba, h5py, scipy and a run's arrays).
WORKER_BYTES = 300_000_000


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def available_memory_bytes() -> int | None:
    """Memory available to new processes (Linux MemAvailable) [bytes]; None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def worker_limit(asked: int | None) -> tuple[int, str]:
    """The local workers to run: ``asked`` (default: the cores) capped at the cores and at the
    available memory (:data:`WORKER_BYTES` each), and why it was capped ("" if not)."""
    cores = default_workers()
    mem = available_memory_bytes()
    by_mem = None if mem is None else max(1, mem // WORKER_BYTES)
    n = cores if asked is None else asked
    why = ""
    if n > cores:
        why = (f"--workers {asked} is more than the {cores} cores: more processes than cores "
               "share them and run slower")
        n = cores
    if by_mem is not None and n > by_mem:
        why = (f"{'--workers ' + str(asked) if asked else str(n) + ' workers'} need about "
               f"{n * WORKER_BYTES / 1e9:.1f} GB ({WORKER_BYTES / 1e6:.0f} MB each) but "
               f"{mem / 1e9:.1f} GB is available")
        n = by_mem
    return n, why


def local_pool(workers: int) -> Executor:
    """A spawn-context process pool of ``workers`` long-lived workers (:func:`worker_init`)."""
    from processing.dataset.task import worker_init

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers = {workers!r} is invalid: expected an integer >= 1")
    _start_resource_tracker()
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=worker_init)


def _connect(distributed, address: str, timeout_s: float):
    """A ``distributed.Client`` of ``address``, made on a helper thread: the caller waits at
    most ``timeout_s`` (+ 1 s) for it, interruptibly (the Client's own timeout does not bound
    a peer that accepts the connection and never answers)."""
    import threading

    box: dict = {}

    def make():
        try:
            box["client"] = distributed.Client(address, timeout=f"{timeout_s:g}s")
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    t = threading.Thread(target=make, name="dask-connect", daemon=True)
    t.start()
    t.join(timeout_s + 1.0)  # a signal handler's exception (daq.signals) still interrupts
    if "client" in box:
        return box["client"]
    err = box.get("error")
    why = "no answer" if err is None else (str(err).strip().splitlines() or ["refused"])[0]
    raise ConfigError(f"--scheduler {address!r}: no Dask scheduler answered there within "
                      f"{timeout_s:g} s ({why}); expected the address of a running scheduler, "
                      "e.g. tcp://host:8786")


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (a helper process the pool needs) ignoring
    SIGHUP, as it ignores SIGINT and SIGTERM: a closed terminal hangs up the whole process group,
    and a tracker killed by it prints a traceback while the sweep stops cleanly."""
    import signal
    import threading
    from multiprocessing import resource_tracker

    hup = getattr(signal, "SIGHUP", None)
    if hup is None or threading.current_thread() is not threading.main_thread():
        resource_tracker.ensure_running()
        return
    old = signal.signal(hup, signal.SIG_IGN)  # inherited through exec, unlike a handler
    try:
        resource_tracker.ensure_running()
    finally:
        signal.signal(hup, old)


def cluster_limit(workers: dict) -> tuple[int, str]:
    """The runs a Dask cluster can hold at once, and why it is fewer than its threads ("" if
    not), from its scheduler's worker records (``Client.scheduler_info()["workers"]``: each
    worker's ``nthreads`` and ``memory_limit`` [bytes], 0 for none). The cluster may be remote,
    so this machine's cores and memory do not bound it: its own threads are its cores (Dask
    starts one per core unless told otherwise), and each worker runs at most one run per
    :data:`WORKER_BYTES` of its memory limit."""
    threads = slots = 0
    short = []
    for w in workers.values():
        n = max(0, int(w.get("nthreads") or 0))
        limit = int(w.get("memory_limit") or 0)
        fit = n if limit <= 0 else min(n, max(1, limit // WORKER_BYTES))
        threads += n
        slots += fit
        if fit < n:
            short.append(limit)
    why = ""
    if short:
        why = (f"the Dask cluster has {threads} worker threads but the memory limits of "
               f"{len(short)} of its {len(workers)} workers ({min(short) / 1e9:.2g} GB and up) hold "
               f"fewer runs than their threads ({WORKER_BYTES / 1e6:.0f} MB each)")
    return max(1, slots), why


@contextlib.contextmanager
def dask_executor(scheduler, *, timeout_s: float = CONNECT_TIMEOUT_S):
    """Yield ``(executor, slots, why)`` for a Dask cluster: ``scheduler`` is an address
    (``tcp://host:8786``) or a ``distributed.Client``; ``slots`` the runs to keep in flight,
    its worker threads capped by its workers' memory (:func:`cluster_limit`, which says
    ``why`` when it caps). A client made here is closed on exit (the cluster keeps running).
    An address that does not answer within ``timeout_s`` is a ConfigError."""
    try:
        import distributed
    except ImportError:
        raise ConfigError(DASK_MISSING) from None
    own = not isinstance(scheduler, distributed.Client)
    if own:
        client = _connect(distributed, str(scheduler), timeout_s)
    else:
        client = scheduler
    try:
        slots, why = cluster_limit(client.scheduler_info(n_workers=-1).get("workers", {}))
        yield client.get_executor(pure=False), slots, why
    finally:
        if own:
            client.close()
