"""The shape of the package: layers, cycles, module and function sizes, faces, mirrored tests.

Read from the source text (``ast``), not by importing, so a violation is reported even where
it would not fail at import time. ``python tests/test_structure.py`` prints the measures.

Layers, low to high; a module may import from its own subpackage and from lower layers only:

    errors, grid, affordance_labels, _checks, _io, _threads, _dask, _cli_errors
    models | maps          (libraries with no simulator inside; neither imports the other)
    sim
    data
    perception
    features
    planning
    eval
    experiments
    demo
    cli
"""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "probaff"
TESTS = ROOT / "tests"

LAYERS: dict[str, int] = {
    "errors": 0,
    "grid": 0,
    "affordance_labels": 0,
    "_checks": 0,
    "_io": 0,
    "_threads": 0,
    "_dask": 0,
    "_cli_errors": 0,
    "_registry": 0,
    "models": 1,
    "maps": 1,
    "sim": 2,
    "data": 3,
    "perception": 4,
    "features": 5,
    "planning": 6,
    "eval": 7,
    "experiments": 8,
    "demo": 9,
    "cli": 10,
}
"""Layer of each top-level module or subpackage of probaff."""

MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 100
MAX_EXPORTS = {"planning": 35, "sim": 35}


def _modules() -> dict[str, Path]:
    """Dotted name -> file of every module of the package."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(path: Path) -> Iterator[str]:
    """Every probaff module `path` imports (function-local imports too)."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.split(".")[0] != "probaff":
                continue
            for alias in node.names:
                name = f"{node.module}.{alias.name}"
                yield name if name in MODULES else node.module
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names if a.name.split(".")[0] == "probaff")


def import_graph() -> dict[str, set[str]]:
    """Module -> the probaff modules it imports."""
    return {m: {d for d in _imports(p) if d in MODULES and d != m} for m, p in MODULES.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs that import from a higher layer, or across one layer."""
    bad = []
    for src, deps in graph.items():
        a = _top(src)
        if a == "__init__":
            continue
        for dst in deps:
            b = _top(dst)
            if b == a or b == "__init__" or LAYERS[a] == LAYERS[b] == 0:
                continue
            if LAYERS[b] >= LAYERS[a]:
                bad.append((src, dst))
    return sorted(bad)


def long_functions() -> list[tuple[int, str]]:
    """(lines, module:function) of every function longer than `MAX_FUNCTION_LINES`."""
    out = []
    for m, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    out.append((n, f"{m}:{node.name}"))
    return sorted(out, reverse=True)


def module_lines() -> list[tuple[int, str]]:
    """(lines, module) of every module, longest first."""
    return sorted(((len(p.read_text().splitlines()), m) for m, p in MODULES.items()), reverse=True)


def subpackages() -> list[str]:
    """Names of probaff's subpackages."""
    return sorted(p.parent.name for p in PACKAGE.glob("*/__init__.py"))


def untested_modules() -> list[str]:
    """Modules with no test file of their name and no test file that names them as covered.

    A module ``probaff/x/y.py`` is covered by ``tests/x/test_y.py`` or ``tests/x/test_x_y.py``
    (or, for a top-level ``probaff/y.py``, ``tests/test_y.py``), or by any test file whose
    text names its dotted path (``probaff.x.y``), its file (``probaff/x/y.py``) or imports
    it by name (``from probaff.x import y``).
    """
    texts = {p: p.read_text() for p in TESTS.rglob("test_*.py")}
    missing = []
    for m, path in MODULES.items():
        if path.name == "__init__.py":
            continue
        parts = m.split(".")[1:]
        folder = TESTS.joinpath(*parts[:-1])
        names = {f"test_{parts[-1].lstrip('_')}.py"}
        if len(parts) > 1:
            names.add(f"test_{parts[-2]}_{parts[-1].lstrip('_')}.py")
        if any((folder / n).exists() for n in names):
            continue
        rel = path.relative_to(ROOT).as_posix()
        parent, _, leaf = m.rpartition(".")
        by_name = re.compile(rf"from {re.escape(parent)} import [^\n]*\b{leaf}\b")
        if any(m in t or rel in t or by_name.search(t) for t in texts.values()):
            continue
        missing.append(m)
    return missing


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_layers_import_downward_only():
    assert set(LAYERS) >= {_top(m) for m in MODULES} - {"__init__"}, "a module has no layer"
    assert upward_imports(import_graph()) == []


def test_modules_and_functions_are_small():
    assert [x for x in module_lines() if x[0] > MAX_MODULE_LINES] == []
    assert long_functions() == []


@pytest.mark.parametrize("name", subpackages())
def test_faces_are_small(name):
    """Each face names what exists, and is small (ruff's RUF022 keeps every `__all__` sorted)."""
    module = importlib.import_module(f"probaff.{name}")
    face = list(module.__all__)
    assert len(set(face)) == len(face) and all(hasattr(module, n) for n in face)
    assert len(face) <= MAX_EXPORTS.get(name, 60), f"probaff.{name} exports {len(face)} names"


def test_package_docstring_names_every_subpackage():
    import probaff

    doc = probaff.__doc__ or ""
    for name in subpackages():
        assert f"    {name}:" in doc, f"probaff's docstring does not describe {name}"


def test_every_module_has_a_test():
    assert untested_modules() == []


if __name__ == "__main__":
    graph = import_graph()
    print(f"modules: {len(MODULES)}")
    print(f"import cycles: {cycles(graph)}")
    print(f"upward imports: {upward_imports(graph)}")
    print(f"largest modules: {module_lines()[:5]}")
    print(f"functions over {MAX_FUNCTION_LINES} lines: {long_functions()}")
    for name in subpackages():
        face = getattr(importlib.import_module(f"probaff.{name}"), "__all__", [])
        print(f"probaff.{name} exports {len(face)} names")
    print(f"modules without a test: {untested_modules()}")


def test_no_patch_or_backup_leftovers_are_tracked():
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():  # an installed copy: nothing is tracked
        pytest.skip("not a git checkout")
    tracked = (
        subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True)
        .stdout.decode()
        .split("\0")
    )
    leftovers = [p for p in tracked if p.endswith((".rej", ".orig", ".bak"))]
    assert leftovers == [], f"patch or backup leftovers tracked in git: {leftovers}"
