"""The planning study (chapters 4 and 5): push-to-edge planners and two-step tool pushes.

Modules:
    config: `PlanningStudyConfig`, the thesis's result, the smoke sizes, the trial seeds.
    run: the episodes and trials as resumable tasks, the planner models, and `run`.
    report: the success rates with their intervals, the failures' blame, the summary.
    figures: success rates, pushes per trial, planned against executed episodes.
    reference: a run's success counts against a stored reference (``--reference``).
    demo: one planned episode, drawn (``probaff demo``).
"""

from probaff.experiments.planning.config import SMOKE, PlanningStudyConfig
from probaff.experiments.planning.run import run

Config = PlanningStudyConfig
"""The study's config class (the registry's name for it)."""

__all__ = ["SMOKE", "Config", "PlanningStudyConfig", "run"]
