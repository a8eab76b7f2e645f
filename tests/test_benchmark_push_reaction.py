"""benchmarks/push_reaction.py: bad flags are refused before any work; the numbers add up."""

import json

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.data.store import load_dataset
from probaff.errors import ConfigError, InputError


@pytest.mark.parametrize(
    ("flags", "error", "message"),
    [
        (["--threshold", "0"], InputError, "--threshold must be a positive finite length"),
        (["--threshold", "nan"], InputError, "--threshold must be a positive finite length"),
        (["--n", "0"], InputError, "--n must be a positive integer"),
        (["--scene", "nope"], ConfigError, "unknown scene 'nope'.*resistance_push"),
    ],
)
def test_bad_flags_are_refused_before_any_work(tmp_path, benchmark_script, flags, error, message):
    with benchmark_script("push_reaction") as module, pytest.raises(error, match=message):
        module.main(["--out", str(tmp_path), *flags])
    assert not (tmp_path / "data").exists()


def test_a_wall_push_dataset_gives_consistent_shares(tmp_path, benchmark_script):
    data = tmp_path / "pushes"
    generate(GenerateConfig("resistance_wall", 3, seed=2, hand="compliant"), data, progress=False)
    with benchmark_script("push_reaction") as module:
        assert module.main(["--data", str(data), "--out", str(tmp_path / "out")]) == 0
        react = module.push_reactions(load_dataset(data))
    result = json.loads((tmp_path / "out" / "push_reaction.json").read_text())
    summary = result["datasets"]["pushes"]
    assert result["threshold_m"] == 0.01 and result["hands"]["pushes"]["mode"] == "compliant"
    assert summary["all"]["path"]["pushes"] == 3
    # the largest reaction along the path is at least the one at its end
    assert np.all(react["path"] >= react["end"] - 1e-12)
    assert summary["all"]["path"]["share_over"] == pytest.approx(np.mean(react["path"] > 0.01))
    assert summary["all"]["path"]["max_mm"] == pytest.approx(1000 * react["path"].max())
    groups = summary["by_met"].values()
    assert sum(g["path"]["pushes"] for g in groups) == 3
    assert (tmp_path / "out" / "push_reaction.md").read_text().startswith("| data |")
