"""Property tests of the fitting options: any out-of-range value of any field raises one
`InputError` naming that field, and any in-range values construct, stored as builtins.

Each field's valid and invalid values are written out here from the documented ranges
(probaff.models.options), not taken from its checks. Derandomised, so the suite is
deterministic.

Covers probaff.models.options (EMOptions, SVIOptions, GPOptions).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from probaff.errors import InputError
from probaff.models import EMOptions, GPOptions, SVIOptions
from probaff.models.options import NOISE_BOUNDS, OUTPUTSCALE_BOUNDS

PROPERTY = settings(derandomize=True, deadline=None, max_examples=60)

# ---------------------------------------------------------------- values by kind
_NOT_A_NUMBER = st.one_of(
    st.text(max_size=4), st.lists(st.integers(), min_size=2, max_size=3), st.just(object())
)
_BAD_FLOAT = st.sampled_from([math.nan, math.inf, -math.inf])


def _count(minimum=1, high=10**6):
    """Integers >= `minimum` (also as numpy integers and integral floats)."""
    n = st.integers(minimum, high)
    return st.one_of(n, n.map(np.int64), n.map(float))


def _bad_count(minimum=1):
    return st.one_of(
        st.integers(max_value=minimum - 1),
        st.floats(minimum, 1e6).filter(lambda v: v != int(v)),  # a fraction
        st.booleans(),
        _BAD_FLOAT,
        _NOT_A_NUMBER,
    )


def _interval(low, high, *, low_open=True, high_open=True):
    return st.floats(low, high, exclude_min=low_open, exclude_max=high_open)


def _outside(low, high, *, low_open=True, high_open=True):
    """Numbers outside the interval, and values that are no numbers."""
    below = st.floats(max_value=low, exclude_max=not low_open, allow_nan=False)
    above = st.floats(min_value=high, exclude_min=not high_open, allow_nan=False)
    return st.one_of(below, above, st.just(math.nan), _NOT_A_NUMBER)


_NONNEG = _interval(0.0, 1e9, low_open=False, high_open=True)
_BAD_NONNEG = st.one_of(st.floats(max_value=-1e-300, allow_nan=False), _BAD_FLOAT, _NOT_A_NUMBER)
_POSITIVE = _interval(0.0, 1e9)
_BAD_POSITIVE = st.one_of(st.floats(max_value=0.0, allow_nan=False), _BAD_FLOAT, _NOT_A_NUMBER)
_BOOL = st.sampled_from([True, False, 0, 1, np.bool_(True), np.bool_(False)])
_BAD_BOOL = st.one_of(
    st.integers().filter(lambda v: v not in (0, 1)),
    st.floats(0.01, 0.99),
    st.text(min_size=1, max_size=4),
    st.just(math.nan),
)


def _optional(values):
    return st.one_of(st.none(), values)


# ------------------------------------------------- the fields: (valid, invalid)
_NAMES = ("auto", "effects", "joint", "grow")
_INIT = (
    st.sampled_from(_NAMES),
    st.one_of(st.text(max_size=6).filter(lambda s: s not in _NAMES), st.integers(), st.none()),
)
EM_FIELDS = {
    "n_restarts": (_count(), _bad_count()),
    "screen_iter": (_optional(_count()), _bad_count()),
    "n_finish": (_count(), _bad_count()),
    "split_merge": (_count(0), _bad_count(0)),
    "max_iter": (_count(), _bad_count()),
    "tol": (_NONNEG, _BAD_NONNEG),
    "n_init": (_count(), _bad_count()),
    "seed": (_count(0), _bad_count(0)),
    "prune_below": (_NONNEG, _BAD_NONNEG),
    "min_size": (_NONNEG, _BAD_NONNEG),
    "gp_max_iter": (_optional(_count()), _bad_count()),
    "warm_max_iter": (_count(), _bad_count()),
    "anneal": (_BOOL, _BAD_BOOL),
    "anneal_start": (
        _interval(0.0, 1.0, high_open=False),
        _outside(0.0, 1.0, high_open=False),
    ),
    "anneal_iter": (_count(), _bad_count()),
    "search_rows": (_optional(_count()), _bad_count()),
    "search_restarts": (_count(), _bad_count()),
    "init": _INIT,
}
SVI_FIELDS = {
    "n_steps": (_count(), _bad_count()),
    "batch_size": (_count(), _bad_count()),
    "lr": (_POSITIVE, _BAD_POSITIVE),
    "n_init": (_count(), _bad_count()),
    "seed": (_count(0), _bad_count(0)),
    "init_rows": (_count(), _bad_count()),
    "natural_step": (_interval(0.0, 1.0, high_open=False), _outside(0.0, 1.0, high_open=False)),
    "gate_lr_scale": (_NONNEG, _BAD_NONNEG),
    "hyper_lr_scale": (_NONNEG, _BAD_NONNEG),
    "init": _INIT,
}
_FLOOR = st.floats(0.0, 1e3)
GP_FIELDS = {
    "max_iter": (_count(), _bad_count()),
    "lengthscale_prior": (  # a switch, or the prior's width
        st.one_of(_BOOL, st.floats(0.01, 10.0)),
        st.one_of(
            st.floats(max_value=0.0, allow_nan=False),
            st.integers(max_value=-1),
            st.just(math.nan),
            st.just(math.inf),
            st.text(min_size=1, max_size=4),
        ),
    ),
    "noise_floor": (
        st.one_of(st.none(), st.just("auto"), _FLOOR, st.lists(_FLOOR, min_size=1, max_size=4)),
        st.one_of(
            st.floats(max_value=-1e-300, allow_nan=False),
            _BAD_FLOAT,
            st.lists(st.floats(max_value=-1e-300, allow_nan=False), min_size=1, max_size=3),
            st.text(max_size=3),
        ),
    ),
    "outputscale": (_interval(*OUTPUTSCALE_BOUNDS), _outside(*OUTPUTSCALE_BOUNDS)),
    "noise": (_interval(*NOISE_BOUNDS), _outside(*NOISE_BOUNDS)),
}
CLASSES = {EMOptions: EM_FIELDS, SVIOptions: SVI_FIELDS, GPOptions: GP_FIELDS}


def test_every_field_is_drawn():
    import dataclasses

    for cls, fields in CLASSES.items():
        assert set(fields) == {f.name for f in dataclasses.fields(cls)}, cls.__name__


def _one_bad(cls):
    fields = CLASSES[cls]
    return st.sampled_from(sorted(fields)).flatmap(
        lambda name: st.tuples(st.just(name), fields[name][1])
    )


def _all_good(cls):
    return st.fixed_dictionaries({name: good for name, (good, _) in CLASSES[cls].items()})


@pytest.mark.parametrize("cls", list(CLASSES), ids=lambda c: c.__name__)
@PROPERTY
@given(data=st.data())
def test_an_out_of_range_value_is_refused_naming_its_field(cls, data):
    name, value = data.draw(_one_bad(cls))
    with pytest.raises(InputError) as caught:
        cls(**{name: value})
    assert name in str(caught.value), (name, value, str(caught.value))


def _same(stored, given_value):
    if isinstance(given_value, (list, tuple)):
        return list(stored) == [float(v) for v in given_value]
    return stored == given_value


@pytest.mark.parametrize("cls", list(CLASSES), ids=lambda c: c.__name__)
@PROPERTY
@given(data=st.data())
def test_in_range_values_construct_as_builtins(cls, data):
    values = data.draw(_all_good(cls))
    options = cls(**values)
    for name, value in values.items():
        stored = getattr(options, name)
        assert _same(stored, value), (name, value, stored)
        if value is None or isinstance(value, str):
            continue
        if isinstance(value, (list, tuple)):
            assert isinstance(stored, tuple) and all(type(v) is float for v in stored)
        else:  # numpy scalars and integral floats become builtins
            assert type(stored) in (int, float, bool), (name, type(stored))
