"""Resumable batch evaluation: independent tasks, each result saved atomically as it lands.

A study is a list of tasks with unique keys (e.g. one cross-validation fold of one model). Each
finished task's result is written to ``ROOT/KEY.json`` at once, so a crashed or interrupted run
loses only the tasks in flight, and a rerun computes only the missing ones. Tasks run in this
process, on a local Dask cluster, or on an existing Dask scheduler.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from probaff._dask import run_batch
from probaff._io import atomic_write_text
from probaff.errors import DatasetError, InputError

__all__ = ["ResultStore", "run_tasks"]

_KEY = re.compile(r"^[A-Za-z0-9_.=+-]+$")


class ResultStore:
    """A folder of JSON results, one file per task key.

    A result's measured fields (wall-clock times, which differ from run to run) can be kept
    apart from what the task computes, so that the result files of two runs with the same
    settings are identical byte for byte: `save` writes them to ``MEASURED_ROOT/KEY.json``
    first, then the rest to ``ROOT/KEY.json`` (the file that marks the task done), and `load`
    joins them again (NaN for a measured file that is missing).

    Args:
        root: The folder (created on first save).
        measured: Names of the measured fields of a result.
        measured_root: The folder of the measured fields (default ``ROOT/measured``).
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        measured: Sequence[str] = (),
        measured_root: str | os.PathLike[str] | None = None,
    ) -> None:
        self.root = Path(root)
        if isinstance(measured, str) or not all(isinstance(m, str) for m in measured):
            raise InputError(
                f"measured must be a sequence of field names, got {measured!r}; give e.g. "
                "('plan_seconds',)."
            )
        self.measured = tuple(measured)
        self.measured_root = Path(measured_root) if measured_root else self.root / "measured"

    def path(self, key: str) -> Path:
        """File of task `key`."""
        if not _KEY.match(key):
            raise InputError(f"task key {key!r} may only hold letters, digits and _.=+-")
        return self.root / f"{key}.json"

    def done(self, key: str) -> bool:
        """Whether task `key` has a saved result."""
        return self.path(key).is_file()

    def save(self, key: str, result: dict[str, Any]) -> None:
        """Save one task's (JSON-serialisable) result atomically.

        Raises:
            InputError: If the result file's path is a folder, lies under a regular file or
                in a folder that cannot be written.
        """
        path = self.path(key)
        if self.measured:
            times = {k: result[k] for k in self.measured if k in result}
            result = {k: v for k, v in result.items() if k not in self.measured}
            atomic_write_text(
                self.measured_root / path.name,
                json.dumps(times, sort_keys=True, indent=1),
                name="measurement file",
            )
        atomic_write_text(path, json.dumps(result, sort_keys=True, indent=1), name="result file")

    def load(self, key: str) -> dict[str, Any]:
        """The saved result of task `key`, its measured fields included.

        Raises:
            DatasetError: If the result file is missing, unreadable, truncated or not a JSON
                object, or its measurement file is unreadable.
        """
        result = self._read(self.path(key), key)
        if self.measured:
            timing = self.measured_root / self.path(key).name
            try:
                times = self._read(timing, key) if timing.is_file() else {}
            except DatasetError as exc:
                raise DatasetError(
                    f"cannot read the measurements {timing} of task {key!r} ({exc.__cause__}); "
                    "delete the file (its measurements then read as NaN), or delete "
                    f"{self.path(key)} too to run the task again."
                ) from exc
            result.update({k: times.get(k, math.nan) for k in self.measured})
        return result

    @staticmethod
    def _read(path: Path, key: str) -> dict[str, Any]:
        """The JSON object in `path`, the saved result (or measurements) of task `key`."""
        try:
            result = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise DatasetError(
                f"task {key!r} has no saved result ({path} does not exist); run the task first."
            ) from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise DatasetError(
                f"cannot read the saved result {path} ({exc}); delete it and rerun to compute "
                "the task again."
            ) from exc
        if not isinstance(result, dict):
            raise DatasetError(
                f"the saved result {path} is not a JSON object; delete it and rerun to compute "
                "the task again."
            )
        return result

    def results(self, keys: Sequence[str]) -> list[dict[str, Any]]:
        """Saved results of `keys`, in order."""
        return [self.load(k) for k in keys]


def run_tasks(
    fn: Callable[..., dict[str, Any]],
    tasks: Sequence[tuple[str, tuple[Any, ...]]],
    store: ResultStore,
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    progress: bool = True,
    desc: str = "tasks",
    shared: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Run every task whose result is not saved yet, then return all results.

    Args:
        fn: ``fn(*args, **shared) -> dict``; must be importable by Dask workers (a
            module-level function).
        tasks: ``(key, args)`` pairs with unique keys, in the order they should start.
        store: Where results live.
        workers: 0 runs in this process; ``None`` or K > 0 uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        progress: Show a tqdm bar.
        desc: Label of the bar.
        shared: Keyword arguments every task receives (e.g. the data set), sent to Dask
            workers once.

    Returns:
        The results of all tasks, in the order of `tasks`.
    """
    keys = [k for k, _ in tasks]
    if len(set(keys)) != len(keys):
        raise InputError("task keys must be unique.")
    todo = [(k, a) for k, a in tasks if not store.done(k)]
    run_batch(
        fn,
        todo,
        lambda key, result: store.save(str(key), result),
        workers=workers,
        scheduler=scheduler,
        shared=shared,
        progress=progress,
        done=len(tasks) - len(todo),
        unit="task",
        desc=desc,
    )
    return store.results(keys)
