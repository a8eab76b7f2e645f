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

Deprecated: the agent's names (``ManipulationLoop``, ``LoopResult``, ``POLICIES``,
``detect_push``, ``AffordanceClassifier``, ``AffordanceEvaluation``, ``collect_voxels``,
``evaluate``, ``PushPlan``, ``plan_pushes``) still resolve here, lazily and with a
`DeprecationWarning` (PEP 562 ``__getattr__``), and so do the modules ``probaff.maps.loop``,
``probaff.maps.classifier`` and ``probaff.maps.planner``. Import them from `probaff.planning`.
"""

from typing import Any

from probaff.maps._deprecated import MOVED, load_moved
from probaff.maps.bp import BeliefPropagationResult, ising_form, loopy_belief_propagation
from probaff.maps.components import component_labels, group_components
from probaff.maps.entropy import map_entropy, marginal_entropy
from probaff.maps.enumeration import MAX_ENUMERATION_VARIABLES, enumerate_marginals
from probaff.maps.evidence import FREE, as_evidence, make_evidence, single_variable_evidence
from probaff.maps.exact import (
    DEFAULT_MAX_EXACT_WIDTH,
    MAX_WIDTH_SCAN_VARIABLES,
    component_widths,
    elimination_width,
    exact_marginals,
)
from probaff.maps.graph import (
    DIRECTIONS,
    EDGE_ISING,
    EDGE_SYMMETRY,
    AffordanceGraph,
)
from probaff.maps.grid_bp import GRID_BYTES_PER_CELL, grid_belief_propagation
from probaff.maps.inference import (
    BP_SOLVERS,
    METHODS,
    MapMarginals,
    affordance_marginals,
    is_full_grid,
)
from probaff.maps.options import (
    DEFAULT_ALPHA,
    DEFAULT_COUPLING,
    DEFAULT_DAMPING,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    MAX_COUPLING,
    BPOptions,
    MRFParams,
    check_alpha,
    check_coupling,
    resolve_bp_options,
)

__all__ = [
    "BP_SOLVERS",
    "DEFAULT_ALPHA",
    "DEFAULT_COUPLING",
    "DEFAULT_DAMPING",
    "DEFAULT_MAX_EXACT_WIDTH",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_TOL",
    "DIRECTIONS",
    "EDGE_ISING",
    "EDGE_SYMMETRY",
    "FREE",
    "GRID_BYTES_PER_CELL",
    "MAX_COUPLING",
    "MAX_ENUMERATION_VARIABLES",
    "MAX_WIDTH_SCAN_VARIABLES",
    "METHODS",
    "AffordanceGraph",
    "BPOptions",
    "BeliefPropagationResult",
    "MRFParams",
    "MapMarginals",
    "affordance_marginals",
    "as_evidence",
    "check_alpha",
    "check_coupling",
    "component_labels",
    "component_widths",
    "elimination_width",
    "enumerate_marginals",
    "exact_marginals",
    "grid_belief_propagation",
    "group_components",
    "is_full_grid",
    "ising_form",
    "loopy_belief_propagation",
    "make_evidence",
    "map_entropy",
    "marginal_entropy",
    "resolve_bp_options",
    "single_variable_evidence",
]


def __getattr__(name: str) -> Any:
    """Resolve a name that moved to `probaff.planning`, with a `DeprecationWarning` (PEP 562).

    Args:
        name: The attribute looked up on `probaff.maps`.

    Returns:
        The object from its new module.

    Raises:
        AttributeError: For any other unknown name.
    """
    if name in MOVED:
        return load_moved(name)
    raise AttributeError(f"module 'probaff.maps' has no attribute {name!r}")


def __dir__() -> list[str]:
    """Public names, including the deprecated ones `__getattr__` still resolves."""
    return sorted({*globals(), *MOVED})
