"""Fixtures of the dataset tests: datasets generated on disk, and edited copies of them."""

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from probaff.data import GenerateConfig, generate


@pytest.fixture(scope="session")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """Generate a dataset serially into a fresh temporary folder.

    Returns:
        ``make(config, name, kind=None)``: generates `config` into ``<tmp>/<name>*/ds``
        (``kind`` as in `generate`, e.g. ``"skill"``) and returns that folder.
    """

    def make(config: GenerateConfig, name: str, kind: str | None = None) -> Path:
        out = tmp_path_factory.mktemp(name) / "ds"
        generate(config, out, workers=0, progress=False, kind=kind)
        return out

    return make


@pytest.fixture
def copy_dataset() -> Callable[..., Path]:
    """Copy a dataset folder, with entries of its manifest changed.

    Returns:
        ``copy(source, out, **changes)``: copies the folder `source` to `out`, sets the
        manifest's top-level keys to `changes` (the manifest is left as it is without
        any) and returns `out`.
    """

    def copy(source: Path, out: Path, **changes: Any) -> Path:
        shutil.copytree(source, out)
        if changes:
            manifest = json.loads((out / "manifest.json").read_text())
            manifest.update(changes)
            (out / "manifest.json").write_text(json.dumps(manifest))
        return out

    return copy
