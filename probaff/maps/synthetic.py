"""Synthetic occupancy grids of shelved boxes, to test and benchmark the map solvers.

Boxes stacked in shelves one or two cells deep and two to five long give many short cycles
in the affordance MRF, the hard case of loopy belief propagation.
"""

from __future__ import annotations

import numpy as np

from probaff._checks import check_count
from probaff.errors import InputError

__all__ = ["SHELF_MIN_SIZE", "drop_shelves"]

SHELF_MIN_SIZE = 5
"""Smallest grid side that holds the longest shelf (5 cells)."""


def drop_shelves(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Shelves dropped uniformly on a square grid until at least `cells` cells are taken.

    Each shelf is 1 or 2 cells deep and 2 to 5 long, turned a quarter with probability 1/2,
    at a uniform position that fits the grid; shelves may overlap.

    Args:
        rng: The source of randomness (its draws, in order, make the map).
        size: The grid's side, an integer >= `SHELF_MIN_SIZE`.
        cells: How many cells to take at least, an integer in ``0 .. size**2``.

    Returns:
        (size, size) bool occupancy, True where a box stands; it may take more than `cells`.

    Raises:
        InputError: For a size or cell count that is not such an integer.
    """
    size = check_count("size", size, minimum=SHELF_MIN_SIZE)
    cells = check_count("cells", cells, minimum=0)
    if cells > size * size:
        raise InputError(f"cells must be at most size**2 = {size * size}, got {cells}.")
    occ = np.zeros((size, size), dtype=bool)
    while occ.sum() < cells:
        h, w = int(rng.integers(1, 3)), int(rng.integers(2, 6))
        if rng.random() < 0.5:
            h, w = w, h
        r, c = int(rng.integers(0, size - h + 1)), int(rng.integers(0, size - w + 1))
        occ[r : r + h, c : c + w] = True
    return occ
