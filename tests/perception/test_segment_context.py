"""Context descriptors of segments: support, load, free space, contact groups; bad input.

Covers probaff.perception.segment_context.
"""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.perception.segment_context import CONTEXT_NAMES, ContextOptions, context_features


def _box(lo, hi, n, rng):
    return rng.uniform(lo, hi, size=(n, 3))


def _scene():
    """Floor, a table top on a leg, a box on the top, and a free-standing block."""
    rng = np.random.default_rng(0)
    floor = _box((-1.0, -1.0, 0.0), (3.0, 1.0, 0.0), 2000, rng)
    leg = _box((0.95, -0.05, 0.0), (1.05, 0.05, 0.7), 300, rng)
    top = _box((0.5, -0.5, 0.7), (1.5, 0.5, 0.72), 800, rng)
    box = _box((0.9, -0.1, 0.72), (1.1, 0.1, 0.9), 300, rng)
    block = _box((2.0, -0.2, 0.0), (2.3, 0.2, 0.4), 400, rng)
    parts = [floor, leg, top, box, block]
    rows = np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)])
    return np.concatenate(parts), rows


def test_support_load_gaps_and_groups():
    points, rows = _scene()
    out = context_features(points, rows, 5)
    col = {name: out[:, k] for k, name in enumerate(CONTEXT_NAMES)}
    assert out.shape == (5, len(CONTEXT_NAMES)) == (5, 23)
    np.testing.assert_allclose(col["log_points"], np.log10([2000, 300, 800, 300, 400]))
    # The box stands on the table top: its support is the top's surface, 0.72 m.
    assert col["support_z"][3] == pytest.approx(0.72, abs=0.01)
    assert col["height_above_support"][3] == pytest.approx(0.0, abs=0.02)
    assert col["support_z"][4] == pytest.approx(0.0, abs=1e-9)  # the block is on the floor
    # Something stands on the top (the box), nothing on the box or the block.
    assert col["load"][2] > 2.0 and col["load"][3] == 0.0 and col["load"][4] == 0.0
    # The block is 0.5 m in front of the table top, seen from the top's front side.
    assert col["gap_front"][2] == pytest.approx(0.5, abs=0.02)
    # Behind the block only the leg is low enough to block it (the top is above its 0.4 m).
    assert col["gap_back"][4] == pytest.approx(2.0 - 1.05, abs=0.02)
    assert col["gap_front"][4] == 1.0  # nothing beyond the block: max_gap
    # Leg, top and box touch: one contact group spanning the top; the block is its own.
    for r in (1, 2, 3):
        assert col["group_span_x"][r] == pytest.approx(1.0, abs=0.02)
        assert col["group_z_max"][r] == pytest.approx(0.9, abs=0.02)
        assert col["group_log_points"][r] == pytest.approx(np.log10(1400), abs=0.05)
    assert col["group_span_x"][4] == pytest.approx(0.3, abs=0.02)
    assert col["group_gap_back"][4] == pytest.approx(2.0 - 1.05, abs=0.02)
    # Seen floor in the 0.15 m strip in front of the block (about 15 of the floor's points).
    assert col["group_floor_front"][4] == pytest.approx(np.log10(16), abs=0.3)
    hidden = ~((rows == 0) & (points[:, 0] > 2.3) & (points[:, 0] < 2.5))
    shadowed = context_features(points[hidden], rows[hidden], 5)
    assert shadowed[4, CONTEXT_NAMES.index("group_floor_front")] == 0.0


def test_unassigned_points_are_obstacles_and_empty_views_work():
    points, rows = _scene()
    rows = np.where(rows == 4, -1, rows)  # the block in no segment still blocks the top
    out = context_features(points, rows, 4)
    assert out[2, CONTEXT_NAMES.index("gap_front")] == pytest.approx(0.5, abs=0.02)
    assert context_features(points, np.full(len(points), -1), 0).shape == (0, 23)


@pytest.mark.parametrize(
    ("points", "rows", "n", "message"),
    [
        ([[0.0, 0.0, np.nan]], [0], 1, "points"),
        ([[0.0, 0.0]], [0], 1, "points"),
        ([[0.0, 0.0, 0.0]], [0, 0], 1, "rows"),
        ([[0.0, 0.0, 0.0]], [0.5], 1, "rows must be integer"),
        ([[0.0, 0.0, 0.0]], [3], 2, r"rows must lie in \[-1, n_segments - 1\]"),
        ([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [0, 0], 2, "segment row 1 has no points"),
        ([[0.0, 0.0, 0.0]], [0], -1, "n_segments"),
    ],
)
def test_bad_input_is_named(points, rows, n, message):
    with pytest.raises(InputError, match=message):
        context_features(np.asarray(points, dtype=float), np.asarray(rows), n)


def test_bad_options():
    with pytest.raises(InputError, match="link_distance"):
        ContextOptions(link_distance=0.0)
    with pytest.raises(InputError, match="options must be a ContextOptions"):
        context_features(np.zeros((1, 3)), np.zeros(1, dtype=int), 1, options={"max_gap": 1})
