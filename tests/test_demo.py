"""`probaff demo`: settings checked before any work, the parts of its report, and one whole run
through the command line read as a report (the only full demo of the suite).

Covers probaff.demo.
"""

import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.data.summary import summarize
from probaff.demo import DemoConfig, _dataset_table, _fit_warnings, _Report, _warning_note, run
from probaff.errors import InputError
from probaff.experiments.modular.demo import demo as modular_demo

COLLAPSE = "collapsed expert(s) (summed responsibility < 3.0) took samples from another expert"
PNG = b"\x89PNG\r\n\x1a\n"
TABLE_HEADER = "object  moved >1 cm  fell off  hand contact  along push    across      turn"


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("n", 0, "n must be a positive integer, got 0"),
        ("seed", -1, "seed must be an integer >= 0, got -1"),
        ("workers", -1, "workers must be an integer >= 0, got -1"),
        ("office_scenes", 1, "office_scenes must be an integer >= 2, got 1"),
    ],
)
def test_bad_settings_are_refused_before_any_work(tmp_path, field, value, message):
    with pytest.raises(InputError, match=message):
        run(DemoConfig(out=str(tmp_path / "demo"), **{field: value}))
    assert not (tmp_path / "demo").exists()


def test_a_note_merges_em_iterations_and_counts_repeats():
    messages = [f"EM iteration {i}: {COLLAPSE}." for i in (3, 1, 1)] + ["GP failed."] * 2
    assert _warning_note("the mixture M=3 fit", messages) == (
        f"note: 5 warnings from the mixture M=3 fit: {COLLAPSE} (3 times, EM iterations 1 to "
        "3); GP failed (2 times)"
    )
    assert _warning_note("x", [f"EM iteration 2: {COLLAPSE}."]) == (
        f"note: 1 warning from x: {COLLAPSE} (EM iteration 2)"
    )


def test_a_fits_runtime_warnings_become_one_note_and_others_still_show():
    notes = []
    with pytest.warns(UserWarning, match="not a fit's") as shown, _fit_warnings("the fit", notes):
        for _ in range(2):  # the same warning from the same line is counted twice
            warnings.warn(f"EM iteration 1: {COLLAPSE}.", RuntimeWarning, stacklevel=1)
        warnings.warn("not a fit's", UserWarning, stacklevel=1)
    assert [w.category for w in shown] == [UserWarning]
    assert notes == [f"note: 2 warnings from the fit: {COLLAPSE} (2 times, EM iteration 1)"]
    with pytest.raises(ValueError, match="failed fit"), _fit_warnings("a failed fit", notes):
        warnings.warn("GP failed.", RuntimeWarning, stacklevel=1)
        raise ValueError("failed fit")
    assert notes[1] == "note: 1 warning from a failed fit: GP failed"


def test_a_stage_prints_its_lines_and_notes_together_under_its_title(capsys):
    report = _Report(2, progress=False)
    with report.stage("first") as notes:
        print("a line")
        warnings.warn(f"EM iteration 4: {COLLAPSE}.", RuntimeWarning, stacklevel=1)
        notes.append("note: from a fit")
    with pytest.raises(ValueError, match="stage 2"), report.stage("second"):
        print("before the failure")
        raise ValueError("stage 2")
    report.close()
    assert capsys.readouterr().out.splitlines() == [
        "",
        "first",
        "  a line",
        "  note: from a fit",
        f"  note: 1 warning from this stage's fits: {COLLAPSE} (EM iteration 4)",
        "",
        "second",
        "  before the failure",
    ]


def test_the_dataset_table_has_a_row_per_object_slot(tmp_path):
    ds = generate(
        GenerateConfig("two_objects", 2, seed=1, shard_size=2, pose_noise=PoseNoise()),
        tmp_path / "ds",
        progress=False,
    )
    lines = _dataset_table(summarize(ds))
    assert lines[0].startswith("2 pushes of scene two_objects (seed 1), 2 objects each")
    assert "poses seen with 3 mm / 1 deg noise" in lines[0]
    assert lines[1] == TABLE_HEADER
    assert [line.split()[0] for line in lines[2:4]] == ["o1", "o2"]
    assert all(len(line) == len(TABLE_HEADER) for line in lines[2:4])
    assert lines[-1].startswith("objects: ")


@pytest.mark.slow
def test_the_demo_command_prints_a_report_ending_with_its_figures(tmp_path):
    proc = subprocess.run(
        # 8 pushes and 4 office scenes (3 train) instead of the default 96 and 23
        [
            sys.executable,
            "-m",
            "probaff.cli",
            "demo",
            "--out",
            str(tmp_path),
            "--n",
            "8",
            "--office-scenes",
            "4",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    lines = proc.stdout.splitlines()
    # a table, not a JSON dump
    assert f"  {TABLE_HEADER}" in lines
    assert '"n_pushes"' not in proc.stdout and not {"{", "}"} & {s.strip() for s in lines}
    # the fits' warnings are notes of the report, never printed as warnings
    assert "RuntimeWarning" not in proc.stdout + proc.stderr
    assert "collapsed expert" not in proc.stderr
    assert all(s.lstrip().startswith("note: ") for s in lines if "collapsed expert" in s)
    # each part's lines
    assert "figure:" in proc.stdout
    assert "three-object chain: position error per object" in proc.stdout
    assert "pick (" in proc.stdout and "place (" in proc.stdout
    # the summary of its headline numbers, then the paths of its figures, last
    start, figures = lines.index("summary"), lines.index("figures")
    headlines = [s.split()[0] for s in lines[start + 1 : figures]]
    assert headlines == ["pushes", "o2", "NLPD", "map", "push", "three-object", "office"]
    # the affordance map's world holds interior wall blocks besides its boxes
    (amap,) = [s for s in lines[start + 1 : figures] if s.split()[0] == "map"]
    assert re.search(r"; [1-9]\d* boxes, [1-9]\d* wall blocks that look like boxes\)$", amap)
    paths = [s.strip() for s in lines[figures + 1 :]]
    for name in ("demo_pushes.png", "demo_o2_density.png", "planning/edge_episode.png"):
        assert str(tmp_path / name) in paths
    for png in (
        tmp_path / "demo_pushes.png",
        tmp_path / "modular" / "tabletop_predictions.png",
        tmp_path / "modular" / "sideview_predictions.png",
        *paths,
    ):
        assert Path(png).read_bytes()[:8] == PNG
    # a second run finds the finished dataset and the chapter 6 records and resumes them
    again = generate(
        GenerateConfig("two_objects", 8, seed=0, shard_size=16, pose_noise=PoseNoise()),
        tmp_path / "two_objects",
        resume=True,
        progress=False,
    )
    assert len(again) == 8
    records = sorted((tmp_path / "modular" / "tasks").glob("*.json"))
    stamp = [p.stat().st_mtime_ns for p in records]
    modular_demo(tmp_path / "modular", progress=False)
    assert [p.stat().st_mtime_ns for p in records] == stamp and len(records) == 3
