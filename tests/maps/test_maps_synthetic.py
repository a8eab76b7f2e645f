"""Shelved-box grids: seeded, at least the cells asked for, and clear errors for bad sizes."""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.maps.synthetic import SHELF_MIN_SIZE, drop_shelves


def test_shelves_take_at_least_the_cells_asked_for_and_repeat_with_the_seed():
    occ = drop_shelves(np.random.default_rng(3), 12, 30)
    assert occ.shape == (12, 12) and occ.dtype == bool and 30 <= occ.sum() < 30 + 10
    assert np.array_equal(occ, drop_shelves(np.random.default_rng(3), 12, 30))
    assert not drop_shelves(np.random.default_rng(3), SHELF_MIN_SIZE, 0).any()


@pytest.mark.parametrize(
    ("size", "cells", "match"),
    [
        (4, 3, "size must be an integer >= 5"),
        (6, -1, "cells must be an integer >= 0"),
        (6, 37, r"cells must be at most size\*\*2 = 36"),
    ],
)
def test_bad_sizes_are_refused(size, cells, match):
    with pytest.raises(InputError, match=match):
        drop_shelves(np.random.default_rng(0), size, cells)
