"""A fitted push model together with the features it was fitted on, for planners.

A planner knows world states and candidate pushes; a push model knows feature matrices. A
`FeaturePushModel` joins them: it computes the named feature set of `PushQueries`, selects the
column groups the model was fitted on, checks them against the model (the groups' names,
order and widths where the model records its feature groups, the number of columns
otherwise), and returns the model's predictive distribution of every candidate in one batched
call. `apply_effects` turns predicted pushing-frame effects back into world poses.

Covered by tests/planning/test_planning_learned.py.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch.distributions import Distribution

from probaff._checks import (
    as_float_array,
    as_float_vectors,
    check_count,
    check_finite,
    check_positive,
)
from probaff.data.queries import PushInputs
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features.ch4 import chapter4_features
from probaff.features.ch5 import chapter5_features
from probaff.features.featureset import FeatureSet
from probaff.models.columns import resolve_groups
from probaff.models.interface import PushModel

__all__ = ["FEATURE_FUNCTIONS", "FeaturePushModel", "apply_effects"]

FEATURE_FUNCTIONS: dict[str, Callable[[PushInputs], FeatureSet]] = {
    "ch4": chapter4_features,
    "ch5": chapter5_features,
}
"""Feature sets a planner can compute, by name."""

_FEATURE_GROUPS: dict[str, tuple[str, ...]] = {
    "ch4": ("f_o", "f_c", "f_x"),
    "ch5": ("f_o", "f_c", "f_x"),
}
"""The column groups of each feature set of `FEATURE_FUNCTIONS`, in column order."""


def _fitted_groups(model: Any, known: tuple[str, ...]) -> list[str]:
    """The feature groups `model` was fitted on, in column order; empty when unrecorded.

    A model records them as ``groups`` (name -> its columns); groups of other names than
    the feature set's `known` ones are the model's own and say nothing of the features.
    """
    groups = getattr(model, "groups", None)
    if not isinstance(groups, dict) or not groups or not set(groups) <= set(known):
        return []

    def first(cols: Any) -> int:
        if isinstance(cols, slice):
            return int(cols.start or 0)
        cols = list(cols)
        return int(min(cols)) if cols else 0

    return sorted(groups, key=lambda g: first(groups[g]))


def _fitted_widths(model: Any, known: tuple[str, ...]) -> dict[str, int]:
    """Columns per recorded feature group of a fitted `model`; empty when it does not say."""
    n = getattr(model, "n_features", None)
    if not _fitted_groups(model, known) or n is None:
        return {}
    return {name: len(cols) for name, cols in resolve_groups(model.groups, int(n)).items()}


@dataclass(frozen=True)
class FeaturePushModel:
    """A fitted `PushModel` and the features it reads.

    Attributes:
        model: The fitted model; it was fitted on ``FEATURE_FUNCTIONS[features](ds)
            .select(*groups)``.
        features: ``"ch4"`` or ``"ch5"``.
        groups: The column groups fitted on, in order, e.g. ``("f_o", "f_c")``.
        cloud_points: Points per object cloud of the training dataset; a planner senses its
            candidates' clouds with as many.
        cloud_noise: Cloud noise (m) of the training dataset.
    """

    model: PushModel
    features: str
    groups: tuple[str, ...]
    cloud_points: int = 256
    cloud_noise: float = 0.002

    def __post_init__(self) -> None:
        if not isinstance(self.model, PushModel):
            raise InputError(
                f"model must be a fitted probaff push model (PushModel), got "
                f"{type(self.model).__name__}."
            )
        if self.features not in FEATURE_FUNCTIONS:
            raise InputError(
                f"unknown feature set {self.features!r}; choose one of {sorted(FEATURE_FUNCTIONS)}."
            )
        groups = (self.groups,) if isinstance(self.groups, str) else tuple(self.groups)
        if not groups:
            raise InputError("groups must name at least one feature group, e.g. ('f_o', 'f_c').")
        known = _FEATURE_GROUPS[self.features]
        unknown = [g for g in groups if g not in known]
        if unknown or len(set(groups)) != len(groups):
            raise InputError(
                f"groups {list(groups)} must name distinct feature groups of {self.features}; "
                f"choose from {list(known)}."
            )
        fitted = _fitted_groups(self.model, known)
        if fitted and fitted != list(groups):
            raise InputError(
                f"the push model was fitted on feature groups {fitted}, but the planner would "
                f"give it {list(groups)} ({self.features}); give the groups the model was fitted "
                f"on, in that order (FeaturePushModel(groups={tuple(fitted)})), or refit it on "
                "FEATURE_FUNCTIONS[features](ds).select(*groups)."
            )
        object.__setattr__(self, "groups", groups)
        object.__setattr__(self, "cloud_points", check_count("cloud_points", self.cloud_points))
        check_positive("cloud_noise", self.cloud_noise, allow_zero=True)

    @classmethod
    def for_dataset(
        cls, model: PushModel, features: str, groups: tuple[str, ...], ds: PushDataset
    ) -> FeaturePushModel:
        """`model`, fitted on `ds`, sensing candidate clouds as `ds` was sensed.

        Args:
            model: The fitted model.
            features: ``"ch4"`` or ``"ch5"``.
            groups: The column groups fitted on, in order.
            ds: The training dataset: its clouds give the points per cloud, its metadata
                the cloud noise (0.002 m, the generator's default, when it is not recorded).
        """
        return cls(
            model,
            features,
            tuple(groups),
            cloud_points=int(ds["cloud_points"].shape[2]),
            cloud_noise=float(ds.meta.get("cloud_noise", 0.002)),
        )

    def feature_matrix(self, queries: PushInputs) -> np.ndarray:
        """The model's input matrix for `queries`.

        Args:
            queries: C candidate pushes (or a dataset's pushes).

        Returns:
            (C, D) the selected feature columns.

        Raises:
            InputError: If the model was fitted on other columns than the planner computes
                (another feature set, other groups or their widths), or a group is unknown.
        """
        fs = FEATURE_FUNCTIONS[self.features](queries)
        X = fs.select(*self.groups)
        want = _fitted_widths(self.model, _FEATURE_GROUPS[self.features])
        have = {g: fs.groups[g].stop - fs.groups[g].start for g in self.groups}
        if want and want != have:
            raise InputError(
                f"the push model was fitted on feature groups of widths {want}, but the planner "
                f"computes {have} ({self.features}); give the feature set the model was fitted "
                "on (FeaturePushModel(features=...)), or refit it on "
                "FEATURE_FUNCTIONS[features](ds).select(*groups)."
            )
        fitted = getattr(self.model, "n_features", None)
        if fitted is not None and int(fitted) != X.shape[1]:
            raise InputError(
                f"the push model was fitted on {fitted} feature columns, but the planner "
                f"computes {X.shape[1]} ({self.features} groups {list(self.groups)}); give the "
                "feature set and groups the model was fitted on (FeaturePushModel(features=..., "
                "groups=...)), or refit it on FEATURE_FUNCTIONS[features](ds).select(*groups)."
            )
        return X

    def predict(self, queries: PushInputs) -> Distribution:
        """Predictive distribution of the effects of every candidate, in one call.

        Args:
            queries: C candidate pushes.

        Returns:
            Batch shape (C,), event shape (E,): the model's prediction of the pushing-frame
            effects ``(dy_p, dz_p, dtheta_p)`` per object.

        Raises:
            InputError: If the model was fitted on other features, or its predictive mean
                is NaN or infinite.
        """
        dist = self.model.predict(torch.as_tensor(self.feature_matrix(queries)))
        mean = dist.mean.detach()
        if not bool(torch.isfinite(mean).all()):
            bad = int((~torch.isfinite(mean)).sum())
            raise InputError(
                f"the push model {type(self.model).__name__} predicted {bad} NaN or infinite "
                f"effect(s) for {mean.shape[0]} push(es): its predictions are not finite; refit "
                "the model or check its inputs (features, training data)."
            )
        return dist


def apply_effects(poses: np.ndarray, effects: np.ndarray, push_yaw: np.ndarray) -> np.ndarray:
    """World poses after pushing-frame effects: the inverse of `push_frame_effect`.

    Args:
        poses: (..., K, 3) world ``(x, y, theta)`` before.
        effects: (..., K, 3) ``(dy_p, dz_p, dtheta_p)`` in each push's frame, broadcastable
            against `poses`.
        push_yaw: (...,) world yaw of each push's z_p (rad).

    Returns:
        (..., K, 3) world ``(x, y, theta)`` after.

    Raises:
        InputError: For anything but finite numbers, or a last axis that is not 3.
    """
    poses = as_float_vectors("poses", poses, 3, "world (x, y, theta) poses")
    effects = as_float_vectors("effects", effects, 3, "push-frame (dy_p, dz_p, dtheta_p) effects")
    yaw = as_float_array("push_yaw", push_yaw)
    check_finite("push_yaw", yaw)
    yaw = yaw[..., None]
    c, s = np.cos(yaw), np.sin(yaw)
    dy, dz, dth = effects[..., 0], effects[..., 1], effects[..., 2]
    out = np.empty(np.broadcast_shapes(poses.shape, effects.shape))
    out[..., 0] = poses[..., 0] + dz * c - dy * s
    out[..., 1] = poses[..., 1] + dz * s + dy * c
    out[..., 2] = poses[..., 2] + dth
    return out
