"""The study tests' helpers report failed checks in detail, like the tests themselves."""

import os
from pathlib import Path

import pytest

pytest.register_assert_rewrite("study_helpers")

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def pusht_python() -> str:
    """The Push-T environment's Python, created at the repository root when missing.

    $PROBAFF_PUSHT_PYTHON when set, else ``.venv-pusht`` at the repository root, which is
    created (``python -m probaff.experiments.pusht.env``, from the package index) if missing.
    """
    from probaff.experiments.pusht.env import DEFAULT_VENV, ENV_VAR, create_env

    given = os.environ.get(ENV_VAR)
    if given:
        return given
    python = ROOT / DEFAULT_VENV / "bin" / "python"
    if not python.is_file():
        create_env(ROOT / DEFAULT_VENV)
    return str(python)
