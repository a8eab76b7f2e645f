"""Push-T training pushes chosen by information gain against random ones, on the same seeds.

Two collections of ``max(--sizes)`` pushes in the unmodified gym-pusht environment, with one
seed (`probaff.experiments.pusht.active`): ``variance`` (after ``--start`` random pushes, each
push is the one of ``--pool`` feasible candidates whose effect the mixture, refitted every
``--refit-every`` pushes, predicts with the largest variance) and ``random``. At every size in
``--sizes``, the mixture of GP experts is fitted on each collection's first pushes (the study's
EM: ``--experts``, ``--em-max-iter``) and scored on ``--test-pushes`` held-out random pushes
(RMSE, NLPD, 90 % coverage), and, with ``--episodes`` above 0, the learned-model planner runs
that many episodes (reset seeds ``--episode-seed + i``, the same for both) and is scored as
LeRobot scores (success with its Wilson interval, mean maximum reward, coverage).

Outputs in ``--out`` (default ``results/pusht_active``): ``pushes_<strategy>.json`` (the
collections, reused when their setup matches), ``results.csv`` and ``summary.md``.

Usage::

    python benchmarks/pusht_active.py [--sizes 20 40 60] [--episodes 0] [--seed 0]
        [--python .venv-pusht/bin/python] [--out results/pusht_active]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from probaff._checks import check_count
from probaff._cli_errors import run_cli
from probaff._io import atomic_write_text
from probaff._threads import limit_threads
from probaff.eval.tables import markdown_table
from probaff.experiments.pusht.active import STRATEGIES, ActiveOptions, collect_pushes
from probaff.experiments.pusht.data import push_dataset, record_chunk, with_worker
from probaff.experiments.pusht.models import evaluate, fit_learned, push_effects, push_features
from probaff.experiments.pusht.planner import SearchSettings, run_episode
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.scoring import score
from probaff.experiments.pusht.transitions import ModelTransition
from probaff.models import EMOptions

_COLUMNS = ["strategy", "train_pushes", "rmse_z", "rmse_theta", "nlpd", "coverage90"]
_EPISODE_COLUMNS = ["success_rate", "success_low", "success_high", "max_reward", "max_coverage"]


def _first(rows: dict[str, Any], n: int) -> dict[str, Any]:
    return {k: v[:n] for k, v in rows.items() if k != "refits"}


def main() -> None:
    """Collect (or reuse) both collections, fit, score, and write the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 60])
    ap.add_argument("--start", type=int, default=10)
    ap.add_argument("--refit-every", type=int, default=10)
    ap.add_argument("--pool", type=int, default=64)
    ap.add_argument("--experts", type=int, default=3)
    ap.add_argument("--em-max-iter", type=int, default=10)
    ap.add_argument("--test-pushes", type=int, default=200)
    ap.add_argument("--episodes", type=int, default=0)
    ap.add_argument("--episode-seed", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--python", default=None, help="the Push-T environment's Python")
    ap.add_argument("--out", default="results/pusht_active")
    args = ap.parse_args()
    sizes = sorted({check_count("--sizes", n) for n in args.sizes})
    seed = check_count("--seed", args.seed, minimum=0)
    episodes = check_count("--episodes", args.episodes, minimum=0)
    em = EMOptions(max_iter=check_count("--em-max-iter", args.em_max_iter), n_restarts=2, seed=seed)
    settings, out = PrimitiveSettings(), Path(args.out)
    collected: dict[str, dict[str, Any]] = {}
    for strategy in STRATEGIES:
        options = ActiveOptions(
            budget=sizes[-1],
            strategy=strategy,
            start=min(args.start, sizes[0]),
            refit_every=args.refit_every,
            pool=args.pool,
        )
        setup = {"seed": seed, "options": repr(options), "settings": repr(settings)}
        path = out / f"pushes_{strategy}.json"
        saved = json.loads(path.read_text()) if path.is_file() else {}
        if saved.get("setup") != setup:
            t0 = time.perf_counter()
            rows = collect_pushes(seed, options, settings, args.python)
            saved = {"setup": setup, "rows": rows, "seconds": time.perf_counter() - t0}
            atomic_write_text(path, json.dumps(saved) + "\n")
        collected[strategy] = saved
    test_n = check_count("--test-pushes", args.test_pushes)
    test = push_dataset(
        [record_chunk("test", 0, seed, test_n, settings=settings, python=args.python)], seed
    )
    Xt, Yt = push_features(test), push_effects(test)
    results = []
    for n in sizes:
        for strategy in STRATEGIES:
            ds = push_dataset([_first(collected[strategy]["rows"], n)], seed)
            with limit_threads(1):
                model, _ = fit_learned(
                    "moe", push_features(ds), push_effects(ds), experts=args.experts, em=em
                )
            row: dict[str, Any] = {"strategy": strategy, "train_pushes": n}
            row |= evaluate(model, Xt, Yt)
            if episodes:
                search = SearchSettings()

                def play(w: Any, model: Any = model, search: Any = search) -> list[dict[str, Any]]:
                    with limit_threads(1):
                        return [
                            run_episode(
                                w, args.episode_seed + i, ModelTransition(model), search, settings
                            )
                            for i in range(episodes)
                        ]

                row |= {k: score(with_worker(args.python, play))[k] for k in _EPISODE_COLUMNS}
            results.append(row)
            print(json.dumps(row), flush=True)
    columns = _COLUMNS + (_EPISODE_COLUMNS if episodes else [])
    header = ",".join(columns)
    csv = [header] + [",".join(str(r[c]) for c in columns) for r in results]
    atomic_write_text(out / "results.csv", "\n".join(csv) + "\n")
    command = "python benchmarks/pusht_active.py " + " ".join(sys.argv[1:])
    secs = {s: round(collected[s]["seconds"], 1) for s in STRATEGIES}
    text = "\n".join(
        [
            "# Push-T training pushes: information gain against random",
            "",
            f"`{command.strip()}`; collection seconds {secs}; {test_n} held-out random pushes.",
            "",
            markdown_table(results, columns, digits=3),
            "",
        ]
    )
    atomic_write_text(out / "summary.md", text)
    print(text)


if __name__ == "__main__":
    sys.exit(run_cli(main))
