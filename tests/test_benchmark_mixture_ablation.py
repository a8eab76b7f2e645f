"""Smoke test of benchmarks/mixture_ablation.py: every model scored on the same folds."""

import csv

import pytest
import torch
from torch.distributions import Normal

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def ablation(benchmark_script):
    with benchmark_script("mixture_ablation") as module:
        yield module


def test_oracle_takes_the_chosen_component(ablation):
    loc = torch.arange(12, dtype=torch.float64).view(2, 3, 2)
    parts = Normal(loc, torch.ones_like(loc))
    chosen = ablation._oracle(parts, torch.tensor([2, 0]))
    torch.testing.assert_close(chosen.mean, torch.stack([loc[0, 2], loc[1, 0]]))
    assert tuple(chosen.batch_shape) == (2,) and tuple(chosen.event_shape) == (2,)


def test_best_expert_takes_the_mean_nearest_the_target(ablation):
    means = torch.tensor([[[0.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0]]])  # (2, 2, 2)
    y = torch.tensor([[0.9, 0.2], [0.2, 0.9]])
    # scaled, output 0 counts a hundredth as much as output 1: row 0 goes to expert 0
    best = ablation._best_expert(means, y, torch.tensor([10.0, 1.0]))
    torch.testing.assert_close(best, torch.tensor([[0.0, 0.0], [1.0, 1.0]]))
    best = ablation._best_expert(means, y, torch.tensor([1.0, 1.0]))
    torch.testing.assert_close(best, torch.tensor([[1.0, 1.0], [1.0, 1.0]]))


def test_smoke_run_scores_every_model_on_every_fold(ablation, tmp_path):
    argv = ["--smoke", "--datasets", "synthetic", "--out", str(tmp_path), "--no-progress"]
    assert ablation.main(argv) == 0
    with open(tmp_path / "ablation.csv") as f:
        rows = list(csv.DictReader(f))
    assert {(r["model"], r["fold"]) for r in rows} == {
        (m, str(k)) for m in ablation.MODELS for k in (0, 1)
    }
    assert all(float(r["srmse"]) > 0 for r in rows)
    by = {(r["model"], r["fold"]): r for r in rows}
    for r in rows:
        if r["model"] == "em_best_expert":  # chosen by its target: RMSE only
            assert r["nlpd"] == "" and r["alpha"] == ""
        else:
            assert abs(float(r["nlpd"])) < 1e6
    for stacked, base in ablation.STACKED.items():
        for k in ("0", "1"):
            # the stacked point shares its mixture's distribution, not its point
            assert by[stacked, k]["nlpd"] == by[base, k]["nlpd"]
            alpha = [float(a) for a in by[stacked, k]["alpha"].split()]
            assert len(alpha) == 2 and all(0.0 <= a <= 1.0 for a in alpha)
            assert by[base, k]["alpha"] == ""
    # synthetic has 3 regimes: em_m3 is the em fit itself
    assert all(by["em_m3", k]["rmse"] == by["em", k]["rmse"] for k in ("0", "1"))
    assert all(by["em_m3_stacked", k]["rmse"] == by["em_stacked", k]["rmse"] for k in ("0", "1"))
    assert (tmp_path / "ablation.png").stat().st_size > 0
    table = (tmp_path / "ablation.md").read_text()
    assert all(f"| synthetic | {m} |" in table for m in ablation.MODELS)
    assert "| synthetic | em_best_expert |" in table and "| — |" in table
    assert "## synthetic: RMSE per output" in table and "| em_stacked | " in table
    # resumed: the saved folds are read back, not refitted
    before = sorted(p.stat().st_mtime_ns for p in (tmp_path / "tasks").glob("*.json"))
    assert ablation.main(argv) == 0
    after = sorted(p.stat().st_mtime_ns for p in (tmp_path / "tasks").glob("*.json"))
    assert before == after


def test_bad_flags_are_one_line_errors(ablation):
    from probaff.errors import InputError

    with pytest.raises(InputError, match="--datasets"):
        ablation.main(["--datasets", "nope"])
    with pytest.raises(InputError, match="--folds"):
        ablation.main(["--folds", "1"])
