"""`probaff demo`: the main job on a small embedded default.

It generates a small two-object push dataset (chapter 5's scene), prints its summary, draws a
few pushes with the arm's reachable region, fits a mixture of GP experts by EM next to a
single GP, printing their held-out RMSE and NLPD, and finally explores a small warehouse map,
pushes a few boxes chosen by information gain on the affordance MRF, and prints the map's
entropy before and after.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from probaff._threads import torch_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.data.schema import PushDataset
from probaff.data.summary import summarize
from probaff.eval.metrics import nlpd, rmse
from probaff.eval.push_figures import plot_pushes
from probaff.features import chapter5_features
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.sim.arm import load_arm
from probaff.sim.config import load_tabletop
from probaff.studies.affordance_map import demo as affordance_demo

__all__ = ["DemoConfig", "run"]


@dataclass(frozen=True)
class DemoConfig:
    """Settings of the demo.

    Attributes:
        out: Output folder (created; an earlier demo there is resumed).
        n: Pushes to generate.
        seed: Dataset seed.
        workers: 0 runs in this process; K > 0 uses a local Dask cluster.
        progress: Show progress bars.
    """

    out: str = "results/demo"
    n: int = 96
    seed: int = 0
    workers: int = 0
    progress: bool = True


def run(config: DemoConfig) -> dict[str, Any]:
    """Run the demo and report what it wrote.

    Args:
        config: Demo settings.

    Returns:
        ``{"summary": ..., "dataset": path, "figure": path}``.
    """
    out = Path(config.out)
    ds_path = out / "two_objects"
    gen = GenerateConfig(scene="two_objects", n=config.n, seed=config.seed, shard_size=16)
    ds = generate(gen, ds_path, workers=config.workers, resume=ds_path.exists(),
                  progress=config.progress)
    summary = summarize(ds)
    print(json.dumps(summary, indent=1))
    world = load_tabletop()
    tx, ty = world.table_size
    reach = load_arm(world.arm).reachable_mask((-tx / 2, tx / 2), (-ty / 2, ty / 2),
                                               resolution=0.04, n_yaws=2)
    figure = out / "demo_pushes.png"
    plot_pushes(ds, list(range(min(6, len(ds)))), figure, reachable=reach)
    models = _compare_models(ds, config.seed)
    print(f"dataset: {os.fspath(ds_path)}")
    print(f"figure:  {os.fspath(figure)}")
    print("affordance map:")
    affordance = affordance_demo(out / "affordance_map", seed=config.seed, steps=3)
    return {"summary": summary, "dataset": os.fspath(ds_path), "figure": os.fspath(figure),
            "models": models, "affordance_map": affordance}


def _compare_models(ds: PushDataset, seed: int) -> dict[str, dict[str, float]]:
    """Held-out RMSE and NLPD of a 3-expert EM mixture and of a single GP (M = 1)."""
    features = chapter5_features(ds)
    X = features.values
    Y = ds["effect"][:, :2].reshape(len(ds), 6)
    rng = np.random.default_rng(seed)
    test = rng.permutation(len(ds))[: len(ds) // 3]
    train = np.setdiff1d(np.arange(len(ds)), test)
    y = torch.as_tensor(Y[test])
    scores = {}
    with torch_threads(1):
        for name, m in (("single GP", 1), ("mixture M=3", 3)):
            model = MixtureOfGPExperts(m, groups=features.groups, gate_features=("f_x",),
                                       expert_features=("f_o", "f_c"), lengthscale_prior=True)
            fit_em(model, X[train], Y[train], max_iter=5, seed=seed)
            pred = model.predict(X[test])
            scores[name] = {"rmse_mean": float(rmse(pred, y).mean()),
                            "rmse_o1_dz_cm": float(100 * rmse(pred, y)[1]),
                            "rmse_o2_dz_cm": float(100 * rmse(pred, y)[4]),
                            "nlpd": float(nlpd(pred, y).sum())}
    print(f"held-out pushes: {len(test)} (trained on {len(train)})")
    print(f"{'model':14s} {'o1 dz RMSE':>11s} {'o2 dz RMSE':>11s} {'NLPD (6 dims)':>14s}")
    for name, s in scores.items():
        print(f"{name:14s} {s['rmse_o1_dz_cm']:8.2f} cm {s['rmse_o2_dz_cm']:8.2f} cm "
              f"{s['nlpd']:14.2f}")
    return scores
