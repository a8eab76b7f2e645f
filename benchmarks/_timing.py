"""Best-of-repeats timing of the benchmark scripts, in wall-clock and CPU seconds, and the
device that a script's ``--device`` names.

Imported by its siblings as ``from _timing import best_times`` (a script's own folder is on
``sys.path`` when it runs as ``python benchmarks/<name>.py``).
"""

import time
from collections.abc import Callable

import numpy as np
import torch

from probaff.errors import InputError


def best_times(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """The least wall-clock and the least CPU seconds (of this process) of `repeats` calls."""
    wall, cpu = np.inf, np.inf
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    return wall, cpu


def bench_device(name: str) -> torch.device:
    """The device that ``--device`` names: the CPU or a CUDA device this machine has.

    Raises:
        InputError: For a malformed name, a device this machine lacks, or another kind.
    """
    if name == "cpu":
        return torch.device("cpu")
    from probaff.models.tensors import resolve_device  # only here: it loads probaff.models

    device = resolve_device("--device", name)
    if device.type not in ("cpu", "cuda"):
        raise InputError(f"--device {name!r} is not supported here; use 'cpu' or 'cuda[:N]'.")
    return device


def synchronize(device: torch.device) -> None:
    """Wait for the work queued on `device` (a no-op on the CPU)."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)
