"""`probaff demo`: the main job on a small embedded default.

It generates a small two-object push dataset (chapter 5's scene), prints its summary, and draws
a few pushes with the arm's reachable region.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probaff.data.generation import GenerateConfig, generate
from probaff.data.summary import summarize
from probaff.eval.push_figures import plot_pushes
from probaff.sim.arm import load_arm
from probaff.sim.config import load_tabletop

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
    n: int = 48
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
    print(f"dataset: {os.fspath(ds_path)}")
    print(f"figure:  {os.fspath(figure)}")
    return {"summary": summary, "dataset": os.fspath(ds_path), "figure": os.fspath(figure)}
