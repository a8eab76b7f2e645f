import pytest

from probaff.errors import InputError
from probaff.models.columns import resolve_features, resolve_groups

GROUPS = {"f_x": slice(0, 3), "f_o": [5, 3], "f_c": slice(6, None)}


def test_resolve_by_name_index_and_default():
    assert resolve_features("gate", ("f_x",), GROUPS, 10) == [0, 1, 2]
    assert resolve_features("gate", "f_o", GROUPS, 10) == [5, 3]
    assert resolve_features("experts", ("f_o", "f_c"), GROUPS, 10) == [5, 3, 6, 7, 8, 9]
    assert resolve_features("experts", [4, -1], None, 10) == [4, 9]
    assert resolve_features("experts", None, None, 4) == [0, 1, 2, 3]
    assert resolve_groups(GROUPS, 8) == {"f_x": [0, 1, 2], "f_o": [5, 3], "f_c": [6, 7]}


def test_unknown_group_lists_known_ones():
    with pytest.raises(InputError, match=r"unknown feature group\(s\) \['f_z'\].*f_c, f_o, f_x"):
        resolve_features("gate_features", ("f_x", "f_z"), GROUPS, 10)
    with pytest.raises(InputError, match="pass groups"):
        resolve_features("gate_features", ("f_x",), None, 10)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ([0, 10], "selects column"),
        ([1, 1], "more than once"),
        (("f_x", 1), "mixes"),
        ([], "no column"),
    ],
)
def test_bad_selections(spec, message):
    with pytest.raises(InputError, match=message):
        resolve_features("expert_features", spec, GROUPS, 10)


def test_empty_group():
    with pytest.raises(InputError, match="selects no column"):
        resolve_features("gate", ("e",), {"e": slice(5, 5)}, 10)
