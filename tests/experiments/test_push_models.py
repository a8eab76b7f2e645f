"""The push-model study runs end to end on a shrunken configuration and resumes.

Covers probaff.experiments.push_models.claims, probaff.experiments.push_models.config,
probaff.experiments.push_models.figures, probaff.experiments.push_models.report,
probaff.experiments.push_models.run.
"""

import pytest
from study_helpers import assert_resumes, assert_wrote, run_smoke

from probaff.errors import InputError
from probaff.experiments.push_models import PushModelStudyConfig, run

pytestmark = pytest.mark.slow


def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "pm"
    files = run_smoke("push_models", out)
    ch5 = ("ch5_summary.csv", "ch5_claims.csv", "ch5_rmse_vs_M.png", "ch5_clusters.png")
    ch5 += ("ch5_ard_relevance.png",)
    assert_wrote(files, out, (*ch5, "ch4_summary.csv", "ch4_clusters.png", "summary.md"))
    text = (out / "summary.md").read_text()
    assert "| ocx | em | 2 |" in text and "| gx-eoc | vi | 1 |" in text
    assert "- **M > 1 beats M = 1 on RMSE**: 2 comparisons over every M" in text  # judged
    tasks = sorted((out / "tasks").glob("*.json"))
    assert_resumes(lambda: run_smoke("push_models", out), tasks)  # resumes: no refits


def test_bad_config():
    with pytest.raises(InputError, match="unknown chapter 5 features"):
        run(PushModelStudyConfig(ch5_features=("xyz",)))
    with pytest.raises(InputError, match="unknown method"):
        run(PushModelStudyConfig(methods=("mcmc",)))
