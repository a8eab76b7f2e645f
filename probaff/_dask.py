"""Where batch work runs: in this process, on a local Dask cluster, or on a given scheduler."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import Any

from probaff._checks import check_count
from probaff.errors import InputError

__all__ = ["check_workers", "dask_client"]


def check_workers(workers: int | None) -> int | None:
    """Return `workers` as an `int` (or ``None``), or raise `InputError`.

    Args:
        workers: ``None`` (one local worker per core), 0 (run in this process) or a number
            of local worker processes.

    Returns:
        ``None``, or `workers` as a builtin `int` >= 0.
    """
    if workers is None:
        return None
    try:
        return check_count("workers", workers, minimum=0)
    except InputError:
        raise InputError(f"workers must be None or an integer >= 0, got {workers!r}.") from None


@contextlib.contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A Dask client: on `scheduler` if given, else on a new local cluster.

    Args:
        workers: Local worker processes (single-threaded each); ``None`` means one per core.
        scheduler: Address of an existing scheduler (``tcp://host:port``).

    Yields:
        A connected `dask.distributed.Client`.
    """
    from dask.distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler) as client:
            yield client
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        yield client
