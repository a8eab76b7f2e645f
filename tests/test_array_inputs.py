"""Arrays that hold no real numbers are refused by name wherever a public function takes one.

The conversions live in `probaff._checks`: `real_float64` (behind `as_float_array`),
`as_real_tensor`, `as_bool_array` and `check_finite`. These tests feed strings, None, objects,
ragged lists, complex numbers and NaN to the functions that used to pass them to numpy or torch
unchecked: they raised numpy's or torch's own errors, or cast silently (None to NaN, a complex
number to its real part, NaN or 0.5 to True in a mask, 0.5 to index 0).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff._checks import as_float_array, as_real_tensor, real_float64
from probaff.errors import InputError
from probaff.eval.metrics import (
    corrected_halfwidth,
    interval_coverage,
    mean_and_halfwidth,
    nlpd,
    rmse,
    wilson_interval,
)
from probaff.maps.bp import ising_form, loopy_belief_propagation
from probaff.maps.entropy import map_entropy, marginal_entropy
from probaff.maps.evidence import as_evidence
from probaff.maps.grid_bp import grid_belief_propagation
from probaff.models.tensors import as_matrix
from probaff.sim.inputs import floats

UNARY = np.zeros((3, 2))
EDGES = np.array([[0, 1], [1, 2]])
PAIRWISE = np.zeros((2, 2, 2))

NOT_REAL = {
    "None": None,
    "a string": "abc",
    "strings": [["a", "b"]],
    "a ragged list": [[1.0], [1.0, 2.0]],
    "objects": np.array([[None, 1.0]], dtype=object),
    "complex numbers": UNARY + 1j,
}


def _refused(call, value, name):
    """`call(value)` raises an `InputError` naming `name`, and no warning on the way."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match=name):
            call(value)


@pytest.mark.parametrize("value", NOT_REAL.values(), ids=NOT_REAL.keys())
def test_the_maps_refuse_arrays_without_real_numbers(value):
    _refused(lambda v: ising_form(v, EDGES, PAIRWISE), value, "unary_log")
    _refused(lambda v: ising_form(UNARY, v, PAIRWISE), value, "edges")
    _refused(lambda v: ising_form(UNARY, EDGES, v), value, "pairwise_log")
    _refused(lambda v: loopy_belief_propagation(v, EDGES, PAIRWISE), value, "unary_log")
    _refused(lambda v: grid_belief_propagation(v, 0.3), value, "unary_log")
    _refused(lambda v: marginal_entropy(v), value, "marginals")
    _refused(lambda v: map_entropy(v), value, "marginals")
    if value is not None:  # None is "no evidence"
        _refused(lambda v: as_evidence(v, (3,)), value, "evidence")


@pytest.mark.parametrize("value", NOT_REAL.values(), ids=NOT_REAL.keys())
def test_the_metrics_refuse_arrays_without_real_numbers(value):
    dist = Independent(Normal(torch.zeros(3, 2), torch.ones(3, 2)), 1)
    _refused(lambda v: nlpd(dist, v), value, "targets")
    _refused(lambda v: rmse(dist, v), value, "targets")
    _refused(lambda v: rmse(v, torch.zeros(3, 2)), value, "point prediction")
    _refused(lambda v: interval_coverage(dist, v), value, "targets")
    _refused(lambda v: mean_and_halfwidth(v), value, "values")
    _refused(lambda v: corrected_halfwidth(v, 0.25), value, "values")


@pytest.mark.parametrize("bad", ["a", None, True, 1.0, 0, float("nan")])
def test_the_interval_levels_must_lie_strictly_between_0_and_1(bad):
    for call in (
        lambda: wilson_interval(1, 2, bad),
        lambda: mean_and_halfwidth([1.0, 2.0], bad),
        lambda: corrected_halfwidth([1.0, 2.0], 0.25, bad),
    ):
        with pytest.raises(InputError, match=r"confidence must lie in \(0, 1\)"):
            call()
    dist = Independent(Normal(torch.zeros(3, 2), torch.ones(3, 2)), 1)
    with pytest.raises(InputError, match=r"level must lie in \(0, 1\)"):
        interval_coverage(dist, torch.zeros(3, 2), level=bad)
    with pytest.raises(InputError, match="test_to_train"):
        corrected_halfwidth([1.0, 2.0], "a")


def test_the_mean_of_no_trials_is_a_nan_cell_and_nan_values_propagate():
    assert np.isnan(mean_and_halfwidth([])[0]) and mean_and_halfwidth([])[1] == 0.0
    mean, half = mean_and_halfwidth([1.0, 2.0, 3.0])
    assert mean == 2.0 and half == pytest.approx(2.484137711750, rel=1e-9)
    assert np.isnan(corrected_halfwidth([1.0, np.nan, 3.0], 0.25))
    with pytest.raises(InputError, match="values has shape"):
        mean_and_halfwidth([[1.0, 2.0]])


def test_complex_numbers_are_refused_in_the_words_scikit_learn_checks():
    for value in (np.ones(3) + 1j, torch.ones(3, dtype=torch.complex64), [1 + 2j, 3.0]):
        for convert in (as_float_array, as_real_tensor, lambda n, v: as_matrix(n, v)):
            with pytest.raises(InputError, match=r"^X holds complex numbers \(Complex data not"):
                convert("X", value)
    assert real_float64(np.ones(2) + 1j) is None
    with pytest.raises(InputError, match="x must hold numbers"):
        floats("x", 1 + 1j)


def test_none_is_refused_rather_than_cast_to_nan():
    for value in (None, [1.0, None], np.array([1.0, None], dtype=object)):
        assert real_float64(value) is None
        with pytest.raises(InputError, match="numeric array"):
            as_float_array("x", value)
    # objects that are numbers still convert
    assert as_float_array("x", np.array([1.5, 2], dtype=object)).tolist() == [1.5, 2.0]


def test_real_tensors_keep_their_kind_and_arrays_become_float64_or_int64():
    t32 = torch.ones(2, dtype=torch.float32)
    assert as_real_tensor("x", t32) is not None and as_real_tensor("x", t32).dtype == t32.dtype
    assert as_real_tensor("x", [0.1]).dtype == torch.float64  # torch.as_tensor gives float32
    assert as_real_tensor("x", np.arange(3, dtype=np.uint16)).dtype == torch.int64
    assert as_real_tensor("x", np.ones(2, dtype=bool)).dtype == torch.bool
    assert as_real_tensor("x", 2.0).shape == ()
    flipped = np.arange(6.0).reshape(2, 3)[:, ::-1]  # a negative stride torch cannot view
    assert as_real_tensor("x", flipped).tolist() == flipped.tolist()
    # the maps' results are unchanged for real input
    assert torch.allclose(
        marginal_entropy([[0.5, 0.5]]), torch.tensor([np.log(2.0)], dtype=torch.float64)
    )


@pytest.mark.parametrize("value", NOT_REAL.values(), ids=NOT_REAL.keys())
def test_an_affordance_graph_refuses_grids_without_real_numbers(value):
    from probaff.maps import AffordanceGraph

    occupancy = np.zeros((3, 3), dtype=bool)
    occupancy[1, 1] = True
    unary = np.full((3, 3, 4), 0.5)
    _refused(lambda v: AffordanceGraph(occupancy, v), value, "unary")
    if not isinstance(value, np.ndarray) or value.dtype != object:
        _refused(lambda v: AffordanceGraph(v, unary), value, "occupancy")
    graph = AffordanceGraph(occupancy, unary)
    _refused(lambda v: graph.to_map(v), value, "values")


def test_evidence_builders_take_integer_variables_and_mappings_only():
    from probaff.maps import make_evidence, single_variable_evidence

    assert single_variable_evidence(3, [2]).tolist() == [[-1, -1, 1], [-1, -1, 0]]
    assert make_evidence(3, [{np.int64(0): 1}]).tolist() == [[1, -1, -1]]
    for bad, word in (
        ([0.5], "integer variable indices"),
        (["a"], "variables"),
        ([None], "variables"),
    ):
        with pytest.raises(InputError, match=word):
            single_variable_evidence(3, bad)
    for bad, word in (
        (None, "assignments must be a list"),
        ({0: 1}, "assignments must be a list"),
        ([[0, 1]], r"assignments\[0\] must be a"),
        ([{"a": 1}], "variables are integer indices"),
        ([{True: 1}], "variables are integer indices"),
    ):
        with pytest.raises(InputError, match=word):
            make_evidence(3, bad)


def test_a_grid_coupling_tuple_is_a_vertical_and_horizontal_pair():
    with pytest.raises(InputError, match=r"\(vertical, horizontal\) pair, got a tuple of 1"):
        grid_belief_propagation(np.zeros((3, 3, 2)), (0.1,))


def test_masks_hold_bools_or_exact_zeros_and_ones():
    from probaff._checks import as_bool_array

    assert as_bool_array("m", [0, 1.0, True]).tolist() == [False, True, True]
    assert as_bool_array("m", torch.tensor([1, 0])).dtype == np.bool_
    for bad, shown in (([0.5], "0.5"), ([np.nan], "nan"), ([2], "2")):
        with pytest.raises(InputError, match=rf"^m must be bool or 0/1 values, got .*{shown}"):
            as_bool_array("m", bad)
    for bad in (["a"], [1 + 0j], None):  # numpy would call each of these True
        with pytest.raises(InputError, match=r"^m "):
            as_bool_array("m", bad)


@pytest.mark.parametrize("bad", [np.full((3, 3), np.nan), np.full((3, 3), 0.5), [["a"] * 3] * 3])
def test_grids_of_free_cells_are_masks(bad):
    from probaff.maps import AffordanceGraph
    from probaff.perception import grid_distances
    from probaff.planning import plan_pushes_on_grid
    from probaff.planning.manipulation.loop import travel_distances

    occupancy = np.zeros((3, 3), dtype=bool)
    occupancy[1, 1] = True
    graph = AffordanceGraph(occupancy, np.full((3, 3, 4), 0.5))
    for call in (
        lambda: grid_distances(bad, (0, 0)),
        lambda: travel_distances(bad, (0, 0)),
        lambda: plan_pushes_on_grid(graph, bad, (0, 0)),
        lambda: AffordanceGraph(bad, np.full((3, 3, 4), 0.5)),
    ):
        with pytest.raises(InputError, match=r"must be bool or 0/1|numeric array"):
            call()
    with pytest.raises(InputError, match="robot"):
        travel_distances(~occupancy, [[0], [0, 1]])
    with pytest.raises(InputError, match="distances"):
        from probaff.planning import plan_pushes

        plan_pushes(graph, [[1], [1, 2]])


def test_the_finiteness_check_refuses_what_holds_no_real_numbers():
    from probaff._checks import check_finite

    check_finite("x", [1, 2])  # integers and bools are finite numbers
    check_finite("x", [True])
    for bad, words in (
        ("abc", "numeric array"),
        (None, "numeric array"),
        ([[1.0], [1.0, 2.0]], "numeric array"),
        (np.array([1.0, None]), "numeric array"),
        ([1 + 1j], "complex"),
    ):
        with pytest.raises(InputError, match=f"^x .*{words}"):
            check_finite("x", bad)


def test_no_candidate_variables_is_an_empty_batch():
    from probaff.maps import single_variable_evidence

    assert tuple(single_variable_evidence(3, []).shape) == (0, 3)


@pytest.mark.parametrize("value", NOT_REAL.values(), ids=NOT_REAL.keys())
def test_the_push_frame_refuses_arrays_without_real_numbers(value):
    from probaff.features import directions_to_push_frame, points_to_push_frame

    yaw, origin = np.zeros(2), np.zeros((2, 2))
    _refused(lambda v: directions_to_push_frame(v, yaw), value, "vectors")
    _refused(lambda v: points_to_push_frame(v, origin, yaw, 0.1), value, "points")
    _refused(lambda v: points_to_push_frame(np.zeros((2, 3)), v, yaw, 0.1), value, "origin")
    _refused(lambda v: directions_to_push_frame(np.zeros((2, 3)), v), value, "yaw")


def test_the_push_frame_checks_shapes_and_height():
    from probaff.features import directions_to_push_frame, points_to_push_frame

    with pytest.raises(InputError, match=r"vectors must be an \(N, \.\.\., 3\)"):
        directions_to_push_frame(np.zeros((2, 2)), np.zeros(2))
    with pytest.raises(InputError, match="yaw has shape"):
        directions_to_push_frame(np.zeros((2, 3)), np.zeros(3))
    with pytest.raises(InputError, match="height must be a finite number"):
        points_to_push_frame(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(2), "0.1")
    # a push along +x from the origin at 0.1 m: a point 0.2 m ahead, on the table
    out = points_to_push_frame(np.array([[0.2, 0.0, 0.0]]), np.zeros((1, 2)), np.zeros(1), 0.1)
    assert np.allclose(out, [[0.1, 0.0, 0.2]])


def test_result_tables_take_lists_of_rows():
    from probaff.eval import csv_table, markdown_table, write_csv
    from probaff.features import scene_feature_names

    assert csv_table([{"a": 1, "b": 2.5}, {"a": 3}]) == "a,b\r\n1,2.5\r\n3,\r\n"
    assert markdown_table([{"a": 0.5}], ["a"], digits=1) == "| a |\n|---|\n| 0.5 |\n"
    for bad, word in (
        ("abc", "rows must be a list"),
        (None, "rows must be a list"),
        ({"a": 1}, "rows must be a list"),
        ([1, 2], r"rows\[0\] must be a"),
        ([], "rows is empty"),
        ([{"a": 1}, {"b": 2}], r"rows\[1\] holds columns \['b'\]"),
    ):
        with pytest.raises(InputError, match=word):
            csv_table(bad)
    with pytest.raises(InputError, match="rows is empty"):
        write_csv("unused.csv", [])
    with pytest.raises(InputError, match=r"rows\[0\] lacks the column\(s\) \['b'\]"):
        markdown_table([{"a": 1}], ["b"])
    with pytest.raises(InputError, match="columns must be a list"):
        markdown_table([{"a": 1}], "a")
    with pytest.raises(InputError, match="digits"):
        markdown_table([{"a": 1.0}], ["a"], digits=-1)
    with pytest.raises(InputError, match="n_objects"):
        scene_feature_names(0)


@pytest.mark.parametrize("value", [*NOT_REAL.values(), np.zeros(2), np.full(3, np.nan)])
def test_the_edge_task_tests_take_finite_book_poses(value):
    from probaff.planning import load_edge_task

    task = load_edge_task()
    for test in ("graspable", "fallen", "heuristic", "progress", "candidate_pushes"):
        with pytest.raises(InputError, match="poses"):
            getattr(task, test)(value)
    batch = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])  # on the table, and far off it
    assert task.fallen(batch).tolist() == [False, True]
    assert task.graspable(batch).tolist() == [False, False]


def test_pose_noise_is_drawn_for_finite_poses_of_one_shape_only():
    from probaff.data import add_pose_noise, observe_poses, parse_pose_noise, summarize

    noise, rng = parse_pose_noise("0.003,1"), np.random.default_rng(0)
    poses = np.zeros((2, 2, 3))
    for args, word in (
        (("0.003", poses, poses, np.zeros(2), rng), "noise must be a PoseNoise"),
        ((noise, "abc", poses, np.zeros(2), rng), "before"),
        ((noise, poses, np.zeros((2, 3)), np.zeros(2), rng), "after has shape"),
        ((noise, poses, poses * np.nan, np.zeros(2), rng), "after contains"),
        ((noise, poses, poses, np.zeros(3), rng), "push_yaw has shape"),
        ((noise, poses, poses, np.zeros(2), 3), "rng must be a numpy.random.Generator"),
    ):
        with pytest.raises(InputError, match=word):
            observe_poses(*args)
    before, after, effect = observe_poses(noise, poses, poses, np.zeros(2), rng)
    assert before.shape == after.shape == effect.shape == (2, 2, 3)
    with pytest.raises(InputError, match="--pose-noise must be POS_M,YAW_DEG text"):
        parse_pose_noise(None)
    with pytest.raises(InputError, match=r"arrays lacks \['state_before'"):
        add_pose_noise({}, noise, rng)
    with pytest.raises(InputError, match="arrays must map"):
        add_pose_noise("abc", noise, rng)
    with pytest.raises(InputError, match="ds must be a PushDataset or a SkillDataset"):
        summarize("abc")


def test_the_arm_checks_joint_angles_and_ranges():
    from probaff.sim import load_arm, load_tabletop

    arm = load_arm(load_tabletop().arm)
    good = torch.zeros(2, arm.dof, dtype=torch.float64)
    assert torch.allclose(arm.fk(good.numpy()), arm.fk(good))  # arrays are taken too
    for bad, word in (
        (None, "q must be"),
        ("abc", "q must be"),
        (torch.zeros(2, arm.dof, dtype=torch.complex64), "Complex data"),
        (torch.zeros(2, 3), "q has shape"),
        (torch.full((2, arm.dof), float("nan")), "q contains"),
    ):
        with pytest.raises(InputError, match=word):
            arm.fk(bad)
    with pytest.raises(InputError, match="q_waypoints holds 1 waypoint"):
        arm.trace(torch.zeros(2, 1, arm.dof), torch.linspace(0, 1, 5))
    with pytest.raises(InputError, match="progress contains"):
        arm.trace(torch.zeros(2, 3, arm.dof), torch.tensor([0.0, float("nan")]))
    with pytest.raises(InputError, match="u has shape"):
        arm.sideview_trace(torch.zeros(2, 3, arm.dof), torch.zeros(3, 4))
    with pytest.raises(InputError, match="xy contains"):
        arm.reachable(torch.full((1, 2), float("nan")), torch.zeros(1))
    for kwargs, word in (
        ({"resolution": 0}, "resolution must be a finite number > 0"),
        ({"x_range": (1.0, 0.0)}, "x_range must rise"),
        ({"y_range": "ab"}, r"y_range must be a \(low, high\) pair"),
    ):
        with pytest.raises(InputError, match=word):
            arm.reachable_mask(**{"x_range": (0.0, 0.1), "y_range": (0.0, 0.1), **kwargs})
    with pytest.raises(InputError, match="plane_y must be a finite number"):
        arm.sideview_reach(0.1, float("nan"))


def test_a_warehouse_maps_cells_and_points_of_real_pairs():
    from probaff.sim import generate_map, load_warehouse

    m = generate_map(load_warehouse(), np.random.default_rng(0))
    cells = np.array([[0, 0], [1, 2]])
    assert np.array_equal(m.cell_of(m.cell_centre(cells)), cells)
    for call, name in ((m.cell_centre, "cells"), (m.cell_of, "xy"), (m.inside, "cells")):
        for bad in (None, "abc", [[1.0], [1.0, 2.0]], np.zeros(3), [[np.nan, 0.0]], [[1j, 0]]):
            with pytest.raises(InputError, match=f"^{name} "):
                call(bad)
