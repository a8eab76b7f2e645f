"""Typed options: `BPOptions` and `MRFParams` validate once, and the solvers accept them."""

import dataclasses
import math

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.maps import (
    AffordanceGraph,
    BPOptions,
    MRFParams,
    affordance_marginals,
    grid_belief_propagation,
    loopy_belief_propagation,
)
from probaff.maps.options import (
    DEFAULT_ALPHA,
    DEFAULT_COUPLING,
    DEFAULT_DAMPING,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    resolve_bp_options,
)


def test_defaults_are_the_module_constants():
    opts = BPOptions()
    assert (opts.damping, opts.tol, opts.max_iterations, opts.dtype) == (
        DEFAULT_DAMPING,
        DEFAULT_TOL,
        DEFAULT_MAX_ITERATIONS,
        torch.float32,
    )
    params = MRFParams()
    assert (params.coupling, params.alpha) == (DEFAULT_COUPLING, DEFAULT_ALPHA)
    assert params.symmetry_coupling is None and params.along_coupling is None
    assert AffordanceGraph(np.ones((1, 1), bool), np.full((1, 1, 4), 0.5)).coupling == (
        DEFAULT_COUPLING
    )


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"damping": 1.0}, "damping must be a number in"),
        ({"damping": -0.1}, "damping"),
        ({"damping": "0.3"}, "damping"),
        ({"damping": True}, "damping"),
        ({"tol": -1e-3}, "tol must be a finite number"),
        ({"tol": math.inf}, "tol"),
        ({"max_iterations": 0}, "max_iterations must be a positive integer"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"max_iterations": True}, "max_iterations"),
        ({"dtype": torch.float16}, "dtype must be torch.float32 or torch.float64"),
    ],
)
def test_bp_options_are_validated_on_construction(kw, match):
    with pytest.raises(InputError, match=match):
        BPOptions(**kw)


def test_bp_options_normalise_and_stay_frozen():
    opts = BPOptions(damping=0, tol=0, max_iterations=np.int64(7), dtype=torch.float64)
    assert type(opts.damping) is float and type(opts.max_iterations) is int
    assert opts.max_iterations == 7
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.tol = 1.0  # type: ignore[misc]
    assert resolve_bp_options(opts) is opts
    assert resolve_bp_options(opts, tol=None, max_iterations=3).max_iterations == 3
    with pytest.raises(InputError, match="unknown BP option"):
        resolve_bp_options(opts, dampening=0.1)
    with pytest.raises(InputError, match="BPOptions"):
        resolve_bp_options({"tol": 0.1})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"coupling": 50.0}, "coupling must be finite"),
        ({"coupling": math.nan}, "coupling"),
        ({"coupling": "x"}, "coupling must be a number"),
        ({"alpha": 1.5}, "alpha must lie in"),
        ({"alpha": "a"}, "alpha must be a number"),
        ({"symmetry_coupling": -6.0}, "symmetry_coupling"),
        ({"symmetry_coupling": math.nan}, "symmetry_coupling must be a finite number"),
        ({"symmetry_coupling": True}, "symmetry_coupling must be a number"),
        ({"along_coupling": math.inf}, "along_coupling"),
    ],
)
def test_mrf_params_are_validated_on_construction(kw, match):
    with pytest.raises(InputError, match=match):
        MRFParams(**kw)


def test_mrf_params_store_floats():
    p = MRFParams(coupling=1, alpha=0, symmetry_coupling=np.float32(0.5), along_coupling=0)
    assert all(type(v) is float for v in dataclasses.astuple(p))


def _chain():
    unary = torch.log(torch.tensor([[0.3, 0.7], [0.6, 0.4], [0.5, 0.5]]))
    edges = torch.tensor([[0, 1], [1, 2]])
    pairwise = torch.tensor([[[0.4, -0.4], [-0.4, 0.4]]]).repeat(2, 1, 1)
    return unary, edges, pairwise


def test_solvers_accept_options_and_keyword_overrides():
    unary, edges, pairwise = _chain()
    opts = BPOptions(tol=0.0, max_iterations=5, dtype=torch.float64)
    by_options = loopy_belief_propagation(unary, edges, pairwise, options=opts)
    by_keywords = loopy_belief_propagation(
        unary, edges, pairwise, tol=0.0, max_iterations=5, dtype=torch.float64
    )
    assert by_options.iterations == by_keywords.iterations == 5
    assert by_options.marginals.dtype == torch.float64
    assert torch.equal(by_options.marginals, by_keywords.marginals)
    # A keyword overrides the matching field of `options`.
    assert (
        loopy_belief_propagation(unary, edges, pairwise, options=opts, max_iterations=2).iterations
        == 2
    )
    grid = grid_belief_propagation(torch.zeros(3, 3, 2), 0.4, options=opts)
    assert grid.iterations == 5 and grid.marginals.dtype == torch.float64
    graph = AffordanceGraph(
        np.eye(3, dtype=bool) | np.eye(3, k=1, dtype=bool), np.full((3, 3, 4), 0.6)
    )
    result = affordance_marginals(graph, method="bp", options=opts)
    assert result.marginals.dtype == torch.float64 and result.bp.iterations == 5
    with pytest.raises(InputError, match="damping"):
        affordance_marginals(graph, damping=1.5)
