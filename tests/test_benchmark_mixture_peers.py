"""Smoke test of benchmarks/mixture_peers.py: same folds for every model, tables and figure."""

import csv
import math

import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def peers(benchmark_script):
    with benchmark_script("mixture_peers") as module:
        yield module


def test_smoke_run_writes_rows_tables_and_figure(peers, tmp_path):
    models = ["single_gp", "ccr", "em"]
    argv = [
        "--smoke",
        "--datasets",
        "synthetic,diabetes",
        "--models",
        ",".join(models),
        "--out",
        str(tmp_path),
        "--no-progress",
    ]
    assert peers.main(argv) == 0

    with open(tmp_path / "peers.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    keys = {(r["dataset"], r["model"], r["fold"]) for r in rows}
    assert keys == {
        (d, m, str(f)) for d in ("synthetic", "diabetes") for m in models for f in (0, 1)
    }
    assert len(rows) == len(keys)
    for r in rows:
        assert r["error"] == "", r["error"]
        for col in ("nlpd", "nlpd_joint", "srmse", "coverage90", "seconds"):
            assert math.isfinite(float(r[col])), (r["model"], col)
        assert 0.0 <= float(r["coverage90"]) <= 1.0
        outputs = ("y0", "y1") if r["dataset"] == "synthetic" else ("progression",)
        assert all(float(r[f"rmse.{o}"]) > 0 for o in outputs)
    # every model saw the same folds
    for d in ("synthetic", "diabetes"):
        sizes = {(r["fold"], r["n_train"], r["n_test"]) for r in rows if r["dataset"] == d}
        assert len(sizes) == 2

    md = (tmp_path / "peers.md").read_text()
    assert "## synthetic" in md and "## diabetes" in md and "**" in md
    assert (tmp_path / "peers.png").stat().st_size > 0
    assert len(list((tmp_path / "tasks").glob("*.json"))) == len(rows)

    # a rerun finds every result saved and fits nothing
    mtimes = {p: p.stat().st_mtime_ns for p in (tmp_path / "tasks").glob("*.json")}
    assert peers.main(argv) == 0
    assert {p: p.stat().st_mtime_ns for p in mtimes} == mtimes


def test_unknown_names_exit_2(peers, tmp_path, capsys):
    assert peers.main(["--models", "nope", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nope" in err
    assert peers.main(["--datasets", "synthetic,mnist", "--out", str(tmp_path)]) == 2
    assert "mnist" in capsys.readouterr().err
    assert not (tmp_path / "peers.csv").exists()


def test_em_init_variants_follow_fit_em_signature(peers):
    has_init = peers.fit_em_accepts("init")
    variants = {f"em_{name}" for name in peers.EM_INITS}
    assert variants <= set(peers.MODELS) if has_init else not variants & set(peers.MODELS)
    assert {"single_gp", "ccr", "clustered", "em", "vi"} <= set(peers.MODELS)


def test_motorcycle_loads_the_shipped_crash_data(peers, tmp_path):
    ds = peers.DATASETS["motorcycle"](tmp_path, None, False)
    assert ds.X.shape == (133, 1) and ds.Y.shape == (133, 1) and ds.outputs == ("accel",)
    assert ds.X[0, 0] < ds.X[-1, 0]  # time after impact, ms, in order
    assert -150.0 < ds.Y.min() < -100.0 < 50.0 < ds.Y.max() < 100.0  # acceleration, g
    assert peers.DATASETS["motorcycle"](tmp_path, 40, False).X.shape == (40, 1)
