"""The chapter 2 demo scans, segments and labels a held-out office scene and draws it."""

import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.eval.label_figures import plot_scanned_scene
from probaff.studies.point_cloud_labels import SMOKE_OVERRIDES, demo, scan_task


def test_demo_draws_the_held_out_scene(tmp_path, capsys):
    summary = demo(tmp_path / "pcl", seed=0, progress=False)
    png = tmp_path / "pcl" / "scanned_scene.png"
    assert summary["file"] == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20_000  # four panels of thousands of points, not a blank page
    assert summary["scenes"] == 4
    assert summary["segments"] > 5 and summary["train_segments"] > 3 * 5
    assert 0 <= summary["unassigned"] < summary["points"]
    for key in ("precision_pct", "recall_pct"):
        assert math.isfinite(summary[key]) and 0.0 <= summary[key] <= 100.0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2
    assert f"{summary['segments']} segments" in out[0]
    assert f"{summary['precision_pct']:.1f} / {summary['recall_pct']:.1f} %" in out[1]
    # The held-out scene is the study's scene 0 scanned with the smoke perception (same stream).
    record = scan_task(0, 0, SMOKE_OVERRIDES["perception"], None)
    assert len(record["object_ids"]) == summary["segments"]
    assert record["n_points"] == summary["points"]
    assert record["n_unassigned"] == summary["unassigned"]


def test_demo_rejects_a_bad_seed(tmp_path):
    with pytest.raises(InputError, match="seed"):
        demo(tmp_path, seed=-1, progress=False)


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
