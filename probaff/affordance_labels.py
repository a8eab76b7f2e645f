"""The six affordance labels of chapter 2, in the order of every ``(..., 6)`` label array.

Pushable forward, backward, left and right (in the robot frame: forward is its +x, left its
+y), liftable and graspable. The office scenes (`probaff.sim.office`) give them as ground
truth per object; the per-label classifiers (`probaff.perception.labels`) predict them per
segment.
"""

from __future__ import annotations

from probaff.errors import InputError

__all__ = ["LABELS", "label_index"]

LABELS: tuple[str, ...] = (
    "push_forward",
    "push_backward",
    "push_left",
    "push_right",
    "liftable",
    "graspable",
)
"""The label names, in column order."""


def label_index(name: str) -> int:
    """Column of label `name` in every label array.

    Args:
        name: One of `LABELS`.

    Returns:
        Its index in `LABELS`.

    Raises:
        InputError: For an unknown name, listing the known ones.
    """
    if name not in LABELS:
        raise InputError(f"unknown label {name!r}; choose one of {', '.join(LABELS)}.")
    return LABELS.index(name)
