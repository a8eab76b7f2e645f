"""Atomic writers and output-path checks: a bad output path is named before anything is written."""

import numpy as np
import pytest

from probaff._checks import check_output_file
from probaff._io import atomic_write_bytes
from probaff.errors import InputError
from probaff.eval.tables import group_rows, write_csv
from probaff.experiments.affordance_map.figures import plot_step_curves


def test_check_output_file(tmp_path):
    regular = tmp_path / "somefile.txt"
    regular.write_text("x")
    assert check_output_file("path", tmp_path / "new" / "out.pt") == tmp_path / "new" / "out.pt"
    assert check_output_file("path", regular) == regular  # an existing file is replaced
    with pytest.raises(InputError, match=r"^path .*somefile\.txt/a/b\.pt lies under .*somefile"):
        check_output_file("path", regular / "a" / "b.pt")
    with pytest.raises(InputError, match=r"^--model .* is a folder, not a file; give a file"):
        check_output_file("--model", tmp_path)
    for bad in ("", 3, None):
        with pytest.raises(InputError, match=r"^path must be"):
            check_output_file("path", bad)


def test_writers_refuse_a_path_under_a_file(tmp_path):
    regular = tmp_path / "somefile.txt"
    regular.write_text("x")
    with pytest.raises(InputError, match=r"^path .*somefile\.txt/t\.csv lies under"):
        write_csv(regular / "t.csv", [{"a": 1}])
    with pytest.raises(InputError, match=r"^path .*somefile\.txt/f\.png lies under"):
        plot_step_curves({"random": np.zeros((2, 3))}, "entropy", "t", regular / "f.png")
    assert regular.read_text() == "x" and sorted(p.name for p in tmp_path.iterdir()) == [
        "somefile.txt"
    ]
    atomic_write_bytes(tmp_path / "a" / "b" / "c.bin", b"data")  # missing folders are created
    assert (tmp_path / "a" / "b" / "c.bin").read_bytes() == b"data"
    with pytest.raises(OSError):  # the low-level writer raises; public writers check first
        atomic_write_bytes(regular / "x.bin", b"data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "somefile.txt"]


def test_group_rows_keeps_the_first_seen_order_of_values_and_of_rows():
    rows = [{"p": "b", "i": 0}, {"p": "a", "i": 1}, {"p": "b", "i": 2}]
    groups = group_rows(rows, "p")
    assert list(groups) == ["b", "a"]
    assert [r["i"] for r in groups["b"]] == [0, 2] and groups["a"] == [rows[1]]
