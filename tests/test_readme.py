"""The README's library example runs as written."""

import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

README = Path(__file__).resolve().parents[1] / "README.md"


def _block(heading: str) -> str:
    text = README.read_text()
    section = text.split(f"## {heading}", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_library_example(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    exec(compile(_block("Library example"), "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert out.count("dy_p=") == 3
    assert (tmp_path / "results" / "example" / "manifest.json").is_file()


def test_ci_runs_the_readme_test_command():
    text = README.read_text()
    cmd = re.findall(r"```bash\n(.*?)\n```", text, re.S)[1].strip()
    ci = (README.parent / ".ci" / "run").read_text()
    assert cmd in ci.splitlines()


def test_push_model_example(capsys):
    from probaff._threads import limit_threads

    with limit_threads(1):
        exec(compile(_block("Push models"), "README.md", "exec"), {})
    assert capsys.readouterr().out.split()[0] in ("grow", "grow-copy", "joint", "effects")


def test_modular_model_example(tmp_path, monkeypatch):
    from probaff._threads import limit_threads

    monkeypatch.chdir(tmp_path)
    text = README.read_text().split("## Push models", 1)[1]
    block = re.findall(r"```python\n(.*?)```", text, re.S)[1]
    scope: dict = {}
    with limit_threads(1):
        exec(compile(block, "README.md", "exec"), scope)
    assert scope["push"].is_fitted and (tmp_path / "results" / "ch6_example").is_dir()


def test_scikit_learn_example(capsys):
    from probaff._threads import limit_threads

    with limit_threads(1):
        exec(compile(_block("scikit-learn"), "README.md", "exec"), {})
    assert capsys.readouterr().out.startswith("{'n_experts': 3}")
