"""Settings of the push-model study: its config, feature configurations and smoke sizes."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

from probaff._checks import check_count
from probaff.data.noise import PoseNoise
from probaff.errors import InputError
from probaff.experiments.base import StudyConfig
from probaff.experiments.config_cli import option_flags
from probaff.models import EMOptions, GPOptions, SVIOptions

__all__ = [
    "CH4_EFFECTS",
    "CH4_FEATURES",
    "CH5_EFFECTS",
    "CH5_FEATURES",
    "MAX_TRIALS",
    "SMOKE",
    "PushModelStudyConfig",
    "effect_noise_floor",
]

CH5_FEATURES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "o": (("f_o",), ("f_o",)),
    "oc": (("f_o", "f_c"), ("f_o", "f_c")),
    "ocx": (("f_o", "f_c", "f_x"), ("f_o", "f_c", "f_x")),
    "gx-eoc": (("f_x",), ("f_o", "f_c")),
}
"""Chapter 5 configurations: name -> (gate groups, expert groups)."""

CH4_FEATURES: dict[str, tuple[str, ...]] = {
    "o": ("f_o",),
    "oc": ("f_o", "f_c"),
    "ocx": ("f_o", "f_c", "f_x"),
}
"""Chapter 4 configurations: name -> groups used by the experts (and the gate)."""

CH5_EFFECTS = ("o1.dy", "o1.dz", "o1.dth", "o2.dy", "o2.dz", "o2.dth")
"""Names of chapter 5's six effects (both objects' planar motion in the push frame)."""

CH4_EFFECTS = ("dy", "dz", "dth")
"""Names of chapter 4's three effects."""

MAX_TRIALS = 100_000
"""Most independent trials of one study (``ch5_trials``): each study seed's trials take
their own range of dataset seeds (`probaff.experiments.push_models.run.trial_data`)."""

SMOKE: Mapping[str, Any] = MappingProxyType(
    {
        "ch5_pushes": 40,
        "ch5_experts": (1, 2),
        "ch5_folds": 2,
        "ch5_features": ("ocx", "gx-eoc"),
        "ch5_trials": 2,
        "ch5_trial_test": 16,
        "ch4_pushes": 24,
        "ch4_experts": (1, 2),
        "ch4_folds": 2,
        "ch4_features": ("oc",),
        "em": {"max_iter": 2, "n_restarts": 2},
        "vi_features": ("gx-eoc",),
        "svi": {"n_steps": 30},
        "gp": {"max_iter": 8},
        "progress": False,
    }
)
"""Sizes of a tiny run that checks the whole pipeline in about a minute."""


@dataclass(frozen=True, kw_only=True)
class PushModelStudyConfig(StudyConfig):
    """Settings of the push-model study (defaults reproduce the thesis's setup).

    Attributes:
        out: Output folder (datasets, per-task results, tables, figures).
        seed: Seed of the datasets, folds and fits.
        ch5_pushes: Two-object pushes.
        ch5_experts: Values of M.
        ch5_folds: Cross-validation folds.
        ch5_repeats: Repeats of the chapter 5 cross-validation, each with its own shuffle
            (scikit-learn's `RepeatedKFold`; the first repeat is the folds of one run). The
            claims' intervals are over every (repeat, fold), with Nadeau and Bengio's
            correction for the splits' shared training rows
            (`probaff.eval.metrics.corrected_halfwidth`).
        ch5_trials: Independent trials of chapter 5 on fresh data (0: none). Trial k fits
            every `ch5_features` path (M in `ch5_experts`, EM only) on ``ch5_pushes`` pushes of
            its own and scores it on ``ch5_trial_test`` more, all simulated anew with seeds of
            the trial's (`trial_data`). No two trials share a push, so the claims judged over
            trials (``ch5_trial_claims.csv``) take the plain t interval: a sharper test than
            the splits of one dataset, which share rows and need the corrected interval.
        ch5_trial_test: Held-out pushes of each trial.
        ch5_features: Names from `CH5_FEATURES`.
        methods: ``"em"`` and/or ``"vi"``.
        ch4_pushes: Single-object pushes near the battery (0 skips chapter 4).
        ch4_experts: Values of m.
        ch4_folds: Cross-validation folds.
        ch4_features: Names from `CH4_FEATURES`.
        em: The EM fits (`probaff.models.EMOptions`; flags ``--em-max-iter``,
            ``--em-init``, ``--em-n-restarts``); its seed is the study's.
        gate: Kind of gate of the EM mixture (``"linear"`` or ``"fourier"``).
        vi_features: Feature configurations (of `ch5_features`) that VI is also fitted on;
            every VI mixture starts from the EM mixture of the same fold and M.
        svi: The SVI fits (`probaff.models.SVIOptions`; flag ``--svi-n-steps``); its seed is the
            study's, its start the EM mixture. From that start 100 steps (about 30 passes over a
            fold's training rows) do as well as 400: on the ``oc`` folds at M = 3 and 6 the held-out
            NLPD of the two differs by at most 0.06 nats per push (summed over the six effects), and
            both stay within 0.03 of EM's.
        vi_inducing: Inducing points per variational expert.
        gp: Every GP expert (`probaff.models.GPOptions`; flags ``--gp-max-iter`` and
            ``--gp-lengthscale-prior``): L-BFGS iterations per expert fit, and the
            dimension-scaled log-normal prior on the ARD length scales (MAP instead of ML-II;
            with N close to D, ML-II overfits). Its noise floor comes from `pose_noise`.
        pose_noise: Observe object poses with `probaff.data.PoseNoise`'s default noise
            (3 mm, 1 degree), as a depth camera would; the models then get the matching
            noise floor (the standard deviation of a difference of two noisy poses,
            sqrt(2) times the pose noise). Without it, the floor is ``"auto"``.
    """

    out: str = "results/push_models"
    ch5_pushes: int = 321
    ch5_experts: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
    ch5_folds: int = 3
    ch5_repeats: int = 1
    ch5_trials: int = 0
    ch5_trial_test: int = 500
    ch5_features: tuple[str, ...] = ("o", "oc", "ocx", "gx-eoc")
    methods: tuple[str, ...] = ("em", "vi")
    ch4_pushes: int = 120
    ch4_experts: tuple[int, ...] = (1, 2, 3, 4)
    ch4_folds: int = 5
    ch4_features: tuple[str, ...] = ("o", "oc", "ocx")
    em: EMOptions = field(
        default=EMOptions(max_iter=10, init="auto", n_restarts=3),
        metadata=option_flags(("max_iter", "init", "n_restarts")),
    )
    gate: str = "linear"
    vi_features: tuple[str, ...] = ("oc",)
    svi: SVIOptions = field(
        default=SVIOptions(n_steps=100),
        metadata=option_flags(("n_steps",)),
    )
    vi_inducing: int = 128
    gp: GPOptions = field(
        default=GPOptions(max_iter=50, lengthscale_prior=True),
        metadata=option_flags(("max_iter", "lengthscale_prior")),
    )
    pose_noise: bool = True

    SMOKE: ClassVar[Mapping[str, Any]] = SMOKE
    SHORTHANDS: ClassVar[Mapping[str, tuple[str, Any, str]]] = MappingProxyType(
        {
            "--exact-poses": (
                "pose_noise",
                False,
                "record exact poses (the same as --no-pose-noise)",
            ),
            "--no-ch4": ("ch4_pushes", 0, "skip chapter 4 (--ch4-pushes 0)"),
        }
    )

    def check(self) -> dict[str, Any]:
        """Raise `InputError` for unknown names or impossible sizes."""
        for name in self.ch5_features:
            if name not in CH5_FEATURES:
                raise InputError(f"unknown chapter 5 features {name!r}; use {list(CH5_FEATURES)}.")
        for name in self.ch4_features:
            if name not in CH4_FEATURES:
                raise InputError(f"unknown chapter 4 features {name!r}; use {list(CH4_FEATURES)}.")
        for m in self.methods:
            if m not in ("em", "vi"):
                raise InputError(f"unknown method {m!r}; use 'em' and/or 'vi'.")
        if "em" not in self.methods:
            raise InputError("methods must include 'em': VI starts from the EM mixtures.")
        for name in self.vi_features:
            if name not in self.ch5_features:
                raise InputError(
                    f"vi_features {name!r} is not among ch5_features {list(self.ch5_features)}."
                )
        if self.gate not in ("linear", "fourier"):
            raise InputError(f"unknown gate {self.gate!r}; use 'linear' or 'fourier'.")
        for name in ("vi_inducing", "ch5_pushes", "ch5_folds", "ch5_repeats", "ch4_folds"):
            check_count(name, getattr(self, name))
        check_count("ch4_pushes", self.ch4_pushes, minimum=0)
        if check_count("ch5_trials", self.ch5_trials, minimum=0) > MAX_TRIALS:
            raise InputError(f"ch5_trials must be at most {MAX_TRIALS}, got {self.ch5_trials}.")
        check_count("ch5_trial_test", self.ch5_trial_test)
        for size in (*self.ch5_experts, *self.ch4_experts):
            check_count("number of experts", size)
        for folds in (self.ch5_folds, self.ch4_folds):
            if folds < 2:
                raise InputError(f"cross-validation needs at least 2 folds, got {folds}.")
        if self.ch5_pushes < self.ch5_folds:
            raise InputError("ch5_pushes must be at least ch5_folds.")
        return {}


def effect_noise_floor(pose_noise: bool, n_objects: int) -> list[float] | str:
    """The experts' noise floor: `PoseNoise().effect_std`, or ``"auto"`` for exact poses.

    Args:
        pose_noise: Whether the dataset observes poses with `PoseNoise()`.
        n_objects: Objects whose effects are stacked in the effect vector.
    """
    return PoseNoise().effect_std(n_objects) if pose_noise else "auto"
