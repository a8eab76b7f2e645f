"""Threads of a small mixture fit: the default choice against one thread and torch's pool.

Each cell fits `MixtureOfGPExpertsRegressor` (M = 2, the estimator's defaults except the EM
budget below) on `probaff.models.synthetic.regime_features` (D = 16, E = 1, ``--seed``) and
predicts 200 held-out rows, in this one process, under three thread settings:

* ``default``: probaff's automatic choice (`probaff._threads.fit_threads`: one thread up to
  `ONE_THREAD_MAX_ROWS` training rows, torch's count above);
* ``one``: ``probaff.set_fit_threads(1)``;
* ``pool``: ``probaff.set_fit_threads(P)`` with `P` torch's thread count when the script
  starts (``--pool``): torch's full pool, what every fit used before probaff chose.

and two conditions (``--conditions``): ``quiet`` (nothing started beside the fit; other jobs
on the machine are not stopped, so the one-minute load average is printed) and ``loaded``
(``--busy`` CPU-bound busy-loop processes started beside it, stopped after). The settings
alternate within each of ``--repeats`` rounds; a cell's wall and CPU (process) seconds are the
least of its repeats. The ratios of the default and the pool to one thread are printed; a
default whose wall and CPU seconds both exceed one thread's by more than noise (a ratio
above 1 + the larger of ``NOISE_FLOOR`` and the spread of the one-thread repeats, and a
difference above ``NOISE_SECONDS``) is flagged ``SLOWER``.

The EM budget is smaller than the estimator's (``--n-restarts 1 --split-merge 0 --max-iter 2
--gp-max-iter 20``; the gate penalties are still cross-validated, and above 1,000 rows the
search still tries 6 starts on 1,000 of them), and a pool cell is skipped, with a note, when
the pool's wall time at the previous size scaled by the sizes' ratio exceeds
``--pool-budget`` seconds (120): under load the pool can take minutes per fit. The flags
take the estimator's values (3, 2, 10, 50) for its full fit.

Run time: with the defaults (N = 100, 500, 2,000, one repeat, both conditions) about 4
minutes on a 2-core machine shared with other jobs (load average 2 to 7), most of it the
pool's cells; ``--sizes 30,60 --max-iter 1`` takes about 2 minutes there.

Usage::

    python benchmarks/mixture_threads.py [--sizes 100,500,2000] [--repeats 1]
        [--conditions quiet,loaded] [--busy 1] [--pool P] [--pool-budget 120]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import torch

import probaff
from probaff._cli_errors import report_error, run_cli
from probaff._threads import ONE_THREAD_MAX_ROWS, threads_for_rows
from probaff.models.sklearn import MixtureOfGPExpertsRegressor
from probaff.models.synthetic import regime_features

SETTINGS = ("default", "one", "pool")
CONDITIONS = ("quiet", "loaded")
NOISE_FLOOR = 0.25
"""Smallest relative difference flagged: repeated fits on a shared machine vary this much."""
NOISE_SECONDS = 0.25
"""Smallest difference in seconds flagged (sub-second fits vary by more than 25 %)."""
N_TEST = 200
D, E = 16, 1


@dataclass
class Cell:
    """The least wall and CPU seconds of one (condition, N, setting) over the repeats."""

    condition: str
    n: int
    setting: str
    threads: int
    wall: list[float]
    cpu: list[float]


@contextlib.contextmanager
def busy_loop(n: int) -> Iterator[list[subprocess.Popen[bytes]]]:
    """Run `n` CPU-bound Python processes for the duration of the block (yields them)."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        time.sleep(0.5 if n else 0.0)  # let them reach the loop
        yield procs
    finally:
        for proc in procs:
            proc.terminate()
        for proc in procs:
            proc.wait()


def _fit(args: argparse.Namespace, n: int, data: tuple[np.ndarray, ...]) -> None:
    """One fit on the first `n` rows and one prediction of the held-out rows."""
    x, y, x_test = data
    est = MixtureOfGPExpertsRegressor(
        random_state=args.seed,
        n_restarts=args.n_restarts,
        split_merge=args.split_merge,
        max_iter=args.max_iter,
        gp_max_iter=args.gp_max_iter,
    )
    est.fit(x[:n], y[:n]).predict(x_test)


def _timed(args: argparse.Namespace, n: int, data: tuple[np.ndarray, ...]) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    _fit(args, n, data)
    return time.perf_counter() - wall, time.process_time() - cpu


def _threads(setting: str, pool: int) -> int | None:
    """`probaff.set_fit_threads`'s value for a setting (None: automatic)."""
    return {"default": None, "one": 1, "pool": pool}[setting]


def run_condition(
    args: argparse.Namespace, condition: str, data: tuple[np.ndarray, ...]
) -> list[Cell]:
    """Every (N, setting) cell of one condition, the settings alternating in each repeat."""
    cells: list[Cell] = []
    load = os.getloadavg()[0]
    busy = args.busy if condition == "loaded" else 0
    print(f"\n{condition}: {busy} busy-loop process(es) started; load average {load:.2f}")
    last_pool: tuple[int, float] | None = None  # N and wall seconds of the last pool cell
    with busy_loop(busy):
        for i, n in enumerate(args.sizes):
            row = {
                s: Cell(condition, n, s, _threads(s, args.pool) or threads_for_rows(n), [], [])
                for s in SETTINGS
            }
            expected = 0.0 if last_pool is None else last_pool[1] * n / last_pool[0]
            settings = SETTINGS if expected <= args.pool_budget else SETTINGS[:2]
            if expected > args.pool_budget:
                print(f"  N={n:5d} pool    skipped: expected {expected:.0f} s > --pool-budget")
            for r in range(args.repeats):
                k = (r + i) % len(settings)  # each setting takes its turn first
                for setting in settings[k:] + settings[:k]:
                    probaff.set_fit_threads(_threads(setting, args.pool))
                    try:
                        wall, cpu = _timed(args, n, data)
                    finally:
                        probaff.set_fit_threads(None)
                    row[setting].wall.append(wall)
                    row[setting].cpu.append(cpu)
                    print(
                        f"  N={n:5d} {setting:7s} ({row[setting].threads} threads): "
                        f"{wall:7.2f} s wall, {cpu:7.2f} s CPU",
                        flush=True,
                    )
            if row["pool"].wall:
                last_pool = (n, min(row["pool"].wall))
            cells.extend(row.values())
    return cells


def _noise(values: list[float]) -> float:
    """Relative spread of repeated measurements, at least `NOISE_FLOOR`."""
    return max(NOISE_FLOOR, (max(values) - min(values)) / min(values))


def _slower(mine: list[float], theirs: list[float]) -> bool:
    """Whether the least of `mine` exceeds the least of `theirs` by more than noise."""
    return min(mine) > min(theirs) * (1.0 + _noise(theirs)) + NOISE_SECONDS


def table(cells: list[Cell]) -> tuple[str, list[str]]:
    """The table of every cell, with ratios to one thread, and the flagged cases.

    A default cell is flagged when both its wall and its CPU seconds exceed one thread's by
    more than noise (on a shared machine either alone varies between identical fits).
    """
    lines = [
        "condition | N     | setting | threads | wall s  | CPU s   | / one: wall | CPU",
        "----------|-------|---------|---------|---------|---------|-------------|------",
    ]
    flags: list[str] = []
    by_key = {(c.condition, c.n, c.setting): c for c in cells}
    for c in cells:
        head = f"{c.condition:9s} | {c.n:5d} | {c.setting:7s} |"
        if not c.wall:
            lines.append(f"{head} skipped")
            continue
        one = by_key[(c.condition, c.n, "one")]
        rw, rc = min(c.wall) / min(one.wall), min(c.cpu) / min(one.cpu)
        ratio = "" if c.setting == "one" else f"{rw:11.2f} | {rc:4.2f}"
        if c.setting == "default" and _slower(c.wall, one.wall) and _slower(c.cpu, one.cpu):
            ratio += "  SLOWER"
            flags.append(
                f"{c.condition} N={c.n}: default is {rw:.2f}x wall, {rc:.2f}x CPU of one thread"
            )
        lines.append(
            f"{head} {c.threads:7d} | {min(c.wall):7.2f} | {min(c.cpu):7.2f} | {ratio}".rstrip()
        )
    return "\n".join(lines), flags


def _positive_list(text: str, flag: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(
            f"{flag} must be comma-separated positive integers, got {text!r}"
        ) from None
    if not values or min(values) < 1:
        raise ValueError(f"{flag} must be comma-separated positive integers, got {text!r}")
    return values


def _integer(text: str, name: str, least: int) -> int:
    """`text` as an integer >= `least`; ValueError names the flag of `name`."""
    try:
        value = int(text)
    except ValueError:
        value = least - 1
    if value < least:
        raise ValueError(f"--{name.replace('_', '-')} must be an integer >= {least}, got {text!r}")
    return value


def _seconds(text: str, flag: str) -> float:
    """`text` as a finite number of seconds > 0; ValueError names `flag`."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < math.inf:
        raise ValueError(f"{flag} must be a number of seconds > 0, got {text!r}")
    return value


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options, checked; ValueError names a bad one."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--sizes", default="100,500,2000", help="training rows (comma-separated)")
    ap.add_argument("--repeats", default="1", help="alternating rounds of the three settings")
    ap.add_argument("--conditions", default="quiet,loaded", help="quiet, loaded or both")
    ap.add_argument("--busy", default="1", help="busy-loop processes of the loaded condition")
    ap.add_argument("--pool", default=str(torch.get_num_threads()), help="threads of 'pool'")
    ap.add_argument("--n-restarts", default="1", help="EM starts (the estimator's: 3)")
    ap.add_argument("--split-merge", default="0", help="split-merge rounds (estimator's: 2)")
    ap.add_argument("--max-iter", default="2", help="EM iterations (the estimator's: 10)")
    ap.add_argument("--gp-max-iter", default="20", help="first L-BFGS iterations (50)")
    ap.add_argument(
        "--pool-budget", default="120", help="seconds a pool cell may be expected to take"
    )
    ap.add_argument("--seed", default="0", help="data and fit seed")
    args = ap.parse_args(argv)
    args.sizes = _positive_list(args.sizes, "--sizes")
    for flag in ("repeats", "busy", "pool", "n_restarts", "max_iter", "gp_max_iter"):
        setattr(args, flag, _integer(getattr(args, flag), flag, 1))
    for flag in ("split_merge", "seed"):
        setattr(args, flag, _integer(getattr(args, flag), flag, 0))
    args.pool_budget = _seconds(args.pool_budget, "--pool-budget")
    conditions = [c for c in args.conditions.split(",") if c]
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown or not conditions:
        raise ValueError(f"--conditions: unknown {unknown or args.conditions!r}; use quiet,loaded")
    args.conditions = conditions
    return args


def main(argv: list[str] | None = None) -> int:
    """Time every cell, print them, the ratios and the flagged cases."""
    try:
        args = parse_args(argv)
    except ValueError as exc:
        return report_error("mixture_threads", exc)
    x, y, _ = regime_features(max(args.sizes) + N_TEST, D, E, seed=args.seed)
    data = (x[N_TEST:].numpy(), y[N_TEST:, 0].numpy(), x[:N_TEST].numpy())
    print(
        f"{os.cpu_count()} CPUs, torch {torch.__version__} with {torch.get_num_threads()} "
        f"threads; pool = {args.pool}; one thread up to {ONE_THREAD_MAX_ROWS} rows; "
        f"EM: {args.n_restarts} start(s), {args.split_merge} split-merge, "
        f"{args.max_iter} iterations, {args.gp_max_iter} first L-BFGS iterations"
    )
    _fit(args, min(30, max(args.sizes)), data)  # warm-up: imports and first allocations
    cells = [c for cond in args.conditions for c in run_condition(args, cond, data)]
    text, flags = table(cells)
    print("\n" + text)
    print(
        "\nno case where the default is slower than one thread beyond noise"
        if not flags
        else "\nSLOWER than one thread beyond noise:\n  " + "\n  ".join(flags)
    )
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="mixture_threads", output_flags=()))
