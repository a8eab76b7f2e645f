"""EM that cannot lose to a smaller model: initialisations, restarts, split/merge, annealing.

Covers probaff.models.mixture.em (the fits), probaff.models.mixture.em_run (one run) and
probaff.models.mixture.em_starts (the starts of one mixture size).
"""

import copy
import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.features import chapter5_features
from probaff.models import MIXTURE_GP, GPOptions, MixtureOfGPExperts, fit_em, fit_em_path
from probaff.models.initialization import initial_responsibilities, split_responsibilities
from probaff.models.mixture.em_run import EMRun, loo_terms
from probaff.models.mixture.em_starts import _copy_state, _objective
from probaff.models.options import EMOptions
from probaff.models.synthetic import piecewise_1d, softmax_regimes

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("single_thread")]

# Cheap settings for tests whose point is not the default's robustness.
FAST = {"max_iter": 4, "warm_max_iter": 8, "gp_max_iter": 25}


def _ch5(tmp_path_factory, n=72):
    root = tmp_path_factory.mktemp("ch5") / "data"
    ds = generate(GenerateConfig("two_objects", n, seed=3), root, workers=0, progress=False)
    features = chapter5_features(ds)
    y = ds["effect"][:, :2].reshape(len(ds), 6)
    return features, y


def _assert_monotone(path, tol):
    objectives = [path[m][1].best for m in sorted(path)]
    for m, (a, b) in enumerate(itertools.pairwise(objectives), start=2):
        assert b >= a - tol, (m, objectives)


def test_objective_never_falls_as_experts_are_added_on_chapter5_folds(tmp_path_factory):
    features, y = _ch5(tmp_path_factory)
    template = MixtureOfGPExperts(
        1,
        groups=features.groups,
        gate_features=("f_o", "f_c"),
        expert_features=("f_o", "f_c"),
    )  # the experts' default settings, MIXTURE_GP: the length-scale prior on
    folds = np.array_split(np.random.default_rng(0).permutation(len(y)), 3)
    for test in folds:
        train = np.setdiff1d(np.arange(len(y)), test)
        path = fit_em_path(
            template,
            features.values[train],
            y[train],
            range(1, 7),
            n_restarts=2,
            split_merge=1,
            **FAST,
        )
        assert sorted(path) == [1, 2, 3, 4, 5, 6]
        _assert_monotone(path, tol=1e-6 * len(train))
        for m, (model, history) in path.items():
            assert model.n_experts == m and history.responsibilities.shape == (len(train), m)
            assert math.isfinite(history.best)


def test_objective_never_falls_on_synthetic_regimes():
    x, y, _ = softmax_regimes(150, seed=2)
    path = fit_em_path(
        MixtureOfGPExperts(1, gate_features=[0, 1]), x, y, range(1, 7), init="grow", **FAST
    )
    _assert_monotone(path, tol=1e-6 * len(x))
    assert path[3][1].best > path[1][1].best + 0.5 * len(x)  # three regimes beat one GP


def test_copied_state_has_exactly_the_smaller_objective():
    x, y, _ = piecewise_1d(60, seed=1)
    small = MixtureOfGPExperts(2)
    fit_em(small, x, y, init="effects", n_restarts=1, **FAST)
    for target in (0, 1):
        grown = _copy_state(small, target, x, y)
        assert grown.n_experts == 3
        assert _objective(grown, x, y) == pytest.approx(_objective(small, x, y), abs=1e-8)
        torch.testing.assert_close(grown.predict(x).log_prob(y), small.predict(x).log_prob(y))


def test_default_em_finds_the_regimes_a_softmax_gate_decides():
    """Regimes overlap in effect space; only the gate's inputs tell them apart."""
    x, y, labels = softmax_regimes(400, seed=0)
    xt, yt, _ = softmax_regimes(1000, seed=1)
    single = MixtureOfGPExperts(1)  # gp=MIXTURE_GP: the length-scale prior on
    fit_em(single, x, y)
    truth = MixtureOfGPExperts(3, gate_features=[0, 1])
    best_true = fit_em(truth, x, y, init=torch.nn.functional.one_hot(labels, 3).double()).best
    model = MixtureOfGPExperts(3, gate_features=[0, 1])
    history = fit_em(model, x, y)
    assert history.best >= best_true - 0.02 * abs(best_true), (history.best, best_true)
    ratio = (model.predict(xt).mean - yt).square().mean(0).sqrt() / (
        single.predict(xt).mean - yt
    ).square().mean(0).sqrt()
    assert float(ratio.mean()) <= 0.7, ratio
    # the thesis's start (a GMM on the effects) cannot see these regimes
    effects = MixtureOfGPExperts(3, gate_features=[0, 1])
    assert fit_em(
        effects, x, y, init="effects", n_restarts=1, split_merge=0
    ).best < history.best - 0.1 * len(x)


def test_named_initialisations_and_their_candidates():
    x, y, _ = piecewise_1d(90, seed=2)
    for init in ("effects", "joint", "grow"):
        history = fit_em(MixtureOfGPExperts(3), x, y, init=init, n_restarts=2, **FAST)
        assert history.init.startswith(init.split("-")[0]) or history.init == "grow-copy"
        expected = 1 if init == "grow" else 2
        assert len(history.candidates) == expected
    auto = fit_em(MixtureOfGPExperts(3), x, y, n_restarts=3, **FAST)
    assert [c[0] for c in auto.candidates] == ["grow", "joint", "effects"]
    assert auto.best == max(c[2] for c in auto.candidates) or auto.split_merge


def test_finishing_more_screened_starts_never_lowers_the_objective():
    x, y, _ = piecewise_1d(60, seed=4)
    one, two = (
        fit_em(MixtureOfGPExperts(3), x, y, init="effects", n_restarts=3, n_finish=k, **FAST)
        for k in (1, 2)
    )
    assert len(one.candidates) == len(two.candidates) == 3
    assert two.best >= one.best


def test_initial_responsibilities_and_split():
    x, y, _labels = softmax_regimes(200, seed=4)
    for init in ("effects", "joint"):
        r = initial_responsibilities(init, x[:, :2], y, 3, seed=0)
        assert r.shape == (200, 3)
        torch.testing.assert_close(r.sum(1), torch.ones(200, dtype=torch.float64))
    r = torch.ones(200, 1, dtype=torch.float64)
    split = split_responsibilities(r, 0, x[:, :2], y - y.mean(0), seed=0)
    assert split.shape == (200, 2)
    torch.testing.assert_close(split.sum(1), torch.ones(200, dtype=torch.float64))
    assert 0.1 < float(split[:, 0].mean()) < 0.9
    with pytest.raises(InputError, match="unknown initialisation"):
        fit_em(MixtureOfGPExperts(2), x, y, init="kmeans")
    with pytest.raises(InputError, match="'effects' or 'joint'"):
        initial_responsibilities("grow", x, y, 2)


def test_tempered_e_step_starts_soft_and_ends_at_beta_one():
    x, y, _ = piecewise_1d(90, seed=3)
    plain = fit_em(MixtureOfGPExperts(3), x, y, init="effects", n_restarts=1, split_merge=0, **FAST)
    annealed = fit_em(
        MixtureOfGPExperts(3),
        x,
        y,
        init="effects",
        n_restarts=1,
        split_merge=0,
        anneal=True,
        anneal_start=0.1,
        anneal_iter=3,
        **{**FAST, "max_iter": 6},
    )
    assert annealed.objective != plain.objective
    assert annealed.n_iter >= 4  # cannot converge while beta < 1
    with pytest.raises(InputError, match="anneal_start"):
        fit_em(MixtureOfGPExperts(2), x, y, anneal=True, anneal_start=1.5)


def test_partial_iterations_move_only_the_active_experts():
    x, y, _ = piecewise_1d(90, seed=3)
    model = MixtureOfGPExperts(3)
    fit_em(model, x, y, init="effects", n_restarts=1, split_merge=0, **FAST)
    x_t, y_t = torch.as_tensor(x), torch.as_tensor(y)
    start = torch.softmax(loo_terms(model, x_t, y_t)[0], dim=1)
    start[:, :2] = start[:, :2].mean(1, keepdim=True)  # experts 0 and 1 merged, as a trial does
    before = [copy.deepcopy(e.state_dict()) for e in model.experts]
    options = EMOptions(**{**FAST, "max_iter": 5})
    run = EMRun(model, x_t, y_t, start.clone(), options, init="t", seed=0, active=(0, 1))
    run.step(2)
    assert run.iteration == 2
    torch.testing.assert_close(run.resp[:, 2], start[:, 2], rtol=0, atol=0)
    torch.testing.assert_close(run.resp.sum(1), torch.ones(90, dtype=torch.float64))

    def moved(j: int) -> bool:
        state = model.experts[j].state_dict()
        return any(not torch.equal(state[k], v) for k, v in before[j].items())

    assert moved(0) and moved(1) and not moved(2)
    run.release().step(1)  # full iterations again: every expert is reassigned
    assert run.active is None and run.iteration == 3
    assert not torch.equal(run.resp[:, 2], start[:, 2])


def test_collapsed_expert_takes_half_of_a_donor():
    x, y, _ = piecewise_1d(60, seed=4)
    with pytest.warns(RuntimeWarning, match="took samples from another expert"):
        history = fit_em(
            MixtureOfGPExperts(3),
            x,
            y,
            init="effects",
            n_restarts=1,
            split_merge=0,
            min_size=22.0,
            **FAST,
        )
    assert history.splits or history.reseeded
    assert all(0 <= j < 3 and 0 <= d < 3 and j != d for _, j, d in history.splits)


def test_hard_gating_uses_the_most_probable_expert():
    x, y, _ = piecewise_1d(90, seed=5)
    model = MixtureOfGPExperts(3)
    fit_em(model, x, y, init="effects", n_restarts=1, split_merge=0, **FAST)
    hard = model.predict(x, gating="hard")
    experts = model.expert_predictions(x)
    pick = model.gate_probs(x).argmax(1)
    torch.testing.assert_close(hard.mean, experts.loc[torch.arange(90), pick])
    with pytest.raises(InputError, match="gating"):
        model.predict(x, gating="median")


def test_noise_floor_keeps_exact_zero_effects_meaningful():
    x, y, _ = piecewise_1d(80, seed=6)
    y = torch.cat([y, torch.zeros(80, 1, dtype=torch.float64)], dim=1)  # an object that never moves
    free = MixtureOfGPExperts(2, gp=replace(MIXTURE_GP, noise_floor=None))
    fit_em(free, x, y, init="effects", n_restarts=1, split_merge=0, **FAST)
    floored = MixtureOfGPExperts(2, gp=replace(MIXTURE_GP, noise_floor=[0.0, 0.0, 0.002]))
    fit_em(floored, x, y, init="effects", n_restarts=1, split_merge=0, **FAST)
    scale = floored.expert_predictions(x).scale[..., 2]
    assert float(scale.min()) >= 0.002 * (1 - 1e-9)
    assert float(free.expert_predictions(x).scale[..., 2].min()) < 0.002
    with pytest.raises(InputError, match="noise_floor"):
        GPOptions(noise_floor=-1.0)
    with pytest.raises(InputError, match="noise_floor"):
        GPOptions(noise_floor="median")
    with pytest.raises(InputError, match=r"noise_floor must be one .* or 3 of them"):
        fit_em(MixtureOfGPExperts(2, gp=GPOptions(noise_floor=[0.1, 0.1])), x, y, **FAST)


def test_same_seed_same_fit_and_counts_must_be_integers():
    x, y, _ = piecewise_1d(60, seed=7)
    a = fit_em(MixtureOfGPExperts(2), x, y, n_restarts=2, **FAST)
    b = fit_em(MixtureOfGPExperts(2), x, y, n_restarts=2, **FAST)
    assert a.objective == b.objective and torch.equal(a.responsibilities, b.responsibilities)
    for name in ("max_iter", "n_restarts", "n_init", "warm_max_iter", "anneal_iter"):
        for bad in (0.5, True, 0, -2):
            with pytest.raises(InputError, match=name):
                fit_em(MixtureOfGPExperts(2), x, y, **{name: bad})
    with pytest.raises(InputError, match="split_merge"):
        fit_em(MixtureOfGPExperts(2), x, y, split_merge=1.5)
    with pytest.raises(InputError, match="n_finish"):
        fit_em(MixtureOfGPExperts(2), x, y, n_finish=1.5)
    with pytest.raises(InputError, match="n_experts"):
        fit_em_path(MixtureOfGPExperts(2), x, y, (1, 2.5))
    with pytest.raises(InputError, match="rows that sum to 1"):
        fit_em(MixtureOfGPExperts(2), x, y, init=torch.full((60, 2), 0.3, dtype=torch.float64))


def test_fit_em_leaves_a_model_equal_to_the_path_one():
    x, y, _ = piecewise_1d(60, seed=8)
    model = MixtureOfGPExperts(2)
    history = fit_em(model, x, y, n_restarts=2, **FAST)
    path = fit_em_path(copy.deepcopy(model), x, y, (2,), n_restarts=2, **FAST)
    torch.testing.assert_close(model.predict(x).log_prob(y), path[2][0].predict(x).log_prob(y))
    assert history.best == path[2][1].best


def test_search_on_a_subset_then_refine_on_every_row():
    """Coarse to fine: the search runs on `search_rows` rows, the kept fit on all of them."""
    x, y, _ = softmax_regimes(300, seed=2)
    xt, yt, _ = softmax_regimes(500, seed=3)
    settings = {"n_restarts": 2, "split_merge": 0, **FAST}
    full = MixtureOfGPExperts(3, gate_features=[0, 1])
    h_full = fit_em(full, x, y, search_rows=None, **settings)
    coarse = MixtureOfGPExperts(3, gate_features=[0, 1])
    h_coarse = fit_em(coarse, x, y, search_rows=120, search_restarts=2, **settings)
    again = MixtureOfGPExperts(3, gate_features=[0, 1])
    h_again = fit_em(again, x, y, search_rows=120, search_restarts=2, **settings)
    # the refined fit holds every row, is deterministic and predicts about as well
    assert coarse.train_weights.shape == (300, 3)
    assert h_coarse.responsibilities.shape == (300, 3)
    assert h_coarse.objective == h_again.objective
    assert len(h_coarse.candidates) == 2  # the search_restarts starts screened on the subset
    lp_full = float(full.predict(xt).log_prob(yt).mean())
    lp_coarse = float(coarse.predict(xt).log_prob(yt).mean())
    assert lp_coarse > lp_full - 0.15, (lp_coarse, lp_full)
    assert h_coarse.best > h_full.best - 0.05 * abs(h_full.best), (h_coarse.best, h_full.best)
    # at or below search_rows rows, the search uses every row (the fit of search_rows=None)
    same = MixtureOfGPExperts(3, gate_features=[0, 1])
    assert fit_em(same, x, y, search_rows=300, **settings).objective == h_full.objective
    for bad in (0, 2.5, True):
        for name in ("search_rows", "search_restarts"):
            with pytest.raises(InputError, match=name):
                fit_em(MixtureOfGPExperts(2), x, y, **{name: bad})


def _count_spike_found(n_init: int, seeds: range) -> int:
    """Seeds at which the effects start gives the 1-count rows a component of their own."""
    found = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        counts = rng.negative_binomial(1, 0.3, size=1000)  # spikes at 0 and 1, a long tail
        y = torch.as_tensor(np.log1p(counts)[:, None])
        resp = initial_responsibilities("effects", y, y, 3, n_init=n_init, seed=seed)
        label = resp.argmax(1).numpy()
        found += any(
            (label == c).sum() > 50 and (counts[label == c] == 1).mean() > 0.95 for c in range(3)
        )
    return found


def test_drawn_restarts_find_a_spike_that_k_means_alone_misses():
    # Known answer: log1p of negative-binomial counts has a spike at log 2 (one count) between
    # the zeros and the tail. k-means alone (n_init=1) splits it between its neighbours; the
    # restarts drawn from the data put a component on it.
    alone = _count_spike_found(1, range(5))
    drawn = _count_spike_found(20, range(5))
    assert alone <= 1 and drawn >= 4, (alone, drawn)
