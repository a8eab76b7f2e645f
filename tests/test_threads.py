"""probaff._threads: the thread count of a fit by its size, its override, nesting and checks."""

import pytest
import torch
from threadpoolctl import threadpool_info, threadpool_limits

import probaff
from probaff._threads import (
    FIT_THREADS_ENV,
    ONE_THREAD_MAX_ROWS,
    fit_threads,
    fit_threads_setting,
    limit_threads,
    rows_of,
    set_fit_threads,
    threads_by_rows,
    threads_for_rows,
)
from probaff.errors import InputError

SMALL, LARGE = ONE_THREAD_MAX_ROWS, ONE_THREAD_MAX_ROWS + 1


@pytest.fixture(autouse=True)
def _two_threads(monkeypatch):
    """Torch at two threads (the suite's conftest sets one), no setting, no variable."""
    monkeypatch.delenv(FIT_THREADS_ENV, raising=False)
    torch.set_num_threads(2)
    yield
    set_fit_threads(None)


def _blas_threads() -> set[int]:
    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


def test_small_fit_runs_on_one_thread_and_restores_torch_and_blas():
    with threadpool_limits(2, user_api="blas"):
        assert _blas_threads() == {2}
        with fit_threads(SMALL) as n:
            assert n == 1 and torch.get_num_threads() == 1 and _blas_threads() == {1}
        assert torch.get_num_threads() == 2 and _blas_threads() == {2}


def test_a_limit_threads_block_limits_blas_too_and_a_fit_inside_keeps_it():
    """A fit inside ``limit_threads(1)`` (every study task) runs its BLAS on one thread."""
    with threadpool_limits(2, user_api="blas"):
        with limit_threads(1):
            assert torch.get_num_threads() == 1 and _blas_threads() == {1}
            with fit_threads(SMALL) as n:
                assert n == 1 and _blas_threads() == {1}
        assert torch.get_num_threads() == 2 and _blas_threads() == {2}


def test_large_fit_keeps_torch_count():
    with fit_threads(LARGE) as n:
        assert n == 2 and torch.get_num_threads() == 2
    assert torch.get_num_threads() == 2


def test_previous_count_is_restored_after_an_error():
    with pytest.raises(RuntimeError, match="boom"), fit_threads(10):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == 2


def test_automatic_choice_never_raises_the_users_count():
    torch.set_num_threads(1)  # the user's own choice
    with fit_threads(LARGE) as n:
        assert n == 1 and torch.get_num_threads() == 1


@pytest.mark.parametrize("how", ["code", "environment"])
def test_setting_overrides_the_choice(monkeypatch, how):
    if how == "code":
        probaff.set_fit_threads(3)
    else:
        monkeypatch.setenv(FIT_THREADS_ENV, " 3 ")
    assert fit_threads_setting() == 3 and threads_for_rows(SMALL) == 3
    with fit_threads(SMALL) as n:
        assert n == 3 and torch.get_num_threads() == 3
    assert torch.get_num_threads() == 2


def test_code_setting_comes_before_the_environment_and_none_restores_it(monkeypatch):
    monkeypatch.setenv(FIT_THREADS_ENV, "2")
    set_fit_threads(1)
    assert fit_threads_setting() == 1
    set_fit_threads(None)
    assert fit_threads_setting() == 2
    monkeypatch.setenv(FIT_THREADS_ENV, "auto")
    assert fit_threads_setting() is None and threads_for_rows(SMALL) == 1


def test_nested_fits_never_raise_the_count():
    with fit_threads(SMALL):
        with fit_threads(LARGE) as inner:
            assert inner == 1 and torch.get_num_threads() == 1
        assert torch.get_num_threads() == 1
    with fit_threads(LARGE):  # a large fit around a small one: the small one lowers it
        with fit_threads(SMALL) as inner:
            assert inner == 1 and torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
    set_fit_threads(4)  # a setting does not raise the count inside a limited block either
    with limit_threads(1), fit_threads(SMALL) as n:
        assert n == 1 and torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2


def test_decorated_fit_counts_the_rows_of_its_argument():
    seen = []

    @threads_by_rows("X")
    def fit(model: object, X: object, *, flag: bool = False) -> int:
        """Docs."""
        seen.append(torch.get_num_threads())
        return 7

    assert fit(None, [[0.0]] * SMALL) == 7 and fit(None, X=torch.zeros(LARGE, 2)) == 7
    assert seen == [1, 2] and fit.__name__ == "fit" and fit.__doc__ == "Docs."
    with pytest.raises(TypeError):
        fit(None)  # Python's own error for a wrong call
    with pytest.raises(TypeError, match="no parameter 'Y'"):
        threads_by_rows("Y")(lambda X: X)


def test_public_fits_are_sized():
    from probaff.models import (
        ClusteredGPModel,
        GPExpert,
        SparseGPExpert,
        fit_em,
        fit_em_path,
        fit_svi,
        fit_transition,
    )
    from probaff.models.sklearn import MixtureOfGPExpertsRegressor as Regressor

    fits = [fit_em, fit_em_path, fit_svi, fit_transition, ClusteredGPModel.fit, GPExpert.fit]
    fits += [SparseGPExpert.fit, Regressor.fit, Regressor.predict]
    assert all(hasattr(f, "__wrapped__") for f in fits)


def test_em_fit_runs_on_one_thread(monkeypatch):
    import probaff.models.mixture.em as em
    from probaff.models import MixtureOfGPExperts, fit_em
    from probaff.models.synthetic import softmax_regimes

    seen = []

    def path(*args, **kwargs):
        seen.append(torch.get_num_threads())
        raise RuntimeError("stop")

    monkeypatch.setattr(em, "fit_em_path", path)
    x, y, _ = softmax_regimes(40)
    with pytest.raises(RuntimeError, match="stop"):
        fit_em(MixtureOfGPExperts(2), x, y)
    assert seen == [1] and torch.get_num_threads() == 2


def test_rows_of_anything():
    assert rows_of(torch.zeros(5, 2)) == 5 and rows_of([[1], [2]]) == 2 and rows_of(None) == 0
    assert rows_of(torch.tensor(1.0)) == 0 and rows_of(3) == 0


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2", True, float("nan")])
def test_bad_counts_are_input_errors_naming_them(bad):
    with pytest.raises(InputError, match=r"set_fit_threads: n must be a positive integer"):
        set_fit_threads(bad)
    with pytest.raises(InputError, match="n must be a positive integer"), limit_threads(bad):
        pass


@pytest.mark.parametrize("bad", ["0", "two", "-3", "1.5"])
def test_bad_environment_variable_is_an_input_error(monkeypatch, bad):
    monkeypatch.setenv(FIT_THREADS_ENV, bad)
    with pytest.raises(InputError, match=f"{FIT_THREADS_ENV}=.*positive integer or 'auto'"):
        fit_threads_setting()
    with pytest.raises(InputError, match=FIT_THREADS_ENV), fit_threads(10):
        pass


def test_bad_row_count_is_an_input_error():
    with pytest.raises(InputError, match="n_rows must be an integer >= 0"):
        threads_for_rows(-1)
