"""Settings of the Push-T study: its config, the planners, the published target, smoke sizes."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.experiments.base import StudyConfig, check_planners
from probaff.experiments.config_cli import option_flags
from probaff.experiments.pusht.observe import OBSERVATIONS
from probaff.experiments.pusht.planner import SearchSettings
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.scoring import DIFFUSION_POLICY
from probaff.models import EMOptions

__all__ = ["DIFFUSION_POLICY", "PLANNERS", "SMOKE", "PlannerSpec", "PushTStudyConfig"]


@dataclass(frozen=True)
class PlannerSpec:
    """One planner: the model it searches over, the search's depth and risk weight.

    Attributes:
        model: ``"moe"``, ``"gp"``, ``"analytic"``, ``"env"`` (the environment itself) or
            ``""`` (random pushes, no search).
        depth: 2 (beam search over two pushes) or 1 (greedy one push).
        risk: Weight of the predictive standard deviation (0: mean only).
    """

    model: str
    depth: int = 2
    risk: float = 0.0


PLANNERS: Mapping[str, PlannerSpec] = MappingProxyType(
    {
        "beam-moe": PlannerSpec("moe"),
        "beam-risk-moe": PlannerSpec("moe", risk=1.0),
        "beam-gp": PlannerSpec("gp"),
        "beam-analytic": PlannerSpec("analytic"),
        "beam-env": PlannerSpec("env"),
        "greedy-moe": PlannerSpec("moe", depth=1),
        "random": PlannerSpec(""),
    }
)
"""The planners by name; ``beam-moe`` is the learned-model planner the goal is about."""

SMOKE: Mapping[str, Any] = MappingProxyType(
    {
        "train_pushes": (40,),
        "plan_pushes": 40,
        "test_pushes": 20,
        "chunk": 20,
        "experts": 2,
        "em": {"max_iter": 2, "n_restarts": 1, "split_merge": 0},
        "episodes": 2,
        "baseline_episodes": 1,
        "curve_episodes": 0,
        "planners": ("beam-moe", "beam-analytic", "greedy-moe", "random"),
        "search": {"candidates": 32, "beam": 2, "children": 8},
        "progress": False,
    }
)
"""Sizes of a tiny run that checks the whole pipeline in about a minute."""


@dataclass(frozen=True, kw_only=True)
class PushTStudyConfig(StudyConfig):
    """Settings of the Push-T study.

    Attributes:
        out: Output folder (pushes, datasets, models, episode records, tables, figures).
        seed: Seed of the recorded pushes and the fits; episode i resets the environment
            with seed + i (every planner sees the same episodes).
        python: The Push-T environment's Python (default: $PROBAFF_PUSHT_PYTHON, else
            .venv-pusht/bin/python under the working folder).
        train_pushes: Training-set sizes of the model comparison (held-out RMSE, NLPD,
            coverage) and of the success-against-data curve (the exact EM fit of 1000 pushes
            takes tens of minutes; larger sizes want the sparse experts).
        plan_pushes: Training pushes of the planners' models.
        test_pushes: Held-out pushes of the model comparison.
        chunk: Pushes recorded per task.
        experts: Experts M of the mixture (the single GP has one).
        em: The EM fits (`probaff.models.EMOptions`; flag ``--em-max-iter``); their seed is
            the study's.
        episodes: Episodes of the learned-model planner ``beam-moe``.
        baseline_episodes: Episodes of every other planner (the first ones of the same seeds).
        env_episodes: Episodes of ``beam-env``, whose every candidate is simulated (None:
            `baseline_episodes`).
        curve_episodes: Episodes of ``beam-moe`` at every training size (0: no curve).
        planners: Names from `PLANNERS`.
        primitives: The push primitives (`PrimitiveSettings`).
        search: The search over a model (`SearchSettings`; flags ``--search-candidates``,
            ``--search-beam``, ``--search-children``).
        env_search: The search over the environment itself, a smaller budget since every
            candidate is simulated (flags ``--env-search-candidates``, ...).
        keep_trajectories: Episodes per planner whose poses are kept for the figures.
        observation: What the planners observe in the episodes, and what the training and
            held-out pushes are recorded from: ``"state"`` (the environment's state) or
            ``"pixels"`` (only the diffusion policy's observation, the 96 x 96 image and the
            agent's position; the goal and the block's pose are perceived, the pushes'
            features and effects are computed from perceived poses, and the state is kept
            for scoring only). Pixel runs key their pushes, datasets, models and episodes
            apart from state runs.
    """

    out: str = "results/pusht"
    python: str | None = None
    train_pushes: tuple[int, ...] = (60, 250)
    plan_pushes: int = 250
    test_pushes: int = 500
    chunk: int = 50
    experts: int = 3
    em: EMOptions = field(
        default=EMOptions(max_iter=10, n_restarts=2), metadata=option_flags(("max_iter",))
    )
    episodes: int = 500
    baseline_episodes: int = 100
    env_episodes: int | None = None
    curve_episodes: int = 50
    planners: tuple[str, ...] = tuple(PLANNERS)
    primitives: PrimitiveSettings = field(default=PrimitiveSettings())
    search: SearchSettings = field(
        default=SearchSettings(),
        metadata=option_flags(("candidates", "beam", "children")),
    )
    env_search: SearchSettings = field(
        default=SearchSettings(candidates=32, beam=4, children=12),
        metadata=option_flags(("candidates", "beam", "children")),
    )
    keep_trajectories: int = 6
    observation: str = "state"

    RUN_ONLY: ClassVar[frozenset[str]] = StudyConfig.RUN_ONLY | {"python"}
    SMOKE: ClassVar[Mapping[str, Any]] = SMOKE

    def check(self) -> dict[str, Any]:
        """Raise `InputError` for unknown planners or counts that are not positive integers."""
        check_planners(self.planners, PLANNERS)
        if self.observation not in OBSERVATIONS:
            raise InputError(
                f"observation must be one of {list(OBSERVATIONS)}, got {self.observation!r}."
            )
        sizes = tuple(check_count("train_pushes", n) for n in self.train_pushes)
        if not sizes:
            raise InputError("train_pushes must name at least one training-set size.")
        counts = {
            name: check_count(name, getattr(self, name))
            for name in ("plan_pushes", "test_pushes", "chunk", "experts", "episodes")
        }
        for name in ("baseline_episodes", "curve_episodes", "keep_trajectories"):
            counts[name] = check_count(name, getattr(self, name), minimum=0)
        if self.env_episodes is not None:
            counts["env_episodes"] = check_count("env_episodes", self.env_episodes, minimum=0)
        if min(*sizes, counts["plan_pushes"]) < 10:
            raise InputError("train_pushes and plan_pushes must be at least 10 pushes each.")
        return {"train_pushes": sizes, **counts}
