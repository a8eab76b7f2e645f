"""Push-T training pushes chosen by information gain (the model's predictive variance).

- `ActiveOptions` refuses a budget that is not a positive integer, and its other bad settings;
- `predictive_spread` against the variances written out by hand;
- `variance_chooser` against the argmax of those variances over the same feasible candidates;
- `reduction_chooser` against the argmax of the integrated variance reduction over the same
  feasible candidates and the same draw of the planner's queries;
- `record_chosen` in gym-pusht: random pushes first, then chosen ones after a refit, the same
  random start as the random strategy on the same seed.

Covers probaff.experiments.pusht.active.
"""

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff.errors import InputError
from probaff.experiments.pusht.active import (
    ActiveOptions,
    predictive_spread,
    primitive_features,
    record_chosen,
    reduction_chooser,
    variance_chooser,
)
from probaff.experiments.pusht.env import PushTWorker
from probaff.experiments.pusht.geometry import GYM_TEE
from probaff.experiments.pusht.models import LearnedModel, QuasiStaticTee
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    feasible_starts,
    sample_primitives,
)
from probaff.models import EMOptions, MixtureOfGPExperts, fit_em
from probaff.models.mixture import integrated_variance_reduction


@pytest.mark.parametrize("budget", [0, -3, 2.5, True, "60", None])
def test_a_budget_that_is_not_a_positive_integer_is_refused(budget):
    with pytest.raises(InputError, match="active-learning budget must be a positive integer"):
        ActiveOptions(budget=budget)


def test_other_bad_settings_are_refused():
    with pytest.raises(InputError, match="start"):
        ActiveOptions(budget=8, start=10)
    with pytest.raises(InputError, match="strategy"):
        ActiveOptions(budget=20, strategy="entropy")
    with pytest.raises(InputError, match="refit_every"):
        ActiveOptions(budget=20, refit_every=0)
    with pytest.raises(InputError, match="reference"):
        ActiveOptions(budget=20, reference=0)


class _Wide:
    """A model whose predictive spread grows with the push's travel (the 5th feature)."""

    def predict(self, X):
        X = torch.as_tensor(X, dtype=torch.float64)
        scale = torch.stack([X[:, 4] / 10, torch.ones(len(X)), X[:, 0].abs() / 1000 + 1e-3], -1)
        return Independent(Normal(torch.zeros_like(scale), scale), 1)


def test_spread_is_the_summed_variance_with_the_turn_as_an_arc():
    qs = QuasiStaticTee(sigma=np.array([2.0, 3.0, 0.05]))
    X = np.zeros((4, 5))
    expected = 4.0 + 9.0 + (GYM_TEE.radius * 0.05) ** 2
    np.testing.assert_allclose(predictive_spread(qs, X), expected, rtol=1e-12)
    X = np.column_stack([np.arange(3.0) * 10, np.zeros((3, 3)), [10.0, 40.0, 20.0]])
    want = (X[:, 4] / 10) ** 2 + 1 + (GYM_TEE.radius * (X[:, 0] / 1000 + 1e-3)) ** 2
    np.testing.assert_allclose(predictive_spread(_Wide(), X), want, rtol=1e-12)


def test_the_chooser_takes_the_feasible_push_of_largest_variance():
    s = PrimitiveSettings()
    pose, agent = np.array([256.0, 300.0, 0.4]), np.array([100.0, 100.0])
    for seed in range(3):
        chosen = variance_chooser(_Wide(), 24, s)(np.random.default_rng(seed), pose, agent)
        prims = sample_primitives(np.random.default_rng(seed), 24, s)
        ok = prims[feasible_starts(pose, prims, s)]
        X = primitive_features(ok, s)
        want = (X[:, 4] / 10) ** 2 + 1 + (GYM_TEE.radius * (np.abs(X[:, 0]) / 1000 + 1e-3)) ** 2
        np.testing.assert_array_equal(chosen, ok[int(np.argmax(want))])


def test_chosen_pushes_follow_a_random_start_in_gym_pusht(pusht_python):
    s = PrimitiveSettings()
    em = EMOptions(max_iter=1, n_restarts=1, split_merge=0)
    common = {"budget": 8, "start": 5, "refit_every": 3, "pool": 8, "experts": 1, "em": em}
    w = PushTWorker(pusht_python)
    try:
        active = record_chosen(w, 3, ActiveOptions(**common), s)
        random = record_chosen(w, 3, ActiveOptions(**common, strategy="random"), s)
    finally:
        w.close()
    assert len(active["before"]) == len(random["before"]) == 8
    assert active["refits"] == [5] and random["refits"] == []
    assert active["before"][:5] == random["before"][:5]  # the same random start
    assert active["dist"][:5] == random["dist"][:5]
    assert active["dist"][5:] != random["dist"][5:]  # then chosen, not random


@pytest.mark.parametrize("measure", ["variance", "information"])
def test_the_reduction_chooser_takes_the_push_that_informs_the_queries_most(measure):
    s = PrimitiveSettings()
    prims = sample_primitives(np.random.default_rng(9), 40, s)
    X = primitive_features(prims, s)
    Y = np.column_stack([X[:, 4] * X[:, 2], X[:, 4] * X[:, 3], X[:, 0] / 100])
    mixture = MixtureOfGPExperts(2)
    fit_em(mixture, torch.as_tensor(X), torch.as_tensor(Y), n_restarts=1, split_merge=0)
    model = LearnedModel("moe", mixture)
    pose, agent = np.array([256.0, 300.0, 0.4]), np.array([100.0, 100.0])
    for seed in range(2):
        chosen = reduction_chooser(model, 24, s, reference=32, measure=measure)(
            np.random.default_rng(seed), pose, agent
        )
        rng = np.random.default_rng(seed)
        cand = sample_primitives(rng, 24, s)
        ok = cand[feasible_starts(pose, cand, s)]
        queries = primitive_features(sample_primitives(rng, 32, s), s)
        weights = [1.0, 1.0, GYM_TEE.radius**2] if measure == "variance" else None
        score = integrated_variance_reduction(
            mixture, primitive_features(ok, s), queries, output_weights=weights, measure=measure
        )
        np.testing.assert_array_equal(chosen, ok[int(torch.argmax(score))])
