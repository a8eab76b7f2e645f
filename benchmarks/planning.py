"""Push-to-edge planning benchmarks (chapter 4): A* planning time, batched prediction, IK cache.

Run with ``python benchmarks/planning.py [--dataset PATH] [--episodes 10] [--repeats 3]
[--quick]`` (a few minutes on a 2-core CPU; ``--quick``: 3 starts, 1 repeat, 120 training
pushes). Without ``--dataset`` the planner models are fitted on 240 pushes of the
``push_to_edge`` scene generated into a temporary folder (about 10 s); with it, on that
dataset folder. Everything runs on one core (one torch and one BLAS thread). Prints:

(a) seconds per A* planning call (`plan_astar`, the task's search options) from the first
    ``--episodes`` seeded episode starts (`sample_episode(task, default_rng(seed))`), with the
    mixture of GP experts (``"moe"``), the single GP (``"gp"``) and the quasi-static model,
    each with a warm reachability cache (the same start planned once before; every plan gets
    a fresh transition of sensor seed 0, so a start's plans repeat one search): median and
    maximum over the starts, the model calls and expansions per plan, the fraction of plans
    that reach a goal, and whether the goal "at most 1 s per planning step on one core with
    the mixture model" is met by every start;
(b) one batched `LearnedTransition.predict` call of every candidate push of one planning
    step (8 book poses x 16 directions = 128 candidates) against 128 calls of one candidate
    each, in the same run, with the ratio; and the largest gap between the two runs'
    predicted positions next to the gap between two batched calls sensed with other cloud
    noise draws (the single calls sense their clouds with other draws too);
(c) the first plan from a start with an empty reachability cache (cold: IK of every push it
    asks about) against the second plan from the same start (warm), per model, with the time
    spent in the reachability queries and the IK cells solved.

Timings are minima over repeats: the machine may be shared, and the minimum is the least
disturbed measurement. Every model is called once on an unrelated start before any timing,
so that one-time costs (imports, allocations, the arm's first IK) are not timed.
"""

from __future__ import annotations

import argparse
import functools
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from probaff.data import GenerateConfig, PushDataset, generate, load_dataset
from probaff.planning.catalogue import fit_edge_model
from probaff.planning.push_to_edge.planners import PushReachability, plan_astar, predict_books
from probaff.planning.push_to_edge.task import EdgeTask, load_edge_task, sample_episode
from probaff.planning.transitions import LearnedTransition, QuasiStaticTransition
from probaff.planning.transitions import Transition as EdgeTransition

GOAL_SECONDS = 1.0
NODES = 8  # book poses of one planning step in (b): the task's search.batch


def best_of(fn: Callable[[], np.ndarray], repeats: int) -> tuple[float, np.ndarray]:
    """The least wall time of `repeats` calls of `fn`, and the last call's result."""
    best, out = float("inf"), np.zeros(0)
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def dataset(args: argparse.Namespace, tmp: Path) -> PushDataset:
    if args.dataset is not None:
        return load_dataset(args.dataset)
    n = 120 if args.quick else 240
    start = time.perf_counter()
    ds = generate(
        GenerateConfig(scene="push_to_edge", n=n, trajectories=False),
        tmp / "push_to_edge",
        workers=0,
        progress=False,
    )
    print(f"generated {len(ds)} push_to_edge pushes in {time.perf_counter() - start:.1f} s")
    return ds


def models(task: EdgeTask, ds: PushDataset) -> dict[str, Callable[[int], EdgeTransition]]:
    """Each model as a factory of fresh transitions by seed (a learned one's sensor seed)."""
    out: dict[str, Callable[[int], EdgeTransition]] = {}
    for name in ("moe", "gp"):
        start = time.perf_counter()
        fitted = fit_edge_model(name, ds)
        print(f"fitted {name!r} on {len(ds)} pushes in {time.perf_counter() - start:.1f} s")
        out[name] = functools.partial(LearnedTransition, fitted, task, name=name)
    out["quasi-static"] = lambda seed: QuasiStaticTransition(task)
    return out


def starts(task: EdgeTask, seeds: range) -> list[tuple[np.ndarray, np.ndarray]]:
    scenes = [sample_episode(task, np.random.default_rng(seed)) for seed in seeds]
    return [(s.poses[0].copy(), s.poses[1].copy()) for s in scenes]


class TimedReachability(PushReachability):
    """`PushReachability` that adds up the wall time of its answers and counts its cells."""

    def __init__(self, task: EdgeTask) -> None:
        super().__init__(task)
        self.seconds = 0.0

    def __call__(self, origins: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        start = time.perf_counter()
        try:
            return super().__call__(origins, yaws)
        finally:
            self.seconds += time.perf_counter() - start

    @property
    def cells(self) -> int:
        return len(self._cache)


def bench_plans(
    task: EdgeTask,
    factories: dict[str, Callable[[int], EdgeTransition]],
    episode_starts: list[tuple[np.ndarray, np.ndarray]],
    repeats: int,
) -> dict[str, dict[str, list[float]]]:
    """Cold and warm A* plans per model and start, for (a) and (c).

    Every plan uses a fresh transition of seed 0, so a start's plans repeat the same search
    (the same clouds sensed, the same pushes asked about) and the warm ones ask the arm
    about no new cell.
    """
    # one-time costs, untimed: an unrelated start (seed 10_000) with its own cache
    book, battery = starts(task, range(10_000, 10_001))[0]
    for make in factories.values():
        plan_astar(task, make(0), book, battery, PushReachability(task))
    keys = ("cold", "cold_ik", "warm", "warm_ik", "cells", "calls", "expansions", "goal")
    results: dict[str, dict[str, list[float]]] = {}
    for name, make in factories.items():
        r: dict[str, list[float]] = {k: [] for k in keys}
        for book, battery in episode_starts:
            reach = TimedReachability(task)
            start = time.perf_counter()
            plan_astar(task, make(0), book, battery, reach)
            r["cold"].append(time.perf_counter() - start)
            r["cold_ik"].append(reach.seconds)
            r["cells"].append(reach.cells)
            warm, warm_ik = float("inf"), 0.0
            for _ in range(repeats):
                reach.seconds = 0.0
                transition = make(0)
                start = time.perf_counter()
                plan = plan_astar(task, transition, book, battery, reach)
                elapsed = time.perf_counter() - start
                if elapsed < warm:
                    warm, warm_ik = elapsed, reach.seconds
            r["warm"].append(warm)
            r["warm_ik"].append(warm_ik)
            r["calls"].append(plan.predictions)
            r["expansions"].append(plan.expansions)
            r["goal"].append(float(plan.reaches_goal))
        results[name] = r
    return results


def print_plans(results: dict[str, dict[str, list[float]]], n_starts: int, repeats: int) -> None:
    print(
        f"\n(a) seconds per A* planning call, warm reachability cache, 1 core "
        f"({n_starts} episode starts, min of {repeats} repeats each)"
    )
    print(
        f"    {'model':14s} {'median s':>9s} {'max s':>8s} {'model calls':>12s} "
        f"{'expansions':>11s} {'s/model call':>13s} {'goal found':>11s}"
    )
    for name, r in results.items():
        per_call = [w / max(c, 1) for w, c in zip(r["warm"], r["calls"], strict=True)]
        print(
            f"    {name:14s} {statistics.median(r['warm']):9.3f} {max(r['warm']):8.3f} "
            f"{statistics.median(r['calls']):12.1f} {statistics.median(r['expansions']):11.0f} "
            f"{statistics.median(per_call):13.4f} {np.mean(r['goal']):11.0%}"
        )
    print("    (model calls, expansions and s/model call: medians over the starts)")
    moe, gp, qs = (statistics.median(results[k]["warm"]) for k in ("moe", "gp", "quasi-static"))
    print(f"    ratio of medians: moe / gp {moe / gp:.2f}, moe / quasi-static {moe / qs:.1f}")
    worst = max(results["moe"]["warm"])
    verdict = "met" if worst <= GOAL_SECONDS else "missed"
    slow = sum(w > GOAL_SECONDS for w in results["moe"]["warm"])
    print(
        f"    goal <= {GOAL_SECONDS:.0f} s per planning step on one core with the mixture "
        f"model: {verdict} (median {moe:.2f} s, max {worst:.2f} s; {slow} of {n_starts} "
        "starts over)"
    )


def print_cache(results: dict[str, dict[str, list[float]]]) -> None:
    print("\n(c) first plan from a start, empty reachability cache (cold), vs the second (warm)")
    print(
        f"    {'model':14s} {'cold s':>8s} {'of it IK s':>11s} {'warm s':>8s} "
        f"{'of it cache s':>14s} {'cold/warm':>10s} {'IK cells':>9s} {'IK ms/cell':>11s}"
    )
    for name, r in results.items():
        med = {k: statistics.median(v) for k, v in r.items()}
        per_cell = statistics.median(
            1e3 * t / max(n, 1) for t, n in zip(r["cold_ik"], r["cells"], strict=True)
        )
        print(
            f"    {name:14s} {med['cold']:8.3f} {med['cold_ik']:11.3f} {med['warm']:8.3f} "
            f"{med['warm_ik']:14.4f} {med['cold'] / med['warm']:10.1f} {med['cells']:9.0f} "
            f"{per_cell:11.2f}"
        )
    print("    (medians over the starts; 'of it': time inside the reachability queries)")


def step_candidates(
    task: EdgeTask, book: np.ndarray, battery: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every candidate of one planning step: `NODES` book poses near `book`, all pushes each."""
    poses = [book]
    while len(poses) < NODES:
        p = book + rng.normal(0.0, [0.05, 0.05, 0.3])
        if not task.collides(p, battery) and not task.fallen(p):
            poses.append(p)
    nodes = np.stack(poses)
    origins, yaws = task.candidate_pushes(nodes)  # (B, C, 2), (C,)
    b, c = origins.shape[:2]
    return np.repeat(nodes, c, axis=0), origins.reshape(b * c, 2), np.tile(yaws, b)


def bench_batch(
    task: EdgeTask,
    factories: dict[str, Callable[[int], EdgeTransition]],
    book: np.ndarray,
    battery: np.ndarray,
    repeats: int,
) -> None:
    books, origins, yaws = step_candidates(task, book, battery, np.random.default_rng(0))
    n = len(books)
    print(
        f"\n(b) predicting the {n} candidates of one planning step ({NODES} nodes x "
        f"{task.directions} directions): one batched call vs {n} single calls"
    )
    print(
        f"    {'model':14s} {'batched ms':>11s} {'single ms':>10s} {'ratio':>7s} "
        f"{'max |d xy| mm':>14s} {'other seed mm':>14s}"
    )
    for name, make in factories.items():
        tr = make(0)

        def batched(tr: EdgeTransition = tr) -> np.ndarray:
            return predict_books(task, tr, books, origins, yaws, battery).mean

        def single(tr: EdgeTransition = tr) -> np.ndarray:
            return np.concatenate(
                [
                    predict_books(
                        task, tr, books[i : i + 1], origins[i : i + 1], yaws[i : i + 1], battery
                    ).mean
                    for i in range(n)
                ]
            )

        t_batched, a = best_of(batched, repeats)
        t_single, b = best_of(single, max(1, repeats - 1))
        other = predict_books(task, make(1), books, origins, yaws, battery).mean
        diff = 1e3 * float(np.abs(np.asarray(a)[:, :2] - np.asarray(b)[:, :2]).max())
        spread = 1e3 * float(np.abs(np.asarray(a)[:, :2] - other[:, :2]).max())
        print(
            f"    {name:14s} {1e3 * t_batched:11.1f} {1e3 * t_single:10.1f} "
            f"{t_single / t_batched:7.1f} {diff:14.2f} {spread:14.2f}"
        )
    print(
        "    (ratio = single / batched; max |d xy|: largest gap between the batched and the "
        "single predictions,\n     other seed: between two batched calls whose clouds are "
        "sensed with other noise draws)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", type=Path, default=None, help="push_to_edge dataset folder")
    ap.add_argument("--episodes", type=int, default=10, help="seeded episode starts in (a)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats (the minimum counts)")
    ap.add_argument("--quick", action="store_true", help="3 starts, 1 repeat, 120 pushes")
    args = ap.parse_args()
    if args.quick:
        args.episodes, args.repeats = 3, 1
    if args.episodes < 1 or args.repeats < 1:
        ap.error("--episodes and --repeats must be positive")
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    with threadpool_limits(1), tempfile.TemporaryDirectory() as tmp:
        task = load_edge_task()
        ds = dataset(args, Path(tmp))
        factories = models(task, ds)
        s = task.search
        print(
            f"task: budget {task.budget}, {task.directions} directions, A* batch {s.batch}, "
            f"max {s.max_expansions} expansions; {torch.get_num_threads()} torch thread"
        )
        episode_starts = starts(task, range(args.episodes))
        results = bench_plans(task, factories, episode_starts, args.repeats)
        print_plans(results, len(episode_starts), args.repeats)
        bench_batch(task, factories, *episode_starts[0], max(2, args.repeats))
        print_cache(results)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
