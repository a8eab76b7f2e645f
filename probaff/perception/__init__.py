"""Perception in the grid warehouse: the occupancy grid and frontier-based exploration.

Modules:
    occupancy: a free/occupied/unknown grid of the floor from the depth sensor's rays.
    exploration: the robot explores a map until no reachable frontier remains.
"""

from probaff.perception.exploration import Exploration, explore, grid_distances
from probaff.perception.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

__all__ = [
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "Exploration",
    "OccupancyGrid",
    "explore",
    "grid_distances",
]
