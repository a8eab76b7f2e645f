"""benchmarks/mixture_peers.py: a smoke run (same folds for every model, tables and figure),
and its regression guard against the committed reference of CI's subset
(benchmarks/reference/mixture_peers_fast.csv), with the guard's bad input and comparison."""

import contextlib
import csv
import io
import math
from pathlib import Path

import pytest

REFERENCE = Path(__file__).resolve().parents[1] / "benchmarks" / "reference"
FAST_REFERENCE = REFERENCE / "mixture_peers_fast.csv"
FAST = [
    "--datasets",
    "engel,motorcycle,synthetic",
    "--models",
    "em,single_gp",
    "--folds",
    "2",
    "--rows",
    "200",
    "--no-progress",
]
"""CI's subset: the command line that wrote FAST_REFERENCE (see the script's docstring)."""


@pytest.fixture(scope="module")
def peers(benchmark_script):
    with benchmark_script("mixture_peers") as module:
        yield module


@pytest.mark.slow
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


def test_unknown_names_exit_2(peers, tmp_path, capsys, refused_flags):
    refused_flags(peers.main, ["--models", "nope", "--out", str(tmp_path)], "nope")
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


# --- the regression guard: CI's subset against its committed reference


def _main(peers, argv):
    """`peers.main(argv)`: its status, standard output and standard error."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = peers.main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def fast_run(peers, tmp_path_factory):
    """CI's subset fitted once (real fits, the default budget), compared with its reference."""
    out = tmp_path_factory.mktemp("fast")
    return out, _main(peers, [*FAST, "--out", str(out), "--reference", str(FAST_REFERENCE)])


@pytest.mark.slow
def test_fast_subset_is_no_worse_than_its_reference(fast_run):
    out, (status, stdout, stderr) = fast_run
    assert status == 0, f"regressions against {FAST_REFERENCE}:\n{stderr}\n{stdout}"
    assert "| engel | em | nlpd | 2/2 |" in stdout and "WORSE" not in stdout
    assert (out / "peers_vs_reference.md").is_file()


@pytest.mark.slow
def test_guard_flags_a_worse_run_and_rewrites_its_reference(peers, fast_run, tmp_path):
    """The same run (resumed from its stored fits) against a reference that it falls short of."""
    out, _ = fast_run
    settings, rows = peers.load_reference(FAST_REFERENCE)
    for row in rows:
        if (row["dataset"], row["model"]) == ("synthetic", "em"):
            row["nlpd"] -= 0.2  # the reference was better by 0.2 nats
        if (row["dataset"], row["model"]) == ("engel", "single_gp"):
            row["rmse"] = [0.9 * v for v in row["rmse"]]
    better = tmp_path / "better.csv"
    better.write_text(peers.reference_text(settings, rows))
    status, stdout, stderr = _main(peers, [*FAST, "--out", str(out), "--reference", str(better)])
    assert status == 1
    flagged = [line for line in stderr.splitlines() if "regression" in line]
    assert len(flagged) == 2, stderr
    assert "synthetic/em nlpd" in stderr and "engel/single_gp rmse.foodexp" in stderr
    assert stdout.count("**WORSE**") == 2
    # a looser tolerance accepts the same run
    loose = ["--tolerance", "0.3", "--rmse-tolerance", "0.2"]
    assert _main(peers, [*FAST, "--out", str(out), "--reference", str(better), *loose])[0] == 0

    written = tmp_path / "sub" / "again.csv"
    status, stdout, _ = _main(peers, [*FAST, "--out", str(out), "--write-reference", str(written)])
    assert status == 0 and f"wrote reference {written}" in stdout
    assert not list(written.parent.glob(".*tmp*"))
    again, committed = peers.load_reference(written), peers.load_reference(FAST_REFERENCE)
    assert again[0] == committed[0]
    assert peers.compare_with_reference(again[1], committed[1], 1e-6, 1e-6) == []


def _reference(peers, tmp_path, edit=None, settings_edit=None):
    """A copy of the fast reference, its text edited by `edit` or its settings by one."""
    settings, rows = peers.load_reference(FAST_REFERENCE)
    if settings_edit:
        settings_edit(settings)
    text = peers.reference_text(settings, rows)
    path = tmp_path / "reference.csv"
    path.write_text(edit(text) if edit else text)
    return path


def _refused(peers, tmp_path, argv, *needles):
    """`main(argv)` exits 2 with one line on stderr that holds every needle, having fit nothing."""
    status, _, err = _main(peers, [*argv, "--out", str(tmp_path / "out"), "--no-progress"])
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1, err
    for needle in needles:
        assert needle in err, err
    assert not (tmp_path / "out" / "tasks").exists()


def _drop_line(prefix):
    return lambda text: "\n".join(x for x in text.splitlines() if not x.startswith(prefix))


def _first_row(edit):
    """Edit the cells of the table's first row (dataset, model, metric, folds, mean, half)."""

    def apply(text):
        lines = text.splitlines()
        at = next(i for i, x in enumerate(lines) if x.startswith("dataset,")) + 1
        lines[at] = ",".join(edit(lines[at].split(",")))
        return "\n".join(lines)

    return apply


CORRUPT = {
    "no settings line": (_drop_line("# settings"), "'# settings:' lines, not one"),
    "settings not JSON": (lambda t: t.replace('"budget": {', '"budget": {{', 1), "not JSON"),
    "renamed column": (lambda t: t.replace("half_width", "hw", 1), "its columns are"),
    "text in a number": (_first_row(lambda c: [*c[:4], "six", c[5]]), "must be numbers"),
    "infinite mean": (_first_row(lambda c: [*c[:4], "inf", c[5]]), "a finite mean"),
    "negative half-width": (_first_row(lambda c: [*c[:5], "-1"]), "a half-width >= 0"),
    "a cell missing": (_first_row(lambda c: c[:5]), "expected 6 cells"),
    "unknown metric": (_first_row(lambda c: [*c[:2], "r2", *c[3:]]), "a metric"),
    "repeated row": (lambda t: t + t.splitlines()[-1] + "\n", "repeats"),
    "metric missing": (_drop_line("engel,em,nlpd"), "engel/em lacks nlpd"),
    "no rows": (lambda t: "\n".join(t.splitlines()[:3]), "holds no results"),
}


@pytest.mark.parametrize("case", list(CORRUPT))
def test_a_corrupted_reference_exits_2(peers, tmp_path, case):
    edit, message = CORRUPT[case]
    path = _reference(peers, tmp_path, edit)
    _refused(peers, tmp_path, [*FAST, "--reference", str(path)], f"--reference {path}", message)


def test_a_missing_or_unreadable_reference_exits_2(peers, tmp_path):
    missing = tmp_path / "nope.csv"
    _refused(peers, tmp_path, [*FAST, "--reference", str(missing)], str(missing), "does not exist")
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    _refused(peers, tmp_path, [*FAST, "--reference", str(binary)], str(binary), "cannot be read")
    _refused(peers, tmp_path, [*FAST, "--reference", str(tmp_path)], "cannot be read")
    old = _reference(peers, tmp_path, settings_edit=lambda s: s.update(version=0))
    _refused(peers, tmp_path, [*FAST, "--reference", str(old)], "format version 0")


SUBSET = ["--datasets", "engel", "--models", "em", "--no-progress"]
MISMATCHED = {
    "folds": (["--folds", "3", "--rows", "200"], "folds=2 but this run has folds=3"),
    "seed": (["--folds", "2", "--rows", "200", "--seed", "1"], "seed=0 but this run has seed=1"),
    "rows": (["--folds", "2", "--rows", "100"], "rows=200 but this run has rows=100"),
    "smoke": (["--rows", "200", "--smoke"], "smoke=false"),
}


@pytest.mark.parametrize("case", list(MISMATCHED))
def test_a_reference_of_other_settings_exits_2(peers, tmp_path, case):
    flags, message = MISMATCHED[case]
    argv = [*SUBSET, *flags, "--reference", str(FAST_REFERENCE)]
    _refused(peers, tmp_path, argv, f"--reference {FAST_REFERENCE}", message)


def test_a_reference_without_the_runs_pairs_or_of_other_data_exits_2(peers, tmp_path):
    argv = ["--datasets", "engel,diabetes", "--models", "em,ccr", "--folds", "2", "--rows", "200"]
    _refused(
        peers,
        tmp_path,
        [*argv, "--reference", str(FAST_REFERENCE)],
        "lacks engel/ccr, diabetes/em, diabetes/ccr",
        "choose --datasets and --models among those",
    )

    def shrink(settings):
        settings["shapes"]["engel"] = [199, 1, 1]

    other = _reference(peers, tmp_path, settings_edit=shrink)
    subset = [*SUBSET, "--folds", "2", "--rows", "200", "--reference", str(other)]
    _refused(peers, tmp_path, subset, "the data changed", "[199, 1, 1]")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-0.1", "abc", ""])
@pytest.mark.parametrize("option", ["--tolerance", "--rmse-tolerance"])
def test_a_bad_tolerance_exits_2(peers, tmp_path, option, value):
    argv = [*FAST, "--reference", str(FAST_REFERENCE), f"{option}={value}"]
    _refused(peers, tmp_path, argv, f"{option} must be a finite number >= 0, got {value!r}")


def test_other_bad_guard_flags_exit_2(peers, tmp_path):
    _refused(peers, tmp_path, [*FAST, "--tolerance", "0.1"], "--tolerance applies only with")
    _refused(peers, tmp_path, [*FAST, "--rows", "1"], "--rows must be at least --folds (2)")
    _refused(peers, tmp_path, [*FAST, "--write-reference", str(tmp_path)], "--write-reference")


def test_no_reference_is_written_from_failed_fits(peers, tmp_path, monkeypatch):
    def broken(fold):
        raise RuntimeError("boom")

    monkeypatch.setitem(peers.MODELS, "em", peers.FitPredict(broken))
    target = tmp_path / "ref.csv"
    argv = ["--datasets", "motorcycle", "--models", "em", "--folds", "2", "--rows", "20"]
    argv += ["--out", str(tmp_path / "out"), "--no-progress", "--write-reference", str(target)]
    status, _, err = _main(peers, argv)
    assert status == 1 and "2 fit(s) failed" in err and not target.exists()


# --- compare_with_reference on hand-made rows


def _row(dataset="d", model="em", *, folds=5, nlpd=1.0, srmse=0.5, rmse=(2.0, 4.0)):
    return {
        "dataset": dataset,
        "model": model,
        "folds": folds,
        "of": 5,
        "outputs": ["a", "b"],
        "nlpd": nlpd,
        "nlpd_ci": 0.1,
        "srmse": srmse,
        "srmse_ci": 0.05,
        "rmse": list(rmse),
        "rmse_ci": [0.2, 0.4],
    }


def test_compare_with_reference_flags_only_what_is_worse_beyond_the_tolerance(peers):
    compare = peers.compare_with_reference
    ref = [_row(), _row(model="single_gp", nlpd=2.0)]
    assert compare(ref, ref) == []
    # within the tolerance: NLPD 0.04 nats worse, RMSE 4 % worse
    near = [_row(nlpd=1.04, srmse=0.52, rmse=(2.08, 4.0)), _row(model="single_gp", nlpd=2.0)]
    assert compare(near, ref, nlpd_tol=0.05, rmse_tol=0.05) == []
    # improvements are never regressions
    better = [_row(nlpd=-3.0, srmse=0.1, rmse=(0.5, 1.0))]
    assert compare(better, ref) == []
    assert {r["status"] for r in peers.comparison_rows(better, ref)} == {"better"}
    # beyond it: NLPD by 0.06 nats, the second output's RMSE by 6 %
    worse = [_row(nlpd=1.06, rmse=(2.0, 4.24)), _row(model="single_gp", nlpd=2.0)]
    (nl, rm) = compare(worse, ref, nlpd_tol=0.05, rmse_tol=0.05)
    assert (nl.dataset, nl.model, nl.metric) == ("d", "em", "nlpd")
    assert nl.reference == 1.0 and nl.now == 1.06 and nl.limit == pytest.approx(1.05)
    assert rm.metric == "rmse.b" and rm.limit == pytest.approx(4.2)
    assert "d/em nlpd: now 1.06" in str(nl)
    # a wider tolerance accepts the same run; SRMSE is held to the relative tolerance too
    assert compare(worse, ref, nlpd_tol=0.1, rmse_tol=0.1) == []
    (sr,) = compare([_row(srmse=0.6)], ref, rmse_tol=0.1)
    assert sr.metric == "srmse" and sr.limit == pytest.approx(0.55)


def test_compare_with_reference_flags_failed_fits(peers):
    ref = [_row()]
    (failed,) = peers.compare_with_reference([_row(folds=4)], ref)
    assert (failed.metric, failed.now, failed.reference) == ("folds", 4, 5)
    unscored = peers.compare_with_reference([_row(folds=0, nlpd=math.nan, srmse=math.nan)], ref)
    assert [r.metric for r in unscored] == ["folds", "nlpd", "srmse"]


def test_compare_with_reference_bad_input(peers):
    ref = [_row()]
    for bad in (math.nan, math.inf, -0.01, "x", None, True):
        with pytest.raises(peers.InputError, match="nlpd_tol must be a finite number >= 0"):
            peers.compare_with_reference(ref, ref, nlpd_tol=bad)
        with pytest.raises(peers.InputError, match="rmse_tol must be a finite number >= 0"):
            peers.compare_with_reference(ref, ref, rmse_tol=bad)
    with pytest.raises(peers.InputError, match="the reference lacks d/vi"):
        peers.compare_with_reference([_row(model="vi")], ref)
    other_outputs = dict(_row(), outputs=["a", "c"])
    with pytest.raises(peers.InputError, match="the reference lacks d/em with outputs"):
        peers.compare_with_reference([other_outputs], ref)


def test_reference_text_round_trips(peers):
    settings = {
        "version": peers.REFERENCE_VERSION,
        "folds": 5,
        "seed": 0,
        "rows": None,
        "smoke": False,
        "budget": {"gp_iter": 50},
        "datasets": ["d"],
        "models": ["em", "single_gp"],
        "shapes": {"d": [10, 2, 2]},
    }
    rows = [_row(), _row(model="single_gp", nlpd=-2.5)]
    back_settings, back = peers.parse_reference(peers.reference_text(settings, rows))
    assert back_settings == settings
    assert [(r["dataset"], r["model"], r["folds"], r["outputs"]) for r in back] == [
        ("d", "em", 5, ["a", "b"]),
        ("d", "single_gp", 5, ["a", "b"]),
    ]
    for got, want in zip(back, rows, strict=True):
        for key in ("nlpd", "nlpd_ci", "srmse", "srmse_ci", "rmse", "rmse_ci"):
            assert got[key] == pytest.approx(want[key], rel=1e-7), key
    assert peers.compare_with_reference(rows, back, 0.0, 0.0) == []
