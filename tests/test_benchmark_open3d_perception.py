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
def test_bad_flags_exit_2_with_one_line(bench, refused_flags, argv, name):
    refused_flags(bench.main, argv, name)


@pytest.mark.skipif(importlib.util.find_spec("open3d") is not None, reason="open3d installed")
def test_missing_open3d_exits_2_saying_how_to_install(bench, refused_flags):
    refused_flags(bench.main, ["--scenes", "2"], "pip install open3d-cpu")
