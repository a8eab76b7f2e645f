"""The chapter 2 study runs end to end on its smoke configuration, resumes without rescanning,
and rejects bad configs and bad figure input; its demo scans, segments and labels a held-out
office scene and draws it.

Covers probaff.experiments.point_cloud_labels.config,
probaff.experiments.point_cloud_labels.comparison,
probaff.experiments.point_cloud_labels.model_report,
probaff.experiments.point_cloud_labels.oracle,
probaff.experiments.point_cloud_labels.demo, probaff.experiments.point_cloud_labels.figures,
probaff.experiments.point_cloud_labels.report, probaff.experiments.point_cloud_labels.run,
probaff.experiments.point_cloud_labels.scans.
"""

import csv
import json
import math
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest
from study_helpers import ROOT, assert_resumes, assert_wrote

from probaff.errors import DatasetError, InputError
from probaff.experiments.point_cloud_labels import SMOKE, PointCloudStudyConfig, run
from probaff.experiments.point_cloud_labels.causes import CAUSES
from probaff.experiments.point_cloud_labels.demo import _centre_view, _undefined_note, demo
from probaff.experiments.point_cloud_labels.figures import (
    plot_entropy_tree,
    plot_label_probabilities,
    plot_merge_views,
    plot_reliability,
    plot_scanned_scene,
    plot_segment_cloud,
)
from probaff.experiments.point_cloud_labels.report import summarise_merge
from probaff.experiments.point_cloud_labels.scans import scan_task
from probaff.perception.labels import LABELS, THESIS_PR
from probaff.perception.scan_labels import PerceptionConfig

_TABLES = ("labels.csv", "refinement.csv", "merge.csv", "models.csv", "causes.csv", "summary.md")
_FIGURES = (
    "segments.png",
    "label_probabilities.png",
    "entropy_tree.png",
    "reliability.png",
    "merge_views.png",
    "labels_vs_truth.png",
)


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _script(out: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]):
    """Run the study script with ``--smoke`` in this process (its imports are paid once)."""
    script = str(ROOT / "inference/point_cloud_labels.py")
    monkeypatch.setattr(sys, "argv", [script, "--smoke", "--out", str(out)])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(script, run_name="__main__")
    assert not done.value.code
    return json.loads(capsys.readouterr().out)["files"]


@pytest.mark.slow
def test_script_smoke_and_resume(tmp_path, monkeypatch, capsys):
    out = tmp_path / "pcl"
    files = _script(out, monkeypatch, capsys)
    assert_wrote(files, out, _TABLES + _FIGURES)
    scans = sorted((out / "tasks").glob("*.json"))
    assert [p.name.split(".")[0] for p in scans] == [f"scene_{i:03d}" for i in range(4)]
    merges = sorted((out / "merge_tasks").glob("*.json"))
    assert len(merges) == 1
    arrays = np.load(next((out / "tasks").glob("scene_000.*.npz")))
    first = json.loads(scans[0].read_text())
    n_seg = len(first["object_ids"])
    assert np.asarray(first["features"]).shape == (n_seg, 25)
    assert arrays["points"].shape == (len(arrays["point_segments"]), 3)
    assert arrays["point_segments"].max() == n_seg - 1
    counts = np.bincount(arrays["point_segments"][arrays["point_segments"] >= 0])
    assert counts.tolist() == first["point_counts"]  # the npz rows are the record's segments
    assert all(0 < p <= 1 for p in first["purity"])

    labels = _rows(out / "labels.csv")
    assert [r["label"] for r in labels] == [*LABELS, "average"] * 2
    assert [r["min_points"] for r in labels] == ["50"] * 7 + ["300"] * 7
    records = [json.loads(p.read_text()) for p in scans]
    total = sum(len(r["object_ids"]) for r in records)
    large = sum(int(n >= 300) for r in records for n in r["point_counts"])
    assert {int(r["segments"]) for r in labels[:7]} == {total}
    assert {int(r["segments"]) for r in labels[7:]} == {large} and large < total
    for r in labels:
        assert float(r["thesis_precision_pct"]) == THESIS_PR[r["label"]][0]
        assert 0.0 <= float(r["auc"]) <= 1.0
    refinement = _rows(out / "refinement.csv")
    assert len(refinement) == 1 and float(refinement[0]["purity_before"]) == 1.0
    assert float(refinement[0]["groups"]) <= float(refinement[0]["segments"])
    merge = {(r["proximity"], int(r["views"])): r for r in _rows(out / "merge.csv")}
    assert list(merge) == [("points", 1), ("points", 2), ("centroid", 1), ("centroid", 2)]
    centroid, points = merge["centroid", 2], merge["points", 2]
    assert float(centroid["segments"]) >= float(merge["centroid", 1]["segments"])  # more seen
    # One view merges nothing either way; over two, the points link more than the centroids.
    assert merge["points", 1] == {**merge["centroid", 1], "proximity": "points"}
    assert float(points["segments"]) < float(centroid["segments"])
    assert float(points["completeness"]) > float(centroid["completeness"])
    record = json.loads(merges[0].read_text())
    with np.load(merges[0].with_suffix(".npz")) as merged_points:
        for v, view in enumerate(record["views"]):  # the npz's points are the views' segments'
            on = merged_points["point_views"] == v
            rows = np.bincount(merged_points["point_segments"][on], minlength=1)
            assert rows.tolist() == view["point_counts"]
            assert merged_points["points"][on].shape == (int(on.sum()), 3)
    assert np.asarray(first["context"]).shape == (n_seg, 23)
    assert np.asarray(first["mixed"]).shape == (n_seg, 6) and len(first["fragment"]) == n_seg
    oracle = first["oracle"]
    assert min(first["oracle_rows"]) >= -1 and max(first["oracle_rows"]) < len(oracle["labels"])
    pairs = set(zip(oracle["views"], oracle["object_ids"], strict=True))
    assert len(pairs) == len(oracle["labels"])
    models = _rows(out / "models.csv")
    names = ["thesis", "capacity", "new", "whole_object"]
    assert [(r["min_points"], r["model"], r["label"]) for r in models] == [
        (m, name, label) for m in ("0", "300") for name in names for label in [*LABELS, "average"]
    ]
    for r in models:
        for key in ("precision", "recall"):
            value, lo, hi = (r[f"{key}{s}"] for s in ("_pct", "_lo", "_hi"))
            if value not in ("", "nan"):
                assert float(lo) <= float(value) <= float(hi)
    causes = _rows(out / "causes.csv")
    assert [r["label"] for r in causes] == [*LABELS, "all"] * 2
    every = causes[6]
    shares = [float(every[f"{c}_pct"]) for c in CAUSES]
    assert int(every["errors"]) == int(every["fp"]) + int(every["fn"]) > 0
    assert sum(shares) == pytest.approx(100.0)
    assert int(every["tp"]) + int(every["fp"]) + int(every["fn"]) + int(every["tn"]) == 6 * total
    text = (out / "summary.md").read_text()
    assert "195 segments from 10 office scenes" in text and "81.8 / 81.7" in text
    assert "Where the baseline's errors come from" in text

    merges += [p.with_suffix(".npz") for p in merges]
    # resumes: no rescans
    assert assert_resumes(lambda: _script(out, monkeypatch, capsys), scans + merges) == files


def test_summarise_merge_needs_points_for_the_points_proximity():
    with pytest.raises(InputError, match="needs points"):
        summarise_merge([], [], (1,), ("points", "centroid"))
    with pytest.raises(InputError, match="1 records; give one per record"):
        summarise_merge([{"index": 0, "views": []}], [], (1,), ("points",), [])


def test_config_boosting_carries_the_tree_settings(tmp_path):
    config = PointCloudStudyConfig(
        out=str(tmp_path), seed=3, boosting_rounds=7, boosting_threshold="0.4"
    )
    opt = config.boosting
    assert (opt.max_iter, opt.seed, opt.threshold, opt.calibration) == (7, 3, 0.4, "sigmoid")
    assert PointCloudStudyConfig(boosting_calibration="isotonic").boosting.calibration == "isotonic"


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"n_splits": 1}, "n_splits must be"),
        ({"n_scenes": 2.5}, "n_scenes must be"),
        ({"scene_counts": (10, 3)}, "fewer scenes than n_splits"),
        ({"scene_counts": ()}, "scene_counts is empty"),
        ({"min_gains": (-0.1,)}, "min_gains must be finite numbers >= 0"),
        ({"min_gains": (float("nan"),)}, "min_gains must be finite"),
        ({"view_counts": (1, 8)}, "more than the 4 merge_pans_deg"),
        ({"view_counts": (0,)}, "view_counts must be"),
        ({"merge_scenes": 11}, "merge_scenes=11 exceeds n_scenes=10"),
        ({"perception": {"k": 30}}, "perception must be a PerceptionConfig"),
        ({"merge_pans_deg": (float("inf"),), "view_counts": (1,)}, "merge_pans_deg must be"),
        ({"merge_proximities": ("centroids",)}, "merge_proximities must hold distinct names"),
        ({"merge_proximities": ("points", "points")}, "merge_proximities must hold distinct"),
        ({"merge_proximities": ()}, "merge_proximities must hold distinct names among points"),
        ({"boosting_threshold": "best"}, "boosting_threshold must be one of 'fixed', 'f1'"),
        ({"boosting_threshold": "1.5"}, r"boosting_threshold must be .* a number in \(0, 1\)"),
        ({"boosting_calibration": "platt"}, "boosting_calibration must be one of isotonic"),
        ({"boosting_rounds": 0}, "boosting_rounds must be a positive integer"),
    ],
)
def test_bad_config(tmp_path, overrides, message):
    config = PointCloudStudyConfig(out=str(tmp_path / "pcl"), **overrides)
    with pytest.raises(InputError, match=message):
        run(config)
    assert not (tmp_path / "pcl").exists()  # nothing scanned before the check


def test_figures_reject_bad_input(tmp_path):
    png = tmp_path / "f.png"
    pts = np.zeros((4, 3))
    with pytest.raises(InputError, match="points is empty"):
        plot_segment_cloud(np.zeros((0, 3)), np.zeros(0), png)
    with pytest.raises(InputError, match="points"):
        plot_segment_cloud([[0.0, np.nan, 0.0]], [0], png)
    with pytest.raises(InputError, match="point_segments"):
        plot_segment_cloud(pts, [0, 1, -2, 0], png)
    with pytest.raises(InputError, match="refers to row 3"):
        plot_label_probabilities(pts, [0, 1, 2, 3], np.full((2, 6), 0.5), png)
    with pytest.raises(InputError, match="probabilities"):
        plot_label_probabilities(pts, [0, 0, 0, 0], np.full((1, 6), 1.5), png)
    with pytest.raises(InputError, match="parent must be -1 for the root"):
        plot_entropy_tree([0, 1, 1], [1.0, 0.5, 0.4], [-1, 0, 2], png)
    with pytest.raises(InputError, match="depth is empty"):
        plot_entropy_tree([], [], [], png)
    with pytest.raises(InputError, match="n_views must hold positive integers"):
        plot_merge_views([0, 2], [1, 1], [1, 1], [1, 1], png)
    with pytest.raises(InputError, match="accuracy"):
        plot_merge_views([1, 2], [1, 1], [1, 1], [1, 2], png)
    with pytest.raises(InputError, match="frequency"):
        plot_reliability([0.25, 0.75], np.zeros((5, 2)), np.zeros((6, 2)), png)
    with pytest.raises(InputError, match="counts must be >= 0"):
        plot_reliability([0.25, 0.75], np.zeros((6, 2)), -np.ones((6, 2)), png)
    assert not png.exists()


def test_entropy_tree_and_merge_figures_are_written(tmp_path):
    tree = plot_entropy_tree(
        [0, 1, 1, 2, 2], [1.2, 0.6, 0.9, 0.2, 0.5], [-1, 0, 0, 1, 1], tmp_path / "tree.png"
    )
    views = plot_merge_views(
        [1, 2, 4], [0.9, 0.85, 0.8], [0.6, 0.7, 0.8], [0.7, 0.75, 0.8], tmp_path / "views.png"
    )
    assert Path(tree).stat().st_size > 0 and Path(views).stat().st_size > 0


def test_damaged_scan_arrays_are_named(tmp_path):
    from probaff.experiments.point_cloud_labels.scans import read_arrays as _read_arrays

    npz = tmp_path / "scan_0.npz"
    np.savez(npz, points=np.zeros((3, 3)), point_segments=np.zeros(3, dtype=np.int32))
    assert _read_arrays(npz, ("points",))["points"].shape == (3, 3)
    with pytest.raises(DatasetError, match=r"scan_0\.npz .*delete it and rerun the study"):
        _read_arrays(npz, ("point_views",))  # an array the file lacks
    npz.write_bytes(npz.read_bytes()[:50])
    with pytest.raises(DatasetError, match=r"cannot read the scan arrays .*scan_0\.npz"):
        _read_arrays(npz, ("points",))
    with pytest.raises(DatasetError, match="cannot read the scan arrays"):
        _read_arrays(tmp_path, ("points",))


# --- the demo


@pytest.mark.slow
def test_demo_draws_the_held_out_scene(tmp_path, capsys):
    # three training scenes of the centre view here; probaff demo's own run trains on 22 scenes
    # of three views
    summary = demo(
        tmp_path / "pcl", seed=0, scenes=4, perception=SMOKE["perception"], progress=False
    )
    png = tmp_path / "pcl" / "scanned_scene.png"
    assert summary["file"] == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20_000  # four panels of thousands of points, not a blank page
    assert summary["scenes"] == 4 and summary["views"] == 1
    assert summary["segments"] > 5 and summary["train_segments"] > 3 * 5
    assert 0 <= summary["unassigned"] < summary["points"]
    for key in ("precision_pct", "recall_pct", "new_precision_pct", "new_recall_pct"):
        assert math.isfinite(summary[key]) and 0.0 <= summary[key] <= 100.0
    # each mean comes with its 95 % interval over the held-out scene's segments
    for model, prefix in (("thesis", ""), ("new", "new_")):
        row = summary["intervals"][model]
        for name in ("precision", "recall"):
            assert row[f"{name}_pct"] == summary[f"{prefix}{name}_pct"]
            assert 0.0 <= row[f"{name}_lo"] <= row[f"{name}_pct"] <= row[f"{name}_hi"] <= 100.0
        assert row["precision_hi"] - row["precision_lo"] > 1.0  # one scene: not a point
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2
    assert f"{summary['segments']} segments" in out[0]
    for model in ("thesis", "new"):
        row = summary["intervals"][model]
        assert (
            f"{row['precision_pct']:.1f} [{row['precision_lo']:.1f}, {row['precision_hi']:.1f}] "
            f"/ {row['recall_pct']:.1f} [{row['recall_lo']:.1f}, {row['recall_hi']:.1f}] %"
        ) in out[1]
    # The held-out scene is the study's scene 0 scanned with the smoke perception (same stream).
    record = scan_task(0, 0, SMOKE["perception"], None)
    assert len(record["object_ids"]) == summary["segments"]
    assert record["n_points"] == summary["points"]
    assert record["n_unassigned"] == summary["unassigned"]


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("seed", -1, "seed must be an integer >= 0, got -1"),
        ("scenes", 1, "scenes must be an integer >= 2, got 1"),
        ("scenes", 2.5, "scenes must be an integer >= 2, got 2.5"),
        ("perception", {"pans_deg": (0.0,)}, "perception must be a PerceptionConfig, got dict"),
    ],
)
def test_demo_rejects_a_bad_seed_or_scene_count_before_any_work(tmp_path, field, value, message):
    with pytest.raises(InputError, match=message):
        demo(tmp_path / "demo", progress=False, **{field: value})
    assert not (tmp_path / "demo").exists()


def test_a_held_out_view_without_labels_says_why_its_means_read_n_a():
    # demo seed 9's centre view: 19 segments, none with a label, none predicted
    assert _undefined_note(np.zeros((19, 6), dtype=bool)).startswith(" (n/a: this scene's")
    assert _undefined_note(np.eye(6, dtype=bool)) == ""


def test_the_demo_draws_the_view_nearest_straight_ahead():
    assert _centre_view(PerceptionConfig()) == 1  # pans -30, 0, 30: the second view
    assert _centre_view(PerceptionConfig(pans_deg=(20.0, -5.0), tilts_deg=(30.0, 40.0))) == 2
    assert _centre_view(SMOKE["perception"]) == 0


def test_scanned_scene_rejects_bad_input(tmp_path):
    points = np.random.default_rng(0).uniform(0.5, 3.0, size=(40, 3))
    rows = np.repeat(np.arange(4), 10)
    probs = np.full((4, 6), 0.5)
    top = tmp_path / "top.png"
    assert plot_scanned_scene(points, rows, probs, top) == str(top) and top.stat().st_size
    plot_scanned_scene(points, rows, probs, tmp_path / "cam.png", viewpoint=(0.0, 0.0, 1.2))
    with pytest.raises(InputError, match="labels"):
        plot_scanned_scene(points, rows, probs, tmp_path / "x.png", labels=())
    with pytest.raises(InputError):
        plot_scanned_scene(points, rows, probs, tmp_path / "x.png", labels=("flyable",))
    with pytest.raises(InputError, match="rows"):
        plot_scanned_scene(points, rows, probs[:3], tmp_path / "x.png")
    with pytest.raises(InputError, match="viewpoint"):
        plot_scanned_scene(points, rows, probs, tmp_path / "x.png", viewpoint=(0.0, 1.2))
