"""The config every study shares and the run skeleton: validation once, tags, tasks, files.

Covers probaff.experiments.base.
"""

import dataclasses
import json
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.base import StudyConfig, StudyRun, world_digest


@dataclass(frozen=True, kw_only=True)
class TinyConfig(StudyConfig):
    """A study of squares.

    Attributes:
        n: Numbers squared.
    """

    n: int = 3

    SMOKE: ClassVar[dict[str, Any]] = {"n": 1, "progress": False}

    def check(self) -> dict[str, Any]:
        if self.n < 1:
            raise InputError(f"n must be at least 1, got {self.n}.")
        return {"n": int(self.n)}


def square(i: int, *, offset: int = 0) -> dict[str, Any]:
    return {"i": i, "square": i * i + offset}


def test_validate_checks_the_shared_fields_once_and_normalises_counts(tmp_path):
    cfg = TinyConfig(out=str(tmp_path), seed=np.int64(2), n=np.int64(3))
    valid = cfg.validate()
    assert type(valid.seed) is int and type(valid.n) is int and valid == cfg
    for bad, message in (
        ({"seed": -1}, "seed must be an integer >= 0, got -1"),
        ({"workers": -2}, "workers must be None or an integer >= 0, got -2"),
        ({"scheduler": "garbage"}, "scheduler 'garbage' is not a Dask scheduler address"),
        ({"n": 0}, "n must be at least 1"),
    ):
        with pytest.raises(InputError, match=message):
            TinyConfig(out=str(tmp_path), **bad).validate()
    regular = tmp_path / "file"
    regular.write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder"):
        TinyConfig(out=str(regular)).validate()


def test_smoke_sizes_never_replace_given_fields():
    assert TinyConfig.smoke().n == 1 and TinyConfig.smoke().progress is False
    assert TinyConfig.smoke(n=5, out="x").n == 5


def test_tags_follow_the_settings_that_shape_results():
    a, b = TinyConfig(out="a"), TinyConfig(out="b", workers=3, progress=False)
    assert a.tag(version=1) == b.tag(version=1)  # run-only fields aside
    assert a.tag(version=1) != a.tag(version=2)
    assert a.tag(version=1) != dataclasses.replace(a, n=4).tag(version=1)
    assert a.tag(version=1, only=("seed",)) == dataclasses.replace(a, n=4).tag(
        version=1, only=("seed",)
    )
    assert len(a.tag(version=1, length=8)) == 8
    tagged = a.tag(version=1, world=("tabletop.yaml",))
    assert tagged == a.tag(version=1) + world_digest(("tabletop.yaml",))


def test_a_run_writes_its_tasks_tables_and_summary(tmp_path):
    study = StudyRun(TinyConfig(out=str(tmp_path / "out"), progress=False))
    tasks = [(f"sq{i}.{study.config.tag(version=1)}", (i,)) for i in range(3)]
    rows = study.tasks(square, tasks, desc="squares", shared={"offset": 1})
    assert [r["square"] for r in rows] == [1, 2, 5]
    assert len(list((tmp_path / "out" / "tasks").glob("sq*.json"))) == 3
    assert study.tasks(lambda *a, **k: {}, tasks, desc="again") == rows  # resumed, not rerun
    study.table("squares.csv", rows)
    study.figure(tmp_path / "out" / "figure.png")
    study.summary(["# Squares", "", "done"])
    assert (tmp_path / "out" / "summary.md").read_text() == "# Squares\n\ndone"
    assert [p.rsplit("/", 1)[-1] for p in study.files] == [
        "squares.csv",
        "figure.png",
        "summary.md",
    ]
    assert json.loads((tmp_path / "out" / "tasks" / f"{tasks[0][0]}.json").read_text())["i"] == 0


def test_a_run_refuses_a_bad_config_before_any_work(tmp_path):
    with pytest.raises(InputError, match="n must be at least 1"):
        StudyRun(TinyConfig(out=str(tmp_path / "out"), n=0))
    assert not (tmp_path / "out").exists()
