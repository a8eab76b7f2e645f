"""The manipulation loop: change detection, belief and evidence updates, both policies."""

import dataclasses

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.maps.entropy import map_entropy
from probaff.maps.inference import affordance_marginals
from probaff.maps.options import MRFParams
from probaff.perception.exploration import explore
from probaff.planning.manipulation.change_detection import (
    VerifiedPush,
    cloud_distance,
    detect_push,
)
from probaff.planning.manipulation.classifier import AffordanceClassifier, collect_voxels
from probaff.planning.manipulation.info_gain import PushCandidate, plan_pushes
from probaff.planning.manipulation.loop import ManipulationLoop, predict_unary
from probaff.sim.depth import DepthSensor
from probaff.sim.warehouse import WarehouseMap, push_box, rule_affordances
from probaff.sim.warehouse_config import load_warehouse

# The loop's logic is tested on the idealised scanner (its grid is exact); the head camera's
# change detection has its own test below.
CAMERA_SPEC = dataclasses.replace(load_warehouse(), rows=7, cols=7, boxes=(6, 11))
SPEC = dataclasses.replace(CAMERA_SPEC, sensor_kind="scanner")
# Row 3 holds a box against the left wall, two boxes in a row, and free boxes elsewhere.
BOXES = [(1, 1), (1, 4), (3, 0), (3, 3), (3, 4), (5, 2), (5, 5)]


@pytest.fixture(scope="module")
def classifier():
    data = collect_voxels(SPEC, 3, np.random.default_rng(0))
    return AffordanceClassifier().fit(data.features, data.labels)


@pytest.fixture(scope="module")
def world():
    m = WarehouseMap.from_boxes((7, 7), BOXES)
    return m, explore(SPEC, m, (6, 0), np.random.default_rng(1))


def test_cloud_distance():
    a = np.zeros((1, 3))
    b = np.array([[1.0, 0, 0], [3.0, 0, 0]])
    assert cloud_distance(a, b) == pytest.approx((1 + 1 + 3) / 3)
    assert cloud_distance(a, a) == 0.0
    assert cloud_distance(a, np.empty((0, 3))) == np.inf


@pytest.mark.parametrize(
    "cell, direction",
    [((3, 0), 2), ((1, 1), 0), ((3, 3), 3), ((3, 4), 2), ((5, 2), 0), ((1, 4), 1)],
)
def test_change_detection_agrees_with_physics(world, cell, direction):
    m, _ = world
    truth = push_box(SPEC, m, cell, direction).moved
    assert truth == rule_affordances(m)[cell][direction]
    after = m.moved(cell, direction) if truth else m
    access = np.asarray(cell) - np.array([[-1, 0], [1, 0], [0, -1], [0, 1]])[direction]
    position = m.cell_centre(access)
    observed = DepthSensor(SPEC, after).scan(position, np.random.default_rng(2)).points
    moved, d_moved, d_still = detect_push(SPEC, m.occupancy, cell, direction, observed, position)
    assert moved == truth and min(d_moved, d_still) < 0.05 < max(d_moved, d_still)


@pytest.mark.parametrize("cell", [(1, (2, 3)), "ab", (1.5, 2), (1, 2, 3), None])
def test_change_detection_names_a_malformed_cell(cell):
    occupancy = np.zeros((7, 7), dtype=bool)
    points = np.zeros((4, 3))
    with pytest.raises(InputError, match=r"cell must be an integer \(row, col\) cell"):
        detect_push(SPEC, occupancy, cell, 0, points, np.zeros(2))


@pytest.mark.parametrize("cell, direction", [((3, 0), 2), ((3, 3), 3), ((5, 2), 0)])
def test_camera_change_detection_agrees_with_physics(cell, direction):
    m = WarehouseMap.from_boxes((7, 7), BOXES)
    truth = push_box(CAMERA_SPEC, m, cell, direction).moved
    after = m.moved(cell, direction) if truth else m
    access = np.asarray(cell) - np.array([[-1, 0], [1, 0], [0, -1], [0, 1]])[direction]
    position = m.cell_centre(access)
    sensor = DepthSensor(CAMERA_SPEC, after)
    observed = sensor.scan(position, np.random.default_rng(2)).points
    moved, d_moved, d_still = detect_push(
        CAMERA_SPEC, m.occupancy, cell, direction, observed, position
    )
    assert moved == truth and min(d_moved, d_still) < max(d_moved, d_still) - 0.02


def test_loop_confirms_pushes_against_ground_truth(world, classifier):
    m, ex = world
    loop = ManipulationLoop(
        SPEC, m, ex, classifier, policy="exhaustive", rng=np.random.default_rng(3)
    )
    assert (loop.believed == m.occupancy).all()
    result = loop.run(6)
    assert result.policy == "exhaustive" and len(result.steps) == 7
    assert [s.step for s in result.steps] == list(range(7))
    assert result.steps[0].push is None and result.steps[0].distance == 0
    assert any(s.moved for s in result.steps[1:]) and not all(s.moved for s in result.steps[1:])
    for s in result.steps[1:]:
        assert s.real_box and s.observed == s.moved
        assert s.gain is None and s.cost is not None
    dist = [s.distance for s in result.steps]
    assert dist == sorted(dist)
    assert loop.true_map.occupancy.sum() == m.occupancy.sum()  # boxes move, none vanish
    assert (loop.believed == loop.true_map.occupancy).all()
    truth = rule_affordances(loop.true_map)
    for (r, c, d), value in loop.confirmed.items():  # every kept confirmation is still true
        assert truth[r, c, d] == bool(value)
    assert 0.0 <= result.steps[-1].accuracy <= 1.0
    assert m.occupancy.sum() == len(BOXES)  # the caller's map is untouched


def test_evidence_is_invalidated_around_a_move(world, classifier):
    m, ex = world
    loop = ManipulationLoop(SPEC, m, ex, classifier, rng=np.random.default_rng(4))
    loop.confirmed = {(1, 4, 3): 1, (1, 1, 0): 1, (3, 3, 3): 0, (3, 4, 1): 1}
    # Push (5, 2) up into (4, 2): a free cell. (3, 3) right stays valid; (3, 4) down points
    # into (4, 4), unchanged, and stays; a neighbour pointing into (4, 2) would go.
    loop.confirmed[(3, 2, 1)] = 1  # a (hypothetical) confirmation pointing into (4, 2)
    push = PushCandidate(
        cell=(5, 2), direction=0, access=(6, 2), variable=-1, p=0.5, reward=0.0, cost=2, gain=0.0
    )
    outcome = loop.execute(push)
    assert isinstance(outcome, VerifiedPush)
    assert outcome.moved and outcome.observed and loop.true_map.occupancy[4, 2]
    assert loop.robot == (6, 2) and loop.distance == 2
    assert (3, 2, 1) not in loop.confirmed
    assert {(1, 4, 3), (1, 1, 0), (3, 3, 3), (3, 4, 1)} <= set(loop.confirmed)
    assert loop.believed[4, 2] and not loop.believed[5, 2]
    assert not np.isnan(loop.unary[4, 2]).any()
    # A failed push is a lasting confirmation of "not pushable".
    blocked = PushCandidate(
        cell=(3, 3), direction=3, access=(3, 2), variable=-1, p=0.5, reward=0.0, cost=3, gain=0.0
    )
    out = loop.execute(blocked)
    assert not out.moved and not out.observed and loop.confirmed[(3, 3, 3)] == 0


def test_information_gain_loop_and_expected_entropy(world, classifier):
    m, ex = world
    loop = ManipulationLoop(SPEC, m, ex, classifier, rng=np.random.default_rng(5))
    mrf = loop.graphs()[1]
    plan = plan_pushes(mrf, loop.travel_distances(), loop.evidence(mrf))
    assert plan.candidates and all(c.reward >= -1e-9 for c in plan.candidates)
    # Confirming the best push lowers the map entropy in expectation over its outcome.
    best = plan.best
    ev = torch.full((2, mrf.num_variables), -1, dtype=torch.int8)
    ev[0, best.variable], ev[1, best.variable] = 1, 0
    h1, h0 = map_entropy(affordance_marginals(mrf, ev, dtype=torch.float64).marginals)
    assert best.p * float(h1) + (1 - best.p) * float(h0) <= plan.entropy + 1e-9
    result = loop.run(4, snapshots=2)
    assert result.stop in ("no_gain", "max_steps", "no_candidate")
    assert 1 <= len(result.snapshots) <= 2
    for s in result.steps[1:]:
        assert s.observed == s.moved and s.gain is not None and s.gain >= 0
        assert s.reward is not None and s.cost is not None
    assert result.steps[0].entropy == pytest.approx(result.steps[0].entropy_mrf)
    keep_going = ManipulationLoop(
        SPEC, m, ex, classifier, rng=np.random.default_rng(5), stop_at_no_gain=False
    ).run(3)
    assert len(keep_going.steps) == 4 and keep_going.stop == "max_steps"
    shot = result.snapshots[0]
    assert shot.pushability.shape == (7, 7, 4) and shot.push == result.steps[1].push[:3]
    assert np.isnan(shot.pushability[~shot.occupancy]).all()


def test_bad_arguments(world, classifier):
    m, ex = world
    with pytest.raises(InputError, match="policy"):
        ManipulationLoop(SPEC, m, ex, classifier, policy="random")
    with pytest.raises(InputError, match="alpha"):
        ManipulationLoop(SPEC, m, ex, classifier, alpha=2.0)
    with pytest.raises(InputError, match="not trained"):
        ManipulationLoop(SPEC, m, ex, AffordanceClassifier())
    with pytest.raises(InputError, match="max_steps"):
        ManipulationLoop(SPEC, m, ex, classifier).run(-1)


def test_mrf_params_and_overrides(world, classifier):
    m, ex = world
    params = MRFParams(coupling=0.6, alpha=0.5, symmetry_coupling=0.2)
    loop = ManipulationLoop(SPEC, m, ex, classifier, mrf=params)
    assert loop.params == params and loop.coupling == 0.6 and loop.alpha == 0.5
    assert loop.graphs()[1].symmetry_coupling == 0.2
    tweaked = ManipulationLoop(SPEC, m, ex, classifier, mrf=params, alpha=0.9)
    assert tweaked.params == MRFParams(coupling=0.6, alpha=0.9, symmetry_coupling=0.2)
    with pytest.raises(InputError, match="coupling"):
        ManipulationLoop(SPEC, m, ex, classifier, coupling=9.0)


def test_a_moved_box_takes_its_points_along(world, classifier):
    m, ex = world
    loops = {
        carry: ManipulationLoop(
            SPEC,
            m,
            ex,
            classifier,
            policy="exhaustive",
            rng=np.random.default_rng(3),
            carry_points=carry,
        )
        for carry in (False, True)
    }
    while True:  # both loops make the same pushes until the first move
        choices = {carry: loop.choose()[0] for carry, loop in loops.items()}
        assert choices[False] is not None and choices[False].cell == choices[True].cell
        old = {carry: loop.points.copy() for carry, loop in loops.items()}
        outcome = {carry: loops[carry].execute(choices[carry]) for carry in loops}
        if outcome[True].observed:
            break
    cell, d = choices[True].cell, choices[True].direction
    dest = (cell[0] + DIRECTION_OFFSETS[d][0], cell[1] + DIRECTION_OFFSETS[d][1])
    source = m.cell_of(old[True][:, :2])
    carried = old[True][(source[:, 0] == cell[0]) & (source[:, 1] == cell[1])]
    step = np.array([DIRECTION_OFFSETS[d][1], -DIRECTION_OFFSETS[d][0], 0.0])  # one 1 m cell
    in_dest = {
        carry: loop.points[(m.cell_of(loop.points[:, :2]) == dest).all(1)]
        for carry, loop in loops.items()
    }
    assert len(carried) > 0
    assert len(in_dest[True]) == len(in_dest[False]) + len(carried)
    moved = in_dest[True][-len(carried) :]
    np.testing.assert_allclose(np.sort(moved, 0), np.sort(carried + step, 0))


def test_loop_arguments_of_the_wrong_kind_are_refused(world, classifier):
    m, ex = world
    with pytest.raises(InputError, match=r"method must be one of \('auto', 'bp', 'exact'\)"):
        ManipulationLoop(SPEC, m, ex, classifier, method="magic")
    for bad in (0, 1.5, float("nan")):
        with pytest.raises(InputError, match="free_fraction"):
            ManipulationLoop(SPEC, m, ex, classifier, free_fraction=bad)
    with pytest.raises(InputError, match="classifier must be an AffordanceClassifier"):
        ManipulationLoop(SPEC, m, ex, "logistic")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="spec must be a WarehouseSpec"):
        ManipulationLoop("warehouse", m, ex, classifier)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="exploration must be an Exploration"):
        ManipulationLoop(SPEC, m, None, classifier)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"rng must be a numpy.random.Generator or None"):
        ManipulationLoop(SPEC, m, ex, classifier, rng=0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="exploration holds no scan cell"):
        ManipulationLoop(SPEC, m, dataclasses.replace(ex, cells=ex.cells[:0]), classifier)


def test_change_detection_refuses_cells_and_directions_off_the_map(world):
    m, _ = world
    observed, position = np.zeros((4, 3)), np.zeros(2)
    with pytest.raises(InputError, match=r"cell \(9, 0\) lies outside the 7 x 7 map"):
        detect_push(SPEC, m.occupancy, (9, 0), 0, observed, position)
    with pytest.raises(InputError, match="direction must be an index into DIRECTION_NAMES"):
        detect_push(SPEC, m.occupancy, (1, 1), 4, observed, position)
    with pytest.raises(InputError, match="direction must be an index into DIRECTION_NAMES"):
        detect_push(SPEC, m.occupancy, (1, 1), 1.0, observed, position)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="observed has shape"):
        detect_push(SPEC, m.occupancy, (1, 1), 0, np.zeros(3), position)
    with pytest.raises(InputError, match="classifier must be an AffordanceClassifier"):
        predict_unary(None, observed, None)  # type: ignore[arg-type]
