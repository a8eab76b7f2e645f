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


def test_smoke_run_scores_every_model_on_every_fold(ablation, tmp_path):
    argv = ["--smoke", "--datasets", "synthetic", "--out", str(tmp_path), "--no-progress"]
    assert ablation.main(argv) == 0
    with open(tmp_path / "ablation.csv") as f:
        rows = list(csv.DictReader(f))
    assert {(r["model"], r["fold"]) for r in rows} == {
        (m, str(k)) for m in ablation.MODELS for k in (0, 1)
    }
    assert all(float(r["srmse"]) > 0 and abs(float(r["nlpd"])) < 1e6 for r in rows)
    assert (tmp_path / "ablation.png").stat().st_size > 0
    table = (tmp_path / "ablation.md").read_text()
    assert all(f"| synthetic | {m} |" in table for m in ablation.MODELS)
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
