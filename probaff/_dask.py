"""Where batch work runs: in this process, on a local Dask cluster, or on a given scheduler."""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from typing import Any

from tqdm.auto import tqdm

from probaff._checks import check_count
from probaff.errors import ClusterError, InputError, ProbaffError

__all__ = ["check_batch", "check_scheduler", "check_workers", "dask_client", "run_batch"]


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


_HOW_TO_START = (
    "start one with `dask scheduler` (and `dask worker ADDRESS` on each machine), or leave "
    "the scheduler out to use a local cluster (--workers K)"
)


def check_scheduler(scheduler: str | None) -> str | None:
    """Return `scheduler` unchanged, or raise `InputError` unless it is a Dask address.

    Checks the address's form only (a scheme Dask knows, a host and a port); whether a
    scheduler listens there is found out when `dask_client` connects.

    Args:
        scheduler: ``None`` (a local cluster) or an address such as ``tcp://host:8786``.

    Returns:
        `scheduler`.
    """
    if scheduler is None:
        return None
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise InputError(
            f"scheduler must be a Dask scheduler address such as tcp://127.0.0.1:8786, got "
            f"{scheduler!r}."
        )
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import backends

    try:
        scheme, location = parse_address(scheduler)
        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r}; Dask knows {sorted(backends)}")
        if scheme in ("tcp", "tls", "ws", "wss"):
            parse_host_port(location)
    except (ValueError, TypeError) as err:
        raise InputError(
            f"scheduler {scheduler!r} is not a Dask scheduler address ({err}); give one such "
            "as tcp://127.0.0.1:8786."
        ) from None
    return scheduler


def check_batch(workers: int | None, scheduler: str | None) -> tuple[int | None, str | None]:
    """Check where a batch runs: `check_workers`, then `check_scheduler`'s address form.

    Args:
        workers: ``None`` (one local worker per core), 0 (this process) or a worker count.
        scheduler: ``None`` (a local cluster) or a Dask scheduler address.

    Returns:
        ``(workers, scheduler)``, `workers` as a builtin `int` (or ``None``).

    Raises:
        InputError: Naming ``scheduler`` or ``workers``.
    """
    return check_workers(workers), check_scheduler(scheduler)


@contextlib.contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A Dask client: on `scheduler` if given, else on a new local cluster.

    Args:
        workers: Local worker processes (single-threaded each); ``None`` means one per core.
        scheduler: Address of an existing scheduler (``tcp://host:port``).

    Yields:
        A connected `dask.distributed.Client`.

    Raises:
        InputError: For a malformed `scheduler` address, or one where no scheduler answers
            within Dask's connect timeout (``distributed.comm.timeouts.connect``).
    """
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler:
        check_scheduler(scheduler)
        try:
            client = Client(scheduler)
        except OSError as err:  # Dask's connect timeout, refused connections, unknown hosts
            raise InputError(
                f"no Dask scheduler could be reached at {scheduler} ({err}); {_HOW_TO_START}."
            ) from None
        with client:
            yield client
        return
    n = workers or os.cpu_count() or 1
    # Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536. Setting it switches off glibc's
    # dynamic mmap threshold, so every GP kernel matrix is mmapped and page-faulted afresh:
    # one EM path took 136 s (43 s in the kernel) with it against 83 s (2 s) without.
    # A Dask nanny started earlier in this process leaves the variable in os.environ, where
    # new workers would inherit it; hide that value while the workers spawn.
    inherited = os.environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    if inherited is not None and inherited != "65536":  # the user's own setting stays
        os.environ["MALLOC_TRIM_THRESHOLD_"] = inherited
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
            )
    finally:
        if inherited is not None:
            os.environ["MALLOC_TRIM_THRESHOLD_"] = inherited
    with cluster, Client(cluster) as client:
        yield client


def run_batch(
    fn: Callable[..., Any],
    todo: Sequence[tuple[Hashable, tuple[Any, ...]]],
    on_result: Callable[[Hashable, Any], None],
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    shared: Mapping[str, Any] | None = None,
    progress: bool = True,
    total: int | None = None,
    done: int = 0,
    size: Callable[[Hashable], int] | None = None,
    unit: str = "task",
    desc: str = "tasks",
) -> None:
    """Run ``fn(*args, **shared)`` for every ``(key, args)`` of `todo`, serially or on Dask.

    The one batch loop of probaff: dataset generation and study tasks both use it. Each
    result is handed to ``on_result(key, result)`` in this process as soon as it lands (in
    completion order on Dask), so the caller can save it atomically; a crash loses only the
    work in flight, and the caller resumes by leaving finished keys out of `todo`.

    Args:
        fn: A module-level function (Dask workers import it).
        todo: ``(key, args)`` pairs, in the order they should start.
        on_result: Called with each key and its result.
        workers: 0 runs in this process; K > 0 or ``None`` (one per core) starts a local
            cluster of single-threaded worker processes.
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        shared: Keyword arguments that every call receives. On Dask they are scattered to
            the workers once (large arrays travel once, not with every task).
        progress: Show a tqdm bar.
        total: Size of the whole batch for the bar (default: the number of tasks in `todo`
            plus `done`).
        done: Size already finished before this call (the bar's start).
        size: Size of one task for the bar (default: 1 each).
        unit: Unit of the bar.
        desc: Label of the bar.

    Raises:
        InputError: For bad `workers`, a malformed `scheduler` or one that cannot be reached.
        ClusterError: If the scheduler goes away during the batch (the results handed to
            `on_result` until then are kept by the caller; a rerun resumes). A worker that
            dies is not an error: Dask runs its unfinished tasks on the other workers, and
            the shared arguments it held are sent again.
    """
    workers, scheduler = check_batch(workers, scheduler)
    shared = dict(shared or {})
    weigh = size or (lambda key: 1)
    serial = workers == 0 and not scheduler
    # Dask's own tracebacks of a lost scheduler stay off stderr, also while the client closes.
    with _quiet_connection_loss(), contextlib.ExitStack() as stack:
        # Connect before the bar starts: an unreachable scheduler is one line, not a bar.
        client = (
            stack.enter_context(dask_client(workers, scheduler)) if todo and not serial else None
        )
        bar = stack.enter_context(
            tqdm(
                total=total if total is not None else done + sum(weigh(k) for k, _ in todo),
                initial=done,
                unit=unit,
                desc=desc,
                disable=not progress,
            )
        )
        if client is None:
            for key, args in todo:
                on_result(key, fn(*args, **shared))
                bar.update(weigh(key))
            return
        from dask.distributed import as_completed

        try:
            remote = _put_shared(client, shared)
            futures = [client.submit(fn, *args, **remote, pure=False) for _, args in todo]
            by_future = {f.key: key for f, (key, _) in zip(futures, todo, strict=True)}
            # Each result is fetched as soon as its task finishes, and released once saved:
            # a worker that dies later holds no finished result, so nothing saved runs again.
            pending = as_completed(futures, with_results=True)
            futures.clear()
            for fut, result in pending:
                if fut.status != "finished":  # cancelled: raise what `result` carries
                    raise result if isinstance(result, BaseException) else RuntimeError(result)
                key = by_future.pop(fut.key)
                on_result(key, result)
                fut.release()
                bar.update(weigh(key))
        except Exception as err:
            lost = _lost_cluster(client, err)
            if lost is None:
                raise
            raise ClusterError(
                f"the Dask scheduler {scheduler or '(local cluster)'} went away during the "
                f"batch ({lost}); every finished task is saved: restart the scheduler and its "
                "workers and rerun the same command, which runs only the missing tasks (or "
                "rerun with --workers K to use a local cluster)."
            ) from None


def _shared_value(value: Any) -> Any:
    """Return `value` (the task that holds a shared argument on the cluster)."""
    return value


def _put_shared(client: Any, shared: Mapping[str, Any]) -> dict[str, Any]:
    """Futures of the `shared` values, each sent to the cluster once.

    Each value is the result of a task (`_shared_value`), not scattered data: Dask's active
    memory manager keeps one replica of a key, so a broadcast copy is dropped again, and
    scattered data lost with the worker that holds it cannot be recovered (every task that
    needs it then fails). A task's result is computed again from the task instead.
    """
    import dask

    # The values travel inside the task spec by design (once, not with every task): no
    # "large graph" warning for them.
    with dask.config.set({"distributed.admin.large-graph-warning-threshold": "1 PiB"}):
        return {k: client.submit(_shared_value, v, pure=False) for k, v in shared.items()}


def _lost_cluster(client: Any, err: BaseException) -> str | None:
    """Why `err` means the scheduler is gone (a short reason), or ``None`` if it does not."""
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError

    if isinstance(err, ProbaffError):  # raised on purpose, by a task or by `on_result`
        return None
    if isinstance(err, CancelledError):
        reason = getattr(err, "reason", "")
        if reason == "scheduler-connection-lost" or client.status != "running":
            return "the client lost its connection to the scheduler"
        return None
    if isinstance(err, (CommClosedError, OSError, TimeoutError)) and client.status != "running":
        cause = err.__cause__ or err.__context__
        why = f" ({type(cause).__name__})" if cause is not None else ""
        return f"its connection closed: {type(err).__name__}{why}"
    return None


class _DropConnectionLoss(logging.Filter):
    """Drop Dask client log records about a lost scheduler connection (reported once, by us)."""

    def filter(self, record: logging.LogRecord) -> bool:
        import asyncio
        import concurrent.futures

        from distributed.comm.core import CommClosedError

        exc = record.exc_info[1] if record.exc_info else None
        cancelled = (asyncio.CancelledError, concurrent.futures.CancelledError)
        if isinstance(exc, (*cancelled, CommClosedError, OSError)):
            return False
        text = record.getMessage()
        lost = ("connection to the scheduler", "Reconnecting", "reconnect to scheduler")
        return not any(words in text for words in lost)


@contextlib.contextmanager
def _quiet_connection_loss() -> Iterator[None]:
    """Keep Dask's own tracebacks of a lost scheduler off stderr while a batch runs.

    After a `ClusterError` the filter stays: the dead client's reconnection task is cancelled
    only when the process exits, and logs its traceback then.
    """
    log = logging.getLogger("distributed.client")
    drop = _DropConnectionLoss()
    log.addFilter(drop)
    try:
        yield
    except ClusterError:
        raise
    except BaseException:
        log.removeFilter(drop)
        raise
    log.removeFilter(drop)
