"""The manipulation loop of chapter 3: push boxes to confirm affordances and refine the map.

The robot starts from an exploration of the warehouse (`probaff.perception.exploration`): an
occupancy grid, the merged point cloud and its last scan cell. Its belief is what the grid says:
cells with an occupied sub-cell are boxes, known-free cells are drivable. A trained
`AffordanceClassifier` gives every believed box its unary pushability per direction.

Each step:

1. choose a push: the ``"information_gain"`` policy scores every candidate with
   `probaff.planning.manipulation.info_gain.plan_pushes` on the MRF (travel distances from
   `travel_distances`) and takes the largest ``G``, stopping when every ``G < 0`` (unless
   told to keep going); the
   ``"exhaustive"`` baseline takes the nearest untested (box, direction) whose access cell it can
   reach (ties row-major, then by direction);
2. drive to the access cell (the path length is added to the distance travelled) and push the box
   one cell with `push_box` on the *true* map (real physics);
3. confirm the outcome by change detection: scan from the access cell and compare the observed
   cloud with noise-free scans predicted from the believed map with the box moved and with it in
   place; the nearer hypothesis (`cloud_distance`) is the observed affordance value;
4. update (the push's record is a `VerifiedPush`): the true map, and the confirmed
   affordances. When the robot concludes that the box moved, the two cells the move changed
   (the one it left and the one it entered) take what the new scan saw of them: their
   occupancy sub-cells and their points are replaced by the scan's; with ``carry_points`` (the
   default, our addition) the box also takes the points of its old cell along, moved one cell,
   since the scan from the access cell sees only its near face and a half-seen box would get
   unsure unaries again.
   The rest of the map keeps its exploration, so that one noisy scan cannot outvote it (with a
   noisy sensor, a single scan's stray hits in rarely-crossed sub-cells would raise phantom
   boxes). The unaries of the changed cells and their 4-neighbours are then recomputed from the
   updated cloud and grid, and so are those of any believed box that has none yet.

A confirmation of (cell, d) stays valid while the cell it pushes into, ``cell + d``, is unchanged:
a move of a box changes two cells (the one it left and the one it entered), so every
confirmation of the box itself and every confirmation of a neighbour pointing into either cell is
dropped. The moved box gets fresh variables in its new cell. A failed push is a lasting
confirmation of "not pushable".

Per step the loop records the map entropy under the policy's own model (the MRF for
information gain; independent unaries, i.e. coupling 0, for the exhaustive baseline, as in the
thesis) and under the MRF, the accuracy of the MAP estimate (marginal > 0.5) against the current
ground truth `rule_affordances` over the believed boxes that truly are blocks (boxes or wall
blocks), and the distance travelled (cells).

Covered by tests/planning/manipulation/test_manipulation_loop.py.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from probaff._checks import (
    as_bool_array,
    as_real_array,
    check_count,
    check_finite,
    check_positive,
    check_shape,
)
from probaff.errors import InputError
from probaff.features.cells import cell_features
from probaff.grid import DIRECTION_OFFSETS
from probaff.maps.entropy import map_entropy
from probaff.maps.evidence import FREE
from probaff.maps.graph import AffordanceGraph
from probaff.maps.inference import METHODS, affordance_marginals
from probaff.maps.options import MRFParams
from probaff.perception.exploration import Exploration, grid_distances
from probaff.perception.occupancy import FREE_SPACE as FREE_CELL
from probaff.perception.occupancy import OCCUPIED, OccupancyGrid
from probaff.planning.manipulation.change_detection import VerifiedPush, detect_push
from probaff.planning.manipulation.classifier import AffordanceClassifier
from probaff.planning.manipulation.info_gain import (
    PushCandidate,
    PushPlan,
    candidate_pushes,
    check_graph,
    plan_pushes,
)
from probaff.sim.depth import DepthScan, DepthSensor
from probaff.sim.warehouse import WarehouseMap, push_box, rule_affordances
from probaff.sim.warehouse_config import WarehouseSpec

__all__ = [
    "POLICIES",
    "UNKNOWN_PRIOR",
    "LoopResult",
    "LoopSnapshot",
    "LoopStep",
    "ManipulationLoop",
    "plan_pushes_on_grid",
    "predict_unary",
    "travel_distances",
]

POLICIES: tuple[str, ...] = ("information_gain", "exhaustive")
"""Manipulation policies: the MRF information-gain planner and the nearest-box baseline."""

UNKNOWN_PRIOR = 0.5
"""Unary pushability of a believed box without any described voxel."""

_CLIP = 1e-6  # unaries are kept in [_CLIP, 1 - _CLIP] so that every clamp stays possible


def travel_distances(passable: Any, robot: Any) -> np.ndarray:
    """Path lengths from the robot to every cell it may push from.

    Args:
        passable: ``(H, W)`` bool, the cells believed free (the robot drives only there).
        robot: ``(row, col)`` integer cell of the robot.

    Returns:
        ``(H, W)`` int64 4-connected path length (cells) through passable cells; -1 where no
        path reaches and at every cell that is not passable (the robot cannot push from it).

    Raises:
        InputError: For a robot cell that is not an integer pair inside the map.
    """
    free = as_bool_array("passable", passable)
    check_shape("passable", free, (None, None))
    cell = as_real_array("robot", robot)
    if cell.shape != (2,) or not np.issubdtype(cell.dtype, np.integer):
        raise InputError(f"robot must be an integer (row, col) cell, got {robot!r}.")
    r, c = int(cell[0]), int(cell[1])
    if not (0 <= r < free.shape[0] and 0 <= c < free.shape[1]):
        raise InputError(
            f"robot cell ({r}, {c}) lies outside the {free.shape[0]} x {free.shape[1]} map."
        )
    return np.where(free, grid_distances(free, (r, c)), -1).astype(np.int64)


def plan_pushes_on_grid(
    graph: AffordanceGraph,
    passable: Any,
    robot: Any,
    evidence: Any = None,
    **settings: Any,
) -> PushPlan:
    """`plan_pushes` from a drivable grid and a robot cell instead of travel distances.

    Args:
        graph: As `plan_pushes`.
        passable: ``(H, W)`` bool, the cells believed free.
        robot: ``(row, col)`` of the robot's cell.
        evidence: As `plan_pushes`.
        **settings: ``alpha``, ``method`` and ``options``, as `plan_pushes` takes them.

    Returns:
        The scored candidates, as `probaff.planning.manipulation.info_gain.plan_pushes`
        returns them.

    Raises:
        InputError: For a mismatched `passable`, a robot outside the map, or bad inputs.
    """
    free = as_bool_array("passable", passable)
    if free.shape != check_graph(graph).shape:
        raise InputError(f"passable has shape {free.shape}, expected the map's {graph.shape}.")
    return plan_pushes(graph, travel_distances(free, robot), evidence, **settings)


def predict_unary(
    classifier: AffordanceClassifier, points: np.ndarray, grid: OccupancyGrid
) -> np.ndarray:
    """Per-cell pushability from the cloud and the grid.

    Args:
        classifier: A trained classifier.
        points: (M, 3) world frame, the merged cloud.
        grid: The occupancy grid of the same observations.

    Returns:
        (rows, cols, 4) probabilities (up, down, left, right); NaN in cells without voxels.

    Raises:
        InputError: For a classifier that is not a trained `AffordanceClassifier`, or
            points that are not a finite (M, 3) array.
    """
    _check_classifier(classifier)
    check_shape("points", points, (None, 3))
    check_finite("points", points)
    vox = cell_features(points, grid)
    if not len(vox.cells):
        return np.full((*grid.shape, 4), np.nan)
    return classifier.predict_cells(vox.features.values, vox.cells, grid.shape)


def _check_classifier(classifier: Any) -> None:
    if not isinstance(classifier, AffordanceClassifier):
        raise InputError(
            "classifier must be an AffordanceClassifier (AffordanceClassifier().fit(features, "
            f"labels)), got {type(classifier).__name__}."
        )
    if not classifier.is_fitted:
        raise InputError("the classifier is not trained; fit it before running the loop.")


@dataclass(frozen=True)
class LoopStep:
    """The state after one manipulation step (step 0: after exploration, before any push).

    Attributes:
        step: Number of pushes made.
        entropy: Whole-map entropy under the policy's model (nats).
        entropy_mrf: Whole-map entropy under the MRF (nats).
        accuracy: Share of the (box, direction) affordances of believed boxes that truly are
            boxes whose MAP estimate matches the ground truth; NaN with no such box.
        distance: Cells driven in all by the manipulation loop.
        n_boxes: Believed boxes.
        n_confirmed: Confirmed affordances still valid.
        push: ``(row, col, direction)`` of the push that led here; None at step 0.
        p: Marginal ``P(x = 1)`` of the pushed affordance when chosen.
        gain: ``G`` of the chosen push (information-gain policy only).
        reward: ``R`` of the chosen push (information-gain policy only).
        cost: ``C``, the path length to the push (cells).
        real_box: Whether a box truly stood in the pushed cell.
        moved: Whether the box moved in the physics.
        observed: Whether change detection said it moved.
    """

    step: int
    entropy: float
    entropy_mrf: float
    accuracy: float
    distance: int
    n_boxes: int
    n_confirmed: int
    push: tuple[int, int, int] | None = None
    p: float | None = None
    gain: float | None = None
    reward: float | None = None
    cost: int | None = None
    real_box: bool | None = None
    moved: bool | None = None
    observed: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary (NaN accuracy becomes None)."""
        out = dataclasses.asdict(self)
        out["push"] = list(self.push) if self.push is not None else None
        if math.isnan(self.accuracy):
            out["accuracy"] = None
        return out


@dataclass(frozen=True)
class LoopSnapshot:
    """The belief before one push, for figures.

    Attributes:
        occupancy: (rows, cols) bool, the believed boxes.
        pushability: (rows, cols, 4) marginal ``P(pushable)`` under the policy's model; NaN off
            the believed boxes.
        robot: ``(row, col)`` of the robot.
        push: ``(row, col, direction)`` of the push chosen from here; None if the loop stops.
        entropy: Whole-map entropy under the policy's model (nats).
    """

    occupancy: np.ndarray
    pushability: np.ndarray
    robot: tuple[int, int]
    push: tuple[int, int, int] | None
    entropy: float


@dataclass(frozen=True)
class LoopResult:
    """A run of the loop on one map.

    Attributes:
        policy: One of `POLICIES`.
        steps: The state after exploration, then after each push.
        snapshots: The belief before each of the first pushes (as many as asked for).
        stop: Why the loop ended: ``"no_gain"`` (every ``G < 0``), ``"no_candidate"`` or
            ``"max_steps"``.
    """

    policy: str
    steps: tuple[LoopStep, ...]
    snapshots: tuple[LoopSnapshot, ...] = field(default=())
    stop: str = "max_steps"


def _cells_and_neighbours(cells: list[tuple[int, int]], shape: tuple[int, int]) -> np.ndarray:
    """(rows, cols) bool: the given cells and their 4-neighbours inside the map."""
    out = np.zeros(shape, dtype=bool)
    for r, c in cells:
        out[r, c] = True
        for dr, dc in DIRECTION_OFFSETS:
            if 0 <= r + dr < shape[0] and 0 <= c + dc < shape[1]:
                out[r + dr, c + dc] = True
    return out


class ManipulationLoop:
    """The robot's belief and the true world during the manipulation loop on one map.

    Args:
        spec: The warehouse world.
        true_map: The map as it really is; the loop moves its boxes.
        exploration: The exploration of `true_map`; it is copied, not modified.
        classifier: A trained affordance classifier.
        policy: One of `POLICIES`.
        mrf: The MRF's couplings and the reward weight ``alpha``; None for `MRFParams()`.
        alpha: Overrides ``mrf.alpha`` when given.
        coupling: Overrides ``mrf.coupling`` when given.
        symmetry_coupling: Overrides ``mrf.symmetry_coupling`` when given.
        along_coupling: Overrides ``mrf.along_coupling`` when given.
        rng: Source of the sensor noise of the scans after each push.
        free_fraction: Share of free sub-cells that makes a cell believed free.
        method: Inference method of `affordance_marginals`.
        stop_at_no_gain: Stop the information-gain policy when every ``G < 0`` (the thesis's
            rule); False keeps pushing the best candidate until `run`'s step limit, to compare
            the policies' choices step by step.
        carry_points: When a box is seen to move, move its old cell's points with it (one
            cell), besides what the new scan saw of the two cells; False keeps only the scan's.

    Raises:
        InputError: For an unknown policy or inference method, ``alpha`` outside [0, 1], a bad
            coupling, a `free_fraction` outside (0, 1], an argument of the wrong kind, an
            exploration without scans, or a classifier that is not trained.
    """

    def __init__(
        self,
        spec: WarehouseSpec,
        true_map: WarehouseMap,
        exploration: Exploration,
        classifier: AffordanceClassifier,
        *,
        policy: str = "information_gain",
        mrf: MRFParams | None = None,
        alpha: float | None = None,
        coupling: float | None = None,
        symmetry_coupling: float | None = None,
        along_coupling: float | None = None,
        rng: np.random.Generator | None = None,
        free_fraction: float = 0.75,
        method: str = "auto",
        stop_at_no_gain: bool = True,
        carry_points: bool = True,
    ) -> None:
        if not isinstance(policy, str) or policy not in POLICIES:
            raise InputError(f"policy must be one of {POLICIES}, got {policy!r}.")
        if not isinstance(method, str) or method not in METHODS:
            raise InputError(f"method must be one of {METHODS}, got {method!r}.")
        for name, value, kind, how in (
            ("spec", spec, WarehouseSpec, "a WarehouseSpec (load_warehouse())"),
            ("true_map", true_map, WarehouseMap, "a WarehouseMap (generate_map(spec, rng))"),
            (
                "exploration",
                exploration,
                Exploration,
                "an Exploration (explore(spec, true_map, start, rng))",
            ),
        ):
            if not isinstance(value, kind):
                raise InputError(f"{name} must be {how}, got {type(value).__name__}.")
        _check_classifier(classifier)
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise InputError(
                f"rng must be a numpy.random.Generator or None, got {type(rng).__name__}."
            )
        check_positive("free_fraction", free_fraction)
        if float(free_fraction) > 1:
            raise InputError(
                f"free_fraction is a share of sub-cells in (0, 1], got {free_fraction!r}."
            )
        if not len(exploration.cells):
            raise InputError(
                "the exploration holds no scan cell; explore the map (explore(...)) before "
                "running the loop."
            )
        if exploration.grid.shape != true_map.shape:
            raise InputError(
                f"the exploration's grid {exploration.grid.shape} does not match "
                f"the map {true_map.shape}."
            )
        self.spec = spec
        self.policy = policy
        base = MRFParams() if mrf is None else mrf
        overrides = {
            "alpha": alpha,
            "coupling": coupling,
            "symmetry_coupling": symmetry_coupling,
            "along_coupling": along_coupling,
        }
        given = {k: v for k, v in overrides.items() if v is not None}
        self.params = dataclasses.replace(base, **given) if given else base
        self.alpha = self.params.alpha
        self.coupling = self.params.coupling
        self.symmetry_coupling = self.params.symmetry_coupling
        self.along_coupling = self.params.along_coupling
        self.classifier = classifier
        self.method = method
        self.stop_at_no_gain = bool(stop_at_no_gain)
        self.carry_points = bool(carry_points)
        self.free_fraction = float(free_fraction)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.true_map = true_map
        self.grid: OccupancyGrid = copy.deepcopy(exploration.grid)
        self.points = np.asarray(exploration.points, dtype=float).copy()
        self.robot = (int(exploration.cells[-1][0]), int(exploration.cells[-1][1]))
        self.distance = 0
        self.confirmed: dict[tuple[int, int, int], int] = {}
        self.unary = predict_unary(classifier, self.points, self.grid)
        self._graphs: tuple[AffordanceGraph, AffordanceGraph] | None = None

    # -- belief -----------------------------------------------------------------------------

    @property
    def believed(self) -> np.ndarray:
        """(rows, cols) bool, the cells the robot believes hold a box."""
        return self.grid.cell_states(self.free_fraction) == OCCUPIED

    @property
    def passable(self) -> np.ndarray:
        """(rows, cols) bool, the cells the robot believes free (it drives only there)."""
        return self.grid.cell_states(self.free_fraction) == FREE_CELL

    def travel_distances(self) -> np.ndarray:
        """(rows, cols) int64 path lengths from the robot to the cells it may push from."""
        return travel_distances(self.passable, self.robot)

    def unary_probabilities(self) -> np.ndarray:
        """(rows, cols, 4) unaries for a graph: the classifier's, `UNKNOWN_PRIOR` where missing."""
        u = np.where(np.isnan(self.unary), UNKNOWN_PRIOR, self.unary)
        return np.clip(u, _CLIP, 1.0 - _CLIP)

    def graphs(self) -> tuple[AffordanceGraph, AffordanceGraph]:
        """``(model, mrf)``: the policy's model and the MRF over the believed boxes.

        The model is the MRF for the information-gain policy and the independent unaries
        (coupling 0, no symmetry factors) for the exhaustive baseline.
        """
        if self._graphs is None:
            occ, unary = self.believed, self.unary_probabilities()
            mrf = AffordanceGraph(
                occ, unary, self.coupling, self.symmetry_coupling, self.along_coupling
            )
            model = mrf if self.policy == "information_gain" else AffordanceGraph(occ, unary, 0.0)
            self._graphs = (model, mrf)
        return self._graphs

    def evidence(self, graph: AffordanceGraph) -> np.ndarray:
        """(V,) int8 confirmed affordances of `graph`'s variables (-1 where unconfirmed)."""
        ev = np.full(graph.num_variables, FREE, dtype=np.int8)
        for (r, c, d), value in self.confirmed.items():
            v = int(graph.variable_index[r, c, d])
            if v >= 0:
                ev[v] = value
        return ev

    def marginals(self, graph: AffordanceGraph) -> torch.Tensor:
        """(V, 2) float64 marginals of `graph` under the confirmed affordances."""
        return affordance_marginals(
            graph, self.evidence(graph), method=self.method, dtype=torch.float64
        ).marginals

    def accuracy(self, graph: AffordanceGraph, marginals: torch.Tensor) -> float:
        """Share of affordances of true boxes whose MAP estimate is right; NaN with none."""
        truth = rule_affordances(self.true_map)
        cells, dirs = graph.variable_cells, graph.variable_directions
        real = self.true_map.occupancy[cells[:, 0], cells[:, 1]]
        if not real.any():
            return math.nan
        guess = marginals[:, 1].numpy() > 0.5
        right = guess == truth[cells[:, 0], cells[:, 1], dirs]
        return float(right[real].mean())

    def record(
        self, step: int, choice: PushCandidate | None = None, outcome: VerifiedPush | None = None
    ) -> LoopStep:
        """The `LoopStep` of the current state."""
        model, mrf = self.graphs()
        m_model = self.marginals(model)
        m_mrf = m_model if mrf is model else self.marginals(mrf)
        info_gain = self.policy == "information_gain"
        return LoopStep(
            step=step,
            entropy=float(map_entropy(m_model)),
            entropy_mrf=float(map_entropy(m_mrf)),
            accuracy=self.accuracy(model, m_model),
            distance=self.distance,
            n_boxes=int(self.believed.sum()),
            n_confirmed=len(self.confirmed),
            push=None if choice is None else (*choice.cell, choice.direction),
            p=None if choice is None else choice.p,
            gain=choice.gain if choice is not None and info_gain else None,
            reward=choice.reward if choice is not None and info_gain else None,
            cost=None if choice is None else choice.cost,
            real_box=None if outcome is None else outcome.real_box,
            moved=None if outcome is None else outcome.moved,
            observed=None if outcome is None else outcome.observed,
        )

    def snapshot(self, push: PushCandidate | None) -> LoopSnapshot:
        """The current belief with the push chosen from it, for figures."""
        model, _ = self.graphs()
        marg = self.marginals(model)
        return LoopSnapshot(
            occupancy=self.believed,
            pushability=model.to_map(marg[:, 1]).numpy(),
            robot=self.robot,
            push=None if push is None else (*push.cell, push.direction),
            entropy=float(map_entropy(marg)),
        )

    # -- acting -----------------------------------------------------------------------------

    def choose(self) -> tuple[PushCandidate | None, str]:
        """The next push of the policy, or None with the reason to stop.

        Returns:
            ``(candidate, reason)``: reason is ``""`` when a push is chosen, else ``"no_gain"``
            or ``"no_candidate"``.
        """
        model, mrf = self.graphs()
        if self.policy == "information_gain":
            plan = plan_pushes(
                mrf, self.travel_distances(), self.evidence(mrf), self.alpha, self.method
            )
            if plan.best is None:
                return None, "no_candidate"
            if plan.worthwhile or not self.stop_at_no_gain:
                return plan.best, ""
            return None, "no_gain"
        ev = self.evidence(model)
        cand = candidate_pushes(model, self.travel_distances(), ev)
        if not len(cand):
            return None, "no_candidate"
        i = int(np.argmin(cand.costs))  # first minimum: row-major cell, then direction
        p = float(self.marginals(model)[cand.variables[i], 1])
        return PushCandidate(
            cell=(int(cand.cells[i, 0]), int(cand.cells[i, 1])),
            direction=int(cand.directions[i]),
            access=(int(cand.access[i, 0]), int(cand.access[i, 1])),
            variable=int(cand.variables[i]),
            p=p,
            reward=math.nan,
            cost=int(cand.costs[i]),
            gain=math.nan,
        ), ""

    def execute(self, choice: PushCandidate) -> VerifiedPush:
        """Drive to the access cell, push, confirm by change detection and update the belief.

        Args:
            choice: The push to make.

        Returns:
            What the push did and what the robot concluded.
        """
        cell, d = choice.cell, choice.direction
        believed = self.believed
        self.distance += choice.cost
        self.robot = choice.access
        real = bool(self.true_map.occupancy[cell])
        if real:
            result = push_box(self.spec, self.true_map, cell, d)
            moved, displacement = result.moved, result.displacement
        else:  # a box the robot wrongly believes in: nothing to push
            moved, displacement = False, np.zeros(2)
        if moved:
            self.true_map = self.true_map.moved(cell, d)
        position = self.true_map.cell_centre(np.array(self.robot))
        scan = DepthSensor(self.spec, self.true_map).scan(position, self.rng)
        observed, d_moved, d_still = detect_push(
            self.spec, believed, cell, d, scan.points, position
        )
        self._update(cell, d, observed, scan)
        return VerifiedPush(
            real_box=real,
            moved=moved,
            observed=observed,
            d_moved=d_moved,
            d_still=d_still,
            displacement=np.asarray(displacement, dtype=float),
        )

    def _update(self, cell: tuple[int, int], d: int, observed: bool, scan: DepthScan) -> None:
        """Fold a push's outcome and its scan into the belief."""
        self._graphs = None
        if not observed:
            self.confirmed[(cell[0], cell[1], d)] = 0
            return
        shape = self.grid.shape
        dest = (cell[0] + int(DIRECTION_OFFSETS[d][0]), cell[1] + int(DIRECTION_OFFSETS[d][1]))
        changed = [cell] + ([dest] if 0 <= dest[0] < shape[0] and 0 <= dest[1] < shape[1] else [])
        mask = np.zeros(shape, dtype=bool)
        for r, c in changed:
            mask[r, c] = True
        # The changed cells take what the new scan saw of them, and only they do.
        seen = OccupancyGrid(
            shape, self.grid.cell_size, self.grid.resolution, self.grid.margin, self.grid.hit_offset
        )
        seen.update(scan)
        fine = np.kron(mask, np.ones((self.grid.per_cell,) * 2, dtype=bool))
        self.grid.passes[fine] = seen.passes[fine]
        self.grid.hits[fine] = seen.hits[fine]
        in_changed = self._in_cells(self.points, mask)
        kept = [self.points[~in_changed], scan.points[self._in_cells(scan.points, mask)]]
        if self.carry_points and len(changed) == 2:
            # The box took its points along: those of its old cell, moved one cell (world xy).
            step = self.grid.cell_size * np.array(
                [DIRECTION_OFFSETS[d][1], -DIRECTION_OFFSETS[d][0], 0.0]
            )
            source = np.zeros(shape, dtype=bool)
            source[cell] = True
            old = self.points[in_changed]
            kept.append(old[self._in_cells(old, source)] + step)
        self.points = np.concatenate(kept)
        self.confirmed = {
            (r, c, e): v
            for (r, c, e), v in self.confirmed.items()
            if not mask[r, c]
            and not self._in_cells_rc(
                r + int(DIRECTION_OFFSETS[e][0]), c + int(DIRECTION_OFFSETS[e][1]), mask
            )
        }
        affected = _cells_and_neighbours(changed, shape)
        affected |= self.believed & np.isnan(self.unary).any(-1)
        fresh = predict_unary(self.classifier, self.points, self.grid)
        self.unary[affected] = fresh[affected]

    def _in_cells(self, points: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(N,) bool: which of the (N, 3) world points lie in a cell set in `mask` (rows, cols)."""
        cells = self.true_map.cell_of(points[:, :2])
        inside = self.true_map.inside(cells)
        out = np.zeros(len(points), dtype=bool)
        out[inside] = mask[cells[inside, 0], cells[inside, 1]]
        return out

    @staticmethod
    def _in_cells_rc(r: int, c: int, mask: np.ndarray) -> bool:
        """Whether cell (r, c) lies inside the map and is set in `mask`."""
        return 0 <= r < mask.shape[0] and 0 <= c < mask.shape[1] and bool(mask[r, c])

    def run(self, max_steps: int, snapshots: int = 0) -> LoopResult:
        """Run the loop until it stops or has made `max_steps` pushes.

        Args:
            max_steps: Most pushes to make (an integer >= 0).
            snapshots: How many of the first pushes to keep a `LoopSnapshot` of (an integer
                >= 0).

        Returns:
            The recorded steps (step 0 first) and snapshots.

        Raises:
            InputError: If `max_steps` or `snapshots` is not an integer >= 0.
        """
        max_steps = check_count("max_steps", max_steps, minimum=0)
        snapshots = check_count("snapshots", snapshots, minimum=0)
        steps = [self.record(0)]
        shots: list[LoopSnapshot] = []
        stop = "max_steps"
        for k in range(1, max_steps + 1):
            choice, reason = self.choose()
            if len(shots) < snapshots:
                shots.append(self.snapshot(choice))
            if choice is None:
                stop = reason
                break
            outcome = self.execute(choice)
            steps.append(self.record(k, choice, outcome))
        return LoopResult(policy=self.policy, steps=tuple(steps), snapshots=tuple(shots), stop=stop)
