"""probaff.models.sklearn: the mixture of GP experts as a scikit-learn regressor."""

import pickle
from dataclasses import replace

import numpy as np
import pytest
import sklearn.exceptions
import torch
from sklearn.base import clone
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import GridSearchCV, KFold, cross_val_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.utils.estimator_checks import parametrize_with_checks

import probaff.errors
from probaff.errors import InputError
from probaff.models import MIXTURE_GP, EMOptions, MixtureOfGPExperts, fit_em
from probaff.models.sklearn import (
    EstimatorNotFittedError,
    MixtureOfGPExpertsRegressor,
    mean_log_predictive_density,
)
from probaff.models.synthetic import piecewise_1d, softmax_regimes

# Small and random data let an expert collapse; EM repairs it with a RuntimeWarning (that
# repair is tested in test_models_em.py), which is noise here.
pytestmark = [
    pytest.mark.filterwarnings("ignore:EM iteration .* collapsed expert:RuntimeWarning"),
    pytest.mark.usefixtures("single_thread"),
]

# One start, no split/merge and few iterations: every test here is about the estimator's
# contract, not about the quality of EM's default search.
CHEAP = {"n_restarts": 1, "split_merge": 0, "max_iter": 3, "gp_max_iter": 20}

# The cheapest fit that still runs EM with two experts, for scikit-learn's ~50 API checks
# (each fits several times on small random data): a fixed gate penalty instead of the
# inner cross-validation, one short run from one Gaussian mixture.
CHECKED = MixtureOfGPExpertsRegressor(
    2,
    gate_l2=1.0,
    init="joint",
    n_restarts=1,
    split_merge=0,
    max_iter=1,
    gp_max_iter=5,
    n_init=1,
)


@pytest.fixture(scope="module")
def data():
    x, y, _ = piecewise_1d(60, seed=0)
    return x.numpy(), y.numpy()


@pytest.fixture(scope="module")
def fitted(data):
    X, Y = data
    return MixtureOfGPExpertsRegressor(2, random_state=0, **CHEAP).fit(X, Y[:, 0])


# ---------------------------------------------------------------- the API
def test_shapes_follow_gaussian_process_regressor(data, fitted):
    X, Y = data
    mean, std = fitted.predict(X[:7], return_std=True)
    assert fitted.predict(X[:7]).shape == mean.shape == std.shape == (7,)
    assert mean.dtype == std.dtype == np.float64 and (std > 0).all()
    assert fitted.n_features_in_ == 1 and fitted.n_targets_ == 1
    assert fitted.n_iter_ == fitted.history_.n_iter >= 1
    assert isinstance(fitted.model_, MixtureOfGPExperts) and fitted.model_.n_experts == 2

    one_column = clone(fitted).fit(X, Y[:, :1])  # (N, 1) gives (N,), as in scikit-learn
    assert one_column.predict(X[:7]).shape == (7,)
    np.testing.assert_array_equal(one_column.predict(X[:7]), mean)

    two = clone(fitted).fit(X, Y)
    mean2, std2 = two.predict(X[:7], return_std=True)
    assert mean2.shape == std2.shape == (7, 2) and two.n_targets_ == 2
    assert fitted.score(X, Y[:, 0]) > 0.8 and two.score(X, Y) > 0.8


def test_point_and_std_are_the_mixtures(data, fitted):
    X, Y = data
    x = torch.as_tensor(X[:5])
    dist = fitted.model_.predict(x)
    point, std = fitted.predict(X[:5], return_std=True)
    want = fitted.model_.predict_point(x)[:, 0].detach().numpy()
    np.testing.assert_allclose(point, want, rtol=0, atol=0)
    np.testing.assert_allclose(std**2, dist.variance[:, 0].detach().numpy(), rtol=1e-12)
    np.testing.assert_array_equal(point, dist.mean[:, 0].detach().numpy())  # point="mean"
    stacked = MixtureOfGPExpertsRegressor(2, point="stacked", random_state=0, **CHEAP)
    stacked.fit(X, Y[:, 0])
    want = stacked.model_.predict_point(x)[:, 0].detach().numpy()
    np.testing.assert_array_equal(stacked.predict(X[:5]), want)


def test_random_state_fixes_the_fit_and_equals_fit_em(data, fitted):
    X, Y = data
    again = MixtureOfGPExpertsRegressor(2, random_state=0, **CHEAP).fit(X, Y[:, 0])
    np.testing.assert_array_equal(again.predict(X), fitted.predict(X))
    assert fitted.seed_ == 0

    model = MixtureOfGPExperts(2, gp=replace(MIXTURE_GP, max_iter=20))
    options = EMOptions(n_restarts=1, split_merge=0, max_iter=3, seed=0)
    assert fitted.em_options(0) == options
    history = fit_em(model, X, Y[:, :1], options)
    assert history.objective == fitted.history_.objective
    direct = model.predict_point(torch.as_tensor(X))[:, 0].detach().numpy()
    np.testing.assert_array_equal(direct, fitted.predict(X))


def test_random_state_none_or_a_generator_draws_a_seed(data):
    X, Y = data
    a = MixtureOfGPExpertsRegressor(1, random_state=np.random.RandomState(3), **CHEAP)
    b = MixtureOfGPExpertsRegressor(1, random_state=np.random.RandomState(3), **CHEAP)
    assert a.fit(X, Y[:, 0]).seed_ == b.fit(X, Y[:, 0]).seed_ >= 0
    none = MixtureOfGPExpertsRegressor(1, **CHEAP).fit(X, Y[:, 0])
    assert 0 <= none.seed_ < 2**31 - 1


def test_params_are_stored_unchanged_and_clone_is_unfitted(fitted):
    groups = {"t": [0]}
    est = MixtureOfGPExpertsRegressor(3, groups=groups, gate_features="t", random_state=4)
    params = est.get_params()
    assert params["groups"] is groups and params["gate_features"] == "t"
    assert params["n_experts"] == 3 and params["random_state"] == 4
    assert est.set_params(n_experts=1, max_iter=2) is est and est.n_experts == 1

    copy = clone(fitted)
    assert copy.get_params() == fitted.get_params()
    assert not hasattr(copy, "model_")
    with pytest.raises(EstimatorNotFittedError, match="call fit"):
        copy.predict(np.zeros((2, 1)))


def test_not_fitted_error_is_both_libraries_error():
    est = MixtureOfGPExpertsRegressor()
    for kind in (sklearn.exceptions.NotFittedError, probaff.errors.NotFittedError):
        with pytest.raises(kind):
            est.predict(np.zeros((2, 1)))
    with pytest.raises(probaff.errors.NotFittedError):
        est.log_predictive_density(np.zeros((2, 1)), np.zeros(2))


def test_pickle_round_trip_predicts_the_same(data, fitted):
    X, _ = data
    back = pickle.loads(pickle.dumps(fitted))
    np.testing.assert_array_equal(back.predict(X), fitted.predict(X))


# --------------------------------------------------------------- bad input
def test_nan_and_wrong_columns_are_input_errors(data, fitted):
    X, Y = data
    bad = X.copy()
    bad[3, 0] = np.nan
    with pytest.raises(InputError, match="Input X contains NaN"):
        MixtureOfGPExpertsRegressor(**CHEAP).fit(bad, Y[:, 0])
    y_bad = Y[:, 0].copy()
    y_bad[5] = np.inf
    with pytest.raises(InputError, match="Input y contains infinity"):
        MixtureOfGPExpertsRegressor(**CHEAP).fit(X, y_bad)
    with pytest.raises(InputError, match="NaN"):
        fitted.predict(bad)
    with pytest.raises(InputError, match="2 features, but MixtureOfGPExpertsRegressor"):
        fitted.predict(np.hstack([X, X]))
    with pytest.raises(InputError, match="minimum of 2 is required"):
        MixtureOfGPExpertsRegressor(1).fit(X[:1], Y[:1, 0])
    with pytest.raises(InputError, match="target"):
        fitted.log_predictive_density(X, Y)


def test_strings_in_x_or_y_name_the_argument(data, fitted):
    X, Y = data
    words = X.astype(object)
    words[2, 0] = "a"
    with pytest.raises(InputError, match=r"^X must be a numeric array .*convert it to floats"):
        MixtureOfGPExpertsRegressor(**CHEAP).fit(words, Y[:, 0])
    with pytest.raises(InputError, match=r"^X must be a numeric array"):
        MixtureOfGPExpertsRegressor(**CHEAP).fit([["a"]] * 60, Y[:, 0])
    with pytest.raises(InputError, match=r"^y must be a numeric array"):
        MixtureOfGPExpertsRegressor(**CHEAP).fit(X, ["up"] * 60)
    with pytest.raises(InputError, match=r"^X must be a numeric array"):
        fitted.predict(words)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"n_experts": 0}, "n_experts"),
        ({"n_experts": 80}, "exceeds the 60 training samples"),
        ({"gate": "tree"}, "gate must be one of"),
        ({"gate_features": "f_x"}, "unknown feature group"),
        ({"max_iter": 0}, "max_iter"),
        ({"tol": -1.0}, "tol"),
        ({"init": "kmeans"}, "init"),
        ({"init": torch.ones(60, 2) / 2}, "init must be 'auto'"),
        ({"random_state": -1}, "random_state must be >= 0"),
        ({"random_state": "seed"}, "random_state must be an integer"),
        ({"gate_l1": True}, r"gate_l1 must be a number, got True"),
        ({"gate_l2": False}, r"gate_l2 must be a number, got False"),
        ({"tol": True}, "tol"),
    ],
)
def test_bad_arguments_fail_at_fit_naming_the_argument(data, params, match):
    X, Y = data
    est = MixtureOfGPExpertsRegressor(**params)  # stored unchanged, checked by fit
    with pytest.raises(InputError, match=match):
        est.fit(X, Y[:, 0])


# ------------------------------------------------------------ model selection
def test_cross_val_score(data):
    X, Y = data
    est = MixtureOfGPExpertsRegressor(2, random_state=0, **CHEAP)
    cv = KFold(3, shuffle=True, random_state=0)
    scores = cross_val_score(est, X, Y, cv=cv)
    assert scores.shape == (3,) and (scores > 0.7).all()
    density = cross_val_score(est, X, Y[:, 0], cv=cv, scoring=mean_log_predictive_density)
    assert np.isfinite(density).all()


def test_grid_search_chooses_three_experts_for_three_regimes():
    # Three regimes decided by inputs 0 and 1 with the same output range: one GP must draw
    # the regime borders itself, three experts behind a gate on (x0, x1) need not. Held-out
    # R^2 of M = 1, 2, 3 is about 0.45, 0.66 and 0.88 (with data seeds 1 and 2, M = 3 wins
    # as well, by 0.29 and 0.17).
    x, y, _ = softmax_regimes(120, seed=0)
    est = MixtureOfGPExpertsRegressor(
        gate_features=[0, 1], n_restarts=1, split_merge=0, max_iter=5, random_state=0
    )
    cv = KFold(3, shuffle=True, random_state=0)
    search = GridSearchCV(est, param_grid={"n_experts": [1, 2, 3]}, cv=cv)
    search.fit(x.numpy(), y.numpy())
    r2 = search.cv_results_["mean_test_score"]
    assert search.best_params_ == {"n_experts": 3}
    assert r2[2] > r2[0] + 0.2, r2
    assert search.best_estimator_.model_.n_experts == 3
    assert search.predict(x[:4].numpy()).shape == (4, 2)


def test_pipeline_with_standard_scaler(data):
    X, Y = data
    X_mm = 1000.0 * X + 50.0  # another unit and origin
    pipe = make_pipeline(StandardScaler(), MixtureOfGPExpertsRegressor(2, random_state=0, **CHEAP))
    pipe.fit(X_mm, Y)
    mean, std = pipe.predict(X_mm[:6], return_std=True)  # forwarded to the last step
    assert mean.shape == std.shape == (6, 2)

    scaler = StandardScaler().fit(X_mm)
    alone = MixtureOfGPExpertsRegressor(2, random_state=0, **CHEAP).fit(scaler.transform(X_mm), Y)
    np.testing.assert_array_equal(mean, alone.predict(scaler.transform(X_mm[:6])))
    assert pipe.score(X_mm, Y) == alone.score(scaler.transform(X_mm), Y)
    density = mean_log_predictive_density(pipe, X_mm, Y)
    assert density == pytest.approx(alone.log_predictive_density(scaler.transform(X_mm), Y).mean())


def test_mean_log_predictive_density_scores_only_the_mixture(data, fitted):
    X, Y = data
    values = fitted.log_predictive_density(X, Y[:, 0])
    assert values.shape == (len(X),) and np.isfinite(values).all()
    assert mean_log_predictive_density(fitted, X, Y[:, 0]) == pytest.approx(values.mean())
    with pytest.raises(InputError, match="got LinearRegression"):
        mean_log_predictive_density(LinearRegression().fit(X, Y), X, Y)


# ------------------------------------------------------- scikit-learn's checks
# Every check applies and passes; none is expected to fail. One is skipped by scikit-learn
# itself: check_array_api_input runs only with SCIPY_ARRAY_API=1 set before SciPy is imported
# (the estimator does not claim array-API support, so the check would feed it numpy only).
@parametrize_with_checks([CHECKED])
def test_scikit_learn_check_estimator(estimator, check):
    check(estimator)
