import itertools

import gtsam
import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.maps import DIRECTIONS, AffordanceGraph
from probaff.maps.components import component_labels, group_components
from probaff.maps.graph import EDGE_ISING, EDGE_SYMMETRY


def _graph(occ, seed=0, **kw):
    occ = np.asarray(occ, dtype=bool)
    unary = np.random.default_rng(seed).uniform(0.05, 0.95, (*occ.shape, 4))
    return AffordanceGraph(occ, unary, **kw)


def test_variables_are_numbered_row_major_direction_fastest():
    g = _graph([[1, 0, 1], [0, 1, 0]])
    assert g.num_variables == 12
    assert g.variable(0, 0, "up") == 0
    assert g.variable(0, 2, "down") == 5
    assert g.variable(1, 1, 3) == 11
    np.testing.assert_array_equal(g.variable_cells[4:8], [[0, 2]] * 4)
    np.testing.assert_array_equal(g.variable_directions[:4], [0, 1, 2, 3])
    np.testing.assert_allclose(g.probabilities[5], g.unary[0, 2, 1])
    assert DIRECTIONS == ("up", "down", "left", "right")


def test_ising_edges_link_the_same_direction_of_4_neighbours():
    g = _graph(np.ones((2, 2)))
    assert g.num_edges == 16  # 2 vertical + 2 horizontal pairs, 4 directions each
    assert (g.edge_kinds == EDGE_ISING).all()
    dirs = g.variable_directions[g.edges]
    assert (dirs[:, 0] == dirs[:, 1]).all()
    cells = g.variable_cells[g.edges]
    assert (np.abs(cells[:, 0] - cells[:, 1]).sum(axis=1) == 1).all()


def test_symmetry_edges_pair_up_with_down_of_the_cell_above():
    g = _graph([[1, 1], [1, 0]], symmetry_coupling=0.7)
    sym = {
        tuple(e) for e, k in zip(g.edges.tolist(), g.edge_kinds, strict=True) if k == EDGE_SYMMETRY
    }
    expected = {
        tuple(sorted((g.variable(1, 0, "up"), g.variable(0, 0, "down")))),
        tuple(sorted((g.variable(0, 1, "left"), g.variable(0, 0, "right")))),
    }
    assert sym == expected
    assert np.allclose(g.edge_couplings[g.edge_kinds == EDGE_SYMMETRY], 0.7)
    # up and down layers of the vertical pair join one component
    assert (
        g.component_labels[g.variable(1, 0, "up")] == g.component_labels[g.variable(0, 0, "down")]
    )


def test_tensors_and_gtsam_graph_define_the_same_distribution():
    g = _graph([[1, 1]], symmetry_coupling=-0.3, coupling=0.9)
    fg = g.to_gtsam()
    assert fg.size() == g.num_variables + g.num_edges
    unary = g.unary_log_potentials(torch.float64).numpy()
    pairwise = g.pairwise_log_potentials(torch.float64).numpy()
    for x in itertools.product((0, 1), repeat=g.num_variables):
        values = gtsam.DiscreteValues()
        for v, xv in enumerate(x):
            values[v] = xv
        gt = np.prod([fg.at(i)(values) for i in range(fg.size())])
        ours = sum(unary[v, xv] for v, xv in enumerate(x)) + sum(
            pairwise[e, x[a], x[b]] for e, (a, b) in enumerate(g.edges)
        )
        assert np.isclose(np.log(gt), ours, rtol=0, atol=1e-12)


def test_gtsam_evidence_replaces_the_unary():
    g = _graph([[1]])
    fg = g.to_gtsam(evidence={2: 1})
    marg = gtsam.DiscreteMarginals(fg)
    np.testing.assert_allclose(marg.marginalProbabilities((2, 2)), [0.0, 1.0])
    with pytest.raises(InputError, match="variable 9"):
        g.to_gtsam(evidence={9: 1})
    with pytest.raises(InputError, match="0 or 1"):
        g.to_gtsam(evidence={1: 3})


def test_components_split_the_map():
    g = _graph([[1, 1, 0], [0, 0, 0], [0, 0, 1]])
    # two horizontally adjacent boxes: 4 pairs; lone box: 4 singletons
    sizes = sorted(c.size for c in g.components)
    assert sizes == [1, 1, 1, 1, 2, 2, 2, 2]
    for k, (variables, edge_ids) in enumerate(zip(g.components, g.component_edge_ids, strict=True)):
        assert (g.component_index[variables] == k).all()
        assert np.isin(g.edges[edge_ids], variables).all()
    assert sum(ids.size for ids in g.component_edge_ids) == g.num_edges


def test_component_labels_match_breadth_first_search():
    rng = np.random.default_rng(3)
    n = 200
    edges = rng.integers(0, n, (150, 2))
    labels = component_labels(n, edges)
    adjacency = [[] for _ in range(n)]
    for a, b in edges.tolist():
        adjacency[a].append(b)
        adjacency[b].append(a)
    seen = -np.ones(n, dtype=int)
    for start in range(n):
        if seen[start] >= 0:
            continue
        stack = [start]
        seen[start] = start
        while stack:
            u = stack.pop()
            for w in adjacency[u]:
                if seen[w] < 0:
                    seen[w] = start
                    stack.append(w)
    np.testing.assert_array_equal(labels, seen)
    groups = group_components(labels)
    assert sum(len(c) for c in groups) == n
    assert group_components(np.zeros(0, dtype=np.int64)) == []


@pytest.mark.parametrize(
    ("edges", "message"),
    [
        ([[0, 5]], r"edges reference nodes outside \[0, 3\): range \[0, 5\]"),
        ([[-1, 0]], r"outside \[0, 3\)"),
        ([[0.5, 1.0]], "edges must hold integer node indices, got dtype float64"),
        ([[True, False]], "edges must hold integer node indices, got dtype bool"),
        ([0, 1, 2], r"edges has shape \(3,\), expected \(\*, 2\)"),
        ([[0, 1], [2]], "edges must be a numeric array"),
        ("ab", "edges must be a numeric array"),
    ],
)
def test_component_labels_and_elimination_width_name_bad_edges(edges, message):
    from probaff.maps.exact import elimination_width

    with pytest.raises(InputError, match=message):
        component_labels(3, edges)
    with pytest.raises(InputError, match=message):
        elimination_width(3, edges)


def test_group_components_takes_integer_labels():
    with pytest.raises(InputError, match="labels must be integer component labels"):
        group_components([0.5, 1.0])
    with pytest.raises(InputError, match=r"labels has shape \(1, 2\)"):
        group_components([[0, 1]])
    assert [c.tolist() for c in group_components([0, 1, 0])] == [[0, 2], [1]]


def test_empty_map_has_no_variables():
    g = _graph(np.zeros((3, 4)))
    assert g.num_variables == 0 and g.num_edges == 0 and g.components == ()
    assert g.unary_log_potentials().shape == (0, 2)
    assert g.pairwise_log_potentials().shape == (0, 2, 2)


def test_to_map_scatters_values_and_marks_free_cells():
    g = _graph([[1, 0]])
    grid = g.to_map(torch.arange(4.0)[None])
    assert grid.shape == (1, 1, 2, 4)
    np.testing.assert_array_equal(grid[0, 0, 0], [0, 1, 2, 3])
    assert torch.isnan(grid[0, 0, 1]).all()


def test_unary_of_free_cells_is_ignored_but_nan_anywhere_raises():
    occ = np.array([[True, False]])
    unary = np.full((1, 2, 4), 0.5)
    unary[0, 1] = 7.0  # free cell: ignored
    assert AffordanceGraph(occ, unary).num_variables == 4
    unary[0, 1, 2] = np.nan
    with pytest.raises(InputError, match="NaN"):
        AffordanceGraph(occ, unary)


@pytest.mark.parametrize("bad", [-0.1, 1.5])
def test_probabilities_of_occupied_cells_must_lie_in_unit_interval(bad):
    unary = np.full((1, 1, 4), 0.5)
    unary[0, 0, 3] = bad
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        AffordanceGraph(np.ones((1, 1), bool), unary)


def test_shape_mismatch_raises():
    with pytest.raises(InputError, match=r"unary has shape \(2, 3, 4\), expected \(2, 2, 4\)"):
        AffordanceGraph(np.ones((2, 2), bool), np.full((2, 3, 4), 0.5))
    with pytest.raises(InputError, match="2-D"):
        AffordanceGraph(np.ones((2, 2, 1), bool), np.full((2, 2, 4), 0.5))
    with pytest.raises(InputError, match="boolean"):
        AffordanceGraph(np.full((2, 2), 2), np.full((2, 2, 4), 0.5))


@pytest.mark.parametrize("coupling", [np.nan, np.inf, 5.5, -6.0, "strong"])
def test_coupling_out_of_range_raises(coupling):
    with pytest.raises(InputError, match="coupling"):
        AffordanceGraph(np.ones((1, 1), bool), np.full((1, 1, 4), 0.5), coupling=coupling)
    with pytest.raises(InputError, match="symmetry_coupling"):
        AffordanceGraph(np.ones((1, 1), bool), np.full((1, 1, 4), 0.5), symmetry_coupling=coupling)


def test_variable_lookup_errors():
    g = _graph([[1, 0]])
    with pytest.raises(InputError, match="free"):
        g.variable(0, 1, "up")
    with pytest.raises(InputError, match="outside"):
        g.variable(3, 0, "up")
    with pytest.raises(InputError, match="direction"):
        g.variable(0, 0, "north")
    with pytest.raises(InputError, match="component 5"):
        g.to_gtsam(component=5)
