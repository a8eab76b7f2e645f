"""Rectangular footprints: chords cut by a line, overlaps by the separating-axis test."""

import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.planning.geometry import box_corners, boxes_overlap, chord_at


def test_chord_of_an_axis_aligned_and_a_turned_book():
    size = (0.24, 0.17)
    # axis aligned: the line x = 0.5 cuts the full 0.17 m side while it crosses the book
    assert chord_at(np.array([0.45, 0.0, 0.0]), size, 0.5) == pytest.approx(0.17)
    assert chord_at(np.array([0.45, 0.0, 0.0]), size, 0.58) == 0.0
    # turned by 90 degrees: the long side is now along y
    assert chord_at(np.array([0.45, 0.0, math.pi / 2]), size, 0.5) == pytest.approx(0.24)
    # a corner: the chord of a square turned 45 degrees at depth t from its tip is 2 t
    sq = (0.2, 0.2)
    tip = 0.1 * math.sqrt(2)
    assert chord_at(np.array([0.0, 0.0, math.pi / 4]), sq, tip - 0.03) == pytest.approx(0.06)


def _inside(points, pose, size):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rel = points - pose[:2]
    u = rel[:, 0] * c + rel[:, 1] * s
    v = -rel[:, 0] * s + rel[:, 1] * c
    return (np.abs(u) <= size[0] / 2) & (np.abs(v) <= size[1] / 2)


def test_boxes_overlap_agrees_with_a_dense_point_test():
    size_a, size_b = (0.24, 0.17), (0.26, 0.175)
    rng = np.random.default_rng(1)
    b = np.array([0.0, 0.0, 0.3])
    poses = np.column_stack(
        [rng.uniform(-0.35, 0.35, 300), rng.uniform(-0.35, 0.35, 300), rng.uniform(-3, 3, 300)]
    )
    got = boxes_overlap(poses, size_a, b, size_b)
    u = np.linspace(-0.5, 0.5, 61)
    grid = np.stack(np.meshgrid(u * size_a[0], u * size_a[1]), -1).reshape(-1, 2)
    for pose, overlap in zip(poses, got, strict=True):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        pts = pose[:2] + grid @ np.array([[c, s], [-s, c]])
        brute = bool(_inside(pts, b, size_b).any())
        if brute != bool(overlap):  # only a sliver thinner than the grid may disagree
            shrunk = boxes_overlap(pose, size_a, b, size_b, margin=-0.004)
            grown = boxes_overlap(pose, size_a, b, size_b, margin=0.004)
            assert bool(grown) and not bool(shrunk)
    assert 30 < got.sum() < 270  # both answers occur
    assert bool(boxes_overlap(np.array([0.251, 0.0, 0.3]), size_a, b, size_b, margin=0.01))


def test_corners_are_counter_clockwise_around_the_pose():
    corners = box_corners(np.array([[0.1, -0.2, math.pi / 2]]), (0.4, 0.2))[0]
    np.testing.assert_allclose(corners.mean(0), [0.1, -0.2], atol=1e-12)
    np.testing.assert_allclose(corners[0], [0.2, -0.4], atol=1e-12)  # (-a, -b) turned 90 degrees
    edges = np.roll(corners, -1, axis=0) - corners
    cross = (
        edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, 0)[:, 0]
    )
    assert (cross > 0).all()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: box_corners([[0.0, 0.0]], (0.1, 0.1)), r"poses must be \(\.\.\., 3\)"),
        (lambda: box_corners([[0.0, 0.0, math.nan]], (0.1, 0.1)), "poses"),
        (lambda: box_corners("abc", (0.1, 0.1)), "poses"),
        (lambda: box_corners([0.0, 0.0, 0.0], (0.1, -0.1)), r"size must be two extents"),
        (lambda: box_corners([0.0, 0.0, 0.0], (0.1,)), "size"),
        (lambda: boxes_overlap(np.zeros(3), (0.1, 0.1), np.zeros((2, 3)), (0.1, 0.1)), "pose_b"),
        (lambda: boxes_overlap(np.zeros(3), (0.1, 0.1), np.zeros(3), None), "size_b"),
        (lambda: boxes_overlap(np.zeros(3), (0.1, 0.1), np.zeros(3), (0.1, 0.1), "0"), "margin"),
        (lambda: chord_at(np.zeros(3), (0.1, 0.1), math.inf), "line_x"),
    ],
)
def test_bad_poses_sizes_and_lines_are_named(call, message):
    with pytest.raises(InputError, match=message):
        call()
