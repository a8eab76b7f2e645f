"""The push-model study runs end to end on a shrunken configuration and resumes.

Covers probaff.experiments.push_models.claims, probaff.experiments.push_models.config,
probaff.experiments.push_models.figures, probaff.experiments.push_models.report,
probaff.experiments.push_models.run.
"""

import pytest
from study_helpers import assert_resumes, assert_wrote, rerun_smoke, run_smoke

from probaff.errors import InputError
from probaff.experiments.push_models import PushModelStudyConfig, run

pytestmark = pytest.mark.slow


def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "pm"
    files = run_smoke("push_models", out)
    ch5 = ("ch5_summary.csv", "ch5_claims.csv", "ch5_rmse_vs_M.png", "ch5_clusters.png")
    ch5 += ("ch5_ard_relevance.png",)
    trials = ("ch5_trials.csv", "ch5_trial_summary.csv", "ch5_trial_claims.csv")
    assert_wrote(files, out, (*ch5, *trials, "ch4_summary.csv", "ch4_clusters.png", "summary.md"))
    text = (out / "summary.md").read_text()
    assert "| ocx | em | 2 |" in text and "| gx-eoc | vi | 1 |" in text
    assert "- **M > 1 beats M = 1 on RMSE**: 2 comparisons over every M" in text  # judged
    trial = text[text.index("## Chapter 5 on fresh data: 2 independent trials") :]
    assert "- **M > 1 beats M = 1 on RMSE**: 2 comparisons over every M" in trial
    assert len(list((out / "tasks").glob("ch5-trials.t*.json"))) == 2
    tasks = sorted((out / "tasks").glob("*.json"))
    assert_resumes(lambda: rerun_smoke("push_models", out), tasks)  # resumes: no refits


def test_bad_config():
    with pytest.raises(InputError, match="unknown chapter 5 features"):
        run(PushModelStudyConfig(ch5_features=("xyz",)))
    with pytest.raises(InputError, match="unknown method"):
        run(PushModelStudyConfig(methods=("mcmc",)))


def test_repeats_add_splits_and_keep_one_runs_keys():
    from types import SimpleNamespace

    import numpy as np
    from sklearn.model_selection import KFold

    from probaff.experiments.push_models.run import _tasks

    features = SimpleNamespace(groups={"o": slice(0, 2)})
    data = (features, np.zeros((12, 6)))
    configs = {"o": (("o",), ("o",))}

    def keyed(repeats):
        config = PushModelStudyConfig(ch5_folds=3, ch5_repeats=repeats, ch4_pushes=0)
        return {key: task for key, (task,) in _tasks(config, "ch5", data, configs, ())}

    one, three = keyed(1), keyed(3)
    assert len(one) == 3 and len(three) == 9
    assert set(one) <= set(three)  # a repeated run resumes one run's tasks
    for (_, test), task in zip(
        KFold(3, shuffle=True, random_state=0).split(data[1]), one.values(), strict=True
    ):
        assert task.repeat == 0 and np.array_equal(np.sort(task.test), np.sort(test))
    later = [task for key, task in three.items() if key not in one]
    assert sorted({t.repeat for t in later}) == [1, 2]
    for r in (1, 2):  # each repeat is a partition of the rows, shuffled anew
        tests = [t.test for t in later if t.repeat == r]
        assert np.array_equal(np.sort(np.concatenate(tests)), np.arange(12))
    assert not np.array_equal(later[0].test, one[next(iter(one))].test)
    with pytest.raises(InputError, match="ch5_repeats"):
        run(PushModelStudyConfig(ch5_repeats=0))
