import contextlib
import importlib.util
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import torch


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist, hand out the test modules in the order `pytest_collection_modifyitems`
    leaves them.

    ``--dist loadscope`` gives each worker a whole module at a time, by default the modules
    with the most tests first; a module of a few long tests (the Dask drills, two tests and
    about 90 s) then came last, and one worker ran it while the other had nothing left.
    """
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put the modules with the most ``slow`` tests first, the order of their tests kept.

    Longest first (the rule that balances a few workers best): the long modules run while the
    other worker still has short ones to take, and the suite ends on short ones. The sort is
    stable, so modules of equal count keep the order they were collected in.
    """
    slow: dict[str, int] = {}
    for item in items:
        module = item.nodeid.split("::")[0]
        slow[module] = slow.get(module, 0) + int(item.get_closest_marker("slow") is not None)
    items.sort(key=lambda item: -slow[item.nodeid.split("::")[0]])


@pytest.fixture(autouse=True, scope="session")
def _one_blas_thread() -> Iterator[None]:
    """The BLAS and OpenMP pools at one thread, as torch's (the suite runs one worker a core).

    numpy's, scipy's and scikit-learn's libraries are loaded first, so that the limit reaches
    them; a test that sets its own limit gets this one back after it.
    """
    import scipy.linalg  # noqa: F401
    import sklearn.cluster  # noqa: F401
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


@pytest.fixture(autouse=True)
def _deterministic_threads():
    """Single-threaded torch keeps batched IK bit-reproducible across tests."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def generate_cli() -> Callable[..., int]:
    """Run ``probaff generate`` serially and quietly.

    Returns:
        ``run(scene, n, out, *flags)``: the exit status of ``probaff generate --scene SCENE
        --n N --out OUT --workers 0 --quiet FLAGS...``.
    """

    def run(scene: str, n: int, out: str | os.PathLike[str], *flags: str) -> int:
        from probaff.cli import main

        argv = ["generate", "--scene", scene, "--n", str(n), "--out", str(out)]
        return main([*argv, "--workers", "0", "--quiet", *flags])

    return run


@contextlib.contextmanager
def _benchmark_script(name: str) -> Iterator[ModuleType]:
    """Import ``benchmarks/<name>.py`` as the module `name`; it leaves `sys.modules` after."""
    script = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop(name, None)


@pytest.fixture(scope="session")
def benchmark_script() -> Callable[[str], contextlib.AbstractContextManager[ModuleType]]:
    """Import a benchmark script as a module.

    Returns:
        ``benchmark_script(name)``: a context manager that imports ``benchmarks/<name>.py`` as
        the module `name`, registered in `sys.modules` (its dataclasses need it) until it exits.
    """
    return _benchmark_script


@pytest.fixture
def refused_flags(capsys: pytest.CaptureFixture[str]) -> Callable[..., str]:
    """Check that a script's ``main`` refuses its command line.

    Returns:
        ``refused_flags(main, argv, *needles)``: asserts that ``main(argv)`` returns 2 having
        printed one line on standard error that holds every needle, and returns that line.
    """

    def refused(main: Callable[[list[str]], int], argv: list[str], *needles: str) -> str:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        for needle in needles:
            assert needle in err, err
        return err

    return refused
