"""The chapter 6 study: modular transition models for push, pick and place, against a monolith.

Modules:
    config: `ModularStudyConfig`, the thesis's numbers, the smoke and demo sizes.
    trials: one trial (a training draw and its test slice) of each part: `TrialSettings`,
        `push_trial`, `skill_trial`, `chain_trained_trial`.
    run: the datasets, the trials as resumable tasks, and `run`.
    report: the tables (backward component, two objects, pick and place, chains), summary.
    figures: the study's figures from its records and tables.
    drawing: predicted against observed scenes on the table and in the side view.
    charts: errors along chains, modular against monolithic, learning curves.
    demo: a small run, drawn (``probaff demo``).
"""

from probaff.experiments.modular.config import SMOKE, ModularStudyConfig
from probaff.experiments.modular.run import run
from probaff.experiments.modular.trials import TrialSettings

Config = ModularStudyConfig
"""The study's config class (the registry's name for it)."""

__all__ = ["SMOKE", "Config", "ModularStudyConfig", "TrialSettings", "run"]
