"""A Dask client for :func:`~sensorless.regressor.distributed.compress_files`: a ``LocalCluster`` on this
machine or an existing scheduler, with Dask's own logging silenced while it is open (a file that cannot be
used is reported once, as the typed error the client raises, not as the scheduler's and workers' log lines)."""

from __future__ import annotations

import contextlib
import logging
import os
from typing import Any, Iterator

from ..errors import DistributedError, setting

__all__ = ["connect"]


@contextlib.contextmanager
def connect(scheduler: str, workers: int | None = None, *, timeout: float = 30.0) -> Iterator[Any]:
    """A ``distributed.Client`` for ``scheduler``: ``"local"`` starts a ``LocalCluster`` of
    ``workers`` processes (default: one per core, one thread each: the regressor loop holds
    the GIL); any other value is a scheduler address (``tcp://host:8786``) of an existing
    cluster, and ``workers`` then waits until that many workers are connected."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise DistributedError(f"{setting('scheduler')} needs dask.distributed: pip install 'sensorless[dist]'") from None
    if workers is not None and workers < 1:
        raise DistributedError(f"{setting('workers')} must be >= 1, got {workers}")
    with _quiet_dask_logs():
        cluster = None
        try:
            if scheduler == "local":
                cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.CRITICAL)
                client = Client(cluster)
            else:
                client = Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError, ValueError) as exc:
            if cluster is not None:
                cluster.close()
            raise DistributedError(f"{scheduler}: cannot reach the Dask scheduler ({type(exc).__name__}: {exc})") from None
        try:
            if workers and cluster is None:
                try:
                    client.wait_for_workers(workers, timeout=timeout)
                except TimeoutError:
                    raise DistributedError(f"{scheduler}: fewer than {workers} workers connected after {timeout:.0f} s") from None
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


@contextlib.contextmanager
def _quiet_dask_logs() -> Iterator[None]:
    """Dask's loggers (``distributed``, ``dask``, ``tornado``) at CRITICAL in this process for the block: a
    failed file is reported once, as a typed error, not as the scheduler's and workers' log lines."""
    loggers = [logging.getLogger(n) for n in ("distributed", "dask", "tornado", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)
