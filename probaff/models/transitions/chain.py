"""The scene a chain of objects is predicted on, and the sampled outcome of the chain.

`ChainScene` holds K boxes and one commanded hand motion, validated once (rigid poses, unit
normals, no overlapping boxes, a known skill and chain order); `ChainPrediction` holds the S
sampled final poses of a chain and their planar summaries. `ModularTransitionModel`
(`probaff.models.transitions.modular`) predicts one from the other.

Frames: poses are world-from-object transforms ``T_world_obj`` of the box centres; the
hand's points are given in the hand frame and placed by its commanded poses. Planar
summaries are tabletop poses ``(x, y, yaw)`` with yaw the turn about world up.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch.distributions import MultivariateNormal

from probaff._checks import (
    as_float_array,
    check_box_sizes,
    check_count,
    check_finite,
    check_rows,
    check_shape,
)
from probaff.errors import InputError
from probaff.models.transitions.transition_base import SKILLS

__all__ = ["MIN_ACTION_LENGTH", "ChainPrediction", "ChainScene", "planar_poses", "wrap_angle"]

MIN_ACTION_LENGTH = 1e-3
"""Actions shorter than this (m) move nothing; they never reach the feature code."""

_RIGID_TOL = 1e-6  # tolerance of the orthonormality and bottom-row checks
_NORMAL_TOL = 1e-4  # allowed deviation of a normal's length from 1
_OVERLAP_TOL = 1e-6  # m; boxes may interpenetrate this much (faces in contact)
_AXIS_TOL = 1e-9  # cross products of near-parallel edges shorter than this are no axis
_COV_JITTER = 1e-10  # added to the diagonal of the moment-matched covariance


# ------------------------------------------------------------------ checks
def _rigid(name: str, T: Any, shape: tuple[int | None, ...]) -> np.ndarray:
    """Validate rigid transforms of `shape` (ending in ``(4, 4)``); return them as float64."""
    arr = as_float_array(name, T, copy=True)
    check_shape(name, arr, shape)
    check_finite(name, arr)
    flat = arr.reshape(-1, 4, 4)
    R = flat[:, :3, :3]
    bottom = np.abs(flat[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    ortho = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((bottom > _RIGID_TOL) | (ortho > _RIGID_TOL) | (np.linalg.det(R) <= 0))
    if bad.size:
        raise InputError(
            f"{name} is not a rigid transform at index {bad[:5].tolist()}: the last row must "
            "be (0, 0, 0, 1) and the 3 x 3 block a rotation (orthonormal, det +1)."
        )
    return arr


def _points(name: str, x: Any) -> np.ndarray:
    """Validate a non-empty, finite (Q, 3) point set; return it as float64."""
    empty = f"{name} holds no points; give at least one (1, 3) point."
    return check_rows(name, x, 3, empty, copy=True)


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _check_order(order: Any, n_objects: int) -> tuple[int, ...]:
    """The chain order as distinct object indices; ``()`` means ``0 .. K-1``."""
    if isinstance(order, (str, bytes)) or not isinstance(order, Sequence | np.ndarray):
        raise InputError(f"order must be a sequence of object indices, got {order!r}.")
    if len(order) == 0:
        return tuple(range(n_objects))
    idx = tuple(check_count("order", i, minimum=0) for i in order)
    out = [i for i in idx if i >= n_objects]
    if out:
        raise InputError(
            f"order names object(s) {out}, but the scene has {n_objects} objects "
            f"(indices 0 .. {n_objects - 1})."
        )
    if len(set(idx)) != len(idx):
        raise InputError(f"order lists an object more than once: {list(idx)}; each acts once.")
    return idx


def _overlapping_pairs(sizes: np.ndarray, T_world_obj: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of boxes that interpenetrate by more than `_OVERLAP_TOL`, by separating axes.

    Two boxes are disjoint when some axis separates their projections; for boxes, testing
    the 3 face normals of each and the 9 cross products of their edge directions decides it.
    Along an axis ``a`` (unit), a box of half extents ``h`` and rotation ``R`` projects to a
    half width ``sum_m h_m |R[:, m] . a|`` about its centre.

    Args:
        sizes: (K, 3) box extents (m).
        T_world_obj: (K, 4, 4) box centre poses.

    Returns:
        The overlapping pairs ``(i, j)``, ``i < j``.
    """
    i, j = np.triu_indices(sizes.shape[0], k=1)
    if i.size == 0:
        return []
    R = T_world_obj[:, :3, :3]
    Ri, Rj = R[i].transpose(0, 2, 1), R[j].transpose(0, 2, 1)  # (M, 3 edges, 3)
    cross = np.cross(Ri[:, :, None, :], Rj[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([Ri, Rj, cross], axis=1)  # (M, 15, 3)
    norm = np.linalg.norm(axes, axis=2)
    valid = norm > _AXIS_TOL
    axes = axes / np.where(valid, norm, 1.0)[..., None]
    half_i = np.abs(np.einsum("mae,mke->mak", axes, Ri)) @ (0.5 * sizes[i])[..., None]
    half_j = np.abs(np.einsum("mae,mke->mak", axes, Rj)) @ (0.5 * sizes[j])[..., None]
    offset = T_world_obj[j, :3, 3] - T_world_obj[i, :3, 3]
    dist = np.abs(np.einsum("mae,me->ma", axes, offset))
    separated = valid & (dist >= half_i[..., 0] + half_j[..., 0] - _OVERLAP_TOL)
    hit = ~separated.any(axis=1)
    return [(int(a), int(b)) for a, b in zip(i[hit], j[hit], strict=True)]


# ------------------------------------------------------------------- scene
@dataclass(frozen=True, eq=False)
class ChainScene:
    """A scene of K boxes and one commanded hand motion, validated once.

    Objects must not overlap at the start: two boxes overlap when no separating axis exists
    between them (of the 3 face normals of each and the 9 cross products of their edges),
    allowing 1 um of interpenetration so that boxes whose faces touch are accepted. For
    upright boxes on a table this is the separating-axis test of their footprints in the
    plane, combined with their vertical extents.

    Attributes:
        sizes: (K, 3) box extents along each box's own x, y, z (m), > 0.
        T_world_obj: (K, 4, 4) start poses of the box centres in the world.
        hand_points: (Q, 3) the hand's surface points in the hand frame (m).
        hand_normals: (Q, 3) their outward unit normals in the hand frame.
        T_world_hand_start: (4, 4) the hand's commanded start pose.
        T_world_hand_end: (4, 4) its commanded end pose, at least 1 mm from the start in
            position.
        skill: The skill of the hand's interaction with the first object (one of `SKILLS`).
        order: The chain: the object indices in the order they act on each other, each at
            most once; the hand acts on ``order[0]``, ``order[k]`` on ``order[k + 1]``.
            Objects not listed stay where they are. ``()`` (default) is ``0 .. K-1``.

    Raises:
        InputError: For malformed, empty or non-finite arrays, sizes that are not positive,
            transforms that are not rigid, normals that are not unit length, a hand motion
            shorter than 1 mm, an unknown skill, a malformed order, or overlapping objects;
            each message names the argument.
    """

    sizes: np.ndarray
    T_world_obj: np.ndarray
    hand_points: np.ndarray
    hand_normals: np.ndarray
    T_world_hand_start: np.ndarray
    T_world_hand_end: np.ndarray
    skill: str = "push"
    order: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        sizes = check_box_sizes(
            "sizes",
            self.sizes,
            "sizes holds no objects; give at least one (1, 3) box size.",
            copy=True,
        )
        k = sizes.shape[0]
        T_obj = _rigid("T_world_obj", self.T_world_obj, (k, 4, 4))
        points = _points("hand_points", self.hand_points)
        normals = _points("hand_normals", self.hand_normals)
        check_shape("hand_normals", normals, points.shape)
        length = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(length - 1.0) > _NORMAL_TOL):
            raise InputError(
                f"hand_normals must be unit vectors; lengths range over [{length.min():.4g}, "
                f"{length.max():.4g}]. Divide each normal by its length first."
            )
        T_start = _rigid("T_world_hand_start", self.T_world_hand_start, (4, 4))
        T_end = _rigid("T_world_hand_end", self.T_world_hand_end, (4, 4))
        move = float(np.linalg.norm(T_end[:3, 3] - T_start[:3, 3]))
        if move < MIN_ACTION_LENGTH:
            raise InputError(
                f"T_world_hand_end is {move:.3g} m from T_world_hand_start; the hand must move "
                f"at least {MIN_ACTION_LENGTH} m for the chain to have an action."
            )
        if not isinstance(self.skill, str) or self.skill not in SKILLS:
            known = ", ".join(repr(s) for s in SKILLS)
            raise InputError(f"unknown skill {self.skill!r}; known skills: {known}.")
        order = _check_order(self.order, k)
        overlap = _overlapping_pairs(sizes, T_obj)
        if overlap:
            raise InputError(
                f"objects {overlap[:5]} overlap at the start (sizes and T_world_obj); move "
                "them apart so that every pair is separated or at most touching."
            )
        for name, value in (
            ("sizes", sizes),
            ("T_world_obj", T_obj),
            ("hand_points", points),
            ("hand_normals", normals),
            ("T_world_hand_start", T_start),
            ("T_world_hand_end", T_end),
        ):
            object.__setattr__(self, name, _frozen(value))
        object.__setattr__(self, "order", order)

    @property
    def n_objects(self) -> int:
        """Number of objects K."""
        return int(self.sizes.shape[0])

    def hand_in_world(self) -> tuple[np.ndarray, np.ndarray]:
        """The hand's points and normals at its start pose, each (Q, 3) in the world."""
        R, t = self.T_world_hand_start[:3, :3], self.T_world_hand_start[:3, 3]
        return self.hand_points @ R.T + t, self.hand_normals @ R.T


# -------------------------------------------------------------- prediction
def planar_poses(T: np.ndarray) -> np.ndarray:
    """(..., 3) tabletop summaries ``(x, y, yaw)`` of (..., 4, 4) poses; yaw about world up."""
    return np.stack([T[..., 0, 3], T[..., 1, 3], np.arctan2(T[..., 1, 0], T[..., 0, 0])], -1)


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to ``[-pi, pi)``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True, eq=False)
class ChainPrediction:
    """Sampled outcome of a chain: S samples of the final poses of K objects.

    Attributes:
        samples: (S, K, 4, 4) final world poses of every object in every sample.
        planar: (S, K, 3) their tabletop summaries ``(x, y, yaw)`` (m, rad); yaw is the start
            yaw plus the object's turn wrapped to ``[-pi, pi)``, so it varies continuously
            about the start.
        start_planar: (K, 3) the summaries of the start poses.
        touched: (S, K) whether each object was touched (and so moved by its model's draw).
        order: The chain order the scene used.
    """

    samples: np.ndarray
    planar: np.ndarray
    start_planar: np.ndarray
    touched: np.ndarray
    order: tuple[int, ...]

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return int(self.samples.shape[0])

    @property
    def displacement(self) -> np.ndarray:
        """(S, K, 3) planar displacement ``(dx, dy, dyaw)`` of every object (world axes)."""
        return self.planar - self.start_planar

    @property
    def mean_displacement(self) -> np.ndarray:
        """(K, 3) mean planar displacement of each object over the samples."""
        return self.displacement.mean(axis=0)

    @property
    def std_displacement(self) -> np.ndarray:
        """(K, 3) standard deviation (over the S samples, ddof 0) of the displacements."""
        return self.displacement.std(axis=0)

    def interval(
        self, level: float = 0.9, *, of: str = "displacement"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Central sample interval of every object and coordinate.

        Args:
            level: Probability in (0, 1) the interval holds; its ends are the sample
                quantiles ``(1 - level) / 2`` and ``(1 + level) / 2`` (linear interpolation).
            of: ``"displacement"`` (default) or ``"pose"`` (the final planar poses).

        Returns:
            ``(lo, hi)``, each (K, 3).

        Raises:
            InputError: For a level outside (0, 1) or an unknown `of`.
        """
        try:
            p = float(level)
        except (TypeError, ValueError):
            raise InputError(f"level must be a number in (0, 1), got {level!r}.") from None
        if not 0.0 < p < 1.0:
            raise InputError(f"level must lie in (0, 1), got {level!r}.")
        if of == "displacement":
            values = self.displacement
        elif of == "pose":
            values = self.planar
        else:
            raise InputError(f"of must be 'displacement' or 'pose', got {of!r}.")
        lo, hi = np.quantile(values, [(1.0 - p) / 2.0, (1.0 + p) / 2.0], axis=0)
        return lo, hi

    def final_distribution(self) -> MultivariateNormal:
        """A normal over the (K * 3) final planar poses, moment-matched to the samples.

        The mean is the sample mean of `planar` flattened object after object (object k's
        ``(x, y, yaw)`` at columns ``3k .. 3k + 2``), the covariance the unbiased sample
        covariance plus 1e-10 on the diagonal (objects that never move have none of their
        own). A moment match keeps only two moments: a chain's samples are often
        multi-modal (touched in some samples, not in others).

        Returns:
            A `MultivariateNormal` with event shape `(K * 3,)`, float64.

        Raises:
            InputError: With fewer than 2 samples (no covariance).
        """
        if self.n_samples < 2:
            raise InputError(
                f"a covariance needs n_samples >= 2, but the prediction has {self.n_samples}."
            )
        flat = torch.as_tensor(self.planar.reshape(self.n_samples, -1))
        mean = flat.mean(dim=0)
        centred = flat - mean
        cov = centred.T @ centred / (self.n_samples - 1)
        cov = cov + _COV_JITTER * torch.eye(flat.shape[1], dtype=flat.dtype)
        return MultivariateNormal(mean, covariance_matrix=cov)
