"""The affordance-map study (chapter 3): information-gain pushing against exhaustive pushing.

Modules:
    config: `AffordanceMapConfig`, the warehouse world it runs in (`world`), smoke sizes.
    run: the classifier's training, one test map's loops (`map_task`), and `run`.
    report: the curves over steps, the areas under them, the classifier, the summary.
    figures: step curves, the MRF's smoothing (Fig. 3.5) and the loop's steps (Fig. 3.6).
    demo: one small map, pushed by information gain (``probaff demo``).
"""

from probaff.experiments.affordance_map.config import SMOKE, STUDY_MRF, AffordanceMapConfig, world
from probaff.experiments.affordance_map.run import run, train_classifier

Config = AffordanceMapConfig
"""The study's config class (the registry's name for it)."""

__all__ = [
    "SMOKE",
    "STUDY_MRF",
    "AffordanceMapConfig",
    "Config",
    "run",
    "train_classifier",
    "world",
]
