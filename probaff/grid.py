"""The grid convention shared by warehouse maps and affordance graphs.

Maps are indexed ``[row, col]`` with row 0 at the top. Directions are ordered (up, down, left,
right); up decreases the row index (world +y) and left decreases the column index (world -x).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DIRECTION_NAMES", "DIRECTION_OFFSETS"]

DIRECTION_NAMES: tuple[str, ...] = ("up", "down", "left", "right")
DIRECTION_OFFSETS = np.array([[-1, 0], [1, 0], [0, -1], [0, 1]])  # (d_row, d_col) per direction
