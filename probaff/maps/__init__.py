"""Affordance maps: an MRF over the pushability of the boxes of a grid map, and its inference.

A pure factor-graph library: importing it loads neither perception, learning, simulation nor
plotting code. The chapter 3 agent built on it (classifier, push planner, manipulation loop)
lives in `probaff.planning`.

Modules:
    options: typed solver settings (`BPOptions`) and MRF parameters (`MRFParams`), with every
        default.
    graph: the MRF of one map as a gtsam factor graph and as tensors.
    evidence: batches of clamped-variable assignments.
    bp: loopy belief propagation batched over evidence; grid_bp: its H x W grid fast path.
    exact: exact marginals through gtsam per connected component.
    enumeration: exact marginals of small components, batched over evidence.
    inference: enumeration, gtsam or BP per component (the grid solver on full rectangles).
    entropy: per-variable and whole-map entropies.
    components: connected components of a map's variables.
    synthetic: random shelved-box grids to test and benchmark the solvers.

The package exports what a user calls: the graph and its parameters, the solvers and the
evidence helpers; defaults, limits and checks stay in their modules (e.g.
`probaff.maps.options.DEFAULT_COUPLING`).
"""

from probaff.maps.bp import BeliefPropagationResult, loopy_belief_propagation
from probaff.maps.entropy import map_entropy, marginal_entropy
from probaff.maps.evidence import FREE, as_evidence, make_evidence, single_variable_evidence
from probaff.maps.exact import exact_marginals
from probaff.maps.graph import DIRECTIONS, AffordanceGraph
from probaff.maps.grid_bp import grid_belief_propagation
from probaff.maps.inference import METHODS, MapMarginals, affordance_marginals
from probaff.maps.options import BPOptions, MRFParams

__all__ = [
    "DIRECTIONS",
    "FREE",
    "METHODS",
    "AffordanceGraph",
    "BPOptions",
    "BeliefPropagationResult",
    "MRFParams",
    "MapMarginals",
    "affordance_marginals",
    "as_evidence",
    "exact_marginals",
    "grid_belief_propagation",
    "loopy_belief_propagation",
    "make_evidence",
    "map_entropy",
    "marginal_entropy",
    "single_variable_evidence",
]
