"""`probaff demo`: the main job on a small embedded default.

It generates a small two-object push dataset (chapter 5's scene, poses observed with a depth
camera's noise), prints its summary, draws a few pushes with the arm's reachable region, fits
a mixture of GP experts by EM next to a single GP, printing their held-out RMSE, NLPD and 90 %
interval coverage and drawing both models' predictive density of o2's motion for a push where
the mixture sees two outcomes (o2 hit or not), and finally explores a small warehouse map,
pushes a few boxes chosen by information gain on the affordance MRF, and prints the map's
entropy before and after, then plans and executes one push-to-edge episode (chapter 4: A*
over the mixture's predictions, closed loop in the simulator), drawn to a PNG, and last fits
chapter 6's per-skill transition models and predicts a pick, a place and a three-object
chained push, drawn against what the simulator did. Then (chapter 2) it scans a few
office scenes from the robot's head, segments them by region growing, trains the label
classifiers on all but one and draws the held-out scene's segments and predicted labels to a
PNG, printing its held-out precision and recall.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.distributions import Normal

from probaff._checks import check_count
from probaff._threads import torch_threads
from probaff.data import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.data.schema import PushDataset
from probaff.data.summary import summarize
from probaff.eval.metrics import interval_coverage, nlpd, rmse
from probaff.experiments.affordance_map.demo import demo as affordance_demo
from probaff.experiments.modular.demo import demo as modular_demo
from probaff.experiments.planning.demo import demo as planning_demo
from probaff.experiments.point_cloud_labels.demo import demo as point_cloud_demo
from probaff.experiments.push_models.figures import plot_predictive_density, plot_pushes
from probaff.features import chapter5_features
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.sim import load_arm, load_tabletop

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
        ``{"summary": ..., "dataset": path, "figure": path, "models", "affordance_map",
        "planning", "modular", "point_cloud_labels": each part's summary}``.
    """
    check_count("n", config.n)
    check_count("seed", config.seed, minimum=0)
    check_count("workers", config.workers, minimum=0)
    out = Path(config.out)
    ds_path = out / "two_objects"
    gen = GenerateConfig(
        scene="two_objects", n=config.n, seed=config.seed, shard_size=16, pose_noise=PoseNoise()
    )
    ds = generate(
        gen, ds_path, workers=config.workers, resume=ds_path.exists(), progress=config.progress
    )
    summary = summarize(ds)
    print(json.dumps(summary, indent=1))
    world = load_tabletop()
    tx, ty = world.table_size
    reach = load_arm(world.arm).reachable_mask(
        (-tx / 2, tx / 2), (-ty / 2, ty / 2), resolution=0.04, n_yaws=2
    )
    figure = out / "demo_pushes.png"
    plot_pushes(ds, list(range(min(6, len(ds)))), figure, reachable=reach)
    models = _compare_models(ds, config.seed, out)
    print(f"dataset: {os.fspath(ds_path)}")
    print(f"figure:  {os.fspath(figure)}")
    print("affordance map:")
    affordance = affordance_demo(out / "affordance_map", seed=config.seed, steps=4)
    print("planning:")
    planning = planning_demo(out / "planning", seed=config.seed, progress=config.progress)
    print("modular transition models (chapter 6):")
    modular = modular_demo(out / "modular", seed=config.seed, progress=config.progress)
    print("point-cloud labels (chapter 2):")
    labels = point_cloud_demo(
        out / "point_cloud_labels", seed=config.seed, progress=config.progress
    )
    return {
        "summary": summary,
        "dataset": os.fspath(ds_path),
        "figure": os.fspath(figure),
        "models": models,
        "affordance_map": affordance,
        "planning": planning,
        "modular": {k: modular[k] for k in ("chains", "skills", "files")},
        "point_cloud_labels": labels,
    }


def _compare_models(ds: PushDataset, seed: int, out: Path) -> dict[str, dict[str, float]]:
    """Held-out scores of a 3-expert EM mixture and of a single GP, and o2's density figure.

    Both models see the same pushes, features (gate: f_x; experts: f_o & f_c) and noise
    floor (that of the dataset's pose noise). The figure shows, for the held-out push where
    the mixture's prediction of o2's displacement along the push is most clearly bimodal
    (o2 hit or not hit), both models' predictive densities and what was observed.
    """
    features = chapter5_features(ds)
    X = features.values
    Y = ds["effect"][:, :2].reshape(len(ds), 6)
    rng = np.random.default_rng(seed)
    test = rng.permutation(len(ds))[: len(ds) // 3]
    train = np.setdiff1d(np.arange(len(ds)), test)
    y = torch.as_tensor(Y[test])
    floor = PoseNoise().effect_std(2) if ds.has_pose_noise else "auto"
    scores: dict[str, dict[str, float]] = {}
    preds = {}
    with torch_threads(1):
        for name, m in (("single GP", 1), ("mixture M=3", 3)):
            model = MixtureOfGPExperts(
                m,
                groups=features.groups,
                gate_features=("f_x",),
                expert_features=("f_o", "f_c"),
                lengthscale_prior=True,
                noise_floor=floor,
            )
            fit_em(model, X[train], Y[train], seed=seed)
            pred = preds[name] = model.predict(X[test])
            err = rmse(pred, y)
            scores[name] = {
                "rmse_o1_dz_cm": float(100 * err[1]),
                "rmse_o2_dz_cm": float(100 * err[4]),
                "nlpd": float(nlpd(pred, y).sum()),
                "coverage90": float(interval_coverage(pred, y, 0.9).mean()),
            }
    print(
        f"held-out pushes: {len(test)} (trained on {len(train)}); "
        f"pose noise: {'on' if ds.has_pose_noise else 'off'}"
    )
    print(
        f"{'model':14s} {'o1 dz RMSE':>11s} {'o2 dz RMSE':>11s} {'NLPD (6 dims)':>14s} "
        f"{'90% coverage':>13s}"
    )
    for name, s in scores.items():
        print(
            f"{name:14s} {s['rmse_o1_dz_cm']:8.2f} cm {s['rmse_o2_dz_cm']:8.2f} cm "
            f"{s['nlpd']:14.2f} {s['coverage90']:13.2f}"
        )
    figure = _plot_o2_density(preds, Y[test], out / "demo_o2_density.png")
    print(f"o2 density figure: {os.fspath(figure)}")
    return scores


def _plot_o2_density(preds: dict[str, Any], Y: np.ndarray, path: Path) -> Path:
    """Plot o2's dz density at the held-out push where the mixture is most bimodal."""
    mixture = preds["mixture M=3"]
    probs = mixture.mixture_distribution.probs  # (N, M)
    loc = mixture.component_distribution.base_dist.loc[..., 4]  # (N, M), o2 dz
    scale = mixture.component_distribution.base_dist.scale[..., 4]
    spread = (loc.max(1).values - loc.min(1).values) / scale.min(1).values
    weight = 1.0 - probs.max(1).values  # mass away from the most probable expert
    i = int(torch.argmax(spread * weight))
    lo = float(torch.min(loc[i] - 4 * scale[i]).clamp_max(Y[i, 4] - 0.01))
    hi = float(torch.max(loc[i] + 4 * scale[i]).clamp_min(Y[i, 4] + 0.01))
    grid = torch.linspace(lo, hi, 400, dtype=torch.float64)
    densities = {}
    for name, pred in preds.items():
        p = pred.mixture_distribution.probs[i]
        comp = pred.component_distribution.base_dist
        d = Normal(comp.loc[i, :, 4], comp.scale[i, :, 4])
        densities[name] = (p[None, :] * d.log_prob(grid[:, None]).exp()).sum(1).numpy()
    plot_predictive_density(
        100 * grid.numpy(),
        {k: v / 100 for k, v in densities.items()},
        100 * float(Y[i, 4]),
        path,
        xlabel="o2 dz_p (cm)",
        title="o2 along the push, one held-out push: hit or not hit",
    )
    return path
