"""Every notebook runs in smoke mode, checks its headline number there within a stated band,
and is committed without outputs."""

import json
import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

pytestmark = pytest.mark.slow

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_is_stripped(path):
    cells = json.loads(path.read_text())["cells"]
    assert not any(c.get("outputs") for c in cells), f"{path.name} has outputs; strip them"
    first = next(c for c in cells if c["cell_type"] == "code")
    assert 'SMOKE_TEST = "CI" in os.environ' in "".join(first["source"])


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_checks_its_headline_number(path):
    """A code cell asserts the headline value, finite always and within its band in smoke
    mode, and states what smoke mode measured (the run below executes it)."""
    cells = json.loads(path.read_text())["cells"]
    checks = [
        "".join(c["source"])
        for c in cells
        if c["cell_type"] == "code" and "# The headline, checked:" in "".join(c["source"])
    ]
    assert len(checks) == 1, f"{path.name} has no headline check cell"
    assert "measured" in checks[0] and "band" in checks[0]
    assert "isfinite" in checks[0] and "if SMOKE_TEST:\n    assert " in checks[0]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_in_smoke_mode(path, tmp_path, monkeypatch):
    monkeypatch.setenv("CI", "true")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    scratch = tmp_path / "tmp"  # the notebooks' tempfile.mkdtemp() folders, removed with it
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute(env={**os.environ})
