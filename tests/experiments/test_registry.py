"""Studies are found folder by folder, and ``probaff study NAME`` runs any of them.

Covers probaff.experiments.registry. A new study is its folder (with its test and notebook):
the tests write one to tmp_path, as a package of its own and as a folder on
`probaff.experiments`'s path, and find it with nothing else edited.
"""

import importlib
import json
import re
import sys
import textwrap
from pathlib import Path

import pytest

import probaff.experiments
from probaff.cli import main
from probaff.errors import ConfigError, InputError
from probaff.experiments import STUDIES, Study, UnknownStudyError, discover_studies, study_main

EXPERIMENTS = Path(probaff.experiments.__file__).parent

TINY = '''
"""A study of squares (a test's study)."""

from dataclasses import dataclass
from typing import Any, ClassVar

from probaff.eval.tables import markdown_table
from probaff.experiments.base import StudyConfig, StudyRun

SMOKE = {"n": 2, "progress": False}


@dataclass(frozen=True, kw_only=True)
class Config(StudyConfig):
    """Squares.

    Attributes:
        n: Numbers squared.
    """

    out: str = "results/squares"
    n: int = 5

    SMOKE: ClassVar[dict[str, Any]] = SMOKE


def square(i: int) -> dict[str, Any]:
    return {"i": i, "square": i * i}


def run(config: Config) -> dict[str, Any]:
    study = StudyRun(config)
    tag = study.config.tag(version=1)
    rows = study.tasks(square, [(f"i{i}.{tag}", (i,)) for i in range(config.n)], desc="sq")
    study.table("squares.csv", rows)
    study.summary(["# Squares", "", markdown_table(rows, ["i", "square"])])
    return {"rows": rows, "files": study.files}
'''


@pytest.fixture
def tiny(tmp_path, monkeypatch):
    """A folder of studies in tmp_path holding one study, ``squares``, importable.

    The package is named after tmp_path, so that each test imports its own.
    """
    package = "studies_" + re.sub(r"\W", "_", tmp_path.name)
    root = tmp_path / package
    (root / "squares").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "squares" / "__init__.py").write_text(textwrap.dedent(TINY))
    (root / "_helpers").mkdir()  # private folders are not studies
    (root / "_helpers" / "__init__.py").write_text("")
    (root / "notes").mkdir()  # nor folders without a package
    monkeypatch.syspath_prepend(str(tmp_path))
    return discover_studies(package)


def test_the_studies_of_probaff_are_its_study_folders():
    folders = sorted(
        p.parent.name
        for p in EXPERIMENTS.glob("*/__init__.py")
        if not p.parent.name.startswith("_")
    )
    assert list(STUDIES) == folders and len(STUDIES) >= 6
    for name in STUDIES:
        study = STUDIES[name]
        assert study.__name__ == STUDIES.study(name).package == f"probaff.experiments.{name}"
        assert study.run and study.SMOKE is study.Config.SMOKE
    # its repr (shown by the API reference) names the package and the studies, no address
    assert repr(STUDIES) == f"StudyRegistry('probaff.experiments', {folders!r})"


def test_every_study_refuses_a_config_of_another_kind_by_name(tmp_path):
    names = list(STUDIES)
    for i, name in enumerate(names):
        study = STUDIES[name]
        other = STUDIES[names[(i + 1) % len(names)]].Config(out=str(tmp_path / "other"))
        for bad in (None, "config.yaml", {"seed": 0}, other):
            with pytest.raises(InputError, match=rf"^config must be a {study.Config.__name__} "):
                study.run(bad)
    assert not (tmp_path / "other").exists()  # refused before any work


def test_a_new_study_folder_beside_the_others_is_found(tmp_path, monkeypatch, capsys):
    """A study folder on `probaff.experiments`'s path: ``probaff study`` runs it, unedited."""
    (tmp_path / "squares").mkdir()
    (tmp_path / "squares" / "__init__.py").write_text(textwrap.dedent(TINY))
    monkeypatch.setattr(
        probaff.experiments, "__path__", [*probaff.experiments.__path__, str(tmp_path)]
    )
    try:
        assert "squares" in STUDIES and list(STUDIES)[-1] == "squares"
        out = tmp_path / "out"
        assert main(["study", "squares", "--smoke", "--out", str(out)]) == 0
        assert json.loads(capsys.readouterr().out)["files"][0] == str(out / "squares.csv")
    finally:
        STUDIES.unregister("squares")
        sys.modules.pop("probaff.experiments.squares", None)


def test_a_new_study_is_one_folder(tiny, tmp_path, capsys):
    assert list(tiny) == ["squares"] and "squares" in tiny
    out = tmp_path / "out"
    assert study_main(["squares", "--smoke", "--out", str(out)], studies=tiny) == 0
    files = json.loads(capsys.readouterr().out)["files"]
    assert files == [str(out / "squares.csv"), str(out / "summary.md")]
    assert "| 1 | 1 |" in (out / "summary.md").read_text()  # n = 2 under --smoke
    assert study_main(["squares", "--n", "3", "--out", str(out)], studies=tiny) == 0
    assert "| 2 | 4 |" in (out / "summary.md").read_text()


def test_bad_names_and_flags_print_one_line(tiny, tmp_path, capsys):
    assert study_main(["cubes"], studies=tiny) == 2
    assert capsys.readouterr().err == (
        "probaff study cubes: error: unknown study 'cubes'; choose one of squares.\n"
    )
    assert study_main(["squares", "--seed", "-1", "--out", str(tmp_path)], studies=tiny) == 2
    assert capsys.readouterr().err == (
        "probaff study squares: error: seed must be an integer >= 0, got -1.\n"
    )
    assert study_main(["squares", "--n", "x"], studies=tiny) == 2  # argparse's own message
    assert "argument --n: invalid int value: 'x'" in capsys.readouterr().err
    assert study_main([], studies=tiny) == 2
    assert "studies: squares" in capsys.readouterr().out
    assert study_main(["--help"], studies=tiny) == 0


def test_a_real_study_refuses_a_bad_flag_before_any_work(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["push_models", "--smoke", "--gate", "bar", "--out", str(out)]
    assert study_main(argv) == 2
    assert capsys.readouterr().err == (
        "probaff study push_models: error: unknown gate 'bar'; use 'linear' or 'fourier'.\n"
    )
    assert not out.exists()


def test_a_folder_without_the_study_face_is_refused(tiny):
    (tiny.folders[0] / "broken").mkdir()
    (tiny.folders[0] / "broken" / "__init__.py").write_text("x = 1\n")
    with pytest.raises(InputError, match=r"does not name \['Config', 'SMOKE', 'run'\]"):
        tiny["broken"]


def test_unknown_and_duplicate_study_names_are_refused_by_name(tiny):
    with pytest.raises(UnknownStudyError, match=r"unknown study 'nothing'; studies: \['squares'\]"):
        tiny["nothing"]
    with pytest.raises(KeyError):  # a Mapping's miss, too
        tiny["nothing"]
    assert tiny.get("nothing") is None and "nothing" not in tiny
    with pytest.raises(InputError, match="study 'squares' is registered already"):
        tiny.register(Study("squares", "elsewhere.squares"))
    cubes = tiny.register(Study("cubes", f"{tiny.package}.squares"))
    assert list(tiny) == ["squares", "cubes"] and tiny["cubes"].SMOKE == {"n": 2, "progress": False}
    assert tiny.unregister("cubes") is cubes and list(tiny) == ["squares"]
    with pytest.raises(InputError, match="must be an identifier"):
        Study("two words", "x")


def test_two_study_folders_of_one_name_are_refused(tiny, tmp_path, monkeypatch):
    other = tmp_path / "other"
    (other / "squares").mkdir(parents=True)
    (other / "squares" / "__init__.py").write_text("")
    package = importlib.import_module(tiny.package)
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(other)])
    with pytest.raises(ConfigError, match=r"study 'squares' is a folder in both .* rename one"):
        list(tiny)
