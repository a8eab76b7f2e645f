"""The push-model study runs end to end on a shrunken configuration and resumes.

Covers probaff.experiments.push_models.config, probaff.experiments.push_models.figures,
probaff.experiments.push_models.report, probaff.experiments.push_models.run.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from probaff.errors import InputError
from probaff.experiments.push_models import PushModelStudyConfig, run

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "pm"
    cmd = [sys.executable, str(ROOT / "inference/push_models.py"), "--smoke", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    files = json.loads(proc.stdout)["files"]
    for name in (
        "ch5_summary.csv",
        "ch5_rmse_vs_M.png",
        "ch5_clusters.png",
        "ch5_ard_relevance.png",
        "ch4_summary.csv",
        "ch4_clusters.png",
        "summary.md",
    ):
        assert str(out / name) in files and (out / name).stat().st_size > 0
    text = (out / "summary.md").read_text()
    assert "| ocx | em | 2 |" in text and "| gx-eoc | vi | 1 |" in text
    tasks = sorted((out / "tasks").glob("*.json"))
    stamp = [p.stat().st_mtime_ns for p in tasks]
    subprocess.run(cmd, capture_output=True, text=True, check=True)  # resumes: no refits
    assert [p.stat().st_mtime_ns for p in tasks] == stamp


def test_bad_config():
    with pytest.raises(InputError, match="unknown chapter 5 features"):
        run(PushModelStudyConfig(ch5_features=("xyz",)))
    with pytest.raises(InputError, match="unknown method"):
        run(PushModelStudyConfig(methods=("mcmc",)))
