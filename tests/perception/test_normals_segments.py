"""Normals, PCL-style region growing and the 25 segment features on synthetic clouds."""

import importlib
import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from probaff.errors import InputError, ProbaffError
from probaff.perception.normals import estimate_normals
from probaff.perception.region_growing import region_growing
from probaff.perception.segment_features import FEATURE_NAMES, segment_features

_HALF: Any = 2.5  # a count that is not an integer
_RG = importlib.import_module("probaff.perception.region_growing")
_SF = importlib.import_module("probaff.perception.segment_features")


def _grid(a, b, step):
    """(M, 2) grid over the rectangle a x b, inclusive of both ends."""
    u = np.arange(a[0], a[1] + step / 2, step)
    v = np.arange(b[0], b[1] + step / 2, step)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    return np.stack([uu.ravel(), vv.ravel()], axis=1)


def _floor_and_wall(step=0.02):
    """Floor z = 0 for x in [1, 2) and a wall x = 2 for z in (0, 1], y in [-0.5, 0.5]."""
    f = _grid((1.0, 2.0 - step), (-0.5, 0.5), step)
    floor = np.column_stack([f[:, 0], f[:, 1], np.zeros(len(f))])
    w = _grid((-0.5, 0.5), (step, 1.0), step)
    wall = np.column_stack([np.full(len(w), 2.0), w[:, 0], w[:, 1]])
    return np.vstack([floor, wall]), np.r_[np.zeros(len(floor)), np.ones(len(wall))]


def _fibonacci_sphere(n, centre, radius):
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = math.pi * (1 + 5**0.5) * i
    unit = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    return np.asarray(centre) + radius * unit, unit


def test_plane_normals_are_exact_and_face_the_viewpoint():
    g = _grid((-1.0, 1.0), (-1.0, 1.0), 0.05)
    pts = np.column_stack([g[:, 0] + 3.0, g[:, 1], 0.3 * g[:, 0] + 0.2 * g[:, 1] + 1.0])
    res = estimate_normals(pts, k=30)
    truth = np.array([-0.3, -0.2, 1.0]) / np.linalg.norm([-0.3, -0.2, 1.0])
    truth = -truth  # the origin lies below the plane
    assert np.abs(res.normals - truth).max() < 1e-3
    assert np.all(res.curvature < 1e-9)
    assert res.n_dropped == 0 and res.valid.all()
    normals, curvature = res  # unpacks as a pair
    assert normals is res.normals and curvature is res.curvature
    assert res.neighbours.shape == (len(pts), 30)
    assert np.all(res.neighbours[:, 0] == np.arange(len(pts)))


def test_sphere_normals_are_radial_and_curvature_positive():
    # a patch of a sphere on a latitude-longitude grid, whose neighbourhoods are near-symmetric
    centre = np.array([3.0, 0.0, 1.0])
    lat, lon = np.meshgrid(np.arange(-50, 51) * 0.002, np.arange(-50, 51) * 0.002)
    unit = np.column_stack(
        [
            (np.cos(lat) * np.cos(lon)).ravel(),
            (np.cos(lat) * np.sin(lon)).ravel(),
            np.sin(lat).ravel(),
        ]
    )
    pts = centre - 0.5 * unit  # the side of the sphere that faces the origin
    res = estimate_normals(pts, k=30)
    inner = (np.abs(lat) < 0.08).ravel() & (np.abs(lon) < 0.08).ravel()
    assert np.abs(res.normals[inner] - (-unit[inner])).max() < 1e-3
    assert np.all(res.curvature > 1e-7) and np.all(res.curvature < 1.0 / 3.0)
    # a whole sphere, normals turned towards its centre: all point inwards
    pts, unit = _fibonacci_sphere(5000, centre, 0.5)
    res = estimate_normals(pts, k=30, viewpoint=centre)
    assert np.einsum("ij,ij->i", res.normals, -unit).min() > math.cos(0.05)
    assert np.all(res.curvature > 1e-4)


def test_normals_match_eigh_on_a_noisy_cloud_and_survive_duplicates():
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(2000, 3)) * [1.0, 0.5, 0.05] + [2.0, 0.0, 0.5]
    res = estimate_normals(pts, k=12)
    _, idx = cKDTree(pts).query(pts, k=12)
    nb = pts[idx] - pts[idx].mean(axis=1, keepdims=True)
    evals, evecs = np.linalg.eigh(np.einsum("bki,bkj->bij", nb, nb) / 12)
    assert np.abs(np.abs(np.einsum("ij,ij->i", res.normals, evecs[:, :, 0])) - 1).max() < 1e-6
    assert res.curvature == pytest.approx(evals[:, 0] / evals.sum(axis=1), abs=1e-9)
    assert np.all(np.einsum("ij,ij->i", res.normals, -pts) >= 0)  # towards the origin
    same = estimate_normals(np.vstack([np.ones((10, 3)), pts[:20]]), k=5)
    assert np.all(same.curvature[:10] == 0)
    assert np.allclose(np.linalg.norm(same.normals, axis=1), 1.0)


def test_normals_equal_a_plain_cov_and_eigh_reference_to_1e_12():
    # a flattened random cloud metres wide and away from the origin, where centring matters
    rng = np.random.default_rng(11)
    pts = rng.normal(size=(3000, 3)) * [2.0, 1.0, 0.02] + [5.0, -3.0, 1.0]
    view = np.array([0.5, 0.2, 1.5])
    res = estimate_normals(pts, k=30, viewpoint=view)
    _, idx = cKDTree(pts).query(pts, k=30)
    assert np.array_equal(res.neighbours, idx)
    cov = np.stack([np.cov(pts[row], rowvar=False, bias=True) for row in idx])
    evals, evecs = np.linalg.eigh(cov)
    normals = evecs[:, :, 0] * np.sign(np.einsum("ij,ij->i", evecs[:, :, 0], view - pts))[:, None]
    assert np.abs(res.normals - normals).max() < 1e-12
    assert np.abs(res.curvature - evals[:, 0] / evals.sum(axis=1)).max() < 1e-12


def test_nan_points_are_dropped_and_counted():
    g = _grid((0.0, 1.0), (0.0, 1.0), 0.05)
    pts = np.column_stack([g, np.full(len(g), 1.0)])
    pts[[3, 50, 100]] = np.nan
    pts[7, 1] = np.nan
    res = estimate_normals(pts, k=10)
    assert res.n_dropped == 4
    assert np.isnan(res.normals[[3, 7, 50, 100]]).all()
    assert (res.neighbours[[3, 7, 50, 100]] == -1).all()
    valid_rows = np.flatnonzero(res.valid)
    assert np.isin(res.neighbours[res.valid], valid_rows).all()
    seg = region_growing(pts, *res, k=10, min_size=5, neighbours=res.neighbours)
    assert seg.n_invalid == 4 and (seg.labels[[3, 7, 50, 100]] == -1).all()
    assert seg.n_segments == 1 and (seg.labels[res.valid] == 0).all()


def test_two_planes_at_right_angles_give_two_segments():
    pts, which = _floor_and_wall()
    res = estimate_normals(pts, k=30, viewpoint=[0.0, 0.0, 1.0])
    seg = region_growing(pts, res.normals, res.curvature, neighbours=res.neighbours)
    assert seg.n_segments == 2
    for s in range(2):
        members = which[seg.labels == s]
        assert len(members) > 1000 and np.all(members == members[0])
    assert (seg.labels == -1).mean() < 0.1  # only the points near the edge are left out
    # the tree query gives the same segmentation as the reused neighbour lists
    again = region_growing(pts, res.normals, res.curvature)
    assert np.array_equal(again.labels, seg.labels)


def _bent_sheet(step=0.01, radius=0.5):
    """A floor, a quarter-cylinder bend of the given radius and a wall, joined smoothly."""
    ys = np.arange(-0.2, 0.2 + step / 2, step)
    xf = np.arange(-0.5, 0.0, step)
    ang = np.arange(0.0, math.pi / 2, step / radius)
    zw = np.arange(radius, radius + 0.5, step)
    parts = []
    kinds = []
    for y in ys:
        parts.append(np.column_stack([xf, np.full(len(xf), y), np.zeros(len(xf))]))
        kinds.append(np.zeros(len(xf)))
        bend = np.column_stack(
            [radius * np.sin(ang), np.full(len(ang), y), radius * (1 - np.cos(ang))]
        )
        parts.append(bend)
        kinds.append(np.ones(len(ang)))
        parts.append(np.column_stack([np.full(len(zw), radius), np.full(len(zw), y), zw]))
        kinds.append(np.full(len(zw), 2.0))
    return np.vstack(parts), np.concatenate(kinds)


def test_the_curvature_threshold_stops_growth_across_a_curved_part():
    pts, kind = _bent_sheet()
    res = estimate_normals(pts, k=30, viewpoint=[0.0, 0.0, 2.0])
    assert res.curvature[kind == 1].min() > 2e-5 and np.median(res.curvature[kind != 1]) < 1e-9
    loose = region_growing(pts, *res, curvature_threshold=1.0, neighbours=res.neighbours)
    assert loose.n_segments == 1
    assert (loose.labels == 0).all()
    tight = region_growing(pts, *res, curvature_threshold=2e-5, neighbours=res.neighbours)
    assert tight.n_segments == 2
    floor, wall = tight.labels[kind == 0], tight.labels[kind == 2]
    assert np.unique(floor).size == 1 and np.unique(wall).size == 1 and floor[0] != wall[0]
    assert tight.n_small > 0  # the bend falls apart into regions that are too small


def test_min_size_drops_small_regions_and_counts_them():
    big = _grid((0.0, 1.0), (0.0, 1.0), 0.05)
    big = np.column_stack([big, np.zeros(len(big))])
    small = _grid((0.0, 0.15), (0.0, 0.15), 0.05)  # 16 points, far away and tilted
    small = np.column_stack([small[:, 0] + 5.0, small[:, 1], small[:, 0] + 1.0])
    pts = np.vstack([big, small])
    res = estimate_normals(pts, k=10, viewpoint=[0.0, 0.0, 3.0])
    seg = region_growing(pts, *res, k=10, min_size=50)
    assert seg.n_segments == 1 and seg.n_small == 1
    assert (seg.labels[len(big) :] == -1).all() and (seg.labels[: len(big)] == 0).all()
    keep = region_growing(pts, *res, k=10, min_size=10)
    assert keep.n_segments == 2 and keep.n_small == 0
    assert np.unique(keep.labels[len(big) :]).size == 1


@pytest.mark.parametrize("seed", range(6))
def test_graph_growth_gives_the_regions_of_growing_one_at_a_time(seed):
    rng = np.random.default_rng(seed)
    m, k = 3000, 8
    # k distinct neighbours per point, the point itself first (as a k-NN query gives them):
    # mostly nearby in index, as on a surface, a few far away
    offsets = np.r_[np.arange(-12, 0), np.arange(1, 13), 500, -900]
    pick = np.argsort(rng.random((m, len(offsets))) + 0.9 * (np.abs(offsets) > 12), axis=1)
    nbrs = (np.arange(m)[:, None] + np.c_[np.zeros(m, int), offsets[pick[:, : k - 1]]]) % m
    smooth = rng.random((m, k)) < (0.35 + 0.1 * seed)  # asymmetric links, many tiny regions
    order = rng.permutation(m)
    grown = _RG._grow_all_seeds(nbrs, smooth, order)
    assert grown is not None
    region, sizes = grown
    expected, expected_sizes = _RG._grow(nbrs, smooth, np.ones(m, dtype=bool), order)
    assert np.array_equal(region, expected)
    assert sizes.tolist() == expected_sizes


def test_a_long_one_way_chain_of_links_is_grown_one_region_at_a_time():
    m = 400  # each point links only to the next: m components in one chain
    pts = np.column_stack([np.arange(m) * 0.01, np.zeros(m), np.zeros(m)])
    normals = np.tile([0.0, 0.0, 1.0], (m, 1))
    curvature = np.linspace(0.1, 0.2, m)  # the chain's first point comes first, reaches all
    nbrs = np.column_stack([np.arange(m), np.minimum(np.arange(m) + 1, m - 1)])
    smooth = np.ones((m, 2), dtype=bool)
    order = np.argsort(curvature, kind="stable")
    assert _RG._grow_all_seeds(nbrs, smooth, order) is None  # past _MAX_PASSES
    seg = region_growing(pts, normals, curvature, k=2, min_size=1, neighbours=nbrs)
    expected, sizes = _RG._grow(nbrs, smooth, np.ones(m, dtype=bool), order)
    assert np.array_equal(seg.labels, expected) and seg.n_segments == len(sizes) == 1


def test_neighbour_lists_with_repeats_grow_the_same_regions():
    pts, _ = _floor_and_wall(0.04)
    res = estimate_normals(pts, k=10, viewpoint=[0.0, 0.0, 2.0])
    repeated = res.neighbours.copy()
    repeated[:, -1] = repeated[:, 1]  # the nearest other point listed twice
    dropped = res.neighbours.copy()
    dropped[:, -1] = -1
    a = region_growing(pts, *res, k=10, min_size=5, neighbours=repeated)
    b = region_growing(pts, *res, k=10, min_size=5, neighbours=dropped)
    assert a.n_segments == b.n_segments == 2 and np.array_equal(a.labels, b.labels)


def test_shortest_distances_between_segments_match_brute_force():
    rng = np.random.default_rng(3)
    floor = np.column_stack([rng.uniform(0, 3, (5000, 2)), rng.normal(0, 0.002, 5000)])
    wall = np.column_stack([np.full(4500, 3.05), rng.uniform(0, 3, 4500), rng.uniform(0, 1, 4500)])
    offset = np.array([1.0, 1.0, 0.0])
    boxes = [rng.uniform(0, 0.3, (n, 3)) + rng.uniform(0, 2.8) * offset for n in (40, 300)]
    lid = rng.uniform(0, 0.1, (20, 3)) + np.array([0.5, 0.5, 0.12])
    groups = [floor, wall, *boxes, lid]
    lo = np.array([g.min(axis=0) for g in groups])
    hi = np.array([g.max(axis=0) for g in groups])
    assert len(floor) > _SF._BY_X and len(wall) > _SF._BY_X  # the sorted path is taken
    s = len(groups)
    best = np.array([[cdist(a, b).min() for b in groups] for a in groups])
    best[np.arange(s), np.arange(s)] = np.inf
    for limit in (0.01, 0.06, 0.15, 1.0):
        dist = _SF._shortest_distances(groups, lo, hi, limit)
        expected = np.where(best <= limit, best, np.inf)
        assert np.isfinite(expected).sum() > (2 if limit > 0.01 else 0)
        assert dist == pytest.approx(expected, rel=1e-12), limit


def _discrete_uniform_variance(n, step):
    return step**2 * (n**2 - 1) / 12.0


def test_box_face_features_match_the_analytic_values():
    step = 0.02
    g = _grid((-0.3, 0.3), (0.0, 0.4), step)  # 31 x 21 points
    face = np.column_stack([np.full(len(g), 2.0), g[:, 0], g[:, 1]])
    labels = np.zeros(len(face), dtype=np.int64)
    var_y = _discrete_uniform_variance(31, step)
    var_z = _discrete_uniform_variance(21, step)
    for viewpoint in (None, [0.0, 0.0, 1.0]):
        out = segment_features(face, labels, viewpoint=viewpoint)
        assert out.features.shape == (1, 25) and out.names == FEATURE_NAMES
        f = dict(zip(out.names, out.features[0], strict=True))
        assert f["scatter"] == pytest.approx(var_y, rel=1e-9)
        assert f["linearity"] == pytest.approx(var_y - var_z, rel=1e-9)
        assert f["planarity"] == pytest.approx(var_z, rel=1e-9)
        assert [f["normal_x"], f["normal_y"], f["normal_z"]] == pytest.approx([-1, 0, 0], abs=1e-9)
        assert [f["span_x"], f["span_y"], f["span_z"]] == pytest.approx([0, 0.6, 0.4], abs=1e-9)
        assert out.centroids[0] == pytest.approx([2.0, 0.0, 0.2], abs=1e-9)
        assert [f["centroid_x"], f["centroid_y"], f["centroid_z"]] == pytest.approx([2, 0, 0.2])
        assert out.features[0, 12:].sum() == 0  # alone: no neighbours, no closeness
    top = np.column_stack([g[:, 0] + 2.0, g[:, 1], np.full(len(g), 0.75)])
    out = segment_features(top, labels)
    assert out.features[0, 3:6] == pytest.approx([0, 0, 1], abs=1e-9)  # a table top faces up


def _patch(centre, half=0.02, step=0.01):
    g = _grid((-half, half), (-half, half), step)
    return np.asarray(centre) + np.column_stack([g, 0.0 * g[:, 0]])


def test_occupancy_bins_of_three_segments_at_known_offsets():
    a, b, c = _patch([0, 0, 0]), _patch([0.3, 0, 0]), _patch([0.05, 0.3, 0.3])
    pts = np.vstack([a, b, c])
    labels = np.repeat([4, 7, 9], len(a))
    out = segment_features(pts, labels, neighbour_distance=1.0, closeness_scale=0.2)
    assert out.segment_ids.tolist() == [4, 7, 9]
    col = {name: i for i, name in enumerate(out.names)}
    occ = out.features[:, 12:24]
    expected = np.zeros((3, 12))
    expected[0, col["occupancy_level_front"] - 12] = 1  # a -> b
    expected[0, col["occupancy_above_left"] - 12] = 1  # a -> c
    expected[1, col["occupancy_level_back"] - 12] = 1  # b -> a
    expected[1, col["occupancy_above_left"] - 12] = 1  # b -> c
    expected[2, col["occupancy_below_right"] - 12] = 2  # c -> a, c -> b
    assert np.array_equal(occ, expected)
    d_ab = 0.26
    d_ac = math.sqrt(0.01**2 + 0.26**2 + 0.3**2)
    d_bc = math.sqrt(0.21**2 + 0.26**2 + 0.3**2)
    close = lambda *d: np.mean(np.exp(-np.asarray(d) / 0.2))  # noqa: E731
    assert out.features[:, 24] == pytest.approx(
        [close(d_ab, d_ac), close(d_ab, d_bc), close(d_ac, d_bc)], rel=1e-9
    )
    near = segment_features(pts, labels, neighbour_distance=0.27)
    assert near.features[:, 12:24].sum(axis=1).tolist() == [1, 1, 0]  # only a and b touch
    assert near.features[2, 24] == 0


def test_small_and_degenerate_segments_are_skipped_and_counted():
    face = _patch([1, 0, 0])
    line = np.column_stack([np.linspace(0, 1, 10), np.full(10, 2.0), np.zeros(10)])
    pair = np.array([[3.0, 0, 0], [3.1, 0, 0]])
    pts = np.vstack([face, line, pair, [[np.nan, np.nan, np.nan]]])
    labels = np.r_[np.zeros(len(face)), np.ones(10), [2, 2], [-1]].astype(int)
    out = segment_features(pts, labels)
    assert out.segment_ids.tolist() == [0] and out.n_skipped == 2


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: estimate_normals(np.zeros((0, 3))), "empty"),
        (lambda: estimate_normals(np.zeros((40, 2))), "points"),
        (lambda: estimate_normals(np.full((40, 3), np.inf)), "infinite"),
        (lambda: estimate_normals(np.full((40, 3), np.nan)), "fewer than k"),
        (lambda: estimate_normals(np.random.default_rng(0).random((40, 3)), k=0), "k must"),
        (lambda: estimate_normals(np.random.default_rng(0).random((40, 3)), k=_HALF), "k must"),
        (lambda: estimate_normals(np.ones((40, 3)), viewpoint=[0, 0]), "viewpoint"),
    ],
)
def test_normals_reject_bad_input(call, match):
    with pytest.raises(InputError, match=match):
        call()


def test_region_growing_and_features_reject_bad_input():
    pts, _ = _floor_and_wall(step=0.1)
    n, c = estimate_normals(pts, k=10)
    cases = [
        (lambda: region_growing(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)), "empty"),
        (lambda: region_growing(pts, n[:-1], c), "normals"),
        (lambda: region_growing(pts, n, c[:, None]), "curvature"),
        (lambda: region_growing(pts, n, c, k=0), "k must"),
        (lambda: region_growing(pts, n, c, min_size=0), "min_size"),
        (lambda: region_growing(pts, n, c, min_size=1.5), "min_size"),
        (lambda: region_growing(pts, n, c, smoothness_deg=0.0), "smoothness_deg"),
        (lambda: region_growing(pts, n, c, smoothness_deg=180.0), "smoothness_deg"),
        (lambda: region_growing(pts, n, c, curvature_threshold=-1), "curvature_threshold"),
        (lambda: region_growing(pts, n, c, neighbours=np.zeros((len(pts), 3), int)), "column"),
        (lambda: region_growing(pts, n + np.inf, c), "infinite"),
        (lambda: segment_features(np.zeros((0, 3)), np.zeros(0, int)), "empty"),
        (lambda: segment_features(pts, np.zeros(len(pts))), "integer"),
        (lambda: segment_features(pts, np.zeros(3, int)), "labels"),
        (lambda: segment_features(pts, np.full(len(pts), -2)), ">= -1"),
        (lambda: segment_features(pts, np.zeros(len(pts), int), elevation_deg=90), "elevation"),
        (lambda: segment_features(pts, np.zeros(len(pts), int), neighbour_distance=0), "neigh"),
    ]
    nan_pts = pts.copy()
    nan_pts[0] = np.nan
    cases.append((lambda: segment_features(nan_pts, np.zeros(len(pts), int)), "NaN"))
    for call, match in cases:
        with pytest.raises(ProbaffError, match=match):
            call()


# ------------------------------------------------------------------ non-numeric input


def _strings(n: int, width: int) -> list[list[str]]:
    return [["a"] * width for _ in range(n)]


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: estimate_normals(_strings(20, 3), k=5), "points"),
        (lambda: estimate_normals(np.zeros((20, 3)), k=5, viewpoint=["x", "y", "z"]), "viewpoint"),
        (lambda: estimate_normals([[0.0, 0.0, 0.0], [1.0, 2.0]], k=5), "points"),
        (
            lambda: region_growing(_strings(4, 3), np.zeros((4, 3)), np.zeros(4), k=3),
            "points",
        ),
        (
            lambda: region_growing(np.zeros((4, 3)), np.zeros((4, 3)), ["c"] * 4, k=3),
            "curvature",
        ),
        (lambda: segment_features(_strings(4, 3), np.zeros(4, dtype=int)), "points"),
    ],
    ids=["normals-points", "normals-viewpoint", "normals-ragged", "rg-points", "rg-curv", "feat"],
)
def test_a_cloud_of_strings_is_a_clear_error(call, name):
    with pytest.raises(InputError, match=rf"^{name} (must be a numeric array|is a ragged)"):
        call()


def test_zero_length_normals_are_named():
    points = np.random.default_rng(0).uniform(size=(40, 3))
    normals = np.tile([0.0, 0.0, 1.0], (40, 1))
    normals[7] = 0.0
    with pytest.raises(InputError, match=r"normals has 1 row\(s\) of zero length .* row 7"):
        region_growing(points, normals, np.zeros(40), k=5)
    normals[7] = np.nan  # a point without a normal is unassigned, not an error
    assert region_growing(points, normals, np.zeros(40), k=5).labels[7] == -1
