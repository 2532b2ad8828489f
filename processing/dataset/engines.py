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

__all__ = ["local_pool", "dask_executor", "default_workers", "DASK_MISSING"]

DASK_MISSING = ("--scheduler needs Dask distributed, the optional extra of pendulum-daq: "
                "pip install 'pendulum-daq[dask]' (or 'dask[distributed]')")


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def local_pool(workers: int) -> Executor:
    """A spawn-context process pool of ``workers`` long-lived workers (:func:`worker_init`)."""
    from processing.dataset.task import worker_init

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers = {workers!r} is invalid: expected an integer >= 1")
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=worker_init)


@contextlib.contextmanager
def dask_executor(scheduler):
    """Yield ``(executor, slots)`` for a Dask cluster: ``scheduler`` is an address
    (``tcp://host:8786``) or a ``distributed.Client``; ``slots`` is its total worker threads.
    A client made here is closed on exit (the cluster keeps running)."""
    try:
        import distributed
    except ImportError:
        raise ConfigError(DASK_MISSING) from None
    own = not isinstance(scheduler, distributed.Client)
    if own:
        try:
            client = distributed.Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError(f"--scheduler {scheduler!r}: cannot connect to a Dask scheduler "
                              f"there ({type(exc).__name__}: {exc}); expected the address of a "
                              "running scheduler, e.g. tcp://host:8786") from None
    else:
        client = scheduler
    try:
        slots = max(1, sum(client.nthreads().values()))
        yield client.get_executor(pure=False), slots
    finally:
        if own:
            client.close()
