"""Deprecated: the manipulation loop moved to `probaff.planning.manipulation_loop`.

Importing this module raises a `DeprecationWarning`. ``PushOutcome`` is the old name of
`probaff.planning.manipulation_loop.VerifiedPush`.
"""

from probaff.maps._deprecated import warn_moved_module

warn_moved_module("probaff.maps.loop", "probaff.planning.manipulation_loop")

from probaff.planning.manipulation_loop import (  # noqa: E402
    POLICIES,
    UNKNOWN_PRIOR,
    LoopResult,
    LoopSnapshot,
    LoopStep,
    ManipulationLoop,
    VerifiedPush,
    cloud_distance,
    detect_push,
    predict_unary,
)

PushOutcome = VerifiedPush
"""Deprecated alias of `VerifiedPush` (not `probaff.sim.tabletop.PushOutcome`)."""

__all__ = [
    "POLICIES",
    "UNKNOWN_PRIOR",
    "LoopResult",
    "LoopSnapshot",
    "LoopStep",
    "ManipulationLoop",
    "PushOutcome",
    "cloud_distance",
    "detect_push",
    "predict_unary",
]
