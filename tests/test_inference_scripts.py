"""Every study script in inference/ is thin and has a smoke test."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "inference").glob("*.py"))


def test_every_script_has_a_smoke_test():
    tests = "\n".join(
        p.read_text() for p in (ROOT / "tests").rglob("test_*.py") if p.name != Path(__file__).name
    )
    missing = [s.name for s in SCRIPTS if f"inference/{s.name}" not in tests]
    assert not missing, f"scripts without a smoke test: {missing}"


def test_scripts_are_thin():
    for script in SCRIPTS:
        tree = ast.parse(script.read_text())
        calls_run = any(
            (isinstance(n, ast.Attribute) and n.attr == "run")
            or (isinstance(n, ast.Name) and n.id == "run")
            for n in ast.walk(tree)
        )
        assert calls_run, f"{script.name} must call a run(config) function in probaff"
        assert len(script.read_text().splitlines()) < 120, f"{script.name} holds logic"
