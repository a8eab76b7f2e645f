"""A JSON-ready summary of a push dataset (what `probaff describe` prints)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from probaff.data.schema import PushDataset

__all__ = ["MOVED_THRESHOLD", "summarize"]

MOVED_THRESHOLD = 0.01  # an object "moved" when its centre travelled more than 1 cm


def summarize(ds: PushDataset) -> dict[str, Any]:
    """Counts and effect statistics per object slot (o1 is the pushed object).

    Every statistic describes what the simulator did: the mean |effect| and the "moved"
    fractions use the exact effect (`PushDataset.true_effect`), never a noisy observation, and
    the fell-off and contact fractions come from the simulator's flags. A dataset with pose
    noise also reports, per slot, the standard deviation of its observation error
    ``effect - true_effect``.

    Args:
        ds: A push dataset.

    Returns:
        A JSON-serialisable dict: counts; ``pose_noise`` (``None``, or the measurement noise's
        ``position_std_m`` and ``yaw_std_rad``); per slot, the mean exact |effect| (dy_p and
        dz_p in m, dtheta_p in rad), the fraction of pushes that moved it more than 1 cm, the
        fraction in which it fell off the table, contact rates and, with pose noise,
        ``observed_effect_error_std`` (m, m, rad).
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
            "fraction_fell_off": float(ds["fell_off"][:, k].mean()) if len(ds) else 0.0,
            "fraction_hand_contact": float(ds["hand_contact"][:, k].mean()) if len(ds) else 0.0,
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
        "fraction_objects_touching": float(ds["object_contact"].any(axis=(1, 2)).mean())
        if len(ds)
        else 0.0,
        "objects": slots,
    }
