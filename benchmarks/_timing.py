"""Best-of-repeats timing of the benchmark scripts, in wall-clock and CPU seconds.

Imported by its siblings as ``from _timing import best_times`` (a script's own folder is on
``sys.path`` when it runs as ``python benchmarks/<name>.py``).
"""

import time
from collections.abc import Callable

import numpy as np


def best_times(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """The least wall-clock and the least CPU seconds (of this process) of `repeats` calls."""
    wall, cpu = np.inf, np.inf
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    return wall, cpu
