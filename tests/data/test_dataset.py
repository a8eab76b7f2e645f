"""The base of every dataset kind: names, dtypes, all-or-none groups, rows and joining."""

from typing import ClassVar

import numpy as np
import pytest

from probaff.data.dataset import ArrayDataset
from probaff.errors import DatasetError


class Pairs(ArrayDataset):
    KIND = "pair"
    REQUIRED: ClassVar[dict[str, str]] = {"object_ids": "int16", "x": "float64"}
    OPTIONAL: ClassVar[dict[str, str]] = {"a": "float32", "b": "float32"}
    GROUPS: ClassVar[dict[str, tuple[str, ...]]] = {"extra": ("a", "b")}


def _arrays(n=3, **extra):
    return {"object_ids": np.array([[0, -1]] * n, dtype=np.int16), "x": np.zeros(n), **extra}


def test_checks_name_the_array():
    with pytest.raises(DatasetError, match=r"pair dataset is missing arrays \['x'\]"):
        Pairs({"object_ids": np.zeros((2, 1), np.int16)}, ["o"])
    with pytest.raises(DatasetError, match=r"unknown arrays \['y'\]"):
        Pairs(_arrays(y=np.zeros(3)), ["o"])
    with pytest.raises(DatasetError, match=r"only some of the extra arrays \['a', 'b'\]"):
        Pairs(_arrays(a=np.zeros(3, np.float32)), ["o"])
    with pytest.raises(DatasetError, match="'x' has dtype float32, expected float64"):
        Pairs({**_arrays(), "x": np.zeros(3, np.float32)}, ["o"])
    with pytest.raises(DatasetError, match="'x' has 2 rows, expected 3"):
        Pairs({**_arrays(), "x": np.zeros(2)}, ["o"])


def test_rows_objects_and_joining():
    ds = Pairs(_arrays(), ["o"], {"scene": "s"})
    assert len(ds) == 3 and ds.objects_of(0) == ["o"] and ds.rows_label == "rows"
    assert ds.check_plan({}) is None
    both = Pairs.concatenate([ds, Pairs(_arrays(2), ["o"])])
    assert isinstance(both, Pairs) and len(both) == 5 and both.meta == {"scene": "s"}
    with pytest.raises(DatasetError, match="zero datasets"):
        Pairs.concatenate([])
    with pytest.raises(DatasetError, match="vocabularies"):
        Pairs.concatenate([ds, Pairs(_arrays(), ["p"])])
