"""Settings of the chapter 6 study: its config, the thesis's numbers, smoke and demo sizes."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.experiments.base import StudyConfig
from probaff.experiments.modular.trials import TrialSettings
from probaff.features.ch6_steps import check_step_length
from probaff.sim.pusher import HAND_MODES
from probaff.sim.tabletop_config import load_scene

__all__ = ["DEMO", "PUSH_SCENES", "SMOKE", "THESIS", "TRAININGS", "ModularStudyConfig"]

THESIS = {
    "backward_along_cm": (5.8, 2.57),
    "modular_along_cm": (1.89, 1.02),
    "monolithic_along_cm": (4.83, 2.49),
}
"""Chapter 6's published numbers: push-along error without -> with the backward component;
modular and monolithic push-along errors of (o1, o2)."""

TRAININGS = {"push": "two-object scenes", "chained": "+ chain_3 rows"}
"""Chain summaries by task part: the thesis's training, and the extension's."""

SMOKE: Mapping[str, Any] = MappingProxyType(
    {
        "push_train": 24,
        "pick_train": 16,
        "place_train": 8,
        "test_scenes": 2,
        "trials": 2,
        "scales": (1.0,),
        "chain_lengths": (3,),
        "chain_train": 6,
        "settings": {"chain_samples": 16, "em": {"max_iter": 2}, "gp": {"max_iter": 10}},
        "progress": False,
    }
)
"""Sizes of a tiny run that checks the whole pipeline in a minute or two."""

DEMO: Mapping[str, Any] = MappingProxyType(
    {
        "push_train": 48,
        "pick_train": 32,
        "place_train": 16,
        "test_scenes": 3,
        "trials": 1,
        "scales": (1.0,),
        "chain_lengths": (3,),
        "chain_train": 0,
        "settings": {
            "chain_samples": 64,
            "em": {"max_iter": 3},
            "gp": {"max_iter": 30},
            "stepped": False,
        },
    }
)
"""The demo's sizes: one small trial of every part, a three-object chain among them (the
stepped push model is left to the study)."""

_PARTS = ("push", "pick", "place")

PUSH_SCENES = ("modular_push", "resistance_push")
"""Two-object push scenes the study's push part can draw from: the thesis's two cuboids, or a
box pushed into a second, often too heavy to move, where the hand meets resistance."""


@dataclass(frozen=True, kw_only=True)
class ModularStudyConfig(StudyConfig):
    """Settings of the chapter 6 study.

    Attributes:
        out: Output folder (datasets, per-task records, tables, figures).
        seed: Seed of the datasets, the training draws and the fits.
        push_train: Training pushes at scale 1 (the thesis's 221 push samples).
        pick_train: Training picks at scale 1 (168).
        place_train: Training places at scale 1 (20).
        test_scenes: Test scenes per skill and trial (the thesis's 10).
        trials: Independent repetitions (a training draw and a test slice each).
        scales: Training-set sizes as multiples of the thesis's; 1 is the thesis's setting,
            larger ones show how the errors fall with data.
        chain_lengths: Objects per test chain.
        chain_train: ``chain_3`` pushes whose rows are added to the chain's push model in
            the extension part (``"chained"`` tasks: does a model that has seen packed rows
            of three predict rows of four and five?); 0 skips it.
        settings: Models, feature groups and sampling of every trial.
        hand: How the simulated hand follows its command in every dataset
            (`probaff.sim.pusher.HAND_MODES`): ``"compliant"`` (the default; a Cartesian
            impedance, so that the hand lags and deflects against resistance as the thesis's
            arm did: "the desired trajectory of the manipulator would not synchronize with
            executed position due to the feedback force", section 6.5.2) or ``"stiff"``
            (the hand held to its command within about 0.5 mm).
        push_scene: The two-object push scene of the push part's pool and test scenes
            (`PUSH_SCENES`): ``"modular_push"`` (the thesis's cuboids) or
            ``"resistance_push"`` (heavy boxes pushed into others: the hand meets
            resistance). The chains stay the ``chain_3`` .. ``chain_5`` cuboid rows.
    """

    out: str = "results/modular"
    push_train: int = 221
    pick_train: int = 168
    place_train: int = 20
    test_scenes: int = 10
    trials: int = 5
    scales: tuple[float, ...] = (1.0, 2.0)
    chain_lengths: tuple[int, ...] = (3, 4, 5)
    chain_train: int = 60
    settings: TrialSettings = field(default_factory=TrialSettings)
    hand: str = "compliant"
    push_scene: str = "modular_push"

    SMOKE: ClassVar[Mapping[str, Any]] = SMOKE

    def check(self) -> dict[str, Any]:
        """Raise `InputError` for impossible sizes, scales, chains or settings."""
        for name in ("push_train", "pick_train", "place_train", "test_scenes", "trials"):
            check_count(name, getattr(self, name))
        check_count("chain_train", self.chain_train, minimum=0)
        if not self.scales or any(
            not isinstance(s, (int, float)) or not math.isfinite(s) or s < 1 for s in self.scales
        ):
            raise InputError(
                f"scales must be finite numbers >= 1 (multiples of the thesis's sizes), got "
                f"{self.scales!r}."
            )
        bad = [k for k in self.chain_lengths if k not in (3, 4, 5)]
        if bad:
            raise InputError(f"chain_lengths may hold 3, 4 and 5 (the chain scenes), got {bad}.")
        if self.hand not in HAND_MODES:
            raise InputError(
                f"hand must be one of {list(HAND_MODES)} (how the simulated hand follows its "
                f"command), got {self.hand!r}."
            )
        if self.push_scene not in PUSH_SCENES:
            raise InputError(
                f"push_scene must be one of {list(PUSH_SCENES)} (a two-object push scene), got "
                f"{self.push_scene!r}."
            )
        s = self.settings
        if not isinstance(s, TrialSettings):
            raise InputError(f"settings must be a TrialSettings, got {type(s).__name__}.")
        if s.stepped:  # the step length must divide the scene's push, before any work
            distance = load_scene(self.push_scene).push.distance
            check_step_length(s.step_length, np.array([distance]))
        return {}

    def train_size(self, part: str, scale: float) -> int:
        """Training rows of `part` (``"push"``, ``"pick"``, ``"place"``) at `scale`."""
        base = {"push": self.push_train, "pick": self.pick_train, "place": self.place_train}
        return max(2, round(base[part] * scale))

    def draw(self, part: str, scale: float, trial: int) -> list[int]:
        """The training rows of one (part, scale, trial): a seeded draw from the pool."""
        pool = self.train_size(part, max(self.scales))
        n = self.train_size(part, scale)
        key = (trial, round(1000 * scale), _PARTS.index(part))
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=key))
        return sorted(rng.choice(pool, size=n, replace=False).tolist())
