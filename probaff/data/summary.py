"""A JSON-ready summary of a push or skill dataset (what `probaff describe` prints)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from probaff.data.schema import PushDataset
from probaff.data.skill_schema import SkillDataset
from probaff.errors import InputError

__all__ = [
    "MOVED_THRESHOLD",
    "SKILL_OUTCOMES",
    "summarize",
    "summarize_pushes",
    "summarize_skills",
]

MOVED_THRESHOLD = 0.01  # an object "moved" when its centre travelled more than 1 cm
SKILL_OUTCOMES: dict[str, tuple[str, ...]] = {
    "pick": ("grasped", "lifted", "slipped"),
    "place": ("grasped", "slipped", "placed"),
}
"""The outcome flags of each skill that `summarize_skills` reports (the others are constant)."""


def summarize(ds: PushDataset | SkillDataset) -> dict[str, Any]:
    """The summary of a push dataset (`summarize_pushes`) or a skill dataset (`summarize_skills`).

    Args:
        ds: The dataset.

    Raises:
        InputError: If `ds` is neither a `PushDataset` nor a `SkillDataset`.
    """
    if isinstance(ds, SkillDataset):
        return summarize_skills(ds)
    if not isinstance(ds, PushDataset):
        raise InputError(
            f"ds must be a PushDataset or a SkillDataset (e.g. load_any_dataset(path)), got "
            f"{type(ds).__name__}."
        )
    return summarize_pushes(ds)


def summarize_pushes(ds: PushDataset) -> dict[str, Any]:
    """Counts and effect statistics per object slot (o1 is the pushed object).

    Every statistic describes what the simulator did: the mean absolute effect and the "moved"
    fractions use the exact effect (`PushDataset.true_effect`), never a noisy observation, and
    the fell-off and contact fractions come from the simulator's flags. A dataset with pose
    noise also reports, per slot, the standard deviation of its observation error
    ``effect - true_effect``.

    Args:
        ds: A push dataset.

    Returns:
        A JSON-serialisable dict: counts; ``pose_noise`` (``None``, or the measurement noise's
        ``position_std_m`` and ``yaw_std_rad``); per slot, the mean exact absolute effect
        (dy_p and dz_p in m, dtheta_p in rad), the fraction of pushes that moved it more than
        1 cm, the fraction in which it fell off the table, contact rates and, with pose noise,
        ``observed_effect_error_std`` (m, m, rad). The simulator's flags of an
        observation-only dataset that lacks them give ``None``; ``observation_only`` says
        whether it is one.
    """
    eff = ds.true_effect
    moved = np.hypot(eff[..., 0], eff[..., 1]) > MOVED_THRESHOLD
    names = Counter(n for i in range(len(ds)) for n in ds.objects_of(i))
    slots = {}
    for k in range(ds.n_objects):
        slots[f"o{k + 1}"] = {
            "mean_abs_effect": {
                "dy_p_m": float(np.abs(eff[:, k, 0]).mean()) if len(ds) else 0.0,
                "dz_p_m": float(np.abs(eff[:, k, 1]).mean()) if len(ds) else 0.0,
                "dtheta_p_rad": float(np.abs(eff[:, k, 2]).mean()) if len(ds) else 0.0,
            },
            "fraction_moved_gt_1cm": float(moved[:, k].mean()) if len(ds) else 0.0,
            "fraction_fell_off": _flag_rate(ds, "fell_off", k),
            "fraction_hand_contact": _flag_rate(ds, "hand_contact", k),
        }
        if ds.has_pose_noise:
            err = ds["effect"][:, k] - eff[:, k]
            std = err.std(axis=0) if len(ds) else np.zeros(3)
            slots[f"o{k + 1}"]["observed_effect_error_std"] = {
                "dy_p_m": float(std[0]),
                "dz_p_m": float(std[1]),
                "dtheta_p_rad": float(std[2]),
            }
    noise = ds.meta.get("pose_noise")
    return {
        "scene": ds.meta.get("scene"),
        "seed": ds.meta.get("seed"),
        "n_pushes": len(ds),
        "n_objects_per_scene": ds.n_objects,
        "object_counts": dict(sorted(names.items())),
        "push_distance_m": sorted({float(d) for d in np.unique(ds["push_distance"])}),
        "has_trajectories": ds.has_trajectories,
        "pose_noise": None
        if noise is None
        else {"position_std_m": noise["position_std"], "yaw_std_rad": noise["yaw_std"]},
        "fraction_objects_touching": None
        if "object_contact" not in ds.arrays
        else float(ds["object_contact"].any(axis=(1, 2)).mean())
        if len(ds)
        else 0.0,
        "observation_only": ds.observation_only,
        "objects": slots,
    }


def _flag_rate(ds: PushDataset, name: str, k: int) -> float | None:
    """The fraction of pushes with flag `name` set for slot `k`; ``None`` when not stored."""
    if name not in ds.arrays:
        return None
    return float(ds[name][:, k].mean()) if len(ds) else 0.0


def _mean(x: np.ndarray) -> float:
    """Mean of `x`, 0 when it is empty."""
    return float(np.mean(x)) if np.size(x) else 0.0


def _effect(e: np.ndarray) -> dict[str, float]:
    """Column means of `e` (M, 3), side-view (dx, dz, dphi), 0 when it has no rows."""
    return {
        "dx_m": _mean(e[:, 0]),
        "dz_m": _mean(e[:, 1]),
        "dphi_rad": _mean(e[:, 2]),
    }


def summarize_skills(ds: SkillDataset) -> dict[str, Any]:
    """Counts, outcome rates and effect statistics of a side-view pick or place dataset.

    The effect of an object is ``state_after - state_before``, world (dx, dz, dphi) in the
    side-view plane. Per object slot, statistics cover the rows where the slot holds an
    object (the others are padding).

    Args:
        ds: A skill dataset.

    Returns:
        A JSON-serialisable dict: ``scene``, ``skill``, ``seed``, ``n_samples``,
        ``n_object_slots``; ``object_counts`` (objects present over all rows) and
        ``target_counts`` (the picked or held object); ``has_trajectories``,
        ``record_rate_hz`` and ``n_trajectory_samples``; ``outcomes``, the fraction of rows
        with each flag of `SKILL_OUTCOMES` for the skill (all four for an unknown one;
        ``None`` for a flag an observation-only dataset does not store);
        ``target`` (the acted-on object: its ``mean_effect``, signed, and
        ``mean_abs_effect``); ``fraction_on_table_support`` (place: the target is the
        table; ``None`` for a pick); ``release_height_m`` (place: mean, min and max;
        ``None`` for a pick or when not stored); ``observation_only``; and per slot
        (``o1`` ...) ``fraction_present``, ``mean_abs_effect`` and ``fraction_moved_gt_1cm``
        (the centre moved more than 1 cm).
    """
    n = len(ds)
    eff = ds["state_after"] - ds["state_before"]
    present = ds.present
    moved = np.hypot(eff[..., 0], eff[..., 1]) > MOVED_THRESHOLD
    rows = np.arange(n)
    target = ds["target"].astype(int)
    ids = ds["object_ids"]
    names = Counter(name for i in range(n) for name in ds.objects_of(i))
    targets = Counter(ds.object_names[int(ids[i, target[i]])] for i in range(n))
    slots = {}
    for k in range(ds.n_objects):
        on = present[:, k]
        slots[f"o{k + 1}"] = {
            "fraction_present": _mean(on),
            "mean_abs_effect": _effect(np.abs(eff[on, k])),
            "fraction_moved_gt_1cm": _mean(moved[on, k]),
        }
    skill = ds.skill
    flags = SKILL_OUTCOMES.get(skill, ("grasped", "lifted", "slipped", "placed"))
    target_eff = eff[rows, target].reshape(n, 3)
    release = ds.arrays.get("release_height")
    return {
        "scene": ds.meta.get("scene"),
        "skill": skill or None,
        "seed": ds.meta.get("seed"),
        "n_samples": n,
        "n_object_slots": ds.n_objects,
        "object_counts": dict(sorted(names.items())),
        "target_counts": dict(sorted(targets.items())),
        "has_trajectories": ds.has_trajectories,
        "record_rate_hz": ds.meta.get("record_rate"),
        "n_trajectory_samples": ds.n_samples,
        "outcomes": {
            f"fraction_{flag}": _mean(ds[flag]) if flag in ds.arrays else None for flag in flags
        },
        "observation_only": ds.observation_only,
        "target": {
            "mean_effect": _effect(target_eff),
            "mean_abs_effect": _effect(np.abs(target_eff)),
        },
        "fraction_on_table_support": _mean(ds["support"] < 0) if skill == "place" else None,
        "release_height_m": {
            "mean": _mean(release),
            "min": float(release.min()) if n else 0.0,
            "max": float(release.max()) if n else 0.0,
        }
        if skill == "place" and release is not None
        else None,
        "objects": slots,
    }
