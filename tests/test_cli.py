"""The `probaff` command line."""

import json
import subprocess
import sys

from probaff.cli import main
from probaff.data.generation import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.experiments.modular.demo import demo as modular_demo


def test_generate_and_describe(tmp_path, capsys):
    out = tmp_path / "ds"
    assert (
        main(
            [
                "generate",
                "--scene",
                "near_obstacle",
                "--n",
                "6",
                "--seed",
                "2",
                "--out",
                str(out),
                "--workers",
                "0",
                "--shard-size",
                "4",
                "--quiet",
            ]
        )
        == 0
    )
    capsys.readouterr()
    assert main(["describe", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_pushes"] == 6
    assert summary["objects"]["o2"]["mean_abs_effect"]["dz_p_m"] < 0.002  # the battery
    assert set(summary["object_counts"]) == {"book", "battery"}
    for key in ("fraction_moved_gt_1cm", "fraction_fell_off"):
        assert key in summary["objects"]["o1"]


def test_existing_output_needs_resume(tmp_path, capsys):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "something").write_text("x")
    code = main(
        [
            "generate",
            "--scene",
            "two_objects",
            "--n",
            "2",
            "--out",
            str(out),
            "--workers",
            "0",
            "--quiet",
        ]
    )
    assert code == 2
    assert "--resume" in capsys.readouterr().err


def test_unknown_scene_and_corrupt_dataset(tmp_path, capsys):
    assert (
        main(
            [
                "generate",
                "--scene",
                "garage",
                "--n",
                "2",
                "--out",
                str(tmp_path / "a"),
                "--workers",
                "0",
                "--quiet",
            ]
        )
        == 2
    )
    assert "unknown scene 'garage'" in capsys.readouterr().err
    assert main(["describe", str(tmp_path)]) == 2
    assert "not a probaff dataset" in capsys.readouterr().err


def test_negative_count(tmp_path, capsys):
    assert (
        main(
            [
                "generate",
                "--scene",
                "two_objects",
                "--n",
                "-3",
                "--out",
                str(tmp_path / "a"),
                "--workers",
                "0",
                "--quiet",
            ]
        )
        == 2
    )
    assert "n must be a positive integer" in capsys.readouterr().err


def test_demo_smoke(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "probaff.cli", "demo", "--out", str(tmp_path), "--n", "8"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "figure:" in proc.stdout
    for png in (
        tmp_path / "demo_pushes.png",
        tmp_path / "modular" / "tabletop_predictions.png",
        tmp_path / "modular" / "sideview_predictions.png",
    ):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "three-object chain: position error per object" in proc.stdout
    assert "pick (" in proc.stdout and "place (" in proc.stdout
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


def test_scenes_listing(capsys):
    assert main(["scenes"]) == 0
    assert "two_objects" in capsys.readouterr().out


def test_study_subcommand_runs_the_registered_studies_with_their_flags(capsys, tmp_path):
    from probaff.cli import main

    assert main(["study", "--help"]) == 0
    assert (
        "studies: affordance_map, modular, planning, point_cloud_labels" in capsys.readouterr().out
    )
    assert main(["study", "nope"]) == 2
    assert "unknown study 'nope'" in capsys.readouterr().err
    out = str(tmp_path / "out")
    assert main(["study", "planning", "--trials", "0", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err == "probaff study planning: error: trials must be a positive integer, got 0.\n"
