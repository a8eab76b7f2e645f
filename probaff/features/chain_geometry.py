"""The chapter 6 geometry of chained predictions: box surfaces, features and effects.

`Ch6Geometry` is the feature layer's side of
`probaff.models.transitions.modular.InteractionGeometry`: `ModularTransitionModel` takes it
by injection, so the models never import the feature layer. Its features are the chapter 6
interaction features (`interaction_features`, 169 columns, or a chosen subset of them),
followed by two columns of the commanded motion that the 169 do not hold:

* ``action_length``: the length of the actor's commanded displacement (m);
* ``travel``: how far the actor moves on after it first touches the target,
  ``max(0, action_length - touch_distance)`` (m), 0 where it never touches.

Together they decide how far a pushed object can be carried when pushes differ in length,
as they do along a chain (each object's motion is the next one's action). Surfaces are
`box_surface` grids and effects are applied by `apply_effect`.

Surface spacing. A point moving onto a face grid of spacing h passes within ``h / sqrt(2)``
(the largest hole of a square grid) of some grid point across its motion, so a spacing below
``sqrt(2) r_d`` never misses a touch. The default, ``1.25 r_d`` (12.5 mm for r_d = 1 cm),
keeps that margin with about half the points of a 1 cm grid; the pair search of
`interaction_features`, the bulk of a chain's time, shrinks accordingly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.features.action_frame import apply_effect, box_surface
from probaff.features.ch6 import (
    INTERACTION_FEATURE_COUNT,
    InteractionFeatureConfig,
    interaction_features,
)

if TYPE_CHECKING:
    from probaff.models.transitions.modular import InteractionGeometry

__all__ = ["MOTION_COLUMNS", "Ch6Geometry", "InteractionRows", "resolve_geometry"]

_SPACING_PER_CONTACT = 1.25  # default surface spacing in units of r_d (below sqrt(2))

MOTION_COLUMNS: tuple[str, ...] = ("action_length", "travel")
"""Names of the columns `Ch6Geometry` appends to the interaction features, in order."""


@dataclass(frozen=True)
class InteractionRows:
    """What every skill's interaction rows hold: one row per actor motion towards a target.

    The push, pick and place rows (`probaff.features.ch6_push.PushInteractions`, ...) add
    their own columns after these.

    Attributes:
        features: (N, D) the geometry's features of the N rows.
        touches: (N,) whether the actor touches the target during its action.
        T_world_action: (N, 4, 4) the action frames A_t.
        effect: (N, 6) the target's observed displacement in its action frame.
        reaction: (N, 2) the actor's end-point deviation from its command in the action
            frame (m).
    """

    features: np.ndarray
    touches: np.ndarray
    T_world_action: np.ndarray
    effect: np.ndarray
    reaction: np.ndarray

    def __len__(self) -> int:
        return int(self.features.shape[0])


def _check_columns(columns: Any) -> tuple[int, ...]:
    """Distinct interaction feature columns in ``0 .. 168``; ``None`` means all of them."""
    if columns is None:
        return tuple(range(INTERACTION_FEATURE_COUNT))
    if isinstance(columns, (str, bytes)) or not isinstance(columns, Sequence | np.ndarray):
        raise InputError(f"columns must be a sequence of feature indices, got {columns!r}.")
    idx = tuple(check_count("columns", c, minimum=0) for c in columns)
    if max(idx, default=0) >= INTERACTION_FEATURE_COUNT:
        raise InputError(
            f"columns must be indices in 0 .. {INTERACTION_FEATURE_COUNT - 1} of the "
            f"interaction features, got {list(idx)}."
        )
    if len(set(idx)) != len(idx):
        raise InputError(f"columns lists a feature more than once: {list(idx)}.")
    return idx


class Ch6Geometry:
    """Chapter 6 surfaces, features and effects for `ModularTransitionModel`.

    Args:
        config: Contact thresholds of `interaction_features`.
        columns: Interaction feature columns to keep, in this order (``None``: all 169);
            an empty selection keeps only the motion columns.
        motion: Append the `MOTION_COLUMNS` (``action_length``, ``travel``).
        spacing: Largest distance between neighbouring box surface points (m), > 0;
            ``None`` (default) is 1.25 times the contact distance r_d (see the module
            docstring; above ``sqrt(2) r_d`` touches can be missed).
        chunk: Samples of `interaction_features` computed at once, a positive integer
            (results do not depend on it; small chunks keep the pair search in cache).

    Attributes:
        n_features: Columns `D` of `features`.

    Raises:
        InputError: For a config of another type, malformed columns, no columns at all
            (empty `columns` with ``motion=False``), a spacing that is not positive or a
            non-integer chunk.
    """

    def __init__(
        self,
        config: InteractionFeatureConfig | None = None,
        *,
        columns: Sequence[int] | None = None,
        motion: bool = True,
        spacing: float | None = None,
        chunk: int = 64,
    ) -> None:
        config = InteractionFeatureConfig() if config is None else config
        if not isinstance(config, InteractionFeatureConfig):
            raise InputError(
                f"config must be an InteractionFeatureConfig, got {type(config).__name__}."
            )
        self.config = config
        self.columns = _check_columns(columns)
        self.motion = bool(motion)
        if not self.columns and not self.motion:
            raise InputError("columns is empty and motion=False: the features would be empty.")
        if spacing is None:
            spacing = _SPACING_PER_CONTACT * config.contact_distance
        check_positive("spacing", spacing)
        self.spacing = float(spacing)
        self.chunk = check_count("chunk", chunk)

    @property
    def n_features(self) -> int:
        """Columns `D` of `features`."""
        return len(self.columns) + (len(MOTION_COLUMNS) if self.motion else 0)

    def surface(self, size: np.ndarray, T_world_box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """See `probaff.models.transitions.modular.InteractionGeometry.surface`.

        The points are `box_surface` grids at this geometry's `spacing`.
        """
        return box_surface(size, T_world_box, self.spacing)

    def features(
        self,
        target_points: np.ndarray,
        target_normals: np.ndarray,
        actor_points: np.ndarray,
        actor_normals: np.ndarray,
        T_world_actor_start: np.ndarray,
        T_world_actor_end: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """See `probaff.models.transitions.modular.InteractionGeometry.features`.

        The features `X` (N, D) are the chosen `columns` of `interaction_features`, then
        ``action_length`` and ``travel`` (`MOTION_COLUMNS`) when `motion` is set; the action
        frames are A_t.

        Raises:
            InputError: As `interaction_features`, e.g. for a zero-length action.
        """
        f = interaction_features(
            target_points,
            target_normals,
            actor_points,
            actor_normals,
            T_world_actor_start,
            T_world_actor_end,
            self.config,
            chunk=self.chunk,
        )
        parts = [f.features.values[:, list(self.columns)]]
        if self.motion:
            touches = f.touches
            travel = np.zeros_like(f.action_length)
            travel[touches] = np.maximum(f.action_length[touches] - f.touch_distance[touches], 0.0)
            parts.append(np.stack([f.action_length, travel], axis=1))
        return np.concatenate(parts, axis=1), f.touches, f.T_world_action

    def apply_effect(
        self, T_world_action: np.ndarray, T_world_before: np.ndarray, effect: np.ndarray
    ) -> np.ndarray:
        """See `probaff.models.transitions.modular.InteractionGeometry.apply_effect`.

        The effect is applied by `probaff.features.action_frame.apply_effect`.
        """
        return apply_effect(T_world_action, T_world_before, effect)


def resolve_geometry(geometry: Any) -> Ch6Geometry:
    """`geometry`, or ``Ch6Geometry()`` for ``None``, for the builders of training rows.

    Raises:
        InputError: If `geometry` is neither ``None`` nor a `Ch6Geometry`.
    """
    if geometry is None:
        return Ch6Geometry()
    if not isinstance(geometry, Ch6Geometry):
        raise InputError(f"geometry must be a Ch6Geometry, got {type(geometry).__name__}.")
    return geometry


if TYPE_CHECKING:  # the type checker confirms that Ch6Geometry satisfies the protocol
    _CONFORMS: InteractionGeometry = Ch6Geometry()
