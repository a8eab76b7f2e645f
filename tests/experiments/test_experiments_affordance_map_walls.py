"""The affordance-map study in the warehouse with interior walls: what it records and reports.

Covers probaff.experiments.affordance_map.report (pooled precision and recall against the
thesis, the paired AUC and the Fig. 3.7 verdict where both loops push),
probaff.experiments.affordance_map.figures (the paired-difference figure, wall blocks on the
loop's map), probaff.experiments.affordance_map.run (the walls of a test map) and
probaff.experiments.affordance_map.demo.
"""

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
from study_helpers import map_result

from probaff.experiments.affordance_map import AffordanceMapConfig, world
from probaff.experiments.affordance_map.demo import demo
from probaff.experiments.affordance_map.figures import plot_auc_difference, plot_loop_steps
from probaff.experiments.affordance_map.report import markdown, summarise
from probaff.experiments.affordance_map.run import STREAM_TEST, map_task, train_classifier
from probaff.planning.manipulation.loop import LoopSnapshot
from probaff.sim import generate_map
from probaff.sim.world_files import worlds_dir

PNG = b"\x89PNG\r\n\x1a\n"


def _result(index, ig_curve, ex_curve, counts):
    return map_result(index, ig_curve, ex_curve, counts, [[0, 0], [0, 1], [2, 2]], [[0, 1]])


COUNTS = {"tp": [8, 8, 6, 6], "fp": [2, 2, 2, 2], "fn": [2, 2, 2, 2], "tn": [4, 4, 4, 4]}


def test_summary_pools_direction_pairs_and_judges_fig_3_7():
    config = AffordanceMapConfig(max_steps=2, sensor="scanner")
    faster = [_result(i, [10.0, 4.0, 2.0], [10.0, 8.0 + 0.1 * i, 6.0], COUNTS) for i in range(4)]
    summary, _, _ = summarise(config, faster, None)
    pairs = summary["classifier"]["pairs"]
    assert pairs["up/down"] == pytest.approx([0.8, 0.8])  # 16 / (16 + 4) both ways
    assert pairs["left/right"] == pytest.approx([0.75, 0.75])
    assert summary["world"] == {"blocks_per_map": 3.0, "wall_blocks_per_map": 1.0}
    diff = summary["auc_difference"]
    # AUC (trapezoid): 10.0 against 16.0 + 0.1 i, so the paired difference is -6 - 0.1 i
    np.testing.assert_allclose(diff["per_map"], [-6.0, -6.1, -6.2, -6.3])
    assert diff["mean"] == pytest.approx(-6.15) and summary["fig_3_7_holds"] is True
    text = markdown(config, world(sensor="scanner"), summary, 2)
    assert "| up/down | 80.0 | 80.0 | 81.5 | 79.7 |" in text
    assert "| left/right | 75.0 | 75.0 | 73.1 | 74.1 |" in text
    assert "Fig. 3.7's finding holds" in text and "1.0 are interior wall blocks" in text
    # Faster on some maps and slower on others: the interval straddles zero, so the finding
    # fails.
    mixed = [
        _result(i, [10.0, 4.0, 2.0] if i % 2 else [10.0, 9.0, 8.0], [10.0, 6.0, 5.0], COUNTS)
        for i in range(4)
    ]
    summary, _, _ = summarise(config, mixed, None)
    assert summary["fig_3_7_holds"] is False
    assert summary["fig_3_7"]["verdict"] == "unresolved"
    assert "is not resolved" in markdown(config, world(sensor="scanner"), summary, 2)
    summary, _, _ = summarise(config, faster[:1], None)
    assert summary["fig_3_7_holds"] is None  # one map: no interval


def test_figures_of_the_paired_difference_and_the_walls(tmp_path):
    plot_auc_difference([-3.0, -1.0, 0.5], 2.0, tmp_path / "auc.png")
    assert (tmp_path / "auc.png").read_bytes()[:8] == PNG
    occ = np.zeros((4, 4), dtype=bool)
    occ[1, 1:3] = True
    walls = np.zeros_like(occ)
    walls[1, 2] = True
    shot = LoopSnapshot(occ, np.full((4, 4, 4), 0.5), (3, 3), (1, 1, 0), 2.0)
    plot_loop_steps([shot], tmp_path / "with.png", walls=walls)
    plot_loop_steps([shot], tmp_path / "without.png")
    assert (tmp_path / "with.png").read_bytes()[:8] == PNG
    assert (tmp_path / "with.png").read_bytes() != (tmp_path / "without.png").read_bytes()


@pytest.mark.slow
def test_a_test_map_records_its_walls_and_their_labels():
    spec = dataclasses.replace(
        world(sensor="scanner"), rows=6, cols=6, boxes=(4, 6), wall_segments=(1, 2)
    )
    classifier, _ = train_classifier(spec, 1, 0)
    settings = {"seed": 0, "max_steps": 1, "stop_at_no_gain": True}
    out = map_task(spec, classifier, 0, settings)
    m = generate_map(spec, np.random.default_rng((0, STREAM_TEST, 0)))  # the task's map
    assert out["walls"] == np.argwhere(m.walls).tolist() and out["walls"]
    assert out["boxes"] == m.boxes.tolist()  # every block, as the sensor sees them
    counts = {k: np.sum(v) for k, v in out["classifier"].items()}
    # Every direction of every described block is scored, walls included (never pushable).
    assert sum(counts.values()) % 4 == 0 and sum(counts.values()) <= 4 * len(out["boxes"])


@pytest.mark.slow
def test_the_demo_map_holds_walls(tmp_path, capsys):
    out = demo(tmp_path, seed=0, steps=1)
    walls = {tuple(c) for c in out["walls"]}
    boxes = {tuple(c) for c in out["boxes"]}
    assert walls and boxes and not walls & boxes
    assert Path(out["figure"]).read_bytes()[:8] == PNG
    assert "interior wall blocks" in capsys.readouterr().out


def test_an_edited_world_file_gets_its_own_results(tmp_path, monkeypatch):
    before = AffordanceMapConfig().fingerprint()
    dst = tmp_path / "worlds"
    shutil.copytree(worlds_dir(), dst)
    text = (dst / "warehouse.yaml").read_text()
    (dst / "warehouse.yaml").write_text(text.replace("segments: [3, 5]", "segments: [1, 2]"))
    monkeypatch.setenv("PROBAFF_WORLDS", str(dst))
    assert world().wall_segments == (1, 2)
    assert AffordanceMapConfig().fingerprint() != before
