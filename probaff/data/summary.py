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

    Args:
        ds: A push dataset.

    Returns:
        A JSON-serialisable dict: counts, per-slot mean |effect| (dy_p and dz_p in m, dtheta_p
        in rad), the fraction of pushes that moved each slot more than 1 cm, the fraction in
        which it fell off the table, and contact rates.
    """
    eff = ds["effect"]
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
    return {
        "scene": ds.meta.get("scene"),
        "seed": ds.meta.get("seed"),
        "n_pushes": len(ds),
        "n_objects_per_scene": ds.n_objects,
        "object_counts": dict(sorted(names.items())),
        "push_distance_m": sorted({float(d) for d in np.unique(ds["push_distance"])}),
        "has_trajectories": ds.has_trajectories,
        "fraction_objects_touching": float(ds["object_contact"].any(axis=(1, 2)).mean())
        if len(ds) else 0.0,
        "objects": slots,
    }
