"""Chapter 5's independent trials: their data, their keys and their plain t intervals.

Covers probaff.experiments.push_models.run (`trial_data`, `TrialTask`, the trials' keys) and
probaff.experiments.push_models.claims over trial rows.
"""

import math

import numpy as np
import pytest
from scipy.stats import t

from probaff.errors import InputError
from probaff.experiments.push_models import PushModelStudyConfig, run
from probaff.experiments.push_models.claims import chapter5_claims
from probaff.experiments.push_models.run import TRIALS, _tag, trial_data


def test_each_trial_simulates_its_own_pushes_apart_from_the_studys():
    config = PushModelStudyConfig(ch5_pushes=30, ch5_trial_test=12)
    seeds = []
    for k in range(3):
        train, test = trial_data(config, k)
        assert (train.scene, train.n, test.n) == ("two_objects", 30, 12)
        assert train.pose_noise is not None and not train.trajectories
        seeds += [train.seed, test.seed]
    assert len(set(seeds)) == 6 and config.seed not in seeds
    other = {c.seed for k in range(3) for c in trial_data(PushModelStudyConfig(seed=1), k)}
    assert not other & set(seeds)  # another study seed, other pushes
    exact = trial_data(PushModelStudyConfig(pose_noise=False), 0)[0]
    assert exact.pose_noise is None


def test_more_trials_only_add_tasks_and_trials_never_refit_the_cross_validation():
    base = PushModelStudyConfig(ch4_pushes=0)
    more = PushModelStudyConfig(ch4_pushes=0, ch5_trials=7, ch5_trial_test=900)
    assert _tag(base, "ch5") == _tag(more, "ch5")  # the folds' keys stay
    assert _tag(base, TRIALS) == _tag(PushModelStudyConfig(ch4_pushes=0, ch5_trials=3), TRIALS)
    assert _tag(base, TRIALS) != _tag(more, TRIALS)  # another held-out size: refit
    folds = PushModelStudyConfig(ch4_pushes=0, ch5_folds=5, methods=("em",))
    assert _tag(folds, TRIALS) == _tag(base, TRIALS)  # folds and VI do not shape a trial
    assert _tag(PushModelStudyConfig(ch5_pushes=99), TRIALS) != _tag(base, TRIALS)


def _trial_row(features, trial, o1_dz):
    rmse = [1.0, o1_dz, 1.0, 1.0, 1.0, 1.0]
    return {"features": features, "method": "em", "M": 3, "repeat": trial, "fold": 0,
            "rmse": rmse, "nlpd": [0.0] * 6}  # fmt: skip


def test_claims_over_trials_take_the_plain_t_interval():
    ratios = [1.05, 1.03, 1.06, 0.995, 1.04]  # gx-eoc's o1 dz RMSE over oc's, per trial
    rows = [_trial_row("oc", k, 2.0) for k in range(5)]
    rows += [_trial_row("gx-eoc", k, 2.0 * r) for k, r in enumerate(ratios)]
    (gate,) = [c for c in chapter5_claims(rows) if c["b"] == "oc, M=3"]
    change = [100 * (r - 1) for r in ratios]
    assert (gate["repeats"], gate["folds"]) == (5, 1)
    assert gate["mean"] == pytest.approx(np.mean(change))
    want = t.ppf(0.975, 4) * np.std(change, ddof=1) / math.sqrt(5)  # no correction
    assert gate["ci95"] == pytest.approx(want)
    assert gate["verdict"] == "refuted" and gate["won"] == pytest.approx(1 / 5)
    # the same values as the 5 folds of one dataset: the corrected interval holds 0
    folds = [{**r, "repeat": 0, "fold": r["repeat"]} for r in rows]
    (cv,) = [c for c in chapter5_claims(folds) if c["b"] == "oc, M=3"]
    assert cv["ci95"] == pytest.approx(want * math.sqrt(1 + 5 / 4))
    assert cv["verdict"] == "not shown"


@pytest.mark.parametrize(
    ("field", "value"),
    [("ch5_trials", -1), ("ch5_trials", 1.5), ("ch5_trials", 100_001), ("ch5_trial_test", 0)],
)
def test_bad_trial_counts_are_refused(field, value):
    with pytest.raises(InputError, match=field):
        run(PushModelStudyConfig(**{field: value}))
