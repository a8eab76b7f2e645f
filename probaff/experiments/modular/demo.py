"""`probaff demo`'s chapter 6 part: a pick, a place and a chained three-object push, drawn."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from probaff.experiments.config_cli import with_smoke
from probaff.experiments.modular.config import DEMO, ModularStudyConfig
from probaff.experiments.modular.run import run

__all__ = ["demo"]


def demo(out: str | Path, *, seed: int = 0, progress: bool = True) -> dict[str, Any]:
    """A small run of the study: a pick, a place and a chained three-object push, drawn.

    ``probaff demo`` calls it. It fits the per-skill models on a few dozen samples of each
    skill, predicts three test scenes of each and prints one line per skill.

    Args:
        out: Output folder (datasets, records, ``tabletop_predictions.png``,
            ``sideview_predictions.png`` and the tables).
        seed: Seed of the datasets and the fits.
        progress: Show the generators' progress bars.

    Returns:
        `run`'s summary.
    """
    config = with_smoke(ModularStudyConfig(out=str(out), seed=seed, progress=progress), DEMO)
    summary = run(config)
    chain = [r for r in summary["chains"] if r["n_objects"] == 3]
    errors = " / ".join(f"{r['error_cm']:.1f}" for r in chain)
    print(f"three-object chain: position error per object {errors} cm (o1 / o2 / o3)")
    for r in summary["skills"]:
        if r["model"] == "forward" and r["case"] != "all":
            print(
                f"{r['skill']} ({r['case']}, {r['n']} cases): predicted displacement "
                f"{r['predicted_cm']:.1f} cm, observed {r['true_cm']:.1f} cm"
            )
    return summary
