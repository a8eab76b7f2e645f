"""Checks of figure inputs shared by the studies' figures."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from probaff.errors import InputError
from probaff.eval.plots import (
    axes_grid,
    check_figure_path,
    check_flag,
    check_records,
    check_unique,
    finite_array,
    finite_number,
    half_width,
    nonempty_text,
    save_titled,
)


def test_records_are_a_list_of_dicts_with_the_keys():
    assert check_records("rows", ({"a": 1},), ("a",), "rows") == [{"a": 1}]
    for bad, message in (
        ({"a": 1}, "rows must be a sequence of rows, got dict"),
        ([], "rows is empty"),
        ([1], r"rows\[0\] must be a dict"),
        ([{"b": 1}], r"rows\[0\] lacks key\(s\) \['a'\]"),
    ):
        with pytest.raises(InputError, match=message):
            check_records("rows", bad, ("a",), "rows")


def test_values_are_checked_by_name():
    assert finite_array("x", [[1, 2]], (1, 2)).shape == (1, 2)
    assert finite_number("x", np.float64(2)) == 2.0 and half_width("ci", 0) == 0.0
    assert nonempty_text("s", "a") == "a" and check_flag("f", np.bool_(True)) is True
    for call, message in (
        (lambda: finite_array("x", None, (2,)), "x is None"),
        (lambda: finite_array("x", [np.nan, 1], (2,)), "x"),
        (lambda: finite_array("x", np.zeros((0, 2)), (None, 2)), "x is empty"),
        (lambda: finite_number("x", True), "x must be a number"),
        (lambda: half_width("ci", -1), "ci"),
        (lambda: nonempty_text("s", ""), "s must be a non-empty string"),
        (lambda: check_flag("f", 1), "f must be true or false"),
        (lambda: check_unique("rows", [1, 2, 1], "key"), r"rows\[2\] repeats key 1 of rows\[0\]"),
        (lambda: check_figure_path(b"x.png"), "path must be a file path"),
        (lambda: check_figure_path(""), "path is empty"),
    ):
        with pytest.raises(InputError, match=message):
            call()


def test_grid_and_titled_save(tmp_path):
    fig = Figure()
    axes = axes_grid(fig, 3, 2)
    assert len(axes) == 3 and not fig.axes[3].axison
    path = save_titled(fig, tmp_path / "f.png", None, "default title")
    assert path == str(tmp_path / "f.png") and fig._suptitle.get_text() == "default title"
