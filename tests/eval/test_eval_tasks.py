import json
import math
import os

import numpy as np
import pytest

from probaff.errors import DatasetError, InputError
from probaff.eval.tasks import ResultStore, run_tasks


def square(x):
    return {"x": x, "y": x * x}


def test_runs_missing_tasks_only(tmp_path):
    store = ResultStore(tmp_path)
    tasks = [(f"t{i}", (i,)) for i in range(5)]
    calls = []

    def counted(x):
        calls.append(x)
        if x == 3 and len(calls) == 4:
            raise KeyboardInterrupt  # killed while computing the fourth task
        return square(x)

    with pytest.raises(KeyboardInterrupt):
        run_tasks(counted, tasks, store, progress=False)
    assert [store.done(f"t{i}") for i in range(5)] == [True, True, True, False, False]
    calls.clear()
    out = run_tasks(counted, tasks, store, progress=False)
    assert calls == [3, 4]
    assert [r["y"] for r in out] == [0, 1, 4, 9, 16]


def square_of_shared(i, *, data):
    return {"y": int(data["x"][i]) ** 2, "trim": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


def test_dask_gives_the_same_results_with_shared_data_and_glibc_defaults(tmp_path):
    tasks = [(f"t{i}", (i,)) for i in range(4)]
    data = {"x": np.arange(4)}
    out = run_tasks(
        square_of_shared,
        tasks,
        ResultStore(tmp_path),
        workers=1,
        progress=False,
        shared={"data": data},
    )
    assert [r["y"] for r in out] == [0, 1, 4, 9]
    # Dask's MALLOC_TRIM_THRESHOLD_ makes GP fits page-fault-bound; workers must not get it.
    assert {r["trim"] for r in out} == {None}
    serial = run_tasks(
        square_of_shared,
        tasks,
        ResultStore(tmp_path / "serial"),
        progress=False,
        shared={"data": data},
    )
    assert [r["y"] for r in serial] == [0, 1, 4, 9]


def test_bad_keys(tmp_path):
    with pytest.raises(InputError, match="unique"):
        run_tasks(square, [("a", (1,)), ("a", (2,))], ResultStore(tmp_path), progress=False)
    with pytest.raises(InputError, match="may only hold"):
        ResultStore(tmp_path).path("a/b")


@pytest.mark.parametrize(
    ("settings", "word"),
    [
        ({"workers": -1}, "workers"),
        ({"workers": 1.5}, "workers"),
        ({"scheduler": " "}, "scheduler"),
    ],
)
def test_bad_batch_settings_are_refused_even_when_every_task_is_saved(tmp_path, settings, word):
    store = ResultStore(tmp_path)
    run_tasks(square, [("a", (2,))], store, progress=False)
    with pytest.raises(InputError, match=word):
        run_tasks(square, [("a", (2,))], store, progress=False, **settings)


def test_damaged_or_blocked_result_files_are_named(tmp_path):
    store = ResultStore(tmp_path / "results")
    store.save("a", {"x": 1})
    assert store.load("a") == {"x": 1}
    store.path("a").write_text('{"x": 1')  # truncated
    with pytest.raises(DatasetError, match=r"cannot read the saved result .*a\.json .*delete it"):
        run_tasks(square, [("a", (1,))], store, progress=False)
    store.path("a").write_text("[1, 2]")
    with pytest.raises(DatasetError, match=r"a\.json is not a JSON object; delete it"):
        store.load("a")
    with pytest.raises(DatasetError, match="task 'b' has no saved result"):
        store.load("b")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError, match=r"result file .*file/c\.json lies under .*file"):
        ResultStore(blocker).save("c", {"x": 1})


def test_measured_fields_are_kept_apart_and_joined_again(tmp_path):
    store = ResultStore(tmp_path / "tasks", measured=("seconds",), measured_root=tmp_path / "t")
    store.save("a", {"x": 1.5, "seconds": 0.25})
    store.save("b", {"x": 2.5})
    assert json.loads((tmp_path / "tasks" / "a.json").read_text()) == {"x": 1.5}
    assert json.loads((tmp_path / "t" / "a.json").read_text()) == {"seconds": 0.25}
    assert store.load("a") == {"x": 1.5, "seconds": 0.25}
    assert math.isnan(store.load("b")["seconds"])  # measured nothing
    (tmp_path / "t" / "a.json").unlink()
    assert math.isnan(store.load("a")["seconds"])  # a lost measurement reads as NaN
    (tmp_path / "t" / "a.json").write_text("{")
    with pytest.raises(DatasetError, match="cannot read the measurements"):
        store.load("a")
    with pytest.raises(InputError, match="measured must be a sequence of field names"):
        ResultStore(tmp_path, measured="seconds")
