"""Affordance maps: an MRF over the pushability of the boxes of a grid map, and its inference.

Modules:
    graph: the MRF of one map as a gtsam factor graph and as tensors.
    evidence: batches of clamped-variable assignments.
    bp: loopy belief propagation batched over evidence; grid_bp: its H x W grid fast path.
    exact: exact marginals through gtsam per connected component.
    enumeration: exact marginals of small components, batched over evidence.
    inference: enumeration, gtsam or BP per component.
    entropy: per-variable and whole-map entropies.
    classifier: per-cell affordance classifier from voxel features, and its evaluation.
    planner: candidate pushes scored by expected entropy reduction against travel.
    loop: the manipulation loop (information gain or exhaustive) on one map.
"""

from probaff.maps.bp import (
    DEFAULT_DAMPING,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    BeliefPropagationResult,
    ising_form,
    loopy_belief_propagation,
)
from probaff.maps.classifier import (
    AffordanceClassifier,
    AffordanceEvaluation,
    collect_voxels,
    evaluate,
)
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
    DEFAULT_COUPLING,
    DIRECTIONS,
    EDGE_ISING,
    EDGE_SYMMETRY,
    MAX_COUPLING,
    AffordanceGraph,
    check_coupling,
)
from probaff.maps.grid_bp import GRID_BYTES_PER_CELL, grid_belief_propagation
from probaff.maps.inference import METHODS, MapMarginals, affordance_marginals
from probaff.maps.loop import POLICIES, LoopResult, ManipulationLoop, detect_push
from probaff.maps.planner import PushPlan, check_alpha, plan_pushes

__all__ = [
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
    "POLICIES",
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "AffordanceGraph",
    "BeliefPropagationResult",
    "LoopResult",
    "ManipulationLoop",
    "MapMarginals",
    "PushPlan",
    "affordance_marginals",
    "as_evidence",
    "check_alpha",
    "check_coupling",
    "collect_voxels",
    "component_labels",
    "component_widths",
    "detect_push",
    "elimination_width",
    "enumerate_marginals",
    "evaluate",
    "exact_marginals",
    "grid_belief_propagation",
    "group_components",
    "ising_form",
    "loopy_belief_propagation",
    "make_evidence",
    "map_entropy",
    "marginal_entropy",
    "plan_pushes",
    "single_variable_evidence",
]
