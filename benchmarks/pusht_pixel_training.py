"""Push-T training pushes recorded from pixels against from the state, on the same seed.

Records ``--pushes`` random training pushes (and ``--test-pushes`` held-out ones) twice in the
unmodified gym-pusht environment, from one seed (`probaff.experiments.pusht.data.record_chunk`):
with the block's poses read off the simulator's state, and perceived from gym-pusht's own
96 x 96 ``pixels_agent_pos`` image (the state logged beside them for scoring only). It reports
the perception's error on the pixel-recorded training pushes (`perception_errors`: mean, median
and 95th percentile of the pose error, px of the image and degrees, and of the pushing-frame
effects the model learns), fits the mixture of GP experts on each training set (the study's EM),
scores both on both held-out sets, and runs the learned-model planner from pixels with each on
the same ``--episodes`` reset seeds (``--episode-seed + i``): success with its Wilson 95 %
interval, as LeRobot scores. The state-fitted model plans from perceived poses only because it
is explicitly allowed (``allow_observation_mismatch=True``): that is the comparison.

Outputs in ``--out`` (default ``results/pusht_pixel_training``): ``pushes_<role>_<obs>.json``
(the records, reused when their setup matches), ``episodes_<model>.json`` (reused likewise,
resumed episode by episode), ``results.json`` and ``summary.md``.

Usage::

    python benchmarks/pusht_pixel_training.py [--pushes 60] [--test-pushes 40]
        [--episodes 10] [--seed 0] [--episode-seed 0] [--search-candidates 192]
        [--python .venv-pusht/bin/python] [--out results/pusht_pixel_training]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff._cli_errors import run_cli
from probaff._io import atomic_write_text
from probaff._threads import limit_threads
from probaff.eval.tables import markdown_table
from probaff.experiments.pusht.data import (
    dataset_observation,
    perception_errors,
    push_dataset,
    record_chunk,
    with_worker,
)
from probaff.experiments.pusht.models import evaluate, fit_learned, push_effects, push_features
from probaff.experiments.pusht.planner import SearchSettings, run_episode
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.scoring import score
from probaff.experiments.pusht.transitions import ModelTransition
from probaff.models import EMOptions

OBSERVATIONS = ("state", "pixels")
_EPISODE_COLUMNS = ["successes", "success_rate", "success_low", "success_high", "max_coverage"]


def _cached(path: Path, setup: dict[str, Any], make: Any) -> Any:
    """`make()`'s result, saved at `path` with `setup` and reused while `setup` matches."""
    saved = json.loads(path.read_text()) if path.is_file() else {}
    if saved.get("setup") != setup:
        t0 = time.perf_counter()
        saved = {"setup": setup, "result": make(), "seconds": time.perf_counter() - t0}
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json.dumps(saved) + "\n")
    return saved["result"]


def _stats(values: np.ndarray) -> dict[str, float]:
    return {
        "mean": float(np.mean(values)),
        "median": float(np.median(values)),
        "p95": float(np.percentile(values, 95)),
        "max": float(np.max(values)),
    }


def main() -> None:
    """Record (or reuse) both training sets, score the perception, fit, score, plan."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pushes", type=int, default=60)
    ap.add_argument("--test-pushes", type=int, default=40)
    ap.add_argument("--episodes", type=int, default=10)
    ap.add_argument("--experts", type=int, default=3)
    ap.add_argument("--em-max-iter", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--episode-seed", type=int, default=0)
    ap.add_argument("--search-candidates", type=int, default=192)
    ap.add_argument("--search-beam", type=int, default=8)
    ap.add_argument("--search-children", type=int, default=48)
    ap.add_argument("--python", default=None, help="the Push-T environment's Python")
    ap.add_argument("--out", default="results/pusht_pixel_training")
    args = ap.parse_args()
    n = check_count("--pushes", args.pushes)
    test_n = check_count("--test-pushes", args.test_pushes)
    episodes = check_count("--episodes", args.episodes, minimum=0)
    seed = check_count("--seed", args.seed, minimum=0)
    em = EMOptions(max_iter=check_count("--em-max-iter", args.em_max_iter), n_restarts=2, seed=seed)
    search = SearchSettings(
        candidates=args.search_candidates, beam=args.search_beam, children=args.search_children
    )
    settings, out = PrimitiveSettings(), Path(args.out)
    records: dict[tuple[str, str], dict[str, Any]] = {}
    seconds: dict[str, float] = {}
    for role, count in (("train", n), ("test", test_n)):
        for obs in OBSERVATIONS:
            setup = {"seed": seed, "n": count, "settings": repr(settings), "observation": obs}
            path = out / f"pushes_{role}_{obs}.json"
            records[role, obs] = _cached(
                path,
                setup,
                lambda role=role, count=count, obs=obs: record_chunk(
                    role, 0, seed, count, settings=settings, python=args.python, observation=obs
                ),
            )
            seconds[f"{role}_{obs}"] = round(json.loads(path.read_text())["seconds"], 1)
    pix = records["train", "pixels"]
    errors = {k: _stats(v) for k, v in perception_errors([pix]).items()}
    test_errors = {k: _stats(v) for k, v in perception_errors([records["test", "pixels"]]).items()}
    tests = {obs: push_dataset([records["test", obs]], seed) for obs in OBSERVATIONS}
    models: dict[str, Any] = {}
    scores = []
    for obs in OBSERVATIONS:
        ds = push_dataset([records["train", obs]], seed)
        with limit_threads(1):
            models[obs], _ = fit_learned(
                "moe",
                push_features(ds),
                push_effects(ds),
                experts=args.experts,
                em=em,
                observation=dataset_observation(ds),
            )
        for test_obs, test in tests.items():
            row = {"trained_on": obs, "tested_on": test_obs}
            row |= evaluate(models[obs], push_features(test), push_effects(test))
            scores.append(row)
    planned = []
    for obs in OBSERVATIONS:
        transition = ModelTransition(models[obs])
        path = out / f"episodes_{obs}.json"
        setup = {"records": seconds, "seed": seed, "em": repr(em), "search": repr(search)}
        saved = json.loads(path.read_text()) if path.is_file() else {}
        done: list[dict[str, Any]] = (
            saved.get("episodes", []) if saved.get("setup") == setup else []
        )
        for i in range(len(done), episodes):

            def play(w: Any, i: int = i, transition: Any = transition) -> dict[str, Any]:
                with limit_threads(1):
                    return run_episode(
                        w,
                        args.episode_seed + i,
                        transition,
                        search,
                        settings,
                        observation="pixels",
                        allow_observation_mismatch=True,  # the state-fitted model, on purpose
                    )

            done.append(with_worker(args.python, play))
            atomic_write_text(path, json.dumps({"setup": setup, "episodes": done}) + "\n")
            print(json.dumps({"trained_on": obs, "episode": i, **done[-1]}), flush=True)
        if done:
            row = {"trained_on": obs} | {k: score(done[:episodes])[k] for k in _EPISODE_COLUMNS}
            row["episodes"] = len(done[:episodes])
            row["pushes"] = float(np.mean([r["pushes"] for r in done[:episodes]]))
            row["error_px"] = float(np.nanmean([r["error_px"] for r in done[:episodes]]))
            row["lost"] = sum(bool(r.get("lost")) for r in done[:episodes])
            planned.append(row)
    counts = pix["perception"]
    result = {
        "train_perception": errors,
        "test_perception": test_errors,
        "train_counts": counts,
        "test_counts": records["test", "pixels"]["perception"],
        "record_seconds": seconds,
        "models": scores,
        "planning_from_pixels": planned,
    }
    atomic_write_text(out / "results.json", json.dumps(result, indent=1) + "\n")
    command = "python benchmarks/pusht_pixel_training.py " + " ".join(sys.argv[1:])
    err_rows = [{"error": k, **v} for k, v in errors.items()]
    lines = [
        "# Push-T training pushes from pixels against from the state",
        "",
        f"`{command.strip()}`; recording seconds {seconds}.",
        "",
        f"Perception error on the {n} pixel-recorded training pushes (pose: before and after "
        "each push, px of the 96 x 96 image and degrees; effects: the pushing-frame effect "
        f"the model learns; start: the push's start in the block frame). Counts: {counts}.",
        "",
        markdown_table(err_rows, ["error", "mean", "median", "p95", "max"], digits=3),
        "",
        "Held-out scores (the mixture fitted on each training set, scored on each test set):",
        "",
        markdown_table(
            scores,
            ["trained_on", "tested_on", "rmse_y", "rmse_z", "rmse_theta", "nlpd", "coverage90"],
            digits=3,
        ),
        "",
    ]
    if planned:
        lines += [
            f"beam-moe planning from pixels on reset seeds {args.episode_seed}..."
            f"{args.episode_seed + episodes - 1}:",
            "",
            markdown_table(
                planned,
                ["trained_on", "episodes", *_EPISODE_COLUMNS, "pushes", "error_px", "lost"],
                digits=3,
            ),
            "",
        ]
    text = "\n".join(lines)
    atomic_write_text(out / "summary.md", text)
    print(text)


if __name__ == "__main__":
    sys.exit(run_cli(main))
