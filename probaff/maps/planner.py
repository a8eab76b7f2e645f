"""Deprecated: the push planner moved to `probaff.planning.info_gain`.

Importing this module raises a `DeprecationWarning`. `plan_pushes` and `candidate_pushes` here
keep their old ``(graph, passable, robot, ...)`` signatures; the new ones take an ``(H, W)``
array of travel distances instead (see `probaff.planning.manipulation_loop.travel_distances`).
"""

from __future__ import annotations

from typing import Any

from probaff.maps._deprecated import warn_moved_module

warn_moved_module("probaff.maps.planner", "probaff.planning.info_gain")

from probaff.maps.graph import AffordanceGraph  # noqa: E402
from probaff.maps.options import DEFAULT_ALPHA, check_alpha  # noqa: E402
from probaff.planning import info_gain as _info_gain  # noqa: E402
from probaff.planning.info_gain import (  # noqa: E402
    PushCandidate,
    PushCandidates,
    PushPlan,
    expected_entropies,
)
from probaff.planning.manipulation_loop import (  # noqa: E402
    plan_pushes_on_grid as plan_pushes,
)
from probaff.planning.manipulation_loop import travel_distances  # noqa: E402

__all__ = [
    "DEFAULT_ALPHA",
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "candidate_pushes",
    "check_alpha",
    "expected_entropies",
    "plan_pushes",
]


def candidate_pushes(
    graph: AffordanceGraph, passable: Any, robot: Any, evidence: Any = None
) -> PushCandidates:
    """Old signature of `probaff.planning.info_gain.candidate_pushes`.

    Args:
        graph: The affordance map over the believed boxes.
        passable: (H, W) bool, the cells believed free.
        robot: ``(row, col)`` of the robot's cell.
        evidence: None or (V,) values in {-1, 0, 1}.

    Returns:
        The candidates, ordered by variable index.
    """
    return _info_gain.candidate_pushes(graph, travel_distances(passable, robot), evidence)
