"""Helpers of the dataset tests: a dataset folder's files, and its manifest."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def folder_files(root: Path) -> dict[str, bytes]:
    """Every file under `root`: its path relative to `root` -> its bytes."""
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def read_manifest(root: Path) -> dict[str, Any]:
    """The ``manifest.json`` of the dataset folder `root`."""
    manifest: dict[str, Any] = json.loads((root / "manifest.json").read_text())
    return manifest
