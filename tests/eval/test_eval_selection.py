import pytest

from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.eval.selection import select_n_experts
from probaff.models.synthetic import piecewise_1d


def test_cross_validation_finds_three_regimes():
    x, y, _ = piecewise_1d(150, seed=0)
    with limit_threads(1):
        sel = select_n_experts(x, y, candidates=(1, 2, 3), folds=3)
    assert sel.best == 3
    assert sel.nlpd[3] < sel.nlpd[1] - 0.5


def test_bad_arguments():
    x, y, _ = piecewise_1d(12, seed=0)
    with pytest.raises(InputError, match="exceed"):
        select_n_experts(x, y, candidates=(9,), folds=3)
    with pytest.raises(InputError, match="folds"):
        select_n_experts(x, y, folds=1)
