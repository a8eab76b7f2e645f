"""Push-T training pushes chosen by information gain against random ones, on the same seeds.

One collection of ``max(--sizes)`` pushes per strategy (``--strategies``) in the unmodified
gym-pusht environment, with one seed (`probaff.experiments.pusht.active`): after ``--start``
random pushes, each push is the one of ``--pool`` feasible candidates that the mixture,
refitted every ``--refit-every`` pushes, scores best: ``reduction`` (the largest reduction of
its predictive variance over ``--reference`` primitives drawn as the planner draws them) or
``variance`` (the largest predictive variance); ``random`` is the baseline. At every size in
``--sizes``, the mixture of GP experts is fitted on each collection's first pushes (the study's
EM: ``--experts``, ``--em-max-iter``) and scored on ``--test-pushes`` held-out random pushes
(RMSE, NLPD, 90 % coverage), and, with ``--episodes`` above 0, the learned-model planner
(risk weight ``--risk``, `SearchSettings.risk`, 0 by default; the search's budget and step
price ``--search-candidates``, ``--search-beam`` and ``--search-step-cost``, `SearchSettings`'s
defaults unless given) runs that many episodes (reset seeds ``--episode-seed + i``, the same
for both) and is scored as LeRobot scores (success with its Wilson interval, mean maximum
reward, coverage).

Outputs in ``--out`` (default ``results/pusht_active``): ``pushes_<strategy>.json`` (the
collections, reused when their setup matches), ``results.csv``, ``summary.md`` and, with
episodes, ``success_vs_pushes.png`` (success against training pushes, one line a strategy,
95 % Wilson intervals). Strategies run in separate processes on the same seeds (for example
one per core) write their own folders; ``--merge DIR ...`` reads their ``results.csv`` and
writes the joint table and figure to ``--out`` without fitting anything.

One collection is one draw of the training pushes, and which pushes a draw holds moves the
planner's success at 60 pushes by tens of points (0.62 to 0.99 for random pushes over
collection seeds 0-3). ``--collections K`` therefore repeats the whole comparison for the
collection seeds ``--seed`` .. ``--seed + K - 1`` (each in ``--out/seed<s>``, episodes on the
same reset seeds), and wherever a strategy and size have more than one collection (from
``--collections`` or from merged runs of different ``--seed``) the output adds
``collections.csv``: the mean success over collections with its 95 % t interval over them,
their range, and the paired difference against ``random`` on the same collection seeds (the
collections of one seed share their first ``--start`` random pushes); the figure then draws
those means and intervals.

Run time: an episode takes about 3 s when it succeeds early and up to about 15 s when it runs
to the 300-step limit, on one core.

Usage::

    python benchmarks/pusht_active.py [--sizes 20 40 60] [--episodes 0] [--seed 0]
        [--strategies reduction,variance,random] [--collections 1] [--risk 0]
        [--search-candidates 192] [--search-beam 8] [--search-step-cost 0.02]
        [--python .venv-pusht/bin/python] [--out results/pusht_active] [--merge DIR ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from tqdm import tqdm

from probaff._checks import check_count, check_positive
from probaff._cli_errors import report_error, run_cli
from probaff._io import atomic_write_text
from probaff._threads import limit_threads
from probaff.errors import InputError, ProbaffError
from probaff.eval.metrics import mean_and_halfwidth
from probaff.eval.tables import markdown_table
from probaff.experiments.pusht.active import STRATEGIES, ActiveOptions, collect_pushes
from probaff.experiments.pusht.data import push_dataset, record_chunk, with_worker
from probaff.experiments.pusht.figures import plot_success_curve
from probaff.experiments.pusht.models import evaluate, fit_learned, push_effects, push_features
from probaff.experiments.pusht.planner import SearchSettings, run_episode
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.scoring import score
from probaff.experiments.pusht.transitions import ModelTransition
from probaff.models import EMOptions

_COLUMNS = ["strategy", "train_pushes", "seed", "rmse_z", "rmse_theta", "nlpd", "coverage90"]
_EPISODE_COLUMNS = ["success_rate", "success_low", "success_high", "max_reward", "max_coverage"]
_COLLECTION_COLUMNS = [
    "strategy",
    "train_pushes",
    "collections",
    "success_rate",
    "success_low",
    "success_high",
    "success_min",
    "success_max",
    "max_reward",
    "vs_random",
    "vs_random_ci95",
]
"""``collections.csv``: success over collection seeds (mean, 95 % t interval, range), the mean
maximum reward, and the paired difference in success against ``random``."""


def _first(rows: dict[str, Any], n: int) -> dict[str, Any]:
    return {k: v[:n] for k, v in rows.items() if k != "refits"}


def _strategies(text: str) -> list[str]:
    """Comma-separated names of `STRATEGIES`; `InputError` naming ``--strategies``."""
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in STRATEGIES]
    if not names or bad:
        raise InputError(
            f"--strategies takes names of {list(STRATEGIES)} separated by commas, got {text!r}."
        )
    return list(dict.fromkeys(names))


def _read_results(folder: Path) -> list[dict[str, Any]]:
    """The rows of an earlier run's ``results.csv``; `InputError` naming ``--merge``."""
    path = folder / "results.csv"
    if not path.is_file():
        raise InputError(f"--merge: {path} does not exist; give folders of finished runs.")
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    if not set(_COLUMNS + _EPISODE_COLUMNS) <= set(header):
        raise InputError(f"--merge: {path} is not a results table with episodes; re-run it.")
    rows = []
    for line in lines[1:]:
        cells = dict(zip(header, line.split(","), strict=True))
        rows.append(
            {k: (v if k == "strategy" else float(v)) for k, v in cells.items()}
            | {"train_pushes": int(cells["train_pushes"]), "seed": int(cells["seed"])}
        )
    return rows


def over_collections(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """`_COLLECTION_COLUMNS` rows: each strategy and size over its collection seeds.

    Args:
        results: Rows of ``results.csv`` with episodes (``strategy``, ``train_pushes``,
            ``seed``, ``success_rate``, ``max_reward``).

    Returns:
        One row per (strategy, size), in the order of `results`: the mean success over the
        collections with its 95 % t interval over them (clipped to [0, 1]), the lowest and
        highest, the mean maximum reward, and the mean paired difference in success
        against ``random`` over the seeds both have, with its 95 % t half-width (NaN
        without a ``random`` row of that size).
    """
    groups: dict[tuple[str, int], dict[int, dict[str, Any]]] = {}
    for r in results:
        groups.setdefault((str(r["strategy"]), int(r["train_pushes"])), {})[int(r["seed"])] = r
    rows = []
    for (strategy, n), by_seed in groups.items():
        rates = [float(r["success_rate"]) for r in by_seed.values()]
        mean, hw = mean_and_halfwidth(rates)
        base = groups.get(("random", n), {})
        diffs = [
            float(by_seed[s]["success_rate"]) - float(base[s]["success_rate"])
            for s in by_seed
            if s in base
        ]
        paired = strategy != "random" and len(diffs) > 0
        gain, gain_hw = mean_and_halfwidth(diffs) if paired else (math.nan, math.nan)
        rows.append(
            {
                "strategy": strategy,
                "train_pushes": n,
                "collections": len(rates),
                "success_rate": mean,
                "success_low": max(mean - hw, 0.0),
                "success_high": min(mean + hw, 1.0),
                "success_min": min(rates),
                "success_max": max(rates),
                "max_reward": sum(float(r["max_reward"]) for r in by_seed.values()) / len(rates),
                "vs_random": gain,
                "vs_random_ci95": gain_hw,
            }
        )
    return rows


def _write(out: Path, results: list[dict[str, Any]], about: str) -> None:
    """Write ``results.csv``, ``summary.md`` and (with episodes) the success figure."""
    episodes = all(c in r for r in results for c in _EPISODE_COLUMNS)
    columns = _COLUMNS + (_EPISODE_COLUMNS if episodes else [])
    csv = [",".join(columns)] + [",".join(str(r[c]) for c in columns) for r in results]
    atomic_write_text(out / "results.csv", "\n".join(csv) + "\n")
    figure, pooled = "", []
    if episodes and results:
        many = len({int(r["seed"]) for r in results}) > 1
        pooled = over_collections(results) if many else []
        if pooled:
            atomic_write_text(
                out / "collections.csv",
                "\n".join(
                    [",".join(_COLLECTION_COLUMNS)]
                    + [",".join(str(r[c]) for c in _COLLECTION_COLUMNS) for r in pooled]
                )
                + "\n",
            )
        png = plot_success_curve(pooled or results, out / "success_vs_pushes.png", by="strategy")
        figure = f"Figure: `{png}`" + (
            " (mean over collections, 95 % t intervals)." if pooled else "."
        )
    over = (
        ["Over collection seeds:", "", markdown_table(pooled, _COLLECTION_COLUMNS, digits=3), ""]
        if pooled
        else []
    )
    text = "\n".join(
        [
            "# Push-T training pushes: information gain against random",
            "",
            about,
            "",
            *over,
            markdown_table(results, columns, digits=3),
            "",
            figure,
            "",
        ]
    )
    atomic_write_text(out / "summary.md", text)
    print(text)


def main(argv: list[str] | None = None) -> int:
    """Collect (or reuse) the collections, fit, score, and write the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 60])
    ap.add_argument("--strategies", default=",".join(STRATEGIES))
    ap.add_argument("--start", type=int, default=10)
    ap.add_argument("--refit-every", type=int, default=10)
    ap.add_argument("--pool", type=int, default=64)
    ap.add_argument("--reference", type=int, default=256)
    ap.add_argument("--experts", type=int, default=3)
    ap.add_argument("--em-max-iter", type=int, default=10)
    ap.add_argument("--test-pushes", type=int, default=200)
    ap.add_argument(
        "--risk", type=float, default=0.0, help="the planner's risk weight (SearchSettings.risk)"
    )
    ap.add_argument(
        "--search-candidates",
        type=int,
        default=SearchSettings.candidates,
        help="first pushes the planner samples (SearchSettings.candidates)",
    )
    ap.add_argument(
        "--search-beam",
        type=int,
        default=SearchSettings.beam,
        help="first pushes it expands (SearchSettings.beam)",
    )
    ap.add_argument(
        "--search-step-cost",
        type=float,
        default=SearchSettings.step_cost,
        help="its price of a control step, px (SearchSettings.step_cost)",
    )
    ap.add_argument("--episodes", type=int, default=0)
    ap.add_argument("--episode-seed", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--collections", type=int, default=1, help="collection seeds from --seed")
    ap.add_argument("--python", default=None, help="the Push-T environment's Python")
    ap.add_argument("--out", default="results/pusht_active")
    ap.add_argument("--merge", nargs="+", default=None, help="folders of finished runs to join")
    args = ap.parse_args(argv)
    try:
        run(args)
    except ProbaffError as exc:
        return report_error("pusht_active", exc)
    return 0


def _order(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return sorted(
        rows, key=lambda r: (r["train_pushes"], STRATEGIES.index(str(r["strategy"])), r["seed"])
    )


def run(args: argparse.Namespace) -> None:
    """The work of `main` on parsed flags (module doc)."""
    out = Path(args.out)
    if args.merge:
        rows = [r for folder in args.merge for r in _read_results(Path(folder))]
        _write(out, _order(rows), f"Joined from {', '.join(f'`{f}`' for f in args.merge)}.")
        return
    strategies = _strategies(args.strategies)
    sizes = sorted({check_count("--sizes", n) for n in args.sizes})
    seed = check_count("--seed", args.seed, minimum=0)
    collections = check_count("--collections", args.collections)
    check_count("--episodes", args.episodes, minimum=0)
    check_positive("--risk", args.risk, allow_zero=True)
    check_count("--search-candidates", args.search_candidates)
    check_count("--search-beam", args.search_beam)
    check_positive("--search-step-cost", args.search_step_cost, allow_zero=True)
    command = "python benchmarks/pusht_active.py " + " ".join(sys.argv[1:])
    if collections == 1:
        _collection(args, strategies, sizes, seed, out, command.strip())
        return
    rows = []
    for s in range(seed, seed + collections):
        rows += _collection(args, strategies, sizes, s, out / f"seed{s}", command.strip())
    _write(out, _order(rows), f"`{command.strip()}`: collection seeds {seed}-{s}.")


def _collection(
    args: argparse.Namespace,
    strategies: list[str],
    sizes: list[int],
    seed: int,
    out: Path,
    command: str,
) -> list[dict[str, Any]]:
    """Collect, fit and score every strategy on collection seed `seed`; write to `out`."""
    episodes = args.episodes
    search = SearchSettings(
        candidates=args.search_candidates,
        beam=args.search_beam,
        risk=args.risk,
        step_cost=args.search_step_cost,
    )
    default = SearchSettings()
    changed = {  # cells of the default search keep their setup
        f.name: getattr(search, f.name)
        for f in dataclasses.fields(search)
        if getattr(search, f.name) != getattr(default, f.name)
    }
    em = EMOptions(max_iter=check_count("--em-max-iter", args.em_max_iter), n_restarts=2, seed=seed)
    settings = PrimitiveSettings()
    collected: dict[str, dict[str, Any]] = {}
    for strategy in strategies:
        options = ActiveOptions(
            budget=sizes[-1],
            strategy=strategy,
            start=min(args.start, sizes[0]),
            refit_every=args.refit_every,
            pool=args.pool,
            reference=args.reference,
        )
        setup = {"seed": seed, "options": repr(options), "settings": repr(settings)}
        path = out / f"pushes_{strategy}.json"
        saved = json.loads(path.read_text()) if path.is_file() else {}
        if saved.get("setup") != setup:
            t0 = time.perf_counter()
            pushes = collect_pushes(seed, options, settings, args.python)
            saved = {"setup": setup, "rows": pushes, "seconds": time.perf_counter() - t0}
            atomic_write_text(path, json.dumps(saved) + "\n")
        collected[strategy] = saved
    test_n = check_count("--test-pushes", args.test_pushes)
    test = push_dataset(
        [record_chunk("test", 0, seed, test_n, settings=settings, python=args.python)], seed
    )
    Xt, Yt = push_features(test), push_effects(test)
    results = []
    for n in tqdm(sizes, desc="sizes", disable=None):
        for strategy in strategies:
            cell = out / "cells" / f"{strategy}_n{n}.json"
            setup = {
                "collection": collected[strategy]["setup"],
                "n": n,
                "experts": args.experts,
                "em": repr(em),
                "test": [seed, test_n],
                "episodes": [episodes, args.episode_seed],
            } | changed
            stored = json.loads(cell.read_text()) if cell.is_file() else {}
            if stored.get("setup") == setup:
                row = stored["row"]
            else:
                ds = push_dataset([_first(collected[strategy]["rows"], n)], seed)
                with limit_threads(1):
                    model, _ = fit_learned(
                        "moe", push_features(ds), push_effects(ds), experts=args.experts, em=em
                    )
                row = {"strategy": strategy, "train_pushes": n} | evaluate(model, Xt, Yt)
                if episodes:

                    def play(
                        w: Any, model: Any = model, search: Any = search
                    ) -> list[dict[str, Any]]:
                        with limit_threads(1):
                            return [
                                run_episode(
                                    w,
                                    args.episode_seed + i,
                                    ModelTransition(model),
                                    search,
                                    settings,
                                )
                                for i in range(episodes)
                            ]

                    scored = score(with_worker(args.python, play))
                    row |= {k: scored[k] for k in _EPISODE_COLUMNS}
                atomic_write_text(cell, json.dumps({"setup": setup, "row": row}) + "\n")
            row["seed"] = seed  # cells stored before the seed column lack it
            results.append(row)
            print(json.dumps(row), flush=True)
    secs = {s: round(collected[s]["seconds"], 1) for s in strategies}
    _write(
        out,
        results,
        f"`{command}`; collection seed {seed}; collection seconds {secs}; {test_n} held-out "
        "random pushes.",
    )
    return results


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="pusht_active"))
