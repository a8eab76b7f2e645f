"""Names that moved from `probaff.maps` to `probaff.planning`, and the warning they raise.

The chapter 3 agent (classifier, push planner, manipulation loop) lives in `probaff.planning`
since issue 8; `probaff.maps` is a pure factor-graph library. The old names keep working for a
while through `probaff.maps.__getattr__` and the shim modules ``probaff.maps.loop``,
``probaff.maps.classifier`` and ``probaff.maps.planner``, each with a `DeprecationWarning`.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

__all__ = ["MOVED", "load_moved", "warn_moved_module"]

MOVED: dict[str, tuple[str, str]] = {
    "AffordanceClassifier": ("probaff.planning.classifier", "AffordanceClassifier"),
    "AffordanceEvaluation": ("probaff.planning.classifier", "AffordanceEvaluation"),
    "collect_voxels": ("probaff.planning.classifier", "collect_voxels"),
    "evaluate": ("probaff.planning.classifier", "evaluate"),
    "POLICIES": ("probaff.planning.manipulation_loop", "POLICIES"),
    "LoopResult": ("probaff.planning.manipulation_loop", "LoopResult"),
    "ManipulationLoop": ("probaff.planning.manipulation_loop", "ManipulationLoop"),
    "detect_push": ("probaff.planning.manipulation_loop", "detect_push"),
    "PushPlan": ("probaff.planning.info_gain", "PushPlan"),
    # The old planner took (passable, robot); the grid wrapper keeps that signature.
    "plan_pushes": ("probaff.planning.manipulation_loop", "plan_pushes_on_grid"),
}
"""Old `probaff.maps` name -> (new module, new name)."""


def load_moved(name: str, old_module: str = "probaff.maps") -> Any:
    """Import a moved name from its new home, with a `DeprecationWarning`.

    Args:
        name: The old name, a key of `MOVED`.
        old_module: Where the caller looked it up.

    Returns:
        The object under its new name.
    """
    module, new = MOVED[name]
    warnings.warn(
        f"{old_module}.{name} is deprecated and will be removed: probaff.maps is a pure "
        f"factor-graph library; import {new} from {module} (or probaff.planning) instead.",
        DeprecationWarning,
        stacklevel=3,
    )
    return getattr(importlib.import_module(module), new)


def warn_moved_module(old: str, new: str) -> None:
    """Warn that the module `old` moved to `new` (called by the shim modules on import).

    Args:
        old: The deprecated module path, e.g. ``"probaff.maps.loop"``.
        new: The module that replaces it.
    """
    warnings.warn(
        f"{old} is deprecated and will be removed: probaff.maps is a pure factor-graph "
        f"library; import from {new} (or probaff.planning) instead.",
        DeprecationWarning,
        stacklevel=3,
    )
