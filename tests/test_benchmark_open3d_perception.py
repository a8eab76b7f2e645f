"""benchmarks/open3d_perception.py: a bad flag, or no Open3D, is one line and exit status 2."""

import importlib.util

import pytest


@pytest.fixture(scope="module")
def bench(benchmark_script):
    with benchmark_script("open3d_perception") as module:
        yield module


@pytest.mark.parametrize(
    ("argv", "name"), [(["--scenes", "1"], "--scenes"), (["--eps", "-0.1"], "--eps")]
)
def test_bad_flags_exit_2_with_one_line(bench, capsys, argv, name):
    assert bench.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and name in err


@pytest.mark.skipif(importlib.util.find_spec("open3d") is not None, reason="open3d installed")
def test_missing_open3d_exits_2_saying_how_to_install(bench, capsys):
    assert bench.main(["--scenes", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install open3d-cpu" in err
