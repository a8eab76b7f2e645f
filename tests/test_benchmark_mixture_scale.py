"""Smoke test of benchmarks/mixture_scale.py: every method on both data sets, resume, bad flags."""

import csv
import json
import math

import numpy as np
import pytest
import statsmodels.api as sm
import torch

pytestmark = pytest.mark.slow

METHODS = ["exact-em", "sparse-em", "vi", "svgp", "ccr"]


@pytest.fixture(scope="module")
def scale(benchmark_script):
    with benchmark_script("mixture_scale") as module:
        yield module


@pytest.mark.parametrize("data", ["regimes", "randhie"])
def test_smoke_run_scores_every_method_and_resumes(scale, tmp_path, data):
    argv = ["--smoke", "--data", data, "--methods", ",".join(METHODS), "--out", str(tmp_path)]
    assert scale.main(argv) == 0
    out = tmp_path / data
    cells = sorted(out.glob("*_N*.json"))
    assert {p.name for p in cells} == {f"{m}_N{n}.json" for m in METHODS for n in (60, 120)}
    e = 2 if data == "regimes" else 1
    for p in cells:
        cell = json.loads(p.read_text())
        assert cell["data"] == data and "skipped" not in cell
        assert math.isfinite(cell["nlpd"]) and cell["rmse"] > 0, p.name
        assert len(cell["nlpd_per_output"]) == cell["e"] == e
        assert cell["fit_cpu_s"] > 0 and cell["n_test"] == 50
        assert math.isclose(sum(cell["nlpd_per_output"]), cell["nlpd"])

    with open(out / "scaling.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {(r["method"], int(r["n"])) for r in rows} == {
        (m, n) for m in METHODS for n in (60, 120)
    }
    assert all(math.isfinite(float(r["nlpd"])) for r in rows)
    md = (out / "scaling.md").read_text()
    assert all(f"| {m} | 120 |" in md for m in METHODS)
    assert (out / "scaling.png").stat().st_size > 10_000

    # a rerun finds every cell and fits nothing
    mtimes = {p: p.stat().st_mtime_ns for p in cells}
    assert scale.main(argv) == 0
    assert {p: p.stat().st_mtime_ns for p in cells} == mtimes


def test_randhie_split_is_fixed_and_disjoint(scale):
    args = scale.parse_args(["--data", "randhie", "--seed", "3"])
    a = scale.load_randhie(500, 100, args)
    b = scale.load_randhie(800, 100, args)
    assert a.x.shape == (500, 9) and a.y.shape == (500, 1) and a.x_test.shape == (100, 9)
    assert a.x_test.equal(b.x_test) and a.x.equal(b.x[:500])  # same held-out rows, nested pools
    assert (a.y >= 0).all() and a.labels is None
    # the held-out rows and the full pool are a shuffle of every row: column sums agree
    full = scale.load_randhie(scale.RANDHIE_ROWS - 100, 100, args)
    assert full.x.shape[0] + full.x_test.shape[0] == scale.RANDHIE_ROWS
    frame = sm.datasets.randhie.load_pandas().data
    x_all = torch.cat([full.x_test, full.x])
    column_sums = np.array(frame.drop(columns="mdvis").sum())  # a copy: pandas' is read-only
    assert torch.allclose(x_all.sum(0), torch.as_tensor(column_sums))
    y_all = torch.cat([full.y_test, full.y])
    assert torch.allclose(y_all.sum(), torch.as_tensor(np.log1p(frame["mdvis"]).sum()))
    assert not x_all.equal(torch.as_tensor(frame.drop(columns="mdvis").values))  # shuffled
    other = scale.load_randhie(500, 100, scale.parse_args(["--data", "randhie", "--seed", "4"]))
    assert not other.x_test.equal(a.x_test)


@pytest.mark.parametrize(
    ("name", "limit"),
    [("ccr", "CCR_MAX_N"), ("exact-em", "EXACT_MAX_N"), ("exact-em-serial", "EXACT_MAX_N")],
)
def test_exact_methods_are_skipped_above_their_limit(scale, name, limit):
    args = scale.parse_args(["--data", "randhie", "--methods", name])
    scale._complete(args)
    n = getattr(scale, limit) + 1
    data = scale.load_randhie(n, 10, args)
    cell = scale.run_cell(name, n, data, args)
    assert cell["skipped"].startswith("too large") and "nlpd" not in cell


@pytest.mark.parametrize(
    ("flags", "word"),
    [
        (["--sizes", "100,-5"], "-5"),
        (["--sizes", "100,1.5"], "1.5"),
        (["--sizes", "0"], "0"),
        (["--methods", "exact-em,nope"], "nope"),
        (["--data", "mnist"], "mnist"),
        (["--data", "randhie", "--init", "oracle"], "oracle"),
    ],
)
def test_bad_flags_exit_2_with_one_line(scale, tmp_path, refused_flags, flags, word):
    err = refused_flags(scale.main, [*flags, "--out", str(tmp_path)], word)
    assert err.startswith("mixture_scale: error:")
    assert not any(tmp_path.iterdir())


def test_regimes_draw_does_not_depend_on_the_sizes(scale):
    args = scale.parse_args(["--smoke"])
    scale._complete(args)
    small = scale.load_regimes(60, 50, args)
    large = scale.load_regimes(scale.REGIMES_POOL + 10, 50, args)
    assert small.x.shape[0] == scale.REGIMES_POOL and small.x_test.shape == (50, 16)
    # past the pool the draw is larger; the features of the shared rows agree
    assert small.x_test.equal(large.x_test) and large.x.shape[0] == scale.REGIMES_POOL + 10
    # at or below the pool size every run draws the same rows: held-out set and function
    again = scale.load_regimes(120, 50, args)
    assert small.x_test.equal(again.x_test) and small.y.equal(again.y)


def test_cells_of_another_setup_are_recomputed_and_left_out(scale, tmp_path, capsys):
    base = ["--smoke", "--data", "randhie", "--methods", "svgp", "--sizes", "60"]
    assert scale.main([*base, "--out", str(tmp_path)]) == 0
    cell = tmp_path / "randhie" / "svgp_N60.json"
    first = json.loads(cell.read_text())
    assert first["setup"]["seed"] == 0 and first["setup"]["pool_rows"] == 60
    # another seed: another shuffle of the rows, so the stored cell is fitted again
    assert scale.main([*base, "--seed", "1", "--out", str(tmp_path)]) == 0
    second = json.loads(cell.read_text())
    assert second["setup"]["seed"] == 1 and second["nlpd"] != first["nlpd"]
    # the table of a setup shows only that setup's cells
    assert scale.read_cells(tmp_path / "randhie", first["setup"]) == []
    assert [r["nlpd"] for r in scale.read_cells(tmp_path / "randhie", second["setup"])] == [
        second["nlpd"]
    ]
