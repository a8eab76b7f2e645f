"""The docs' examples run and print what they show.

Each entry point a newcomer calls first carries a short ``>>>`` example in its docstring,
rendered in the API reference; this runs them with the standard `doctest` module, on one torch
thread and one BLAS thread, and fails on any example whose output differs or that raises. The
getting-started page's worked example (a robot's arrays to predictions) runs too.
"""

import contextlib
import doctest
import importlib
import io
import re
import tempfile
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

from probaff._threads import limit_threads

ENTRY_POINTS = (
    "probaff.data.observation_dataset",
    "probaff.data.import_hdf5",
    "probaff.data.PushDataset",
    "probaff.models.MixtureOfGPExperts",
    "probaff.models.fit_em",
    "probaff.models.MixtureOfGPExpertsRegressor",
    "probaff.sim.PushSimulator",
    "probaff.planning.edge_transition",
    "probaff.planning.tool_push.ToolPushPlanner",
    "probaff.perception.scan_segments",
    "probaff.perception.BoostedLabelClassifier",
)
FLAGS = doctest.NORMALIZE_WHITESPACE
GETTING_STARTED = Path(__file__).resolve().parents[1] / "docs" / "getting_started.md"


def _examples(name: str) -> list[doctest.DocTest]:
    """The doctests of the docstring of `name` (the object itself, not its members)."""
    module, _, attr = name.rpartition(".")
    obj = getattr(importlib.import_module(module), attr)
    finder = doctest.DocTestFinder(recurse=False)
    return [t for t in finder.find(obj, name, globs={}) if t.examples]


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_docstring_example_runs(name, tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the examples' mkdtemp() folders
    tests = _examples(name)
    assert tests, f"{name}'s docstring has no >>> example"
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    with limit_threads(1), threadpool_limits(limits=1):
        for test in tests:
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed"


def test_getting_started_worked_example_runs():
    text = GETTING_STARTED.read_text()
    section = text.split("### A worked example", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    out = io.StringIO()
    with limit_threads(1), threadpool_limits(limits=1), contextlib.redirect_stdout(out):
        exec(compile(code, str(GETTING_STARTED), "exec"), {"__name__": "getting_started"})
    error = float(re.search(r"along the push: ([\d.]+) mm", out.getvalue()).group(1))
    assert error < 5.0, out.getvalue()  # the pushes moved the block 0 to 6 cm
