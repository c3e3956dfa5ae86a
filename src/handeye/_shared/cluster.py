"""Work beyond one machine: a Dask distributed client for the Monte-Carlo study.

Dask is an optional extra (``pip install handeye[cluster]``): without it, and without a
``scheduler``, the study runs in local processes as before. ``scheduler="local"`` starts a
``LocalCluster`` of ``jobs`` worker processes for the call; any other value is the address of a
running scheduler (``tcp://host:8786``). Each task carries its own seed, so the numbers are those
of the local run whatever worker runs it.
"""

from __future__ import annotations

import importlib
from contextlib import contextmanager
from typing import Any, Iterator

from ..errors import HandEyeError
from .lazy import lazy_module

cv2 = lazy_module("cv2")

__all__ = ["dask_client", "dask_completed", "single_threaded", "CONNECT_TIMEOUT"]

#: How long to try to reach a scheduler's address before saying it cannot be reached.
CONNECT_TIMEOUT = "10s"


def _distributed() -> Any:
    try:
        return importlib.import_module("distributed")
    except ImportError:
        raise HandEyeError("a Dask scheduler was asked for, but Dask distributed is not installed: "
                           "pip install 'handeye[cluster]' (or leave the scheduler out to run in local processes)") from None


@contextmanager
def dask_client(scheduler: str, jobs: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` for ``scheduler`` ('local', or an address), closed afterwards (with
    the LocalCluster it started)."""
    distributed = _distributed()
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise HandEyeError(f"scheduler={scheduler!r}: give 'local' or the address of a Dask scheduler (tcp://host:8786)")
    if scheduler == "local":
        dask = importlib.import_module("dask")
        # Dask starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which hands freed memory back
        # to the system at once: for handeye's short tasks, each allocating and freeing images and
        # figures, that costs ~15% of a worker's time (measured: 50 sessions on 2 workers); a
        # LocalCluster handeye starts for one call and closes after it keeps glibc's own threshold.
        # Its statistical profiler samples the task's stack every 10 ms: ~5% of a worker's CPU
        # (measured: 1.47 -> 1.38 s a session), for a dashboard nobody opens here. Its periodic
        # housekeeping (event-loop ticks every 20 ms, memory checks every 100 ms, system monitor,
        # work stealing) costs an idle 2-worker cluster 0.50 s of CPU every 10 s, 0.15 s at the
        # intervals below, which tasks of a second or more do not need shorter
        environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ", {}).items()
                   if k != "MALLOC_TRIM_THRESHOLD_"}
        with dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                              "distributed.worker.profile.enabled": False,
                              "distributed.admin.tick.interval": "500ms",
                              "distributed.worker.memory.monitor-interval": "1s",
                              "distributed.admin.system-monitor.interval": "2s",
                              "distributed.scheduler.work-stealing-interval": "1s"}):
            cluster = distributed.LocalCluster(n_workers=jobs or None, threads_per_worker=1, processes=True,
                                               dashboard_address=None)
        try:
            with distributed.Client(cluster) as client:
                yield client
        finally:
            cluster.close()
        return
    try:
        client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise HandEyeError(f"cannot reach the Dask scheduler at {scheduler} ({exc}): start one "
                           "(dask scheduler) or use 'local'") from None
    try:
        yield client
    finally:
        client.close()


def dask_completed(futures: list[Any]) -> Iterator[Any]:
    """The Dask ``futures`` in the order they finish."""
    return _distributed().as_completed(futures)


@contextmanager
def single_threaded() -> Iterator[None]:
    """One BLAS thread and one OpenCV thread while the block runs, as in a worker process that
    shares the cores with others: two workers each spreading OpenCV's detector and OpenBLAS over
    every core fight over them (measured on 2 cores, 16 sessions in 2 worker processes: 1.06x the
    time of a plain loop over them without this, 0.79x with it)."""
    from threadpoolctl import threadpool_limits

    saved = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with threadpool_limits(1):
            yield
    finally:
        cv2.setNumThreads(saved)
