"""The push-model study (chapters 5 and 4): mixtures of GP experts fitted by EM and VI.

Modules:
    config: `PushModelStudyConfig`, the feature configurations and the smoke sizes.
    run: the cross-validation tasks, their fits, and `run`.
    report: the tables and the summary, with the thesis's findings checked.
    figures: the study's figures, and `plot_pushes` for pushes of any dataset.
"""

from probaff.experiments.push_models.config import SMOKE, PushModelStudyConfig
from probaff.experiments.push_models.run import run

Config = PushModelStudyConfig
"""The study's config class (the registry's name for it)."""

__all__ = ["SMOKE", "Config", "PushModelStudyConfig", "run"]
