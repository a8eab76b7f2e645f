"""The inference studies: one folder each, over a shared config and run skeleton.

Each study is a subpackage with ``Config``, ``SMOKE`` and ``run(config)``; `STUDIES` finds
them by folder, and ``probaff study NAME`` and ``inference/NAME.py`` run them.

Studies:
    point_cloud_labels: chapter 2, affordance labels of scanned office segments, Algorithm 1
        and the multi-view merge.
    affordance_map: chapter 3, the manipulation loop's information gain against exhaustive
        pushing over generated warehouse maps (Figs. 3.5-3.7).
    planning: chapters 4 and 5, push-to-edge planners and two-step tool pushes, closed loop.
    push_models: chapters 5 and 4, mixtures of GP experts fitted by EM and VI,
        cross-validated.
    modular: chapter 6, modular push, pick and place transition models against a monolith.
    pusht: Push-T in the unmodified gym-pusht, learned push models and beam-search planners,
        closed loop.

Modules:
    base: `StudyConfig` (out, seed, workers, scheduler, progress, the smoke sizes, and their
        checks) and `StudyRun` (the run skeleton: tasks on Dask, tables, figures, summary).
    config_cli: command-line flags from a config's fields, ``--smoke``.
    registry: `STUDIES` (a `StudyRegistry` of `Study`, in the shared registry),
        `discover_studies` and `study_main` (``probaff study``).

A new study is one folder here (its ``config``, ``run``, ``report`` and ``figures``), its
test and its notebook; nothing else names it (``probaff study NAME`` runs it, and the build
finds its package).
"""

from probaff.experiments.base import StudyConfig, StudyRun
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.registry import (
    STUDIES,
    Study,
    StudyRegistry,
    UnknownStudyError,
    discover_studies,
    study_main,
)

__all__ = [
    "STUDIES",
    "Study",
    "StudyConfig",
    "StudyRegistry",
    "StudyRun",
    "UnknownStudyError",
    "discover_studies",
    "parse_study_args",
    "study_main",
]
