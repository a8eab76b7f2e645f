"""The six affordance labels: one order for every label array, and clear errors for others."""

import pytest

from probaff.affordance_labels import LABELS, label_index
from probaff.errors import InputError


def test_labels_are_the_six_of_chapter_2_in_column_order():
    assert LABELS == (
        "push_forward",
        "push_backward",
        "push_left",
        "push_right",
        "liftable",
        "graspable",
    )
    assert [label_index(name) for name in LABELS] == list(range(6))


@pytest.mark.parametrize("name", ["pushable", "", "LIFTABLE", None])
def test_an_unknown_label_lists_the_known_ones(name):
    with pytest.raises(InputError, match=r"unknown label .*; choose one of push_forward"):
        label_index(name)
