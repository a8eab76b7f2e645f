import numpy as np
import pytest
import torch
from maps_helpers import reference_marginals, shelf_map, sparse_map

from probaff.errors import InputError
from probaff.maps import AffordanceGraph, affordance_marginals, single_variable_evidence
from probaff.maps.enumeration import MAX_ENUMERATION_VARIABLES, enumerate_marginals
from probaff.maps.evidence import as_evidence


@pytest.mark.parametrize("make", [sparse_map, shelf_map])
@pytest.mark.parametrize("symmetry", [None, 0.6])
def test_enumeration_matches_gtsam_under_batched_evidence(make, symmetry):
    rng = np.random.default_rng(4)
    occ = make(rng)
    g = AffordanceGraph(
        occ, rng.uniform(0.05, 0.95, (12, 12, 4)), coupling=0.4, symmetry_coupling=symmetry
    )
    small = [k for k, c in enumerate(g.components) if c.size <= MAX_ENUMERATION_VARIABLES]
    clamp = rng.choice(g.num_variables, size=6, replace=False)
    ev, _ = as_evidence(single_variable_evidence(g.num_variables, clamp), (g.num_variables,))
    got = enumerate_marginals(g, ev, small)
    mask = np.isin(g.component_index, small)
    for b in range(ev.shape[0]):
        row = ev[b].numpy()
        ref = reference_marginals(g, {int(v): int(row[v]) for v in np.flatnonzero(row >= 0)})
        np.testing.assert_allclose(got[b, mask].numpy(), ref[mask], atol=1e-10)


def test_auto_is_exact_on_warehouse_maps():
    """Random 10-30 box maps: every component is small, so "auto" equals gtsam."""
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(5):
        occ = sparse_map(rng)
        g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), coupling=0.4)
        ev = single_variable_evidence(g.num_variables, range(g.num_variables))
        result = affordance_marginals(g, ev, method="auto", dtype=torch.float64)
        assert set(result.component_methods) == {"enumeration"}
        for b in range(0, ev.shape[0], 7):
            row = ev[b].numpy()
            ref = reference_marginals(g, {int(v): int(row[v]) for v in np.flatnonzero(row >= 0)})
            worst = max(worst, float(np.abs(result.marginals[b].numpy() - ref).max()))
    assert worst < 1e-9


def test_enumeration_refuses_large_components():
    occ = np.ones((5, 5), dtype=bool)
    g = AffordanceGraph(occ, np.full((5, 5, 4), 0.5), coupling=0.4)
    ev, _ = as_evidence(None, (g.num_variables,))
    with pytest.raises(InputError, match="enumeration handles at most"):
        enumerate_marginals(g, ev, [0])


def test_along_coupling_sets_the_aligned_pairs_only():
    occ = np.zeros((4, 4), dtype=bool)
    occ[1, 1] = occ[2, 1] = occ[1, 2] = True  # (1,1) has a box below and one to the right
    g = AffordanceGraph(occ, np.full((4, 4, 4), 0.6), coupling=0.4, along_coupling=-0.3)
    couplings = {}
    for (a, b), j in zip(g.edges, g.edge_couplings, strict=True):
        ca, cb = tuple(g.variable_cells[a]), tuple(g.variable_cells[b])
        couplings[(ca, cb, int(g.variable_directions[a]))] = j
    # vertical pair: up/down lie along it, left/right across
    assert couplings[((1, 1), (2, 1), 0)] == couplings[((1, 1), (2, 1), 1)] == -0.3
    assert couplings[((1, 1), (2, 1), 2)] == couplings[((1, 1), (2, 1), 3)] == 0.4
    # horizontal pair: left/right lie along it
    assert couplings[((1, 1), (1, 2), 2)] == couplings[((1, 1), (1, 2), 3)] == -0.3
    assert couplings[((1, 1), (1, 2), 0)] == 0.4
    ev, _ = as_evidence(None, (g.num_variables,))
    got = enumerate_marginals(g, ev, range(len(g.components)))[0]
    np.testing.assert_allclose(got.numpy(), reference_marginals(g), atol=1e-12)
