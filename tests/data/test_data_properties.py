"""Property tests of the dataset validators: a robot's arrays with one thing wrong, and HDF5
files of arbitrary or damaged bytes.

- `observation_dataset` refuses any one corruption of a valid push (a missing array, another
  shape, a NaN or infinity, text, an id outside the names, a unit of another scale, a meta
  value of the wrong kind) with one `InputError` naming the array or entry;
- `import_hdf5` of arbitrary bytes raises `DatasetError` and writes nothing; of a valid file
  with bytes overwritten, it either raises `DatasetError` or writes a dataset that loads.

Derandomised, so the suite is deterministic.

Covers probaff.data.observations, probaff.data.observation_checks and probaff.data.hdf5.
"""

import json
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from probaff.data import import_hdf5, observation_dataset
from probaff.errors import DatasetError, InputError

PROPERTY = settings(
    derandomize=True,
    deadline=None,
    max_examples=60,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
FIXTURE = Path(__file__).resolve().parent / "fixtures" / "foreign_big_endian.h5"

with h5py.File(FIXTURE, "r") as _fh:
    _DATA = _fh["data"]
    BASE = {k: np.asarray(v[()]).astype(v.dtype.newbyteorder("=")) for k, v in _DATA.items()}
    UNITS = {k: str(v.attrs["units"]) for k, v in _DATA.items()}
    NAMES = json.loads(_DATA.attrs["object_names"])
    META = json.loads(_DATA.attrs["meta"])
REQUIRED = ("object_ids", "state_before", "state_after", "push_origin", "push_yaw", "push_distance")
REAL = tuple(k for k in BASE if k != "object_ids")


def test_the_uncorrupted_push_is_accepted():
    ds = observation_dataset(BASE, NAMES, META, units=UNITS)
    assert len(ds) == 3 and np.array_equal(ds["state_before"], BASE["state_before"])


def _missing():
    return st.sampled_from(REQUIRED).map(lambda n: (n, lambda a, m, u: a.pop(n)))


def _reshaped():
    shapes = st.lists(st.integers(1, 4), min_size=0, max_size=4).map(tuple)
    return (
        st.tuples(st.sampled_from(sorted(BASE)), shapes)
        .filter(lambda t: t[1] != BASE[t[0]].shape)
        .map(lambda t: (t[0], lambda a, m, u: a.__setitem__(t[0], np.ones(t[1]))))
    )


def _non_finite():
    def corrupt(name, flat, value):
        def apply(a, m, u):
            arr = a[name].astype(np.float64).copy()
            arr.reshape(-1)[flat % arr.size] = value
            a[name] = arr

        return name, apply

    return st.builds(
        corrupt,
        st.sampled_from(REAL),
        st.integers(0, 10**6),
        st.sampled_from([np.nan, np.inf, -np.inf]),
    )


def _text():
    def corrupt(name, word):
        return name, lambda a, m, u: a.__setitem__(name, np.full(a[name].shape, word))

    return st.builds(corrupt, st.sampled_from(sorted(BASE)), st.text(min_size=1, max_size=3))


def _bad_id():
    def corrupt(flat, value):
        def apply(a, m, u):
            ids = a["object_ids"].copy()
            ids.reshape(-1)[flat % ids.size] = value
            a["object_ids"] = ids

        return "object_ids", apply

    ids = st.one_of(st.integers(-1000, -1), st.integers(len(NAMES), 1000))
    return st.builds(corrupt, st.integers(0, 10**6), ids)


def _unit():
    wrong = ["mm", "cm", "deg", "mm, mm, deg", "m, m, deg", "cm, cm, rad", "kg", "s", "px"]

    def corrupt(name, unit):
        return name, lambda a, m, u: u.__setitem__(name, unit)

    pairs = st.tuples(st.sampled_from(sorted(BASE)), st.sampled_from(wrong))
    return pairs.filter(lambda t: t[1].replace(" ", "") != UNITS[t[0]].replace(" ", "")).map(
        lambda t: corrupt(*t)
    )


def _meta():
    bad = st.one_of(
        st.text(max_size=4),
        st.floats(max_value=0.0, allow_nan=False),
        st.just(float("nan")),
        st.just(float("inf")),
        st.booleans(),
        st.lists(st.floats(0.1, 1.0), min_size=0, max_size=3).filter(lambda v: len(v) != 2),
    )
    keys = st.sampled_from(["push_height", "gripper_opening", "finger_radius", "table_size"])

    def corrupt(key, value):
        return f"meta['{key}']", lambda a, m, u: m.__setitem__(key, value)

    return st.builds(corrupt, keys, bad)


CORRUPTIONS = st.one_of(
    _missing(), _reshaped(), _non_finite(), _text(), _bad_id(), _unit(), _meta()
)


@PROPERTY
@given(corruption=CORRUPTIONS)
def test_one_corruption_of_a_push_is_refused_naming_it(corruption):
    name, apply = corruption
    arrays, meta, units = dict(BASE), dict(META), dict(UNITS)
    apply(arrays, meta, units)
    with pytest.raises(InputError) as caught:
        observation_dataset(arrays, NAMES, meta, units=units)
    assert name in str(caught.value), str(caught.value)


_SIGNATURE = b"\x89HDF\r\n\x1a\n"


@settings(PROPERTY, max_examples=20)  # each file with the signature is read in a subprocess
@given(head=st.sampled_from([b"", _SIGNATURE]), body=st.binary(max_size=3000))
def test_arbitrary_bytes_are_refused_as_a_damaged_file(head, body):
    with tempfile.TemporaryDirectory() as tmp:
        file, out = Path(tmp) / "x.h5", Path(tmp) / "ds"
        file.write_bytes(head + body)
        with pytest.raises(DatasetError, match=r"x\.h5"):
            import_hdf5(file, out)
        assert not out.exists() or not any(out.iterdir())
