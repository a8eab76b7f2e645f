"""`probaff demo`'s planning part: one planned push-to-edge episode, drawn."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from probaff.experiments.base import StudyRun
from probaff.experiments.planning.config import PlanningStudyConfig, trial_seed
from probaff.experiments.planning.figures import plot_edge_episodes
from probaff.experiments.planning.run import edge_models, edge_trial
from probaff.planning import load_edge_task

__all__ = ["demo"]


def demo(
    out: str | Path, *, seed: int = 0, train_pushes: int = 64, progress: bool = True
) -> dict[str, Any]:
    """One planned push-to-edge episode with the mixture of experts, rendered to a PNG.

    Generates `train_pushes` pushes of the task's scene, fits the ``"moe"`` model on them and
    runs one closed-loop A* episode; ``probaff demo`` calls it.

    Args:
        out: Output folder (the dataset, ``edge_episode.png``).
        seed: Seed of the pushes, the fit and the episode.
        train_pushes: Training pushes (at least 10).
        progress: Show the generator's progress bar.

    Returns:
        ``{"outcome", "pushes", "replans", "error_cm", "figure"}``.
    """
    out = Path(out)
    study = StudyRun(
        PlanningStudyConfig(out=str(out), seed=seed, train_pushes=train_pushes, progress=progress)
    )
    models = edge_models(study, {"moe"})
    record = edge_trial("astar-moe", 0, trial_seed(seed, 0), True, models=models)
    figure = plot_edge_episodes(
        [record], load_edge_task(), out / "edge_episode.png", title="A* with the mixture of experts"
    )
    result = {
        "outcome": record["outcome"],
        "pushes": record["pushes"],
        "replans": record["replans"],
        "error_cm": 100 * record["mean_error"],
        "figure": figure,
    }
    print(
        f"push to the edge: {record['outcome']} after {record['pushes']} pushes, "
        f"{record['replans']} replans, mean one-step error {result['error_cm']:.2f} cm"
    )
    return result
