import numpy as np
import pytest
from maps_helpers import reference_marginals, shelf_map, sparse_map

from probaff.errors import InputError
from probaff.maps import AffordanceGraph, exact_marginals, make_evidence
from probaff.maps.exact import component_widths, elimination_width


def test_elimination_width_of_known_graphs():
    assert elimination_width(5, np.zeros((0, 2))) == 0
    assert elimination_width(5, [[0, 1], [1, 2], [2, 3], [3, 4]]) == 1
    assert elimination_width(4, [[0, 1], [1, 2], [2, 3], [3, 0]]) == 2
    complete = [[a, b] for a in range(6) for b in range(a + 1, 6)]
    assert elimination_width(6, complete) == 5
    assert elimination_width(6, complete, limit=2) == 5  # stops at the first clique > 2
    ids = np.arange(16).reshape(4, 4)
    grid = np.concatenate(
        [
            np.stack([ids[:-1].ravel(), ids[1:].ravel()], 1),
            np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], 1),
        ]
    )
    assert 4 <= elimination_width(16, grid) <= 6


def test_component_widths_of_a_map():
    g = AffordanceGraph(np.ones((3, 3), bool), np.full((3, 3, 4), 0.5))
    assert component_widths(g) == (3, 3, 3, 3)
    chain = AffordanceGraph(np.ones((1, 5), bool), np.full((1, 5, 4), 0.5))
    assert component_widths(chain) == (1, 1, 1, 1)  # one chain per direction
    with pytest.raises(InputError, match="components \\[99\\] do not exist"):
        component_widths(g, [99])


def test_exact_marginals_match_a_whole_map_gtsam_run():
    rng = np.random.default_rng(0)
    for sym in (None, 0.5):
        occ = shelf_map(rng)
        g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), 0.4, sym)
        np.testing.assert_allclose(exact_marginals(g).numpy(), reference_marginals(g), atol=1e-12)


def test_exact_marginals_with_batched_evidence():
    rng = np.random.default_rng(1)
    g = AffordanceGraph(sparse_map(rng), rng.uniform(0.05, 0.95, (12, 12, 4)), 0.4, 0.3)
    big = max(g.components, key=len)
    rows = [{int(big[0]): 1}, {int(big[-1]): 0, 0: 1}, {}]
    out = exact_marginals(g, make_evidence(g.num_variables, rows))
    assert out.shape == (3, g.num_variables, 2)
    for b, clamp in enumerate(rows):
        np.testing.assert_allclose(out[b].numpy(), reference_marginals(g, clamp), atol=1e-12)


def test_exact_on_a_subset_of_components_leaves_others_nan():
    g = AffordanceGraph(np.ones((1, 3), bool), np.full((1, 3, 4), 0.3))
    out = exact_marginals(g, components=[0])
    assert not out[g.components[0]].isnan().any()
    assert out[g.components[1]].isnan().all()


def test_exact_refuses_wide_components():
    g = AffordanceGraph(np.ones((9, 9), bool), np.full((9, 9, 4), 0.5))
    with pytest.raises(InputError, match=r"component 0 \(81 variables.*method='bp'"):
        exact_marginals(g)
    assert exact_marginals(g, components=[]).isnan().all()
