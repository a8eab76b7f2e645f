"""benchmarks/estimator_cost.py: both models on the same folds, the ratio line, bad flags."""

import math

import pytest


@pytest.fixture(scope="module")
def cost(benchmark_script):
    with benchmark_script("estimator_cost") as module:
        yield module


def test_both_models_are_scored_on_the_same_rows(cost, capsys):
    rows = cost.compare(folds=2, seed=0, rows=60)
    assert [r["model"] for r in rows] == ["probaff", "sklearn_gpr"]
    for r in rows:
        assert r["cpu_s"] > 0 and r["wall_s"] > 0
        assert 0 < r["rmse"] < 150 and math.isfinite(r["log_density"])
    assert cost.main(["--folds", "2", "--rows", "40"]) == 0
    out = capsys.readouterr().out
    assert "CPU ratio probaff / sklearn_gpr:" in out and "goal: at most 2" in out


@pytest.mark.parametrize(
    ("flags", "word"),
    [(["--folds", "1"], "--folds"), (["--rows", "3"], "--rows"), (["--seed", "-1"], "--seed")],
)
def test_bad_flags_print_one_line_and_exit_2(cost, refused_flags, flags, word):
    refused_flags(cost.main, flags, word)
