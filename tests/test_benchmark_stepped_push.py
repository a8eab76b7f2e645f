"""benchmarks/stepped_push.py: bad flags fail at once in one line; a tiny run writes its table."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "stepped_push.py"


def test_a_bad_flag_prints_one_line_and_exits_2(tmp_path):
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--out", str(tmp_path), "--step-length", "0"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1
    assert "step_length must be a positive finite length" in run.stderr


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--step-length", "nan"], "step_length must be a positive finite length"),
        (["--step-length", "-0.025"], "step_length must be a positive finite length"),
        (["--train", "200", "--test", "80"], "exceed the --n 240 pushes"),
        (["--chain-samples", "1"], "--chain-samples must be at least 2"),
        (["--scene", "chain_3"], "--scene chain_3 places 3 objects"),
    ],
)
def test_bad_flags_are_refused_before_any_work(tmp_path, benchmark_script, flags, message):
    with benchmark_script("stepped_push") as module, pytest.raises(InputError, match=message):
        module.main(["--out", str(tmp_path), *flags])
    assert not (tmp_path / "data").exists()


@pytest.mark.slow
def test_a_tiny_run_writes_its_numbers(tmp_path, benchmark_script):
    data = tmp_path / "pushes"
    generate(GenerateConfig("modular_push", 6, seed=3, hand="compliant"), data, progress=False)
    argv = ["--data", str(data), "--train", "4", "--test", "2", "--gp-max-iter", "2"]
    argv += ["--chain-samples", "2", "--ablation", "--out", str(tmp_path / "out")]
    with benchmark_script("stepped_push") as module:
        assert module.main(argv) == 0
        with pytest.raises(InputError, match=r"does not divide the 0\.35 m push"):
            module.main([*argv, "--step-length", "0.03"])
    result = json.loads((tmp_path / "out" / "stepped_push.json").read_text())
    assert set(result["errors"]) == {
        "stepped_forward",
        "stepped_forward_planned",
        "stepped_backward",
        "whole_push_forward",
        "whole_push_backward",
        "stepped_hand_reaction_only",
        "stepped_link_reaction_only",
    }
    finals = np.load(tmp_path / "out" / "stepped_push_finals.npz")
    assert finals["stepped_backward"].shape == finals["true"].shape == (2, 2, 3)
    assert result["steps_per_push"] == 14 and 0 <= result["reaction"]["share_path_over_1cm"] <= 1
    assert (tmp_path / "out" / "stepped_push.md").read_text().startswith("| model |")
