"""Perception in the grid warehouse: the occupancy grid and frontier-based exploration.

Modules:
    occupancy: a free/occupied/unknown grid of the floor from the depth sensor's rays.
    exploration: the robot explores a map until no reachable frontier remains.
"""

from probaff.perception.exploration import Exploration, explore, grid_distances
from probaff.perception.occupancy import FREE_SPACE, OCCUPIED, UNKNOWN, OccupancyGrid


def __getattr__(name: str) -> object:
    """Deprecated aliases (PEP 562)."""
    if name == "FREE":
        from probaff.perception import occupancy

        return occupancy.FREE
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "FREE_SPACE",
    "OCCUPIED",
    "UNKNOWN",
    "Exploration",
    "OccupancyGrid",
    "explore",
    "grid_distances",
]
